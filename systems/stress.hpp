#pragma once
// Contact (Love-Weber) stress of the periodic cell, docs/physics.md section 5: S = (1/V) sum_c f_c (x) r_c with f_c
// the force on i and r_c = x_i - (x_j + H n) the branch vector; compression positive for repulsive
// contacts. Deterministic reduction over the pair list. The stress homogenizer system builds on it.
#include "engine/executor.hpp"
#include "engine/state.hpp"

namespace sandcell {

/// sum_c f_c (x) r_c over the pair list (not divided by V, not symmetrized), N m. Deterministic:
/// fixed-grain chunks folded in order.
Mat3 contact_stress_sum(const ContactPairs& pairs, const std::vector<Vec3>& force, const std::vector<Vec3>& x,
                        const Cell& cell, Executor& exec);

/// Symmetrized contact stress tensor, Pa, compression positive.
Mat3 contact_stress(const State& state, Executor& exec);

/// Number of pairs with positive overlap.
std::size_t count_touching(const State& state);

}  // namespace sandcell
