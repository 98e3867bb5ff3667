#pragma once
// contact: the contact pass. For every pair of the list, the normal law (ContactSettings::normal:
// Hertz by default, or any law registered in systems/laws/normal_laws.hpp), the tangential law
// (ContactSettings::tangential) with its Coulomb cap and the rolling law (ContactSettings::rolling)
// when the model has one, composed at compile time (systems/laws/law.hpp); docs/physics.md
// sections 2 and 3.
//
// Reads the pair list, positions, fluctuating and angular velocities, masses (epsd rolling),
// materials, the cell and the per-pair constants (radii, R*, m*, image code) of the list. Writes,
// per pair slot, the force on i and the torques on i and j (contact_forces), the tangential history
// (contact_tangential) and the rolling history (contact_rolling). One parallel_for over pairs; each
// pair writes only its own slots, so no atomics are needed and the per-particle sums are left to
// force_gather in a fixed order. Keeps, as its own scratch (ContactScratch), each pair's regime
// of the last step (caps, or open) and the order in which it visits the pairs of a block: the
// order is a branch hint that changes no result; an open pair marked open is not written again,
// so the regimes are started again with every new pair list (contact_kernel.hpp).
// The relative velocity at the contact includes the affine part D r unless liggghts_compat.
// Pairs in the list that do not touch get zero force and zero history (history resets when a
// contact opens). The pass is instantiated per (laws, affine term), so the hot loop has no
// run-time switches.
#include "engine/system.hpp"
#include "systems/laws/law.hpp"

#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace sandcell {

struct ContactPass {
  static constexpr std::string_view name = "contact";
  static constexpr ComponentMask reads =
      mask_of({Component::contact_pairs, Component::particle_position, Component::particle_velocity,
               Component::particle_angular_velocity, Component::particle_mass, Component::particle_material,
               Component::cell, Component::pair_constants, Component::gather_index});
  static constexpr ComponentMask writes =
      mask_of({Component::contact_forces, Component::contact_tangential, Component::contact_rolling,
               Component::halo, Component::stress_blocks});
  static void run(const Model& model, State& state, Scratch& scratch, Executor& exec);
  /// Checks the laws' names and parameters (std::invalid_argument naming the key); allocates the
  /// rolling history only for the rolling laws that keep one (epsd2, epsd).
  static void prepare(const Model& model, State& state);
  /// The forces of the initial configuration, histories frozen.
  static void setup(const Model& model, State& state, Scratch& scratch, Executor& exec);
  /// The step the contacts allow now (contact_stable_step), for an adaptive time step, and what it reads.
  static double stable_step(const Model& model, const State& state);
  static constexpr ComponentMask stable_step_reads =
      mask_of({Component::contact_pairs, Component::particle_id, Component::particle_position,
               Component::particle_radius, Component::particle_mass, Component::particle_inv_inertia,
               Component::particle_material, Component::cell});
};

/// Contact pass private buffers: last step's regime of each pair and the order in which the pass
/// visits the pairs of each block of 64 (contact_kernel.hpp says why). Every pair is visited once
/// whatever the order and writes only its own slots. One regime is more than a hint: an open pair
/// marked apart is not written again, its outputs being zero since it opened; so the regimes hold
/// for one list only (a new list, PairConstants::generation, starts them again) and a World made
/// from a state starts without them. Not checkpointed.
struct ContactScratch {
  static constexpr std::uint8_t k_apart = 4;  // regime of an open pair: its outputs and histories zero since it opened
  std::vector<std::uint8_t> regime;           // (m) -, pair k in the last step: bit 0 Coulomb cap, bit 1 rolling cap;
                                              //   or k_apart
  std::vector<std::uint8_t> order;            // (m) -, per block, a permutation of its pair offsets 0..63
  std::vector<std::uint8_t> stale;            // (blocks) -, 1: a regime in the block changed, sort it again
  std::vector<std::uint8_t> sorted;  // (blocks) -, 1: visit in `order`; 0: all touching, none capped: array order
  std::uint64_t generation = ~std::uint64_t{0};  // -, PairConstants::generation the regimes describe
};

/// On the steps the homogenizer measures the stress (servo_due), the contact pass sums f (x) r over
/// each block of k_stress_block pairs from the branch vectors and forces it has in hand, and the
/// homogenizer adds the blocks in order (scratch component `stress_blocks`): the pairs are not read
/// a second time. Each block's sum is in array order, pair t into partial sum t % 4, the four
/// combined as (0 + 1) + (2 + 3): the same operations in every build and for any visiting order,
/// so the same bits for any thread count and partition. Allocated on the first servo step: a run
/// without a servo has none.
struct StressBlocks {
  static constexpr Component component = Component::stress_blocks;
  static constexpr std::size_t k_stress_block = 64;  // pairs per block (the pass's blocks)
  std::vector<double> sum;                           // (9 per block) N m, sum of f_a r_b, a-major
  std::uint64_t step = ~std::uint64_t{0};            // -, clock step they were summed at (none: max)
  std::size_t pairs = 0;                             // -, pairs of that pass
};

/// Pairs per parallel_for chunk for per-contact loops (1024: ~76 chunks on the 20k benchmark, so
/// the last chunk leaves a thread idle for less of the pass than with 4096).
inline constexpr std::size_t k_contact_grain = 1024;

/// The elastic energy stored in the touching contacts (normal springs, tangential and rolling
/// histories), J, as the model's laws define it; serial, in pair order (an output-step cost).
double contact_elastic_energy(const Model& model, const State& state);

/// Where the stiffness time step is bound: the particle, the mode and its stiffness.
struct StableStepBound {
  double step = 0.0;            // s, min over particles of sqrt(m / K) and sqrt(I / K_rot) (+inf: no contact)
  std::uint32_t id = 0;         // the particle's id
  bool rotational = false;      // sqrt(I / K_rot) (the tangential and rolling springs on its rotation)
  double stiffness = 0.0;       // N/m or N m/rad, the summed K of that particle, axis and mode
};

/// The largest step the contacts allow now, before the safety factor (docs/physics.md section 4.1):
/// per particle and axis a, K_a = sum over its touching contacts of k_n' n_a^2 + k_t (1 - n_a^2)
/// and K_rot,a = sum (k_t r^2 + k_r) (1 - n_a^2), with k_n' = dF_n/d delta the tangent normal
/// stiffness, k_t counted only with friction and k_r (the rolling law's, epsd2 and epsd) only with
/// rolling friction; the bound is the least sqrt(m / K_a), sqrt(I / K_rot,a). Serial, in pair order.
StableStepBound contact_stable_step(const Model& model, const State& state);

/// The registered normal laws' names, comma-separated (for messages).
std::string normal_law_names();

/// The registered normal laws with their parameters (name, units, range: systems/laws/law.hpp).
struct NormalLawInfo {
  std::string name;
  std::vector<LawParameter> parameters;
};
std::vector<NormalLawInfo> normal_laws();

// The tangential and rolling laws by name (systems/laws/mindlin.hpp TangentialLaws, rolling.hpp
// k_rolling_laws): what the apps' configs, dem-bench and Python accept.
std::vector<std::string> tangential_law_names();
std::optional<TangentialModel> tangential_law(std::string_view name);
std::string tangential_law_name(TangentialModel law);
std::vector<std::string> rolling_law_names();
std::optional<RollingModel> rolling_law(std::string_view name);
std::string rolling_law_name(RollingModel law);

}  // namespace sandcell
