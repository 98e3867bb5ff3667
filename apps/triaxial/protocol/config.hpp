#pragma once
// The triaxial app's configuration: one TOML file (SI units), parsed and fully validated before
// anything is written. Every key, its default and its allowed range are listed in
// apps/triaxial/README.md; parse_config() rejects unknown keys, wrong types and out-of-range
// values with a ConfigError naming the key, the value and what is allowed.
#include "engine/generate.hpp"
#include "engine/model.hpp"
#include "systems/path_watch.hpp"

#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace sandcell::triaxial {

/// A bad configuration: what() is one line naming the key, the value and what is allowed.
struct ConfigError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

struct SampleConfig {
  std::string packing_file;  // a packing from elsewhere (text format of engine/packing.hpp), or empty
  GenerationSettings generation;
};

struct PrepareConfig {
  double friction = 0.0;                // -, Coulomb coefficient during preparation (restored for shearing)
  double rolling_friction = 0.0;        // -, rolling coefficient during preparation
  double gain = 0.0;                    // 1/s, servo gain (0: derived, apps/triaxial/README.md)
  double max_rate = 5.0;                // 1/s, largest compression rate (the shrink of the loose cloud)
  double tolerance = 0.01;              // -, |sigma_k - p0| / p0 on every axis
  double unbalanced = 0.01;             // -, unbalanced force ratio
  std::uint64_t check_interval = 1000;  // steps between convergence checks
  std::uint64_t max_steps = 5'000'000;  // give up (error) after this many steps
  bool chain = false;        // each higher p0 starts from the next lower p0's sample (false: each from the cloud)
  double dt_fraction = 0.0;  // -, time step of the preparation / Rayleigh time (0: time.dt_fraction)
  // prepare.target_e0: the void ratio asked for at p0 (one for all p0, or one per distinct tests.p0 in
  // config order; empty: none). The preparation's friction is searched (prepare_run.cpp).
  std::vector<double> target_e0;
  double target_tolerance = 0.005;     // -, |e0 - target| accepted (prepare.target_e0_tolerance)
  double max_friction = 1.0;           // -, the search's upper friction (prepare.max_friction)
  std::uint64_t trial_count = 2000;    // spheres of the search's trial preparations (at most sample.count)
  /// The target for p0 (NaN: none). `p0s`: the distinct tests.p0 in config order.
  double target_for(double p0, const std::vector<double>& p0s) const;
};

/// The path of a test (tests.path); its name and needs are its row in protocol/paths.cpp.
enum class ShearPath {
  constant_p,
  constant_sigma3,
  strain,
  undrained,
  cyclic,
  simple_shear,
  simple_shear_cv,
  rotation
};

struct ShearConfig {
  double strain_rate = 0.0;          // 1/s, axial (axis 1) compression rate of the stress paths (0: not given)
  double inertial_number = 0.0;      // -, instead of strain_rate: the axial rate follows the measured p so that
                                     // eps_dot_1 d50 sqrt(rho / p) = inertial_number (0: not given)
  double ramp_strain = 0.0;          // -, axial strain over which the rate rises linearly from 0 (0: none)
  double gain = 0.0;                 // 1/s, lateral servo gain (0: derived, apps/triaxial/README.md)
  double integral_time = 0.0;        // s, integral time of the lateral servo (0: derived, apps/triaxial/README.md)
  double integral_strain = 0.0;      // -, the integral time is at most the time the axial rate takes to strain by
                                     // this much (0: 3e-4 at a set inertial number, else none; README.md)
  double max_rate = 0.0;             // 1/s, cap on lateral rates (0: max_rate_ratio x the axial rate at p0)
  double max_rate_ratio = -1.0;      // -, the cap is at least this multiple of the axial rate at each update
                                     // (-1: not given: 20, or 0 with a max_rate; 0: the fixed max_rate alone)
  int servo_interval = 1;            // steps between servo updates
  double max_axial_strain = 0.2;     // -, stop at this axial (log) strain
  double max_deviatoric_strain = 0.0;  // -, also stop at this eps_q (0: none); axial stress paths only
  bool stop_at_critical = false;     // also stop when critical state is detected
  double critical_window = 0.1;      // -, deviatoric strain eps_q window over which eta, p, e, Z_mech and the fabric
                                     // anisotropy must be stationary (critical.hpp)
  double critical_tolerance = 0.02;  // -, largest relative change (+ 2 SE) of eta = q/p, p and Z_mech over the window
  double critical_tolerance_e = 0.005;       // -, largest change (+ 2 SE) of e over the window
  double critical_tolerance_fabric = 0.05;   // -, largest relative change (+ 2 SE) of the fabric anisotropy F_a
  Vec3 strain_rates = Vec3::Zero();     // 1/s per axis, compression positive, for path "strain"
  Vec3 shear_rates = Vec3::Zero();      // 1/s, engineering shear rates xy xz yz (-L_ab, soil convention), path "strain"
  std::uint64_t steps = 0;              // steps of a strain-controlled stage
  double max_shear_strain = 0.0;        // -, simple shear paths: stop at this engineering shear strain
                                        // gamma = F_xz (0: not given; required by those paths)
};

/// [cell]: whether the cell's shear components are held fixed (an orthorhombic cell, the study's) or
/// free (the three shear stresses servo-controlled to zero, docs/physics.md section 6.2).
struct CellConfig {
  bool free = false;
  bool given = false;  // the key is in the file
};

