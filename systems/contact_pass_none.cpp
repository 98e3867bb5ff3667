// The contact pass's kernels for the rolling law none (contact_parts.hpp).
#include "systems/contact_kernel.hpp"

namespace sandcell::contact_parts {

void run_none(const Model& model, State& state, Scratch& scratch, Executor& exec, bool update) {
  run_rolling<RollingModel::none>(model, state, scratch, exec, update);
}

}  // namespace sandcell::contact_parts
