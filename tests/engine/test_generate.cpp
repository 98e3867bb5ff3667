// Sample generation: non-overlapping (periodic images included), reproducible for a seed, and the
// size distribution asked for (uniform by number, or a gradation by mass).
#include "engine/generate.hpp"
#include "engine/packing.hpp"

#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>

using namespace sandcell;

namespace {

// Smallest gap r_ij - R_i - R_j over all pairs and the 27 images (brute force).
double smallest_gap(const Packing& p) {
  double gap = HUGE_VAL;
  for (std::size_t i = 0; i < p.position.size(); ++i)
    for (std::size_t j = i + 1; j < p.position.size(); ++j)
      for (int nx = -1; nx <= 1; ++nx)
        for (int ny = -1; ny <= 1; ++ny)
          for (int nz = -1; nz <= 1; ++nz) {
            const Vec3 d = p.position[i] - p.position[j] - Vec3(nx * p.box[0], ny * p.box[1], nz * p.box[2]);
            gap = std::min(gap, d.norm() - p.radius[i] - p.radius[j]);
          }
  return gap;
}

}  // namespace

TEST_CASE("generate: uniform sizes, no overlap with any sphere or image, reproducible") {
  GenerationSettings g;
  g.count = 600;
  g.sizes.d_min = 1e-3;
  g.sizes.d_max = 2e-3;
  g.solid_fraction = 0.3;
  g.seed = 5;
  const Packing a = generate_packing(g);
  REQUIRE(a.position.size() == 600);
  CHECK(smallest_gap(a) >= 0.0);
  double solid = 0.0;
  for (std::size_t k = 0; k < a.radius.size(); ++k) {
    CHECK(a.radius[k] >= 0.5e-3);
    CHECK(a.radius[k] <= 1e-3);
    for (int d = 0; d < 3; ++d) {
      CHECK(a.position[k][d] >= 0.0);
      CHECK(a.position[k][d] < a.box[d]);
    }
    solid += 4.0 / 3.0 * std::numbers::pi * std::pow(a.radius[k], 3);
  }
  // The cube is sized for the solid fraction exactly (to round-off of the cube root).
  CHECK(solid / a.box.prod() == doctest::Approx(0.3).epsilon(1e-12));
  // Mean diameter of 600 uniform draws on [1, 2] mm: 1.5 mm, standard error 0.29/sqrt(600) = 0.012
  // mm; 4 standard errors is 0.047 mm.
  double mean = 0.0;
  for (double r : a.radius) mean += 2.0 * r / 600.0;
  CHECK(std::abs(mean - 1.5e-3) < 0.047e-3);
  // Same seed, same sample, bit for bit; another seed, another sample.
  const Packing b = generate_packing(g);
  CHECK(a.position == b.position);
  CHECK(a.radius == b.radius);
  g.seed = 6;
  CHECK(generate_packing(g).position != a.position);
}

TEST_CASE("generate: a gradation by mass is honoured") {
  // Gradation: 0 % passing 1 mm, 50 % at 2 mm, 100 % at 3 mm (by mass). 20000 draws; the mass
  // fraction passing 2 mm has a sampling error of roughly 1/sqrt(number of large spheres) ~ 1 %
  // (in percent points ~ 0.5-1); 3 percent points is well over 3 standard errors.
  SizeDistribution sizes;
  sizes.kind = SizeDistribution::Kind::gradation;
  sizes.table = {{1e-3, 0.0}, {2e-3, 50.0}, {3e-3, 100.0}};
  const std::vector<double> d = sample_diameters(sizes, 20000, 3);
  const std::vector<double> pass = percent_passing(d, {1.5e-3, 2e-3, 2.5e-3});
  // Linear interpolation of the table: 25 % at 1.5 mm, 50 % at 2 mm, 75 % at 2.5 mm.
  CHECK(std::abs(pass[0] - 25.0) < 3.0);
  CHECK(std::abs(pass[1] - 50.0) < 3.0);
  CHECK(std::abs(pass[2] - 75.0) < 3.0);
  CHECK(*std::min_element(d.begin(), d.end()) >= 1e-3);
  CHECK(*std::max_element(d.begin(), d.end()) <= 3e-3);
}

TEST_CASE("generate: bad settings name the key and the allowed range") {
  GenerationSettings g;
  g.count = 10;
  g.sizes.d_min = 2e-3;
  g.sizes.d_max = 1e-3;
  CHECK_THROWS_WITH_AS(validate(g), doctest::Contains("sample.d_max"), std::invalid_argument);
  g.sizes.d_max = 3e-3;
  g.solid_fraction = 0.5;
  CHECK_THROWS_WITH_AS(validate(g), doctest::Contains("sample.solid_fraction = 0.5"), std::invalid_argument);
  g.solid_fraction = 0.3;
  g.sizes.kind = SizeDistribution::Kind::gradation;
  g.sizes.table = {{1e-3, 0.0}, {0.5e-3, 100.0}};
  CHECK_THROWS_WITH_AS(validate(g), doctest::Contains("diameters must increase"), std::invalid_argument);
  g.sizes.table = {{1e-3, 10.0}, {2e-3, 100.0}};
  CHECK_THROWS_WITH_AS(validate(g), doctest::Contains("gradation[0].percent"), std::invalid_argument);
}

TEST_CASE("tile_packing: k^3 copies in a k times larger box, the same periodic packing") {
  // A periodic packing repeated k x k x k times is the same periodic packing: the solid fraction is
  // the original's and every sphere has the same nearest gap (brute force over pairs and images).
  // Tolerances: 1e-12 relative for sums of 8 x 150 volumes; 1e-15 m for a gap of a sum of shifted
  // positions (a few ulps of 1e-2 m).
  GenerationSettings g;
  g.count = 150;
  g.sizes.d_min = 1e-3;
  g.sizes.d_max = 2e-3;
  g.solid_fraction = 0.3;
  g.seed = 11;
  const Packing a = generate_packing(g);
  const Packing t = tile_packing(a, 2);
  REQUIRE(t.position.size() == 8 * a.position.size());
  CHECK(t.box == 2.0 * a.box);
  const auto solid = [](const Packing& p) {
    double v = 0.0;
    for (double r : p.radius) v += 4.0 / 3.0 * std::numbers::pi * r * r * r;
    return v / (p.box[0] * p.box[1] * p.box[2]);
  };
  CHECK(solid(t) == doctest::Approx(solid(a)).epsilon(1e-12));
  CHECK(smallest_gap(t) == doctest::Approx(smallest_gap(a)).epsilon(1e-12));
  // copy (i, j, l) = block (4 i + 2 j + l): the last copy is the original shifted by the box
  const std::size_t n = a.position.size();
  for (std::size_t s = 0; s < n; ++s) {
    CHECK((t.position[7 * n + s] - a.position[s] - a.box).norm() < 1e-15);
    CHECK(t.radius[7 * n + s] == a.radius[s]);
  }
  CHECK(tile_packing(a, 1).position == a.position);
  CHECK_THROWS_AS(tile_packing(a, 0), std::invalid_argument);
}
