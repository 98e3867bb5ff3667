#pragma once
// wrap: brings every position back into the cell, x_k in [0, L_k) (a tilted cell: its reduced
// coordinates s = H^-1 x in [0, 1)), after the drift. Scheduled only
// in scenes without contacts; with contacts the broadphase wraps at each list build instead, since
// wrapping between builds would invalidate the periodic images stored with the pairs.
// Reads the cell; writes positions. Per-particle independent: a parallel_for.
#include "engine/system.hpp"

#include <array>

namespace sandcell {

struct Wrap {
  static constexpr std::string_view name = "wrap";
  static constexpr ComponentMask reads = mask_of({Component::cell});
  static constexpr ComponentMask writes = mask_of({Component::particle_position});
  static void run(const Model& model, State& state, Scratch& scratch, Executor& exec);
};

/// Wraps positions [b, e) into [0, L): one subtraction or addition of L per axis, so a particle
/// that moved less than one cell length per step lands exactly at x -/+ L. With `shift`, writes
/// shift[k] = s (indexed from 0 for particle b) such that the new x = old x - s L per axis: what a
/// pair's periodic image must change by to describe the same branch vector.
void wrap_positions(Vec3* x, const Vec3& length, std::size_t b, std::size_t e, std::array<int, 3>* shift = nullptr);

/// The same for any cell: an orthorhombic one as above (bitwise); a tilted one by its reduced
/// coordinates, x <- x - H floor(s), shift = floor(s) (the images of the lattice basis H).
void wrap_positions(Vec3* x, const Cell& cell, std::size_t b, std::size_t e, std::array<int, 3>* shift = nullptr);

}  // namespace sandcell
