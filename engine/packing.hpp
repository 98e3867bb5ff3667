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

/// A State holding the packing's spheres (ids 0..N-1 in file order, at rest, positions wrapped
/// into the box), all of the given material.
State make_state(const Model& model, const Packing& packing, std::uint32_t material = 0);

}  // namespace sandcell
