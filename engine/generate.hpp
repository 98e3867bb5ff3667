#pragma once
// Sample generation: N non-overlapping spheres placed at random (seeded, reproducible on every
// platform) in a periodic cube at low density, from a size distribution.
//
// Sizes: either uniform in [d_min, d_max] by number, or a gradation table (diameter, percent
// passing by mass), the form a lab sieve analysis gives. A gradation is by mass, so sampling by
// number draws a diameter from the mass distribution (linear between table points) and keeps it
// with probability (d_min/d)^3: the kept diameters then follow the number distribution whose
// mass distribution is the table.
// Placement: random sequential addition, largest first, each candidate tested against every
// sphere already placed and their periodic images (cell lists); a sphere that finds no room after
// `max_attempts` tries is an error naming the solid fraction asked (random sequential addition
// of spheres jams near 0.38).
#include "engine/packing.hpp"

#include <cstdint>
#include <utility>
#include <vector>

namespace sandcell {

struct SizeDistribution {
  enum class Kind { uniform, gradation };
  Kind kind = Kind::uniform;
  double d_min = 0.0;  // m, uniform: smallest diameter
  double d_max = 0.0;  // m, uniform: largest diameter
  // gradation: (diameter m, percent passing by mass), diameters increasing, percent from 0 to 100
  // non-decreasing; the first row's percent is 0 and the last's 100.
  std::vector<std::pair<double, double>> table;

  double smallest() const { return kind == Kind::uniform ? d_min : table.front().first; }
  double largest() const { return kind == Kind::uniform ? d_max : table.back().first; }
};

struct GenerationSettings {
  std::size_t count = 0;  // spheres
  SizeDistribution sizes;
  double solid_fraction = 0.3;  // -, of the generated cloud, in (0, 0.35]
  std::uint64_t seed = 1;
  std::size_t max_attempts = 100000;  // placement tries per sphere
};

/// Checks the settings; throws std::invalid_argument naming the key, the value and what is allowed.
void validate(const GenerationSettings& settings);

/// Diameters, m, drawn by number from the distribution (deterministic for a seed).
std::vector<double> sample_diameters(const SizeDistribution& sizes, std::size_t count, std::uint64_t seed);

/// The generated cloud: cube side from the solid fraction, spheres in [0, L)^3, none overlapping
/// another or a periodic image. Throws std::runtime_error when it cannot place a sphere.
Packing generate_packing(const GenerationSettings& settings);

/// Percent passing by mass at each diameter of `sieves`, m, of a set of spheres (for checking a
/// generated sample against its gradation).
std::vector<double> percent_passing(const std::vector<double>& diameters, const std::vector<double>& sieves);

}  // namespace sandcell
