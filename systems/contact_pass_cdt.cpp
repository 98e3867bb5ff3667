// The contact pass's kernels for the rolling law cdt (contact_parts.hpp).
#include "systems/contact_kernel.hpp"

namespace sandcell::contact_parts {

void run_cdt(const Model& model, State& state, Scratch& scratch, Executor& exec, bool update) {
  run_rolling<RollingModel::cdt>(model, state, scratch, exec, update);
}

}  // namespace sandcell::contact_parts
