// The app's critical-state test (apps/triaxial/protocol/critical.cpp) on series read from a CSV file, for
// test_critical_twin.py, which runs the Python test (sandcell_analysis.critical) on the same series
// and asserts that the two agree.
//
//     critical_twin SERIES.csv [WINDOW TOLERANCE TOLERANCE_E TOLERANCE_FABRIC]
//
// SERIES.csv: a header, then rows `series,eps_q,p,q,e,z_mech,fabric_anisotropy` (series: an integer
// id; the rows of a series consecutive, eps_q non-decreasing). Prints one line per series:
//     series reached rows (change se n_eff) x (eta p e z fa) first_row
// for the test on the whole series with the app's defaults (CriticalTest{}, or the four settings
// given: a run's shear.critical_window, critical_tolerance, critical_tolerance_e and
// critical_tolerance_fabric), and first_row: the
// rows n of the first prefix [0, n) the test accepts, as the app applies it after every series row
// with shear.stop_at_critical (0: none). Exit 2 with one line on bad input.
#include "critical.hpp"

#include <cstdio>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

namespace {

struct Series {
  std::vector<double> eps_q, p, q, e, z, fa;
};

int fail(const std::string& msg) {
  std::fprintf(stderr, "critical_twin: %s\n", msg.c_str());
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  using sandcell::triaxial::check_critical;
  using sandcell::triaxial::CriticalSeries;
  using sandcell::triaxial::CriticalTest;
  if (argc != 2 && argc != 6) return fail("usage: critical_twin SERIES.csv [WINDOW TOL TOL_E TOL_FABRIC]");
  std::ifstream in(argv[1]);
  if (!in) return fail(std::string("cannot read SERIES.csv: ") + argv[1]);
  std::map<long, Series> all;
  std::string line;
  std::getline(in, line);  // header
  for (std::size_t row = 2; std::getline(in, line); ++row) {
    if (line.empty()) continue;
    std::istringstream s(line);
    long id = 0;
    double v[6];
    char comma = 0;
    s >> id;
    for (double& x : v) {
      s >> comma >> x;
      if (comma != ',') break;
    }
    if (!s || comma != ',')
      return fail(std::string(argv[1]) + ": row " + std::to_string(row) + " is not 'series,eps_q,p,q,e,z_mech,fabric_anisotropy'");
    Series& t = all[id];
    t.eps_q.push_back(v[0]);
    t.p.push_back(v[1]);
    t.q.push_back(v[2]);
    t.e.push_back(v[3]);
    t.z.push_back(v[4]);
    t.fa.push_back(v[5]);
  }
  CriticalTest test{};
  if (argc == 6) {
    test.window = std::stod(argv[2]);
    test.tolerance = std::stod(argv[3]);
    test.tolerance_e = std::stod(argv[4]);
    test.tolerance_fabric = std::stod(argv[5]);
  }
  for (const auto& [id, t] : all) {
    const auto series = [&](std::size_t n) {
      const auto head = [&](const std::vector<double>& v) { return std::span<const double>(v.data(), n); };
      return CriticalSeries{head(t.eps_q), head(t.p), head(t.q), head(t.e), head(t.z), head(t.fa)};
    };
    const auto c = check_critical(series(t.eps_q.size()), test);
    std::size_t first = 0;
    for (std::size_t n = 1; n <= t.eps_q.size() && first == 0; ++n)
      if (check_critical(series(n), test).reached) first = n;
    std::printf("%ld %d %zu", id, c.reached ? 1 : 0, c.rows);
    for (const auto& tr : {c.eta, c.p, c.e, c.z, c.fabric}) std::printf(" %.17g %.17g %.17g", tr.change, tr.se, tr.n_eff);
    std::printf(" %zu\n", first);
  }
  return 0;
}
