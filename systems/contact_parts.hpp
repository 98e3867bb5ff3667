#pragma once
// The contact pass's kernels for each rolling law (RollingModel), each compiled in a translation
// unit of its own (contact_pass_none.cpp, _epsd2, _epsd, _cdt; the kernel in contact_kernel.hpp) so
// that a build compiles them side by side: together they are 216 instantiations of one kernel, and
// in one file they were the build's longest step (3 min of a 4.7 min build on 2 cores). The library
// alone now builds 20-26 % faster on 2 cores; a whole build there is CPU-bound either way
// (docs/architecture.md).
// ContactPass::run and setup (contact_pass.cpp) call the one the model's rolling law names, with
// `update` true for a step and false for the setup pass (histories frozen).
#include "systems/contact_pass.hpp"

namespace sandcell::contact_parts {

void run_none(const Model& model, State& state, Scratch& scratch, Executor& exec, bool update);
void run_epsd2(const Model& model, State& state, Scratch& scratch, Executor& exec, bool update);
void run_epsd(const Model& model, State& state, Scratch& scratch, Executor& exec, bool update);
void run_cdt(const Model& model, State& state, Scratch& scratch, Executor& exec, bool update);

}  // namespace sandcell::contact_parts
