#include "protocol/paths.hpp"

#include "engine/name_table.hpp"

#include <iterator>

namespace sandcell::triaxial {

namespace {

constexpr TestPath k_paths[] = {
    {ShearPath::constant_p, "constant_p", "p", true, false, true, true,
     "axis 1 compressed at the axial rate; axes 2 and 3 hold the mean stress p0 and b (systems/stress_paths.cpp)"},
    {ShearPath::constant_sigma3, "constant_sigma3", "s3", true, false, true, true,
     "axis 1 compressed at the axial rate; axes 2 and 3 hold sigma3 = p0 and b"},
    {ShearPath::strain, "strain", "strain", false, true, false, false,
     "every axis at its rate of shear.strain_rates for shear.steps steps; no servo"},
    {ShearPath::undrained, "undrained", "u", false, false, false, false,
     "constant volume: axis 1 compressed at shear.strain_rate, axes 2 and 3 at the common rate that keeps eps_v = 0 "
     "(the excess pore pressure of the saturated sample is u = p0 - p')"},
    {ShearPath::cyclic, "cyclic", "cyc", false, false, false, false,
     "[cyclic]: q/p0 (stress mode) or eps1 (strain mode, at shear.strain_rate) between the bounds, undrained or at "
     "sigma3 = p0, until cyclic.cycles or cyclic.max_strain"},
    {ShearPath::simple_shear, "simple_shear", "ss", false, false, true, true,
     "xz sheared at shear.strain_rate (engineering, gamma_dot = -L_xz > 0), xx and yy fixed, S_zz held at p0, until "
     "shear.max_shear_strain"},
    {ShearPath::simple_shear_cv, "simple_shear_cv", "sscv", false, false, true, true,
     "xz sheared at shear.strain_rate, xx, yy and zz fixed (constant volume), until shear.max_shear_strain"},
    {ShearPath::rotation, "rotation", "rot", true, false, false, false,
     "[rotation]: p = p0 and b held, q raised to eta p0 over ramp_time, then sigma1 turned in the xz plane at rate "
     "through angle (all six stress components servo-controlled)"},
};

static_assert(in_id_order(k_paths), "k_paths: one row per ShearPath, in enum order");

}  // namespace

std::span<const TestPath> test_paths() { return k_paths; }

const TestPath& test_path(ShearPath path) { return k_paths[static_cast<std::size_t>(path)]; }

const TestPath* find_test_path(std::string_view name) { return find_named(test_paths(), name); }

std::string test_path_names() { return joined_names(test_paths(), " ", "\""); }

}  // namespace sandcell::triaxial
