#pragma once
// The paths a triaxial test can follow (tests.path), one row each in paths.cpp: the one name a
// path has in the config, the results files ("path" attribute, index.csv) and the analysis, the
// prefix of its tests' names, and what it needs. A new path is an enum value in config.hpp, its
// row, and its case in shear_model (protocol.cpp); the analysis lists the names in
// sandcell_analysis.results.PATHS (a test checks they agree).
#include "protocol/config.hpp"

#include <span>
#include <string>
#include <string_view>

namespace sandcell::triaxial {

struct TestPath {
  ShearPath id;
  std::string_view name;    // tests.path, the results' "path"
  std::string_view prefix;  // test names: "<prefix>-b0.50-p0_500kPa" (with b), "<prefix>-p0_500kPa" (without)
  bool has_b;               // one test per value of tests.b, and the servo holds b
  bool by_steps;            // ends after shear.steps (else at shear.max_axial_strain)
  bool inertial_number;     // the axial rate may follow shear.inertial_number (else shear.strain_rate only)
  bool ramp;                // shear.ramp_strain applies
  std::string_view description;
};

/// Every path, in enum order.
std::span<const TestPath> test_paths();
const TestPath& test_path(ShearPath path);
/// The row of a name, or nullptr.
const TestPath* find_test_path(std::string_view name);
/// The names as the config writes them: "constant_p" "constant_sigma3" ...
std::string test_path_names();

}  // namespace sandcell::triaxial
