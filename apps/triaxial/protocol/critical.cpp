#include "protocol/critical.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace sandcell::triaxial {

namespace {

struct Line {
  double slope;  // least-squares slope of y against x
  double mean;   // mean of y
};

// The straight line through rows [first, n), with y given per row by `value`.
template <class Value>
Line fit(std::span<const double> x, std::size_t first, Value value) {
  const std::size_t n = x.size();
  double mx = 0.0, my = 0.0;
  for (std::size_t k = first; k < n; ++k) {
    mx += x[k];
    my += value(k);
  }
  const double count = static_cast<double>(n - first);
  mx /= count;
  my /= count;
  double sxy = 0.0, sxx = 0.0;
  for (std::size_t k = first; k < n; ++k) {
    sxy += (x[k] - mx) * (value(k) - my);
    sxx += (x[k] - mx) * (x[k] - mx);
  }
  return Line{sxx > 0.0 ? sxy / sxx : std::numeric_limits<double>::quiet_NaN(), my};
}

}  // namespace

CriticalCheck check_critical(std::span<const double> eps1, std::span<const double> p, std::span<const double> q,
                             std::span<const double> e, const CriticalTest& test) {
  CriticalCheck out;
  const std::size_t n = eps1.size();
  if (n == 0 || p.size() != n || q.size() != n || e.size() != n) return out;
  const double end = eps1[n - 1];
  std::size_t first = n - 1;
  while (first > 0 && eps1[first - 1] >= end - test.window) --first;
  out.rows = n - first;
  if (end < test.window + test.pre_strain || out.rows < std::max<std::size_t>(test.min_rows, 3) ||
      end - eps1[first] < 0.9 * test.window)
    return out;
  const auto eta = [&](std::size_t k) { return q[k] / p[k]; };
  const auto pk = [&](std::size_t k) { return p[k]; };
  const auto ek = [&](std::size_t k) { return e[k]; };
  const auto relative = [&](auto value) {
    const Line line = fit(eps1, first, value);
    return std::abs(line.slope * test.window) / (line.mean != 0.0 ? std::abs(line.mean) : 1.0);
  };
  out.change_eta = relative(eta);
  out.change_p = relative(pk);
  out.change_e = std::abs(fit(eps1, first, ek).slope * test.window);
  // NaN (a series that is not finite) fails every comparison: not critical.
  out.reached = out.change_eta <= test.tolerance && out.change_p <= test.tolerance && out.change_e <= test.tolerance_e;
  return out;
}

}  // namespace sandcell::triaxial
