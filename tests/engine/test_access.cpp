// The access check: a system touching a component outside its declared sets is caught, with names.
#include "engine/assert.hpp"
#include "engine/step_graph.hpp"
#include "support/scenes.hpp"

#include <doctest/doctest.h>

using namespace sandcell;
using C = Component;

namespace {
struct HandlerGuard {
  AssertHandler previous = set_assert_handler(&test::throwing_assert_handler);
  ~HandlerGuard() { set_assert_handler(previous); }
};

// Declares: reads position, writes velocity. Touches force (not declared) when asked to.
struct Sneaky {
  static constexpr std::string_view name = "sneaky";
  static constexpr ComponentMask reads = mask_of(C::particle_position);
  static constexpr ComponentMask writes = mask_of(C::particle_velocity);
  static inline int mode = 0;  // 0: only declared access, 1: writes force, 2: reads torque, 3: writes position
  static void run(const Model&, State& state, Scratch&, Executor&) {
    (void)state.read<C::particle_position>();
    state.write<C::particle_velocity>().clear();
    if (mode == 1) state.write<C::particle_force>().clear();
    if (mode == 2) (void)state.read<C::particle_torque>();
    if (mode == 3) state.write<C::particle_position>().clear();
  }
};
}  // namespace

TEST_CASE("undeclared component access fails the check with the system's and component's names") {
  static_assert(access_checks_enabled(), "this build disabled SANDCELL_CHECK_ACCESS; the test needs it");
  HandlerGuard guard;
  Model model;
  State state;
  Scratch scratch;
  Executor exec({Backend::serial, 1});
  const SystemSpec sys = make_system<Sneaky>();

  Sneaky::mode = 0;
  CHECK_NOTHROW(run_system(sys, model, state, scratch, exec));

  Sneaky::mode = 1;
  CHECK_THROWS_WITH_AS(run_system(sys, model, state, scratch, exec),
                       "system 'sneaky' writes component 'particle_force' outside its declared write set",
                       test::AssertionError);
  Sneaky::mode = 2;
  CHECK_THROWS_WITH_AS(run_system(sys, model, state, scratch, exec),
                       "system 'sneaky' reads component 'particle_torque' outside its declared read set",
                       test::AssertionError);
  // Declared as read only: writing it is a violation too.
  Sneaky::mode = 3;
  CHECK_THROWS_WITH_AS(run_system(sys, model, state, scratch, exec),
                       "system 'sneaky' writes component 'particle_position' outside its declared write set",
                       test::AssertionError);

  // Through the step graph (serial backend, so the exception reaches the caller directly).
  Sneaky::mode = 1;
  StepGraph graph({sys}, exec);
  CHECK_THROWS_AS(graph.run(model, state, scratch), test::AssertionError);
  Sneaky::mode = 0;
}

TEST_CASE("outside any system, access is unchecked (setup code, I/O)") {
  HandlerGuard guard;
  State state;
  CHECK_NOTHROW(state.write<C::particle_force>().clear());
}
