#pragma once
// Plain-text packings, the format of the benchmark scene: lines starting with '#' are comments;
// the first data line is `Lx Ly Lz N`; then N lines `x y z r` (SI units, box [0, L) periodic).
#include "engine/state.hpp"

#include <string>
#include <vector>

namespace sandcell {

struct Packing {
  Vec3 box = Vec3::Zero();     // m
  std::vector<Vec3> position;  // m
  std::vector<double> radius;  // m
};

/// Reads a packing; throws std::runtime_error naming the file, the line and what was expected.
Packing read_packing(const std::string& path);

/// The packing repeated k x k x k times in its periodic box (k >= 1): box k times larger, k^3 N spheres,
/// copy (i, j, l) shifted by (i, j, l) . box, in that order (copy-major, then the file's order). A
/// periodic packing tiled is the same periodic packing: every sphere has the same neighbours at the same
/// distances, so the density, contacts per sphere and stress are the original's (a large benchmark
/// scene without a new preparation). Throws std::invalid_argument for k < 1.
Packing tile_packing(const Packing& packing, int k);

/// A State holding the packing's spheres (ids 0..N-1 in file order, at rest, positions wrapped
/// into the box), all of the given material.
State make_state(const Model& model, const Packing& packing, std::uint32_t material = 0);

}  // namespace sandcell
