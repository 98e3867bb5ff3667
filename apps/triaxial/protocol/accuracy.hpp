#pragma once
// The live accuracy indicators of a shearing run (the inertial number, the unbalanced force, the
// kinetic/elastic energy ratio, the largest overlap), each with its safe range.
#include "protocol/text.hpp"

#include "systems/homogenizer.hpp"

#include <algorithm>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace sandcell::triaxial {

// The live accuracy indicators of a shearing run, each with its safe range. A run that leaves one
// gets a warning line (once per indicator and job: the step, the value, the range and what to
// change); the worst value is in the job's last line.
class AccuracyWatch {
 public:
  /// `warn` receives each warning line (the app: its log).
  AccuracyWatch(std::string job, std::function<void(const std::string&)> warn)
      : job_(std::move(job)), warn_(std::move(warn)) {}

  void check(const Measures& m, std::uint64_t step) {
    const double ratio = m.elastic_energy > 0.0 ? m.kinetic_energy / m.elastic_energy : 0.0;
    // The axial form (what shear.inertial_number sets); a path with no axial rate (simple shear) the
    // principal strain rates' (eps_dot_1 - eps_dot_3) form.
    const double inertial = m.inertial_number_axial > 0.0 ? m.inertial_number_axial : m.inertial_number;
    const double values[k_count] = {inertial, m.unbalanced, ratio, m.max_overlap_ratio};
    for (int k = 0; k < k_count; ++k) {
      worst_[k] = std::max(worst_[k], values[k]);
      if (values[k] > k_limits[k].limit && !warned_[k]) {
        warned_[k] = true;
        warn_(job_ + ": warning: step " + std::to_string(step) + ": " + k_limits[k].name + " = " +
                  num(values[k], "%.3g") + " > " + num(k_limits[k].limit, "%g") + " (" + k_limits[k].why + ")");
      }
    }
  }
  /// The worst values so far, for a checkpoint; restore() takes them back on resume (with the
  /// warnings they already caused), so the last line covers the whole test.
  std::vector<double> worst_values() const { return {worst_, worst_ + k_count}; }
  void restore(const std::vector<double>& w) {
    for (int k = 0; k < k_count && k < static_cast<int>(w.size()); ++k) {
      worst_[k] = w[k];
      warned_[k] = w[k] > k_limits[k].limit;
    }
  }
  std::string worst() const {
    return "max I " + num(worst_[0], "%.2g") + ", unbalanced " + num(worst_[1], "%.2g") + ", Ek/Ee " +
           num(worst_[2], "%.2g") + ", overlap/R " + num(worst_[3], "%.2g");
  }

  struct Limit {
    const char* name;
    double limit;
    const char* why;
  };
  static constexpr int k_count = 4;
  // Safe ranges. The inertial number in the form shear.inertial_number sets (eps_dot_1 d50
  // sqrt(rho/p)): the inertia study (experiments/2026-11-22-study-inertia) found every measure within one test's
  // scatter from I = 1e-5 up to 3e-3 and the peak q/p 0.05-0.5 too high at 1e-2; the limit is 3e-3
  // plus 5 % for the fluctuation of the measured p between servo updates. An unbalanced force
  // ratio above 0.1 means forces far from balance; the kinetic energy reached 4 % of the stored
  // elastic energy in the fast protocol's validation (19,436 spheres at I = 3e-3, docs/reproducing-the-study.md), whose
  // peak and dilatancy errors stayed within the seed scatter and whose critical q/p rose by 2 %:
  // 5 % is the limit; Hertz theory assumes overlaps small beside the radius.
  static constexpr Limit k_limits[k_count] = {
      {"inertial number eps_dot_1 d50 sqrt(rho/p)", 3.15e-3,
       "validated up to 3e-3 (experiments/2026-11-22-study-inertia): lower shear.strain_rate or shear.inertial_number"},
      {"unbalanced force ratio", 0.1,
       "forces far from balance: lower shear.strain_rate or shear.inertial_number; from the first rows on, "
       "lower time.dt_fraction or time.safety (stiff contacts at high p: 0.35 t_R was unstable at 16 MPa)"},
      {"kinetic / elastic energy", 0.05,
       "inertia carries load: lower shear.strain_rate or shear.inertial_number, or time.dt_fraction (time.safety)"},
      {"max overlap / radius", 0.05, "beyond small-strain Hertz contact: raise material.young or lower p0"},
  };

 private:
  std::string job_;
  std::function<void(const std::string&)> warn_;
  bool warned_[k_count] = {};
  double worst_[k_count] = {};
};

}  // namespace sandcell::triaxial
