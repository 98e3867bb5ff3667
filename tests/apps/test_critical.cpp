// The app's critical-state test (apps/triaxial/protocol/critical.hpp) on synthetic series: it measures a
// drift as the fitted line's change over the window, accepts a stationary series whose rows
// fluctuate by more than the tolerance (what a large sample does), refuses a drift of eta, p or e
// beyond its tolerance whatever the fluctuations, and refuses windows that are not covered.
#include "critical.hpp"

#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

using sandcell::triaxial::check_critical;
using sandcell::triaxial::CriticalTest;

namespace {

// Rows every 0.05 % of axial strain from 0 to 30 %: the last 5 % window holds 101 rows.
struct Series {
  std::vector<double> eps1, p, q, e;
};

// eta = M (1 + d_eta (eps1 - 0.3) / W + noise_q), p = p0 (1 + d_p (...) / W + noise_p),
// e = e0 + d_e (eps1 - 0.3) / W + noise_e: d_* is the drift over the last window W = 0.05.
// The fluctuations are a fixed quasi-random sequence (sin of an irrational multiple of the row),
// so the test is the same on every platform.
Series make(double d_eta, double d_p, double d_e, double noise_q, double noise_p, double noise_e) {
  Series s;
  const double M = 0.93, p0 = 0.5e6, e0 = 0.74, W = 0.05;
  for (int k = 0; k <= 600; ++k) {
    const double x = 0.0005 * k;
    const double u = (x - 0.3) / W;
    const double eta = M * (1.0 + d_eta * u + noise_q * std::sin(1.7 * k));
    const double p = p0 * (1.0 + d_p * u + noise_p * std::sin(2.3 * k + 1.0));
    s.eps1.push_back(x);
    s.p.push_back(p);
    s.q.push_back(eta * p);
    s.e.push_back(e0 + d_e * u + noise_e * std::sin(3.1 * k + 2.0));
  }
  return s;
}

sandcell::triaxial::CriticalCheck check(const Series& s, const CriticalTest& t = {}) {
  return check_critical(s.eps1, s.p, s.q, s.e, t);
}

}  // namespace

TEST_CASE("critical-state test: the fitted line's change over the window is the drift, exactly for a straight series") {
  // Without fluctuations the least-squares line is the series itself, so the change it predicts
  // over the window is the drift: relative to the window mean for eta and p (the mean of u over the
  // window's 101 rows, -1 .. 0, is -0.5), absolute for e. Tolerance 1e-12: round-off of sums of
  // 101 terms of order 1.
  const Series s = make(0.015, -0.01, 0.003, 0.0, 0.0, 0.0);
  const auto c = check(s);
  CHECK(c.rows == 101);
  CHECK(c.change_eta == doctest::Approx(0.015 / (1.0 - 0.5 * 0.015)).epsilon(1e-12));
  CHECK(c.change_p == doctest::Approx(0.01 / (1.0 + 0.5 * 0.01)).epsilon(1e-12));
  CHECK(c.change_e == doctest::Approx(0.003).epsilon(1e-12));
  CHECK(c.reached);  // 1.5 % and 1 % < 2 %, 0.003 < 0.005
}

TEST_CASE("critical-state test: a stationary series whose q fluctuates by 8 % row to row is critical") {
  // As a 19,436-sphere test at 0.5 MPa: q within +-4 % about a stationary mean (the range test the
  // app used before, max - min of q in the window < 2 %, never fired on it).
  const Series s = make(0.0, 0.0, 0.0, 0.04, 0.01, 0.002);
  const auto c = check(s);
  const auto [lo, hi] = std::minmax_element(s.q.end() - 101, s.q.end());
  CHECK((*hi - *lo) / s.q.back() > 0.02);  // the case the range test refused
  // The fluctuations leave a trend of a few tenths of a per cent in a line through 101 rows
  // (about 6 x amplitude / rows for a sequence like this): far inside 2 %.
  CHECK(c.change_eta < 0.005);
  CHECK(c.change_p < 0.005);
  CHECK(c.change_e < 0.001);
  CHECK(c.reached);
}

TEST_CASE("critical-state test: a drift beyond the tolerance is refused through the same fluctuations") {
  // 3 % over the window, 1.5 x the tolerance, against a fluctuation trend below 0.5 % (above).
  CHECK_FALSE(check(make(0.03, 0.0, 0.0, 0.04, 0.01, 0.002)).reached);   // eta still rising
  CHECK_FALSE(check(make(-0.03, 0.0, 0.0, 0.04, 0.01, 0.002)).reached);  // eta still falling (softening)
  CHECK_FALSE(check(make(0.0, 0.03, 0.0, 0.04, 0.01, 0.002)).reached);   // p drifting
  CHECK_FALSE(check(make(0.0, 0.0, 0.01, 0.04, 0.01, 0.002)).reached);   // still dilating: e + 0.01
  // The tolerances are the config's: the same eta drift passes at tolerance 4 %.
  CriticalTest loose;
  loose.tolerance = 0.04;
  CHECK(check(make(0.03, 0.0, 0.0, 0.04, 0.01, 0.002), loose).reached);
  CriticalTest strict_e;
  strict_e.tolerance_e = 0.001;
  CHECK_FALSE(check(make(0.0, 0.0, 0.003, 0.0, 0.0, 0.0), strict_e).reached);
}

TEST_CASE("critical-state test: windows not covered, or series not finite, are not critical") {
  const Series flat = make(0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
  REQUIRE(check(flat).reached);
  // The test must have reached window + pre-strain: 10 % for the defaults.
  Series early = flat;
  early.eps1.resize(190);  // up to 9.45 %
  early.p.resize(190);
  early.q.resize(190);
  early.e.resize(190);
  CHECK_FALSE(check(early).reached);
  // At least min_rows rows in the window: every 20th row only leaves 6.
  Series sparse;
  for (std::size_t k = 0; k < flat.eps1.size(); k += 20) {
    sparse.eps1.push_back(flat.eps1[k]);
    sparse.p.push_back(flat.p[k]);
    sparse.q.push_back(flat.q[k]);
    sparse.e.push_back(flat.e[k]);
  }
  CHECK_FALSE(check(sparse).reached);
  CriticalTest few;
  few.min_rows = 5;
  CHECK(check(sparse, few).reached);
  // A NaN in the window (a run gone unstable would have stopped first; a corrupt series here).
  Series bad = flat;
  bad.p[590] = std::numeric_limits<double>::quiet_NaN();
  CHECK_FALSE(check(bad).reached);
  // Series of different lengths: refused, not read out of range.
  Series ragged = flat;
  ragged.e.pop_back();
  CHECK_FALSE(check(ragged).reached);
}
