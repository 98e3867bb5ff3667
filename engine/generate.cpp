#include "engine/generate.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <stdexcept>
#include <string>

namespace sandcell {

namespace {

// mt19937_64's output sequence is fixed by the C++ standard; the conversion to [0, 1) is ours
// (std::uniform_real_distribution is implementation-defined), so a seed gives the same sample on
// every platform.
struct Random {
  std::mt19937_64 engine;
  explicit Random(std::uint64_t seed) : engine(seed) {}
  double uniform() { return static_cast<double>(engine() >> 11) * 0x1.0p-53; }
};

std::string num(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

// Diameter at mass fraction u in [0, 1] of a gradation table (linear interpolation).
double gradation_inverse(const std::vector<std::pair<double, double>>& table, double u) {
  const double percent = 100.0 * u;
  for (std::size_t k = 1; k < table.size(); ++k)
    if (percent <= table[k].second && table[k].second > table[k - 1].second) {
      const double t = (percent - table[k - 1].second) / (table[k].second - table[k - 1].second);
      return table[k - 1].first + t * (table[k].first - table[k - 1].first);
    }
  return table.back().first;
}

}  // namespace

void validate(const GenerationSettings& s) {
  const auto fail = [](const std::string& key, const std::string& value, const std::string& allowed) {
    throw std::invalid_argument("sample." + key + " = " + value + ": " + allowed);
  };
  if (s.count < 1) fail("count", std::to_string(s.count), "must be >= 1");
  if (!(s.solid_fraction > 0.0 && s.solid_fraction <= 0.35))
    fail("solid_fraction", num(s.solid_fraction), "must be in (0, 0.35] (random placement jams near 0.38)");
  if (s.sizes.kind == SizeDistribution::Kind::uniform) {
    if (!(s.sizes.d_min > 0.0)) fail("d_min", num(s.sizes.d_min), "must be > 0 m");
    if (!(s.sizes.d_max >= s.sizes.d_min))
      fail("d_max", num(s.sizes.d_max), "must be >= d_min = " + num(s.sizes.d_min) + " m");
  } else {
    const auto& t = s.sizes.table;
    if (t.size() < 2)
      fail("gradation", std::to_string(t.size()) + " rows", "needs at least 2 rows (diameter, percent passing)");
    for (std::size_t k = 0; k < t.size(); ++k) {
      const std::string row = "gradation[" + std::to_string(k) + "]";
      if (!(t[k].first > 0.0)) fail(row + ".diameter", num(t[k].first), "must be > 0 m");
      if (!(t[k].second >= 0.0 && t[k].second <= 100.0))
        fail(row + ".percent", num(t[k].second), "must be in [0, 100]");
      if (k > 0 && !(t[k].first > t[k - 1].first))
        fail(row + ".diameter", num(t[k].first), "diameters must increase (previous " + num(t[k - 1].first) + " m)");
      if (k > 0 && !(t[k].second >= t[k - 1].second))
        fail(row + ".percent", num(t[k].second),
             "percent passing must not decrease (previous " + num(t[k - 1].second) + ")");
    }
    if (t.front().second != 0.0)
      fail("gradation[0].percent", num(t.front().second), "must be 0 (the smallest diameter)");
    if (t.back().second != 100.0)
      fail("gradation[" + std::to_string(t.size() - 1) + "].percent", num(t.back().second),
           "must be 100 (the largest diameter)");
    // sample_diameters draws by mass and keeps a draw with probability (d_min/d)^3 (by number): the
    // mean of that over the mass distribution is the share of draws kept. A gradation over many
    // decades keeps almost none, and sampling would not end.
    double kept = 0.0;
    constexpr int k_points = 4096;
    for (int k = 0; k < k_points; ++k) {
      const double d = gradation_inverse(t, (k + 0.5) / k_points);
      kept += std::pow(t.front().first / d, 3.0) / k_points;
    }
    if (kept < 1e-4)
      fail("gradation", "[" + num(t.front().first) + " ... " + num(t.back().first) + " m]",
           "spans too wide a range to sample: " + num(1.0 / kept) +
               " draws a sphere (allowed: up to 1e4, e.g. "
               "d_max / d_min <= ~20 for a mass-linear gradation)");
  }
}

std::vector<double> sample_diameters(const SizeDistribution& sizes, std::size_t count, std::uint64_t seed) {
  Random rng(seed);
  std::vector<double> d;
  d.reserve(count);
  if (sizes.kind == SizeDistribution::Kind::uniform) {
    for (std::size_t k = 0; k < count; ++k) d.push_back(sizes.d_min + (sizes.d_max - sizes.d_min) * rng.uniform());
    return d;
  }
  const double d_min = sizes.table.front().first;
  while (d.size() < count) {
    const double candidate = gradation_inverse(sizes.table, rng.uniform());
    const double keep = (d_min / candidate) * (d_min / candidate) * (d_min / candidate);
    if (rng.uniform() < keep) d.push_back(candidate);
  }
  return d;
}

Packing generate_packing(const GenerationSettings& s) {
  validate(s);
  std::vector<double> d = sample_diameters(s.sizes, s.count, s.seed);
  // Largest first: the big spheres find room while the cloud is empty.
  std::sort(d.begin(), d.end(), std::greater<>());
  double solid = 0.0;
  for (double v : d) solid += std::numbers::pi / 6.0 * v * v * v;
  const double side = std::cbrt(solid / s.solid_fraction);
  if (!(side > d.front()))
    throw std::runtime_error("sample: cube side " + num(side) +
                             " m from count and solid fraction is not larger than the largest diameter " +
                             num(d.front()) + " m: use more spheres");

  // Cell lists of width >= d_max: a sphere can only overlap spheres in the 27 surrounding bins.
  const int n_bins = std::max(1, static_cast<int>(std::floor(side / d.front())));
  const double bin_width = side / n_bins;
  std::vector<std::vector<std::uint32_t>> bins(static_cast<std::size_t>(n_bins) * n_bins * n_bins);
  const auto bin_of = [&](double x) { return std::clamp(static_cast<int>(x / bin_width), 0, n_bins - 1); };

  Packing packing;
  packing.box = Vec3::Constant(side);
  packing.position.reserve(d.size());
  packing.radius.reserve(d.size());
  Random rng(s.seed ^ 0x9e3779b97f4a7c15ull);  // placement stream, independent of the size stream
  for (std::size_t k = 0; k < d.size(); ++k) {
    const double r = 0.5 * d[k];
    bool placed = false;
    for (std::size_t attempt = 0; attempt < s.max_attempts && !placed; ++attempt) {
      const Vec3 x(rng.uniform() * side, rng.uniform() * side, rng.uniform() * side);
      const int b[3] = {bin_of(x[0]), bin_of(x[1]), bin_of(x[2])};
      bool free = true;
      // With fewer than 3 bins per axis the offsets revisit a bin: harmless for an overlap test.
      for (int oz = -1; oz <= 1 && free; ++oz)
        for (int oy = -1; oy <= 1 && free; ++oy)
          for (int ox = -1; ox <= 1 && free; ++ox) {
            const int t[3] = {(b[0] + ox + n_bins) % n_bins, (b[1] + oy + n_bins) % n_bins,
                              (b[2] + oz + n_bins) % n_bins};
            for (std::uint32_t q : bins[(static_cast<std::size_t>(t[2]) * n_bins + t[1]) * n_bins + t[0]]) {
              Vec3 dx = x - packing.position[q];
              for (int a = 0; a < 3; ++a) dx[a] -= side * std::nearbyint(dx[a] / side);  // minimum image
              const double reach = r + packing.radius[q];
              if (dx.squaredNorm() < reach * reach) {
                free = false;
                break;
              }
            }
          }
      if (!free) continue;
      bins[(static_cast<std::size_t>(b[2]) * n_bins + b[1]) * n_bins + b[0]].push_back(
          static_cast<std::uint32_t>(packing.position.size()));
      packing.position.push_back(x);
      packing.radius.push_back(r);
      placed = true;
    }
    if (!placed)
      throw std::runtime_error("sample: no room for sphere " + std::to_string(k) + " of " + std::to_string(d.size()) +
                               " (d = " + num(d[k]) + " m) after " + std::to_string(s.max_attempts) +
                               " random tries: lower sample.solid_fraction = " + num(s.solid_fraction));
  }
  return packing;
}

std::vector<double> percent_passing(const std::vector<double>& diameters, const std::vector<double>& sieves) {
  double total = 0.0;
  for (double v : diameters) total += v * v * v;
  std::vector<double> out;
  for (double sieve : sieves) {
    double pass = 0.0;
    for (double v : diameters)
      if (v <= sieve) pass += v * v * v;
    out.push_back(total > 0.0 ? 100.0 * pass / total : 0.0);
  }
  return out;
}

}  // namespace sandcell
