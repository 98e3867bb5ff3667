#pragma once
// The critical-state test the app applies while shearing (shear.stop_at_critical). It is the test
// of `triaxial analyze` (analyze.py, detect_critical) on the same series rows, so a test the app
// stops is one the analysis accepts:
//   over the last `window` of axial strain, a straight line is fitted (least squares) to each of
//   eta = q/p, p and e against eps_1; the change each line predicts over the window (slope x
//   window) must be at most `tolerance` for eta and p (relative to their window mean) and
//   `tolerance_e` for e (absolute); the window must hold at least `min_rows` rows spanning 90 % of
//   it, and the test must have reached window + pre_strain.
// A trend and not the range: the deviatoric stress of a large sample fluctuates by several per
// cent about a stationary mean (2.5-5 % of q in every 5 % window of a 19,436-sphere test at
// 0.5 MPa), so a test of the range (the app's test before this one) kept such a test shearing to
// its strain limit; a line through the window's rows averages the fluctuations out.
// (The analysis also tests eps_v; with de = -(1 + e) d eps_v, |de| <= 0.005 bounds eps_v's change
// to 0.005 / (1 + e) < 0.004, inside the analysis's 0.005, so e alone suffices here.)
#include <cstddef>
#include <span>

namespace sandcell::triaxial {

struct CriticalTest {
  double window = 0.05;        // -, axial strain
  double tolerance = 0.02;     // -, largest relative change of eta and p over the window
  double tolerance_e = 0.005;  // -, largest change of e over the window
  double pre_strain = 0.05;    // -, the test must have reached window + pre_strain
  std::size_t min_rows = 10;   // rows in the window
};

struct CriticalCheck {
  bool reached = false;
  double change_eta = 0.0;  // -, relative change over the window predicted by the fitted line
  double change_p = 0.0;    // -, relative
  double change_e = 0.0;    // -, absolute
  std::size_t rows = 0;     // rows in the window
};

/// The test on the end of the series (eps1 increasing; all four the same length).
CriticalCheck check_critical(std::span<const double> eps1, std::span<const double> p, std::span<const double> q,
                             std::span<const double> e, const CriticalTest& test);

}  // namespace sandcell::triaxial
