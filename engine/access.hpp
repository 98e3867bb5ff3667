#pragma once
// Component access declarations and their run-time check.
//
// A system declares the components it reads and writes; the step graph orders systems from those
// sets. While a system runs inside the graph (or through run_system), an AccessScope names it on
// the calling thread, and every State/Scratch accessor checks the component against the declared
// sets. A violation fails SANDCELL_CHECK with the system's and the component's names. The check
// costs one thread-local load and a mask test per accessor call (systems fetch arrays once per
// run, not per element), so it stays on unless SANDCELL_CHECK_ACCESS is disabled at configure time.
#include "components/fields.hpp"

#include <cstdint>
#include <initializer_list>
#include <string_view>

namespace sandcell {

using ComponentMask = std::uint64_t;

constexpr ComponentMask mask_of(Component c) { return ComponentMask{1} << static_cast<unsigned>(c); }

constexpr ComponentMask mask_of(std::initializer_list<Component> cs) {
  ComponentMask m = 0;
  for (Component c : cs) m |= mask_of(c);
  return m;
}

struct AccessSets {
  std::string_view system;
  ComponentMask reads = 0;
  ComponentMask writes = 0;
};

/// Marks the calling thread as running `sets.system` until destroyed (restores the previous one,
/// so nested scopes from work stealing stay correct).
class AccessScope {
 public:
  explicit AccessScope(const AccessSets& sets);
  ~AccessScope();
  AccessScope(const AccessScope&) = delete;
  AccessScope& operator=(const AccessScope&) = delete;

 private:
  const AccessSets* previous_;
};

namespace detail {
void check_access_slow(Component c, bool write);
}

/// Checks that the system running on this thread declared `c` (as written, when `write`).
/// No-op outside any system (setup code, I/O, tests).
inline void check_access([[maybe_unused]] Component c, [[maybe_unused]] bool write) {
#ifdef SANDCELL_CHECK_ACCESS
  detail::check_access_slow(c, write);
#endif
}

/// Whether component access checks are compiled in.
constexpr bool access_checks_enabled() {
#ifdef SANDCELL_CHECK_ACCESS
  return true;
#else
  return false;
#endif
}

}  // namespace sandcell
