// The app's critical-state test (apps/triaxial/protocol/critical.hpp) on synthetic series: a drift
// is the fitted line's change over a window of eps_q; a change is accepted only with two standard
// errors to spare (so a stationary series passes and a drift hidden in noise does not); serially
// correlated noise widens the error; each of eta, p, e, Z_mech and the fabric anisotropy is tested;
// windows that are not covered are refused; F_a is the Li-Dafalias coefficient.
#include "critical.hpp"

#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <vector>

using sandcell::Mat3;
using sandcell::triaxial::check_critical;
using sandcell::triaxial::CriticalSeries;
using sandcell::triaxial::CriticalTest;
using sandcell::triaxial::fabric_anisotropy;

namespace {

// Rows every 0.05 % of eps_q from 0 to 60 %: the last 10 % window holds 201 rows.
struct Series {
  std::vector<double> eps_q, p, q, e, z, fa;
};

struct Drift {
  double eta = 0.0, p = 0.0, e = 0.0, z = 0.0, fa = 0.0;  // over the last window W = 0.1
};
struct Noise {
  double q = 0.0, p = 0.0, e = 0.0;  // amplitudes of the row-to-row fluctuations
  double period_rows = 0.0;          // 0: a fast quasi-random sequence (sin of an irrational multiple
                                     // of the row); > 0: a slow sine of this period (serially correlated)
};

// eta = M (1 + d_eta u + n_q s1), p = p0 (1 + d_p u + n_p s2), e = e0 + d_e u + n_e s3,
// Z = Z0 (1 + d_z u), F_a = F0 (1 + d_fa u), u = (eps_q - 0.6) / W: d_* is the drift over the last window.
Series make(Drift d, Noise n = {}) {
  Series s;
  const double M = 0.93, p0 = 0.5e6, e0 = 0.74, z0 = 4.1, f0 = 0.45, W = 0.1;
  for (int k = 0; k <= 1200; ++k) {
    const double x = 0.0005 * k, u = (x - 0.6) / W;
    const auto wave = [&](double fast, double phase) {
      return n.period_rows > 0.0 ? std::sin(2.0 * std::numbers::pi * k / n.period_rows + phase) : std::sin(fast * k + phase);
    };
    const double eta = M * (1.0 + d.eta * u + n.q * wave(1.7, 0.0));
    const double p = p0 * (1.0 + d.p * u + n.p * wave(2.3, 1.0));
    s.eps_q.push_back(x);
    s.p.push_back(p);
    s.q.push_back(eta * p);
    s.e.push_back(e0 + d.e * u + n.e * wave(3.1, 2.0));
    s.z.push_back(z0 * (1.0 + d.z * u));
    s.fa.push_back(f0 * (1.0 + d.fa * u));
  }
  return s;
}

sandcell::triaxial::CriticalCheck check(const Series& s, const CriticalTest& t = {}) {
  return check_critical(CriticalSeries{s.eps_q, s.p, s.q, s.e, s.z, s.fa}, t);
}

}  // namespace

TEST_CASE("critical-state test: the fitted line's change over the eps_q window is the drift, exactly for a straight series") {
  // Without fluctuations the least-squares line is the series itself: the change over the window is
  // the drift (relative to the window mean for eta, p, Z_mech and F_a: the mean of u over the
  // window's 201 rows, -1 .. 0, is -0.5; absolute for e) and its standard error is zero (to
  // round-off). Tolerance 1e-12: round-off of sums of 201 terms of order 1.
  const Series s = make({.eta = 0.015, .p = -0.01, .e = 0.003, .z = 0.01, .fa = 0.03});
  const auto c = check(s);
  CHECK(c.rows == 201);
  CHECK(c.eta.change == doctest::Approx(0.015 / (1.0 - 0.5 * 0.015)).epsilon(1e-12));
  CHECK(c.p.change == doctest::Approx(0.01 / (1.0 + 0.5 * 0.01)).epsilon(1e-12));
  CHECK(c.e.change == doctest::Approx(0.003).epsilon(1e-12));
  CHECK(c.z.change == doctest::Approx(0.01 / (1.0 - 0.5 * 0.01)).epsilon(1e-12));
  CHECK(c.fabric.change == doctest::Approx(0.03 / (1.0 - 0.5 * 0.03)).epsilon(1e-12));
  for (double se : {c.eta.se, c.p.se, c.e.se, c.z.se, c.fabric.se}) CHECK(se < 1e-12);
  CHECK(c.reached);  // every change inside its tolerance, no error to add
}

TEST_CASE("critical-state test: a stationary series whose q fluctuates by 8 % row to row is critical") {
  // As a 19,436-sphere test at 0.5 MPa: q within +-4 % about a stationary mean. The line through
  // 201 rows of such noise changes by a few tenths of a per cent, with a standard error of about
  // amplitude / sqrt(2) x sqrt(12 / rows) = 0.7 %: change + 2 SE ~ 1.5 % < 2 %.
  const auto c = check(make({}, {.q = 0.04, .p = 0.005, .e = 0.001}));
  CHECK(c.eta.change + 2.0 * c.eta.se < 0.02);
  CHECK(c.eta.se > 0.004);  // the error is the noise's, not zero
  CHECK(c.reached);
}

