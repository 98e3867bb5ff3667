#pragma once
// Velocity-Verlet integration of spheres in a deforming periodic cell, in the form of
// LAMMPS/LIGGGHTS nve/sphere, split into the two halves the step graph places around the forces:
//
//   integrate_initial: v~ += F/m dt/2, w += T/I dt/2, x += (v~ + D x) dt, L_k += D_kk L_k dt
//                      (a shearing cell: x += (v~ + L x) dt, H += L H dt, L upper triangular);
//   integrate_final:   v~ += F/m dt/2, w += T/I dt/2.
//
// Newton's law acts on the fluctuating velocity v~; positions move with the full velocity
// v~ + D x, so with v~ = 0 a particle keeps its reduced coordinates x_k / L_k (affine motion): the
// cell and the positions are scaled by the same factor (1 + D_kk dt) each step.
// Positions are not wrapped here: the pair list stores each pair's periodic image, which stays
// valid only while positions are continuous. The broadphase wraps them into the cell when it
// rebuilds the list (so they leave the cell by at most half a skin), and scenes without contacts
// schedule the `wrap` system after this one (systems/wrap.hpp). Since the affine field D x is
// homogeneous, a branch vector x_i - x_j - H n evolves the same with wrapped or unwrapped x.
// Within one World::step(n) call (Scratch::batching), integrate_final may leave its kick to the
// next step's integrate_initial (it declares `deferred_to`), which then applies both half kicks and
// the drift in one pass: the same additions in the same order, one pass over the particles less
// per step. World calls integrate_final's `flush` before returning, which applies a kick left
// pending. The two share a KickState (Scratch::own): both write the velocities, so the graph
// orders them and never runs them at once.
// Reads forces, torques, masses and inverse inertias; writes positions, velocities, angular
// velocities, and the cell lengths (initial half only). Per-particle independent: a parallel_for.
#include "engine/system.hpp"

namespace sandcell {

struct IntegrateInitial {
  static constexpr std::string_view name = "integrate_initial";
  static constexpr ComponentMask reads = mask_of({Component::particle_force, Component::particle_torque,
                                                  Component::particle_mass, Component::particle_inv_inertia});
  static constexpr ComponentMask writes = mask_of({Component::particle_position, Component::particle_velocity,
                                                   Component::particle_angular_velocity, Component::cell});
  static void run(const Model& model, State& state, Scratch& scratch, Executor& exec);
};

/// The final half kick left to the next integrate_initial (shared by the two integrator halves).
struct KickState {
  bool pending = false;
};

/// Whether a final half kick is waiting for the next step (World never leaves one between calls).
inline bool kick_pending(const Scratch& scratch) {
  return scratch.has<KickState>() && scratch.own<KickState>().pending;
}

struct IntegrateFinal {
  static constexpr std::string_view name = "integrate_final";
  static constexpr std::string_view deferred_to = "integrate_initial";
  static constexpr ComponentMask reads = mask_of({Component::particle_force, Component::particle_torque,
                                                  Component::particle_mass, Component::particle_inv_inertia});
  static constexpr ComponentMask writes = mask_of({Component::particle_velocity, Component::particle_angular_velocity});
  static void run(const Model& model, State& state, Scratch& scratch, Executor& exec);
  /// Applies a kick left pending (the end of a World::step_until call).
  static void flush(const Model& model, State& state, Scratch& scratch, Executor& exec);
};

/// Particles per parallel_for chunk for per-particle loops.
inline constexpr std::size_t k_particle_grain = 1024;

}  // namespace sandcell
