#pragma once
// The critical-state test the app applies while shearing (shear.stop_at_critical). It is the test
// of `triaxial analyze` (sandcell_analysis/critical.py, detect_critical) on the same series rows,
// so a test the app stops is one the analysis accepts (tests/analysis/test_critical_twin.py):
//   over the last `window` of deviatoric strain eps_q (the same distortion at every b: a window in
//   eps_1 spans about twice the eps_q at b = 1 as at b = 0), a straight line is fitted (least
//   squares) to each of eta = q/p, p, e, the mechanical coordination number Z_mech and the fabric
//   anisotropy F_a against eps_q. Each line's change over the window (slope x window) plus two
//   standard errors of it must be at most its tolerance: `tolerance` for eta, p and Z_mech
//   (relative to their window mean), `tolerance_fabric` for F_a (relative), `tolerance_e` for e
//   (absolute). The window must hold at least `min_rows` rows spanning 90 % of it, and the test
//   must have reached window + pre_strain of eps_q.
// Why a trend plus its error, and not a trend alone (the test before this one): the deviatoric
// stress of a 19,436-sphere sample fluctuates by several per cent about its mean, so a fitted line
// through a window can be flat by chance while the sample still dilates; the first row whose
// line happened to be flat stopped the test (48 of 50 critical tests of the full campaign passed at
// >= 90 % of a tolerance, 42 were still dilating). Requiring the change to be small with 2 standard
// errors to spare asks the data to show stationarity, not merely to fail to show a trend.
// The standard error: rows 50 steps apart are serially correlated, so the least-squares error of
// the slope is inflated by sqrt((1 + r1) / (1 - r1)), r1 the lag-1 autocorrelation of the
// residuals clipped to [0, 0.99] (the AR(1) effective sample size).
// Version 3 of the test (this one): where the window holds fewer than `min_effective_rows`
// effective rows, n_eff = n (1 - r1) / (1 + r1), the change must be below the tolerance by
// `short_window_se` (6) standard errors instead of 2: there the AR(1) error is as little as a third
// of the truth, and 2 of them let through 8.4 % of series drifting by 1.5 tolerances (6: at most
// 2.4 %; experiments/2026-11-29-rule-check).
// F_a = sqrt(F':F'), F' = 15/2 (phi - tr(phi)/3 I), phi = <n (x) n> the contact fabric: the
// anisotropy coefficient of the contact normal density (1 + F'_ij n_i n_j) / 4 pi (Li & Dafalias
// 2012's normalization).
#include "components/types.hpp"

#include <cstddef>
#include <span>

namespace sandcell::triaxial {

struct CriticalTest {
  double window = 0.1;             // -, deviatoric strain eps_q
  double tolerance = 0.02;         // -, largest relative change (+ 2 SE) of eta, p and Z_mech over the window
  double tolerance_e = 0.005;      // -, largest change (+ 2 SE) of e over the window
  double tolerance_fabric = 0.05;  // -, largest relative change (+ 2 SE) of F_a over the window
  double pre_strain = 0.2;         // -, eps_q: the test must have reached window + pre_strain
  std::size_t min_rows = 10;       // rows in the window
  double min_effective_rows = 10.0;  // n_eff below which the change needs short_window_se errors to spare
  double short_window_se = 6.0;      // standard errors to spare in such a window (2 above it)
};

/// One quantity's trend over the window: the fitted line's change (relative or absolute, as its
/// tolerance), the standard error of that change (AR(1)-inflated), the window's effective row count
/// and the errors to spare that it asks for (2, or CriticalTest::short_window_se).
struct Trend {
  double change = 0.0;
  double se = 0.0;
  double n_eff = 0.0;
  double k = 2.0;
  bool ok(double tolerance) const { return change + k * se <= tolerance; }  // NaN: not ok
};

struct CriticalCheck {
  bool reached = false;
  Trend eta, p, e, z, fabric;  // eta, p, z, fabric relative; e absolute
  std::size_t rows = 0;        // rows in the window
};

/// The rows of a test's series the test reads (all the same length; eps_q non-decreasing at the end).
struct CriticalSeries {
  std::span<const double> eps_q, p, q, e, z_mech, fabric_anisotropy;
};

/// The test on the end of the series.
CriticalCheck check_critical(const CriticalSeries& s, const CriticalTest& test);

/// F_a of a fabric tensor phi (trace 1 for a non-empty contact set).
double fabric_anisotropy(const Mat3& phi);

}  // namespace sandcell::triaxial
