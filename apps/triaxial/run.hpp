#pragma once
// The triaxial app as a library function, so tests run it in-process.
#include <iosfwd>

namespace sandcell::triaxial {

/// `triaxial [CONFIG.toml] [--threads N] [--out DIR] [--resume] [--overwrite] ...` (see --help).
/// Returns the process exit code: 0 done, 1 a run failed (unstable, I/O), 2 bad input (config or
/// command line; nothing written), 3 stopped on request (--stop-after; continue with --resume).
int triaxial_main(int argc, const char* const* argv, std::ostream& out, std::ostream& err);

}  // namespace sandcell::triaxial
