#include "protocol/critical.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace sandcell::triaxial {

namespace {

constexpr double k_nan = std::numeric_limits<double>::quiet_NaN();

// The least-squares line of y against x over rows [first, n), as a Trend over the test's window: the
// change slope x window and its standard error, relative to |mean y| when `relative` (critical.hpp).
Trend trend(std::span<const double> x, std::span<const double> y, std::size_t first, const CriticalTest& test,
            bool relative) {
  const double window = test.window;
  const std::size_t n = x.size();
  const double count = static_cast<double>(n - first);
  double mx = 0.0, my = 0.0;
  for (std::size_t k = first; k < n; ++k) {
    mx += x[k];
    my += y[k];
  }
  mx /= count;
  my /= count;
  double sxy = 0.0, sxx = 0.0;
  for (std::size_t k = first; k < n; ++k) {
    sxy += (x[k] - mx) * (y[k] - my);
    sxx += (x[k] - mx) * (x[k] - mx);
  }
  if (!(sxx > 0.0) || n - first < 3) return Trend{k_nan, k_nan};
  const double slope = sxy / sxx, icpt = my - slope * mx;
  // Residuals: their variance and lag-1 autocorrelation.
  double ss = 0.0, lag = 0.0, prev = 0.0;
  for (std::size_t k = first; k < n; ++k) {
    const double r = y[k] - (slope * x[k] + icpt);
    ss += r * r;
    if (k > first) lag += r * prev;
    prev = r;
  }
  const double r1 = ss > 0.0 ? std::clamp(lag / ss, 0.0, 0.99) : 0.0;
  const double se_slope = std::sqrt(ss / (count - 2.0) / sxx) * std::sqrt((1.0 + r1) / (1.0 - r1));
  const double scale = relative && my != 0.0 ? std::abs(my) : 1.0;
  const double n_eff = count * (1.0 - r1) / (1.0 + r1);
  return Trend{std::abs(slope * window) / scale, se_slope * window / scale, n_eff,
               n_eff >= test.min_effective_rows ? 2.0 : test.short_window_se};
}

}  // namespace

double fabric_anisotropy(const Mat3& phi) {
  const Mat3 dev = 7.5 * (phi - phi.trace() / 3.0 * Mat3::Identity());
  return std::sqrt((dev.array() * dev.array()).sum());
}

CriticalCheck check_critical(const CriticalSeries& s, const CriticalTest& test) {
  CriticalCheck out;
  const std::size_t n = s.eps_q.size();
  if (n == 0 || s.p.size() != n || s.q.size() != n || s.e.size() != n || s.z_mech.size() != n ||
      s.fabric_anisotropy.size() != n)
    return out;
  const double end = s.eps_q[n - 1];
  std::size_t first = n - 1;
  while (first > 0 && s.eps_q[first - 1] >= end - test.window) --first;
  out.rows = n - first;
  if (!(end >= test.window + test.pre_strain) || out.rows < std::max<std::size_t>(test.min_rows, 3) ||
      !(end - s.eps_q[first] >= 0.9 * test.window))
    return out;
  // eta of the window's rows only (an output-step cost: the window, not the whole history).
  std::vector<double> eta(n - first);
  for (std::size_t k = first; k < n; ++k) eta[k - first] = s.q[k] / s.p[k];
  out.eta = trend(s.eps_q.subspan(first), eta, 0, test, true);
  out.p = trend(s.eps_q, s.p, first, test, true);
  out.e = trend(s.eps_q, s.e, first, test, false);
  out.z = trend(s.eps_q, s.z_mech, first, test, true);
  out.fabric = trend(s.eps_q, s.fabric_anisotropy, first, test, true);
  // NaN (a series that is not finite, or a history from before these columns) fails every comparison.
  out.reached = out.eta.ok(test.tolerance) && out.p.ok(test.tolerance) && out.z.ok(test.tolerance) &&
                out.e.ok(test.tolerance_e) && out.fabric.ok(test.tolerance_fabric);
  return out;
}

}  // namespace sandcell::triaxial
