// The contact pass's kernels for the rolling law epsd2 (contact_parts.hpp).
#include "systems/contact_kernel.hpp"

namespace sandcell::contact_parts {

void run_epsd2(const Model& model, State& state, Scratch& scratch, Executor& exec, bool update) {
  run_rolling<RollingModel::epsd2>(model, state, scratch, exec, update);
}

}  // namespace sandcell::contact_parts