TEST_CASE("critical-state test: a drift beyond the tolerance is refused, and so is one the noise leaves unproven") {
  const Noise noise{.q = 0.04, .p = 0.005, .e = 0.001};
  CHECK_FALSE(check(make({.eta = 0.03}, noise)).reached);    // eta still rising
  CHECK_FALSE(check(make({.eta = -0.03}, noise)).reached);   // eta still falling (softening)
  CHECK_FALSE(check(make({.p = 0.03}, noise)).reached);      // p drifting
  CHECK_FALSE(check(make({.e = 0.008}, noise)).reached);     // still dilating: e + 0.008
  CHECK_FALSE(check(make({.z = 0.03}, noise)).reached);      // contacts still being lost or made
  CHECK_FALSE(check(make({.fa = 0.08}, noise)).reached);     // fabric still turning
  // A drift of 1.5 % (inside 2 %) through noise of +-8 %: the change alone (the first-passage test
  // before this one) passes it; with 2 standard errors (~1.4 % each) it is not shown stationary.
  const auto c = check(make({.eta = 0.015}, {.q = 0.08, .p = 0.005, .e = 0.001}));
  CHECK(c.eta.change < 0.02);
  CHECK_FALSE(c.reached);
  // The tolerances are the config's: the same 3 % eta drift passes at tolerance 6 %.
  CriticalTest loose;
  loose.tolerance = 0.06;
  CHECK(check(make({.eta = 0.03}, noise), loose).reached);
}

TEST_CASE("critical-state test: serially correlated noise widens the standard error (AR(1) effective rows)") {
  // The same amplitude as a slow sine (period 100 rows, two periods in the window, so the line
  // absorbs little of it: lag-1 autocorrelation cos(2 pi / 100) = 0.998, clipped to 0.99: a factor
  // sqrt(1.99 / 0.01) = 14 on the error) against the fast sequence (lag-1 autocorrelation < 0: no
  // factor). Bound 5: the least-squares errors of the two differ by less than a factor 2 (residual
  // variances both ~ amplitude^2 / 2), so only the inflation puts 5 within reach.
  const auto slow = check(make({}, {.q = 0.02, .period_rows = 100.0}));
  const auto fast = check(make({}, {.q = 0.02}));
  CHECK(slow.eta.se > 5.0 * fast.eta.se);
}

TEST_CASE("critical-state test: windows not covered, or series not finite, are not critical") {
  const Series flat = make({});
  REQUIRE(check(flat).reached);
  const auto cut = [](Series s, std::size_t n) {
    for (auto* v : {&s.eps_q, &s.p, &s.q, &s.e, &s.z, &s.fa}) v->resize(n);
    return s;
  };
  // The test must have reached window + pre-strain: 30 % of eps_q for the defaults.
  CHECK_FALSE(check(cut(flat, 590)).reached);  // up to 29.45 %
  CHECK(check(cut(flat, 602)).reached);        // 30.05 %
  // At least min_rows rows in the window: every 40th row only leaves 5.
  Series sparse;
  for (std::size_t k = 0; k < flat.eps_q.size(); k += 40)
    for (auto [to, from] : {std::pair{&sparse.eps_q, &flat.eps_q}, {&sparse.p, &flat.p}, {&sparse.q, &flat.q},
                            {&sparse.e, &flat.e}, {&sparse.z, &flat.z}, {&sparse.fa, &flat.fa}})
      to->push_back((*from)[k]);
  CHECK_FALSE(check(sparse).reached);
  CriticalTest few;
  few.min_rows = 4;
  CHECK(check(sparse, few).reached);
  // A NaN in the window: a corrupt series, or a history resumed from a checkpoint without Z_mech.
  Series bad = flat;
  bad.z[1190] = std::numeric_limits<double>::quiet_NaN();
  CHECK_FALSE(check(bad).reached);
  // Series of different lengths: refused, not read out of range.
  Series ragged = flat;
  ragged.fa.pop_back();
  CHECK_FALSE(check(ragged).reached);
}

TEST_CASE("critical-state test: F_a is the coefficient of the contact normal density (1 + F' : n n) / 4 pi") {
  // For that density <n (x) n> = I/3 + 2 F' / 15 (the fourth moment of the uniform density), so
  // 15/2 (phi - I/3) recovers F' exactly and F_a = |F'|. Isotropic fabric: 0. Tolerance 1e-15:
  // round-off of order-1 sums.
  Mat3 f;
  f << 0.3, 0.1, -0.05, 0.1, -0.2, 0.02, -0.05, 0.02, -0.1;  // traceless, symmetric
  const Mat3 phi = Mat3::Identity() / 3.0 + 2.0 * f / 15.0;
  CHECK(fabric_anisotropy(phi) == doctest::Approx(f.norm()).epsilon(1e-15));
  CHECK(fabric_anisotropy(Mat3::Identity() / 3.0) < 1e-15);
}