/// [rotation]: the rotation of the principal stress axes (tests.path = "rotation"): p = p0 and b
/// held, q raised to eta p0 over ramp_time at alpha0, then sigma1's direction turned in the xz plane
/// at `rate` through `angle`.
struct RotationConfig {
  double eta = 0.0;        // -, q / p0, > 0
  double alpha0 = 0.0;     // degrees, sigma1's angle from x toward z during the ramp
  double angle = 180.0;    // degrees, total rotation after the ramp
  double rate = 0.0;       // degrees/s, > 0
  double ramp_time = 0.0;  // s, > 0
  bool given = false;
};

struct TestSpec {
  std::string name;  // e.g. "p-b0.50-p0_500kPa"
  ShearPath path = ShearPath::constant_p;
  double p0 = 0.0;  // Pa, isotropic preparation stress
  double b = 0.0;   // -
};

struct OutputConfig {
  std::uint64_t series_interval = 1000;   // steps between rows of /series
  std::uint64_t snapshot_interval = 0;    // steps between particle snapshots (0: stage ends only)
  std::uint64_t checkpoint_interval = 0;  // steps between checkpoints (0: by time only)
  double checkpoint_minutes = 10.0;       // wall minutes between checkpoints (0: by steps only)
  std::uint64_t flush_interval = 10;      // series rows between flushes of the results file
  bool plot = true;                       // PNG of q and eps_v vs eps_1 per test (python3 + matplotlib)
  double max_size_gib = 64.0;             // GiB, largest estimated size of the run's results files (refused above)
};

/// [cyclic]: the cyclic path's settings (tests.path = "cyclic"; systems/servo.hpp CyclicSettings). In
/// stress mode the bounds are q / p0 (so one table serves every p0 of a campaign); in strain mode
/// axial strains, compressed at shear.strain_rate. The drained form holds sigma3 = p0.
struct CyclicConfig {
  std::string axial = "stress";  // "stress" (q between the bounds) or "strain" (eps1 between them)
  double lower = 0.0, upper = 0.0;
  double tolerance = 0.02;
  bool undrained = true;
  int cycles = 0;
  double max_strain = 0.0;
  bool given = false;  // the table is in the file
};

/// [watch]: the stress-path watchdog of the shearing stage (systems/path_watch.hpp). `start` is
/// not a key: the checks begin at the end of the ramp (shear.ramp_strain).
struct WatchConfig {
  PathTolerance tolerance;
  bool stop = true;  // a test that leaves its path stops there (false: runs to its end, failed all the same)
};

struct Config {
  std::string text;    // the TOML text as read (stored in every results file)
  std::string source;  // file name, or "<embedded default>"
  SampleConfig sample;
  Material material;
  ContactSettings contact;   // skin 0 in the file: derived (0.1 x smallest diameter)
  double dt_fraction = 0.2;  // -, dt / Rayleigh time of the smallest sphere (time.step = "rayleigh"; the
                             // preparation's too unless prepare.dt_fraction)
  TimeStepRule dt_rule = TimeStepRule::fixed;  // time.step: "rayleigh" (fixed) or "stiffness" (shearing only)
  double dt_safety = 0.8;                      // -, time.safety (stiffness): dt = safety x min sqrt(m / K)
  int dt_interval = 100;                       // steps, time.interval (stiffness): between updates of dt
  double max_dt_fraction = 1.0;                // -, time.max_dt_fraction (stiffness): the largest dt / t_R
  PrepareConfig prepare;
  ShearConfig shear;
  std::vector<TestSpec> tests;  // the campaign: path x b x p0
  int parallel = 1;             // tests run at once (the thread budget is split between them)
  OutputConfig output;
  WatchConfig watch;
  CyclicConfig cyclic;
  CellConfig cell;
  RotationConfig rotation;
};

/// The embedded default: ~2000 spheres prepared at 0.5 MPa, sheared along constant p, b = 0.5, to
/// 20 % axial strain.
extern const char* const k_default_config;

/// Parses and validates. `source` names the file in messages. Throws ConfigError.
Config parse_config(const std::string& text, const std::string& source);

/// Reads a config file and parses it (parse_config, the path as its source). Throws ConfigError,
/// naming the path, when it cannot be read (or is a directory).
Config load_config(const std::string& path);

/// The keys ("section.key") whose values differ between two valid config texts, a key present in
/// one only included; keys a resume may change without changing what was computed (`safe`:
/// output.*, tests.*, shear.max_axial_strain) are left out unless `include_safe`.
std::vector<std::string> changed_keys(const std::string& before, const std::string& after, bool include_safe = false);

/// A key whose effective value differs between two configs, with both values as text.
struct KeyChange {
  std::string key;     // "section.key"
  std::string before;  // the value in the first config (e.g. the one a sample was prepared with)
  std::string after;   // the value in the second
};

/// The keys that shape a prepared sample ([sample], material density, young, poisson and
/// restitution, [contact], the preparation's time step and [prepare] but max_steps) whose
/// effective values differ between `before` (the config text a sample was prepared with) and
/// `after`. A `before` that no longer parses is compared key by key as written.
std::vector<KeyChange> sample_changes(const std::string& before, const Config& after);

/// Short text name of a path ("constant_p", ...).
const char* path_name(ShearPath path);

}  // namespace sandcell::triaxial
