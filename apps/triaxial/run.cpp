#include "run.hpp"

#include "config.hpp"
#include "critical.hpp"
#include "lock.hpp"
#include "signals.hpp"
#include "slurm.hpp"

#include "engine/checkpoint.hpp"
#include "engine/generate.hpp"
#include "engine/packing.hpp"
#include "engine/results.hpp"
#include "engine/world.hpp"
#include "systems/catalogue.hpp"
#include "systems/homogenizer.hpp"
#include "systems/path_watch.hpp"

#include <CLI/CLI.hpp>

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <numbers>
#include <optional>
#include <ostream>
#include <sstream>
#include <thread>

#ifndef SANDCELL_SCRIPT_DIR
#define SANDCELL_SCRIPT_DIR ""
#endif

namespace sandcell::triaxial {

namespace fs = std::filesystem;

namespace {

using Clock = std::chrono::steady_clock;

// The Python helpers (plot, analysis): next to an installed binary (<prefix>/share/sandcell), else
// in the source tree the binary was built from. Empty when neither exists.
fs::path script_path(const std::string& name) {
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    const fs::path installed = exe.parent_path().parent_path() / "share" / "sandcell" / name;
    if (fs::exists(installed)) return installed;
  }
  const fs::path source = fs::path(SANDCELL_SCRIPT_DIR) / name;
  if (!std::string(SANDCELL_SCRIPT_DIR).empty() && fs::exists(source)) return source;
  return {};
}

// The interpreter: $SANDCELL_PYTHON, else Debian's python3 (it has h5py, numpy, scipy, matplotlib).
std::string python() {
  const char* env = std::getenv("SANDCELL_PYTHON");
  if (env && *env) return env;
  return fs::exists("/usr/bin/python3") ? "/usr/bin/python3" : "python3";
}

std::string num(double v, const char* format = "%.6g") {
  char buf[64];
  std::snprintf(buf, sizeof buf, format, v);
  return buf;
}

// The partitions' names for CLI11 (IsMember lists them in its message).
CLI::IsMember partition_names() {
  return CLI::IsMember(std::vector<std::string>(k_partition_names.begin(), k_partition_names.end()));
}

struct Options {
  std::string config_path;
  int threads = 0;
  std::string partition = "adaptive";  // --thread-partition: how threads share a pass (same results for all)
  std::string out;
  bool resume = false;
  bool overwrite = false;
  double max_axial_strain = 0.0;  // > 0: overrides shear.max_axial_strain (short runs, CI)
  bool progress = false;
  bool prepare_only = false;              // run the preparations, no test
  bool list = false;                      // print the tasks and exit
  std::vector<std::string> task_specs;    // --task values as given
  std::vector<std::string> allow_change;  // --allow-change keys: a resume may change them
  std::uint64_t stop_after = 0;           // > 0: each job stops after this many steps of this process, with a
                                          // checkpoint, as a killed run would (to test --resume)
  /// Whether a job that started this process at step0 stops (--stop-after) at step s.
  /// Also true once a stop signal arrived (signals.hpp): the job checkpoints and stops.
  bool stop_due(std::uint64_t s, std::uint64_t step0) const {
    return (stop_after > 0 && s - step0 >= stop_after) || stop_requested();
  }
  /// Why a job stopped, for its last line.
  static std::string stop_reason() {
    if (!stop_requested()) return "--stop-after";
    const int sig = stop_signal();
    return sig == SIGTERM   ? "SIGTERM"
           : sig == SIGINT  ? "SIGINT"
           : sig == SIGUSR1 ? "SIGUSR1"
                            : "signal " + std::to_string(sig);
  }
};

// A job stopped on request (--stop-after) after writing its checkpoint.
struct Interrupted : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// A job whose lock another process holds (the same --task run twice): bad input, not a failed test.
struct InUse : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// The message of a job found in use: the job, its lock file and the holder's PID and host.
std::string in_use_message(const fs::path& lock, const std::string& job) {
  return job + " is in use: " + lock.string() + " is held by " + FileLock::holder(lock) +
         "; not started twice; allowed: wait for it to end, or run another task";
}

// Everything derived from the config before anything runs.
struct Plan {
  Config config;
  Options options;
  fs::path out;
  Packing packing;  // from sample.file, or generated per test (same seed: same cloud)
  bool from_file = false;
  double r_min = 0.0, r_max = 0.0;
  double servo_time = 0.0;          // s, the servo's time unit: max(dt, 0.2 Rayleigh time), see derived_gain
  double prepare_dt = 0.0;          // s, time step of the preparations (prepare.dt_fraction, else the shear's)
  double prepare_servo_time = 0.0;  // s, max(prepare_dt, 0.2 Rayleigh time)
  double d50 = 0.0;                 // m, mass-weighted median diameter of the sample (the inertial number's)
  Model base;                       // dt, material, contact settings of the shear stage
  std::vector<double> p0;           // distinct preparation stresses, in config order (ascending with prepare.chain)
  /// The p0 whose sample the preparation for p0 starts from (prepare.chain: the next lower p0), or 0
  /// when it starts from the cloud.
  double chained_from(double p0) const {
    if (!config.prepare.chain) return 0.0;
    double from = 0.0;
    for (double q : this->p0)
      if (q < p0) from = std::max(from, q);
    return from;
  }
  int job_threads = 1;      // threads of one test (the budget split between `parallel` tests)
  int prepare_threads = 1;  // threads of one preparation (all of them when chained ones run one by one)
  Partition partition = Partition::adaptive;  // --thread-partition
  double output_bytes = 0.0;                  // estimated size of the run's results files (estimate_output)
  std::string output_note;                    // the estimate, for the warning above 1 GiB ("" below)
};

std::string p0_tag(double p0) { return "p0_" + num(p0 / 1e3, "%g") + "kPa"; }

// Logs shared by parallel jobs: whole lines, one writer at a time.
class Log {
 public:
  Log(std::ostream& out, bool progress) : out_(out), progress_(progress) {}
  void line(const std::string& text) {
    std::lock_guard lock(mutex_);
    if (pending_) out_ << '\n';
    pending_ = false;
    out_ << text << '\n' << std::flush;
  }
  // A progress line: rewritten in place on a terminal, nothing otherwise.
  void progress(const std::string& text, bool single_job) {
    if (!progress_) return;
    std::lock_guard lock(mutex_);
    if (single_job) {
      out_ << '\r' << text << "\x1b[K" << std::flush;
      pending_ = true;
    } else {
      out_ << text << '\n' << std::flush;
    }
  }

 private:
  std::ostream& out_;
  bool progress_;
  bool pending_ = false;
  std::mutex mutex_;
};

// The series row of docs/physics.md section 8, from measure().
void append_row(ResultsFile& results, const State& state, const Measures& m, double wall) {
  const Mat3& s = m.stress;
  const Mat3& f = m.fabric;
  const double stress[6] = {s(0, 0), s(1, 1), s(2, 2), s(0, 1), s(0, 2), s(1, 2)};
  const double fabric[6] = {f(0, 0), f(1, 1), f(2, 2), f(0, 1), f(0, 2), f(1, 2)};
  results.append("time", state.clock.time, "s");
  results.append("step", static_cast<double>(state.clock.step), "-");
  results.append("strain", std::span<const double>(m.strain.data(), 3), "- (logarithmic, compression positive)");
  results.append("strain_engineering", std::span<const double>(m.strain_engineering.data(), 3), "-");
  results.append("strain_rate", std::span<const double>(m.strain_rate.data(), 3), "1/s (compression positive)");
  results.append("stress", std::span<const double>(stress, 6), "Pa (xx yy zz xy xz yz, compression positive)");
  results.append("principal_stress", std::span<const double>(m.inv.principal.data(), 3), "Pa (s1 >= s2 >= s3)");
  results.append("p", m.inv.p, "Pa");
  results.append("q", m.inv.q, "Pa");
  results.append("eta", m.inv.eta, "-");
  results.append("b", m.inv.b, "-");
  results.append("theta", m.inv.theta, "rad");
  results.append("eps_v", m.eps_v, "-");
  results.append("eps_q", m.eps_q, "-");
  results.append("e", m.void_ratio, "-");
  results.append("Z", m.z, "-");
  results.append("Z_mech", m.z_mech, "-");
  results.append("rattlers", static_cast<double>(m.rattlers), "-");
  results.append("fabric", std::span<const double>(fabric, 6), "- (xx yy zz xy xz yz)");
  results.append("kinetic_energy", m.kinetic_energy, "J");
  results.append("elastic_energy", m.elastic_energy, "J");
  results.append("max_overlap_ratio", m.max_overlap_ratio, "- (largest overlap / smaller radius)");
  results.append("unbalanced_force_ratio", m.unbalanced, "-");
  results.append("inertial_number", m.inertial_number, "- ((eps_dot_1 - eps_dot_3) d50 sqrt(rho/p))");
  results.append("inertial_number_axial", m.inertial_number_axial,
                 "- (eps_dot_1 d50 sqrt(rho/p): what shear.inertial_number sets)");
  results.append("rotation", principal_rotation_deg(m.stress),
                 "degrees (the principal axes' turn off the cell axes, 1/2 asin(2 |tau| / (s1 - s3)))");
  results.append("shear_ratio", shear_ratio(m.stress), "- (largest |shear stress| / p)");
  results.append("wall_time", wall, "s");
}

// A run that has gone unstable stops here with the step, the particle and what blew up.
void check_finite(const State& state, const Measures& m) {
  const Particles& p = state.particles;
  for (std::size_t k = 0; k < p.size(); ++k) {
    const char* what = !p.position[k].allFinite()           ? "position"
                       : !p.velocity[k].allFinite()         ? "velocity"
                       : !p.angular_velocity[k].allFinite() ? "angular velocity"
                       : !p.force[k].allFinite()            ? "force"
                                                            : nullptr;
    if (what)
      throw SimulationError("step " + std::to_string(state.clock.step) + ": particle id " + std::to_string(p.id[k]) +
                            ": " + what +
                            " is not finite (the run went unstable: lower time.dt_fraction or the strain rate)");
  }
  if (!std::isfinite(m.inv.p) || !state.cell.length.allFinite())
    throw SimulationError("step " + std::to_string(state.clock.step) + ": cell stress or lengths are not finite");
}

// The live accuracy indicators of a shearing run, each with its safe range. A run that leaves one
// gets a warning line (once per indicator and job: the step, the value, the range and what to
// change); the worst value is in the job's last line.
class AccuracyWatch {
 public:
  AccuracyWatch(std::string job, Log& log) : job_(std::move(job)), log_(log) {}

  void check(const Measures& m, std::uint64_t step) {
    const double ratio = m.elastic_energy > 0.0 ? m.kinetic_energy / m.elastic_energy : 0.0;
    const double values[k_count] = {m.inertial_number_axial, m.unbalanced, ratio, m.max_overlap_ratio};
    for (int k = 0; k < k_count; ++k) {
      worst_[k] = std::max(worst_[k], values[k]);
      if (values[k] > k_limits[k].limit && !warned_[k]) {
        warned_[k] = true;
        log_.line(job_ + ": warning: step " + std::to_string(step) + ": " + k_limits[k].name + " = " +
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
  // sqrt(rho/p)): the inertia study (docs/study-inertia) found every measure within one test's
  // scatter from I = 1e-5 up to 3e-3 and the peak q/p 0.05-0.5 too high at 1e-2; the limit is 3e-3
  // plus 5 % for the fluctuation of the measured p between servo updates. An unbalanced force
  // ratio above 0.1 means forces far from balance; the kinetic energy reached 4 % of the stored
  // elastic energy in the fast protocol's validation (19,436 spheres at I = 3e-3, docs/reproducing-the-study.md), whose
  // peak and dilatancy errors stayed within the seed scatter and whose critical q/p rose by 2 %:
  // 5 % is the limit; Hertz theory assumes overlaps small beside the radius.
  static constexpr Limit k_limits[k_count] = {
      {"inertial number eps_dot_1 d50 sqrt(rho/p)", 3.15e-3,
       "validated up to 3e-3 (docs/study-inertia): lower shear.strain_rate or shear.inertial_number"},
      {"unbalanced force ratio", 0.1,
       "forces far from balance: lower shear.strain_rate or shear.inertial_number; from the first rows on, "
       "lower time.dt_fraction (stiff contacts at high p: 0.35 t_R was unstable at 16 MPa)"},
      {"kinetic / elastic energy", 0.05,
       "inertia carries load: lower shear.strain_rate or shear.inertial_number, or time.dt_fraction"},
      {"max overlap / radius", 0.05, "beyond small-strain Hertz contact: raise material.young or lower p0"},
  };

 private:
  std::string job_;
  Log& log_;
  bool warned_[k_count] = {};
  double worst_[k_count] = {};
};

// Wall time and checkpoint timing of a job.
struct Timer {
  Clock::time_point start = Clock::now();
  double before = 0.0;  // s of earlier segments of a resumed job
  Clock::time_point last_checkpoint = Clock::now();
  double elapsed() const { return before + std::chrono::duration<double>(Clock::now() - start).count(); }
};

bool checkpoint_due(const OutputConfig& o, std::uint64_t step, Timer& timer) {
  if (o.checkpoint_interval > 0 && step % o.checkpoint_interval == 0) return true;
  if (o.checkpoint_minutes > 0.0 &&
      std::chrono::duration<double>(Clock::now() - timer.last_checkpoint).count() > 60.0 * o.checkpoint_minutes)
    return true;
  return false;
}

void save(const fs::path& path, const State& state, CheckpointExtra extra, Timer& timer) {
  extra.doubles["wall_time"] = {timer.elapsed()};
  write_checkpoint(path, state, extra);
  timer.last_checkpoint = Clock::now();
}

// ---- models -------------------------------------------------------------------------------------

// Servo gain derived from the physics when the config leaves it 0. A strain increment changes the
// stress through the packing's stiffness K ~ p (E*/p)^(2/3) (Hertzian contacts), so a servo acting
// for a time t changes the normalized error by about c g t (E*/p)^(2/3), c of order 10 for the
// affine response. g = alpha (p/E*)^(2/3) / t_s keeps that loop gain at c alpha whatever the
// material and pressure. The time unit t_s is physical, 0.2 Rayleigh times (the default dt), so
// the servo's response in time does not change with time.dt_fraction: a gain per step (t_s = dt,
// as before) made a 4x smaller dt a 4x stiffer servo against the same inertia of the sample, and
// the preparation of 400 spheres at dt_fraction 0.05 hovered at 2.8 % stress error for 5e6 steps.
// Above 0.2 t_R, t_s = dt bounds the loop gain per step, which must stay below the period-2
// limit: measured (every step sampled, 300 soft spheres sheared at 10/s, constant p, b = 0,
// dt = 0.2 t_R) alpha = 0.25 and 0.2 oscillate with period 2 steps (p alternating +-10 %), 0.1 does
// not. A P law lags a moving target by err ~ rate / g (2 % there); the integral term removes it:
// with T_i = 1000 t_s the rms |p - p0|/p0 after 1 % strain fell from 2.0 % to 0.4 % (T_i = 200 t_s:
// 0.1 %, closer to the slow modes of large samples). Preparation (a fixed target from rest through
// jamming) keeps the P law with alpha = 0.05. Every dt_fraction = 0.2 config runs bitwise as before.
constexpr double k_shear_alpha = 0.1;
constexpr double k_integral_units = 1000.0;
constexpr double k_integral_strain = 3e-4;  // at a set inertial number: T_i <= 3e-4 / axial rate
constexpr double k_servo_time_fraction = 0.2;  // t_s / t_Rayleigh, floor of the servo time unit

double derived_gain(double alpha, double p, const Model& m, double servo_time) {
  const Material& mat = m.materials[0];
  const double e_star = mat.young / (2.0 * (1.0 - mat.poisson * mat.poisson));
  return alpha * std::pow(p / e_star, 2.0 / 3.0) / servo_time;
}

Model prepare_model(const Plan& plan, double p0) {
  Model m = plan.base;
  m.dt = plan.prepare_dt;
  m.materials[0].friction = plan.config.prepare.friction;
  m.materials[0].rolling_friction = plan.config.prepare.rolling_friction;
  ServoSettings& s = m.servo;
  s.enabled = true;
  s.path = StressPath::isotropic;
  s.control = {AxisControl::stress, AxisControl::stress, AxisControl::stress};
  s.p = p0;
  s.max_rate = plan.config.prepare.max_rate;
  s.gain =
      plan.config.prepare.gain > 0.0 ? plan.config.prepare.gain : derived_gain(0.05, p0, m, plan.prepare_servo_time);
  s.interval = 1;
  return m;
}

// The axial rate of a test at p = p0, 1/s: shear.strain_rate, or what shear.inertial_number sets.
double axial_rate(const Plan& plan, double p0) {
  const ShearConfig& h = plan.config.shear;
  if (h.inertial_number > 0.0) return h.inertial_number * std::sqrt(p0 / plan.config.material.density) / plan.d50;
  return h.strain_rate;
}

Model shear_model(const Plan& plan, const TestSpec& test) {
  Model m = plan.base;
  const ShearConfig& h = plan.config.shear;
  ServoSettings& s = m.servo;
  if (test.path == ShearPath::strain) return m;  // rates set once on the cell; no servo scheduled
  s.enabled = true;
  s.path = test.path == ShearPath::constant_p ? StressPath::constant_p_b : StressPath::constant_sigma3_b;
  s.control = {AxisControl::strain, AxisControl::stress, AxisControl::stress};
  const double rate0 = axial_rate(plan, test.p0);
  if (h.inertial_number > 0.0) {
    // The servo scales the direction (1, 0, 0) by I sqrt(p/rho) / d50 at each update.
    s.strain_rate = Vec3(1.0, 0.0, 0.0);
    s.inertial_number = h.inertial_number;
    s.d50 = plan.d50;
    s.density = plan.config.material.density;
  } else {
    s.strain_rate = Vec3(h.strain_rate, 0.0, 0.0);
  }
  // A linear ramp over ramp_strain of (logarithmic) axial strain takes 2 ramp_strain / rate (at a
  // set inertial number, the rate at p = p0).
  s.ramp_time = 2.0 * h.ramp_strain / rate0;
  s.p = test.p0;
  s.sigma3 = test.p0;
  s.b = test.b;
  // The default cap follows the axial rate (10 x, the rate at p0 a floor): at a set inertial number the
  // axial rate grows with sqrt(p), and a cap fixed at p0 ran the b = 1 constant-sigma3 test away
  // (docs/physics.md section 6). An explicit shear.max_rate is a fixed cap, as set.
  s.max_rate = h.max_rate > 0.0 ? h.max_rate : 10.0 * rate0;
  s.max_rate_ratio = h.max_rate > 0.0 ? 0.0 : 10.0;
  s.gain = h.gain > 0.0 ? h.gain : derived_gain(k_shear_alpha, test.p0, m, plan.servo_time);
  s.integral_time = h.integral_time > 0.0 ? h.integral_time : k_integral_units * plan.servo_time;
  // At a set inertial number the axial rate is 6-80 /s (0.5-16 MPa, I = 3e-3) and T_i = 1000 t_s spans
  // up to 1 % of axial strain: on constant sigma3 the lateral axes lagged through the peak (sigma3 up to
  // 31 % high over 1 % of strain at b = 1, 1,000 spheres). T_i at most the time of 3e-4 axial strain
  // held every b at 0.5 and 16 MPa within 1.0 % (docs/physics.md section 6). At a set strain rate of
  // 1 /s every path held within 0.2 % with T_i = 1000 t_s, which stays (the default test is unchanged).
  s.integral_strain = h.integral_time > 0.0          ? 0.0
                      : h.integral_strain > 0.0      ? h.integral_strain
                      : h.inertial_number > 0.0      ? k_integral_strain
                                                     : 0.0;
  s.interval = h.servo_interval;
  return m;
}

// The stress-path watchdog of a test ([watch]; systems/path_watch.hpp): its checks begin at the end
// of the ramp. The strain path has no stress targets and its shear stresses are the material's
// answer, not a departure: there only the overlap and the unbalanced force are judged.
PathWatch make_path_watch(const Plan& plan, const TestSpec& test) {
  PathTolerance t = plan.config.watch.tolerance;
  t.start = plan.config.shear.ramp_strain;
  if (test.path == ShearPath::strain) {
    t.rotation = 45.0;  // the largest turn 1/2 asin(2 |tau| / (s1 - s3)) can give: never beyond
    t.shear = 10.0;
  }
  return PathWatch(shear_model(plan, test).servo, t);
}

// ---- jobs ---------------------------------------------------------------------------------------

struct Summary {
  std::string name;
  std::string status = "not run";
  std::string from = "cloud";  // preparations: what it started from (the cloud, or a lower p0's sample)
  double e0 = 0.0, z0 = 0.0, peak_eta = 0.0, peak_strain = 0.0, final_eta = 0.0, final_e = 0.0, final_p = 0.0;
  double final_strain = 0.0;
  double z_mech = 0.0, unbalanced = 0.0;  // preparations: at the end
  std::uint64_t steps = 0;
  double wall = 0.0;
  bool critical = false;
  // Tests: the stress-path watchdog's verdict (systems/path_watch.hpp): why it failed ("" while on
  // its path) and the largest errors it saw (NaN: not judged).
  std::string reason;
  double path_error = std::numeric_limits<double>::quiet_NaN();
  double b_error = std::numeric_limits<double>::quiet_NaN();
  double rotation = std::numeric_limits<double>::quiet_NaN();
  bool left_path() const { return !reason.empty(); }
  // The watch's largest errors; NaN when it judged no window (a test shorter than the ramp and one
  // window, that did not fail either).
  void set_path_errors(const PathWatch& watch) {
    const bool judged = watch.rows_checked() > 0 || left_path();
    const double nan = std::numeric_limits<double>::quiet_NaN();
    path_error = judged ? watch.worst_path() : nan;
    b_error = judged ? watch.worst_b() : nan;
    rotation = judged ? watch.worst_rotation() : nan;
  }
};

class Runner {
 public:
  Runner(const Plan& plan, Log& log) : plan_(plan), log_(log) {}

  fs::path sample_path(double p0) const { return plan_.out / ("sample-" + p0_tag(p0) + ".h5"); }

  /// The summary of a finished preparation, read back from its sample file.
  Summary sample_summary(double p0) const;
  /// The summary of a test from its checkpoint (state and extras): done when marked complete.
  Summary test_summary(const TestSpec& test, const State& state, CheckpointExtra& extra) const;
  /// What the output directory says of a test run elsewhere (another task): from its checkpoint.
  Summary test_summary_on_disk(const TestSpec& test) const;
  /// Makes sure the sample for p0 exists: prepares it (and, chained, the lower ones first) under
  /// its job lock unless another process already did. Returns false when a preparation failed.
  bool ensure_sample(double p0);

  // Prepares the sample for p0 (or finds it prepared). Returns false on failure.
  bool prepare(double p0, Summary& summary);
  void shear(const TestSpec& test, Summary& summary);

 private:
  const Plan& plan_;
  Log& log_;
  bool single_job() const { return plan_.config.parallel == 1; }
};

Summary Runner::sample_summary(double p0) const {
  Summary summary;
  summary.name = "prepare-" + p0_tag(p0);
  CheckpointExtra extra;
  const State st = read_checkpoint(sample_path(p0), &extra);
  const auto value = [&](const char* key) {  // NaN when a sample file of an older version lacks it
    const auto it = extra.doubles.find(key);
    return it != extra.doubles.end() && !it->second.empty() ? it->second.front() : std::nan("");
  };
  summary.e0 = value("e0");
  summary.z0 = value("Z");
  summary.z_mech = value("Z_mech");
  summary.unbalanced = value("unbalanced");
  summary.final_p = value("p");
  summary.steps = st.clock.step;
  summary.wall = value("wall_time");
  summary.status = "done (earlier run)";
  if (const double from = plan_.chained_from(p0); from > 0.0) summary.from = "sample-" + p0_tag(from);
  return summary;
}

// One sample's isotropic compression to p0 (Runner::prepare): from the cloud (or the packing
// file), from the next lower p0's sample (prepare.chain) or, with --resume, from its checkpoint,
// to the sample file that the tests on p0 start from.
class PrepareRun {
 public:
  PrepareRun(const Plan& plan, Log& log, double p0, Summary& summary)
      : plan_(plan),
        log_(log),
        p0_(p0),
        summary_(summary),
        name_(summary.name),
        pc_(plan.config.prepare),
        o_(plan.config.output),
        ckpt_(plan.out / (name_ + ".checkpoint.h5")),
        series_(plan.out / (name_ + ".h5")),
        from_(plan.chained_from(p0)) {}

  /// Opens the preparation (its state and series file) and the world that steps it; a new one
  /// gets its first row.
  void open(const Runner& runner);
  /// Steps until converged (prepare.tolerance, prepare.unbalanced). Throws SimulationError past
  /// prepare.max_steps, Interrupted after a checkpoint when asked to stop.
  void run();
  /// The last snapshot, the sample file (the state and its measures), the summary and the last line.
  void finish(const fs::path& sample);

 private:
  State resume();
  State start_from_sample(const fs::path& sample);
  State start_from_cloud(const Model& model);
  void row(const Measures& m);
  bool converged(std::uint64_t s);
  void checkpoint_or_stop(std::uint64_t s);

  const Plan& plan_;
  Log& log_;
  const double p0_;
  Summary& summary_;
  const std::string name_;  // "prepare-p0_...kPa"
  const PrepareConfig& pc_;
  const OutputConfig& o_;
  const fs::path ckpt_, series_;  // the checkpoint, the series file
  const double from_;             // the p0 of the sample it starts from (prepare.chain), else 0
  Timer timer_;
  std::optional<ResultsFile> results_;
  bool resumed_ = false;
  std::optional<World> world_;
  MeasureOptions mo_;
  Measures m_;  // the last measured
  std::uint64_t rows_ = 0;
  std::uint64_t step0_ = 0;  // the step this process started stepping at
  Clock::time_point t0_;
};

void PrepareRun::open(const Runner& runner) {
  const Model model = prepare_model(plan_, p0_);
  State state;
  if (plan_.options.resume && fs::exists(ckpt_))
    state = resume();
  else if (from_ > 0.0)
    state = start_from_sample(runner.sample_path(from_));
  else
    state = start_from_cloud(model);
  if (from_ > 0.0) summary_.from = "sample-" + p0_tag(from_);
  // A chained preparation continues a sample whose forces are in its state, as a test does.
  const bool initial_forces = !resumed_ && from_ == 0.0;
  world_.emplace(model, std::move(state), systems_for(model),
                 ExecutorConfig{Backend::tbb, plan_.prepare_threads, plan_.partition}, initial_forces);
  mo_.d50 = median_diameter(world_->state().particles);
  mo_.density = plan_.config.material.density;
  log_.line(name_ + ": isotropic compression to " + num(p0_ / 1e6) + " MPa from the " +
            (summary_.from == "cloud" ? std::string(plan_.from_file ? "packing file" : "cloud") : summary_.from) +
            ", " + std::to_string(world_->state().particles.size()) + " spheres, dt = " + num(model.dt) +
            " s, servo gain " + num(model.servo.gain, "%.4g") + " 1/s, " + std::to_string(plan_.prepare_threads) +
            " threads");
  if (!resumed_) row(measure(world_->model(), world_->state(), world_->executor(), mo_));
}

// --resume: the checkpoint's state and wall time, the series file cut back to its step.
State PrepareRun::resume() {
  CheckpointExtra extra;
  State state = read_checkpoint(ckpt_, &extra);
  timer_.before = extra.doubles["wall_time"].at(0);
  results_.emplace(ResultsFile::reopen(series_, state.clock.step));
  resumed_ = true;
  log_.line(name_ + ": resumed at step " + std::to_string(state.clock.step));
  return state;
}

// prepare.chain: the laboratory sequence, the sample prepared at the next lower p0 compressed on to p0.
State PrepareRun::start_from_sample(const fs::path& sample) {
  State state = read_checkpoint(sample, nullptr);
  state.clock = {};
  state.cell.rate.setZero();
  state.cell.servo_integral.setZero();  // servo state resets between stages
  results_.emplace(ResultsFile::create(series_, plan_.config.text,
                                       {{"job", name_}, {"stage", "prepare"}, {"from", "sample-" + p0_tag(from_)}}));
  return state;
}

// The packing file's spheres, or the cloud generated from [sample] (the same seed: the same cloud).
State PrepareRun::start_from_cloud(const Model& model) {
  Packing packing = plan_.packing;
  if (!plan_.from_file && plan_.config.sample.generation.count > 100'000)  // the placement takes a while
    log_.line(name_ + ": placing " + std::to_string(plan_.config.sample.generation.count) + " spheres at random");
  if (!plan_.from_file) packing = generate_packing(plan_.config.sample.generation);
  State state = make_state(model, packing);
  results_.emplace(ResultsFile::create(series_, plan_.config.text, {{"job", name_}, {"stage", "prepare"}}));
  return state;
}

// A row of the series (flushed every output.flush_interval rows).
void PrepareRun::row(const Measures& m) {
  append_row(*results_, world_->state(), m, timer_.elapsed());
  if (++rows_ % o_.flush_interval == 0) results_->flush();
}

void PrepareRun::run() {
  t0_ = Clock::now();
  step0_ = world_->state().clock.step;
  for (;;) {
    // Steps until the body below has something to do: one call for many steps is bitwise the
    // same as one call per step, and faster (World::step_until).
    world_->step_until(std::numeric_limits<std::uint64_t>::max(), [&](Cell&, const sandcell::Clock& clock) {
      const std::uint64_t s = clock.step;
      return s % o_.series_interval == 0 || s % pc_.check_interval == 0 || checkpoint_due(o_, s, timer_) ||
             plan_.options.stop_due(s, step0_);
    });
    const std::uint64_t s = world_->state().clock.step;
    const bool series_due = s % o_.series_interval == 0;
    const bool check = s % pc_.check_interval == 0;
    if (series_due || check) {
      m_ = measure(world_->model(), world_->state(), world_->executor(), mo_);
      check_finite(world_->state(), m_);
      if (series_due) row(m_);
      if (check && converged(s)) break;
    }
    checkpoint_or_stop(s);
  }
}

// The check every prepare.check_interval steps, on the last measures: a progress line; true when
// every axis is within prepare.tolerance of p0 and the unbalanced force ratio below
// prepare.unbalanced; a SimulationError when not by prepare.max_steps.
bool PrepareRun::converged(std::uint64_t s) {
  double worst = 0.0;
  for (int k = 0; k < 3; ++k) worst = std::max(worst, std::abs(m_.stress(k, k) - p0_) / p0_);
  const double rate = double(s - step0_) / std::chrono::duration<double>(Clock::now() - t0_).count();
  log_.progress(name_ + " step " + std::to_string(s) + "  p " + num(m_.inv.p / 1e6, "%.4f") + " MPa  e " +
                    num(m_.void_ratio, "%.4f") + "  stress error " + num(100 * worst, "%.2f") + " %  unbalanced " +
                    num(m_.unbalanced, "%.2e") + "  " + num(rate, "%.0f") + " steps/s",
                plan_.config.parallel == 1);
  if (worst < pc_.tolerance && m_.unbalanced < pc_.unbalanced) return true;
  if (s >= pc_.max_steps)
    throw SimulationError(name_ + ": not converged after prepare.max_steps = " + std::to_string(pc_.max_steps) +
                          " steps: worst axis stress error " + num(100 * worst) + " % (tolerance " +
                          num(100 * pc_.tolerance) + " %), unbalanced force ratio " + num(m_.unbalanced) +
                          " (tolerance " + num(pc_.unbalanced) + ")");
  return false;
}

// A checkpoint when one is due; on a stop request (--stop-after, a signal) a checkpoint, then
// Interrupted.
void PrepareRun::checkpoint_or_stop(std::uint64_t s) {
  if (checkpoint_due(o_, s, timer_)) {
    results_->flush();
    save(ckpt_, world_->state(), {}, timer_);
  }
  if (plan_.options.stop_due(s, step0_)) {
    results_->flush();
    save(ckpt_, world_->state(), {}, timer_);
    throw Interrupted(name_ + ": stopped at step " + std::to_string(s) + " (" + Options::stop_reason() +
                      "), checkpoint written");
  }
}

void PrepareRun::finish(const fs::path& sample) {
  State& st = world_->state();
  st.cell.length0 = st.cell.length;  // strains of the tests count from the prepared sample
  results_->write_snapshot(st);
  results_->close();
  CheckpointExtra extra;
  extra.doubles["p0"] = {p0_};
  extra.doubles["e0"] = {m_.void_ratio};
  extra.doubles["Z"] = {m_.z};
  extra.doubles["Z_mech"] = {m_.z_mech};
  extra.doubles["unbalanced"] = {m_.unbalanced};
  extra.doubles["p"] = {m_.inv.p};
  extra.strings["config"] = plan_.config.text;
  save(sample, st, extra, timer_);
  std::error_code ignore;
  fs::remove(ckpt_, ignore);
  summary_.e0 = m_.void_ratio;
  summary_.z0 = m_.z;
  summary_.z_mech = m_.z_mech;
  summary_.unbalanced = m_.unbalanced;
  summary_.final_p = m_.inv.p;
  summary_.steps = st.clock.step;
  summary_.wall = timer_.elapsed();
  summary_.status = "done";
  log_.line(name_ + ": done at step " + std::to_string(st.clock.step) + ": e0 = " + num(m_.void_ratio, "%.4f") +
            ", Z = " + num(m_.z, "%.3f") + ", Z_mech = " + num(m_.z_mech, "%.3f") +
            ", p = " + num(m_.inv.p / 1e6, "%.4f") + " MPa, unbalanced " + num(m_.unbalanced, "%.2e") + ", wall " +
            num(summary_.wall, "%.1f") + " s");
}

bool Runner::prepare(double p0, Summary& summary) {
  const std::string tag = p0_tag(p0);
  summary.name = "prepare-" + tag;
  const fs::path sample = sample_path(p0);
  // One process prepares a sample at a time; another task that needs it waits here, then finds it.
  FileLock job;
  job.lock(plan_.out / ".locks" / ("prepare-" + tag + ".lock"), FileLock::Mode::exclusive);
  if (fs::exists(sample)) {  // only reachable with --resume or --task: a finished preparation
    summary = sample_summary(p0);
    return true;
  }
  PrepareRun run(plan_, log_, p0, summary);
  run.open(*this);
  run.run();
  run.finish(sample);
  return true;
}

// The series rows of the test, for the critical-state test (critical.hpp) and the peak.
struct History {
  std::vector<double> eps1, p, q, e;
  CriticalCheck critical(const ShearConfig& h) const {
    return check_critical(
        eps1, p, q, e,
        CriticalTest{
            .window = h.critical_window, .tolerance = h.critical_tolerance, .tolerance_e = h.critical_tolerance_e});
  }
  CheckpointExtra save() const {
    CheckpointExtra x;
    x.doubles = {{"history_eps1", eps1}, {"history_p", p}, {"history_q", q}, {"history_e", e}};
    return x;
  }
  void load(CheckpointExtra& x) {
    eps1 = x.doubles["history_eps1"];
    p = x.doubles["history_p"];
    q = x.doubles["history_q"];
    e = x.doubles["history_e"];
  }
};

Summary Runner::test_summary(const TestSpec& test, const State& state, CheckpointExtra& extra) const {
  Summary summary;
  summary.name = test.name;
  CheckpointExtra sample_extra;
  read_checkpoint(sample_path(test.p0), &sample_extra);
  summary.e0 = sample_extra.doubles["e0"].at(0);
  summary.z0 = sample_extra.doubles["Z"].at(0);
  const bool complete = extra.integers.count("complete") && extra.integers["complete"].at(0) == 1;
  summary.reason = extra.strings.count("path_failure") ? extra.strings["path_failure"] : "";
  summary.status = !complete ? "interrupted" : summary.left_path() ? "failed" : "done (earlier run)";
  if (extra.doubles.count("path_watch")) {
    PathWatch watch = make_path_watch(plan_, test);
    watch.restore(extra.doubles["path_watch"]);
    summary.set_path_errors(watch);
  }
  History history;
  history.load(extra);
  summary.steps = state.clock.step;
  summary.wall = extra.doubles["wall_time"].at(0);
  if (!history.eps1.empty()) {
    const auto peak = std::max_element(history.q.begin(), history.q.end()) - history.q.begin();
    summary.peak_eta = history.q[peak] / history.p[peak];
    summary.peak_strain = history.eps1[peak];
    summary.final_eta = history.q.back() / history.p.back();
    summary.final_e = history.e.back();
    summary.final_p = history.p.back();
    summary.final_strain = history.eps1.back();
  }
  return summary;
}

Summary Runner::test_summary_on_disk(const TestSpec& test) const {
  const fs::path ckpt = plan_.out / (test.name + ".checkpoint.h5");
  Summary summary;
  summary.name = test.name;
  if (!fs::exists(ckpt) || !fs::exists(sample_path(test.p0))) return summary;  // "not run"
  CheckpointExtra extra;
  const State state = read_checkpoint(ckpt, &extra);
  return test_summary(test, state, extra);
}

bool Runner::ensure_sample(double p0) {
  if (fs::exists(sample_path(p0))) return true;
  if (const double from = plan_.chained_from(p0); from > 0.0 && !ensure_sample(from)) return false;
  Summary summary;
  return prepare(p0, summary);
}

// One test's shearing stage (Runner::shear): from its prepared sample, or with --resume from its
// checkpoint, to the finished results file, the checkpoint marked complete and the summary.
class ShearRun {
 public:
  ShearRun(const Plan& plan, Log& log, const TestSpec& test, Summary& summary)
      : plan_(plan),
        log_(log),
        test_(test),
        summary_(summary),
        h_(plan.config.shear),
        o_(plan.config.output),
        ckpt_(plan.out / (test.name + ".checkpoint.h5")),
        path_(plan.out / (test.name + ".h5")),
        max_strain_(plan.options.max_axial_strain > 0.0 ? plan.options.max_axial_strain : h_.max_axial_strain),
        watch_(test.name, log),
        path_watch_(make_path_watch(plan, test)) {}

  /// Opens the test (its state and results file, from the sample or the checkpoint) and the world
  /// that steps it; a new test gets its first row and snapshot. Returns false when the checkpoint
  /// marks the test complete (an earlier run's): the summary is then that run's.
  bool open(const Runner& runner, const fs::path& sample);
  /// Steps to the end: the maximum axial strain (the steps of path "strain"), or critical state
  /// with shear.stop_at_critical. Throws Interrupted after a checkpoint when asked to stop.
  void run();
  /// The last snapshot, the checkpoint marked complete, the summary and the job's last line.
  void finish();
  /// The PNG of q and eps_v (plot_triaxial.py); a missing python3/matplotlib is a warning.
  void plot() const;

 private:
  void resume(const State& state, CheckpointExtra& extra);
  State start_from_sample(const fs::path& sample);
  void row();
  CheckpointExtra extras() const;
  static double axial_strain(const Cell& cell) { return -std::log(cell.length[0] / cell.length0[0]); }
  bool finished(std::uint64_t s, double eps1) const {
    return test_.path == ShearPath::strain ? s >= h_.steps : eps1 >= max_strain_;
  }
  bool progress_due() const {
    return plan_.options.progress && std::chrono::duration<double>(Clock::now() - last_progress_).count() > 1.0;
  }
  bool event_due(std::uint64_t s, double eps1);
  void check_critical(double eps1);
  void checkpoint_or_stop(std::uint64_t s);
  void report_progress(std::uint64_t s, double eps1);

  const Plan& plan_;
  Log& log_;
  const TestSpec& test_;
  Summary& summary_;
  const ShearConfig& h_;
  const OutputConfig& o_;
  const fs::path ckpt_, path_;  // the checkpoint, the results file
  const double max_strain_;     // shear.max_axial_strain, or --max-axial-strain
  Timer timer_;
  History history_;
  AccuracyWatch watch_;
  PathWatch path_watch_;
  std::optional<ResultsFile> results_;
  bool resumed_ = false;
  std::optional<World> world_;
  MeasureOptions mo_;
  Measures m_;  // the last row's
  std::uint64_t rows_ = 0;
  std::uint64_t step0_ = 0;  // the step this process started stepping at
  Clock::time_point t0_, last_progress_;
};

bool ShearRun::open(const Runner& runner, const fs::path& sample) {
  const Model model = shear_model(plan_, test_);
  CheckpointExtra sample_extra;
  read_checkpoint(sample, &sample_extra);
  summary_.e0 = sample_extra.doubles["e0"].at(0);
  summary_.z0 = sample_extra.doubles["Z"].at(0);
  State state;
  if (plan_.options.resume && fs::exists(ckpt_)) {
    CheckpointExtra extra;
    state = read_checkpoint(ckpt_, &extra);
    timer_.before = extra.doubles["wall_time"].at(0);
    if (extra.integers.count("complete") && extra.integers["complete"].at(0) == 1) {
      summary_ = runner.test_summary(test_, state, extra);
      return false;
    }
    resume(state, extra);
  } else {
    state = start_from_sample(sample);
  }
  world_.emplace(model, std::move(state), systems_for(model),
                 ExecutorConfig{Backend::tbb, plan_.job_threads, plan_.partition}, false);
  mo_.d50 = median_diameter(world_->state().particles);
  mo_.density = plan_.config.material.density;
  log_.line(test_.name + ": " + path_name(test_.path) +
            (test_.path == ShearPath::strain ? "" : ", b = " + num(test_.b)) + ", p0 = " + num(test_.p0 / 1e6) +
            " MPa, e0 = " + num(summary_.e0, "%.4f") + ", to axial strain " + num(max_strain_) + ", servo gain " +
            num(model.servo.gain, "%.4g") + " 1/s, " + std::to_string(plan_.job_threads) + " threads");
  if (!resumed_) {
    row();
    results_->write_snapshot(world_->state());
  }
  return true;
}

// --resume: the series and the accuracy watch as checkpointed, the results file cut back to the
// checkpoint's step.
void ShearRun::resume(const State& state, CheckpointExtra& extra) {
  history_.load(extra);
  watch_.restore(extra.doubles["watch_worst"]);
  if (extra.doubles.count("path_watch")) path_watch_.restore(extra.doubles["path_watch"]);
  results_.emplace(ResultsFile::reopen(path_, state.clock.step));
  resumed_ = true;
  log_.line(test_.name + ": resumed at step " + std::to_string(state.clock.step));
}

// A new test: the prepared sample with its clock, strains and servo state reset and the first
// rates set; a new results file.
State ShearRun::start_from_sample(const fs::path& sample) {
  State state = read_checkpoint(sample, nullptr);
  state.clock = {};
  state.cell.length0 = state.cell.length;
  state.cell.servo_integral.setZero();  // servo state resets between stages
  if (test_.path == ShearPath::strain)
    state.cell.rate = -h_.strain_rates;
  else
    state.cell.rate = Vec3(h_.ramp_strain > 0.0 ? 0.0 : -axial_rate(plan_, test_.p0), 0.0, 0.0);
  results_.emplace(ResultsFile::create(path_, plan_.config.text,
                                       {{"job", test_.name},
                                        {"stage", "shear"},
                                        {"path", path_name(test_.path)},
                                        {"b", num(test_.b)},
                                        {"p0", num(test_.p0)}}));
  return state;
}

// A row of the series: measured, checked, appended (and flushed every output.flush_interval rows),
// watched, and kept in the history.
void ShearRun::row() {
  m_ = measure(world_->model(), world_->state(), world_->executor(), mo_);
  check_finite(world_->state(), m_);
  append_row(*results_, world_->state(), m_, timer_.elapsed());
  if (world_->state().clock.step > 0) watch_.check(m_, world_->state().clock.step);
  const std::uint64_t step = world_->state().clock.step;
  const auto failure = path_watch_.add({step, m_.strain[0], m_.stress, m_.max_overlap_ratio, m_.unbalanced});
  if (failure && !summary_.left_path()) {  // (a resumed watch.stop = false run keeps its first reason)
    summary_.reason = failure->message;
    log_.line(test_.name + ": failed: " + failure->message +
              (plan_.config.watch.stop ? "; stopped" : "; runs on (watch.stop = false)"));
  }
  history_.eps1.push_back(m_.strain[0]);
  history_.p.push_back(m_.inv.p);
  history_.q.push_back(m_.inv.q);
  history_.e.push_back(m_.void_ratio);
  if (++rows_ % o_.flush_interval == 0) results_->flush();
}

// What a checkpoint keeps besides the state: the history and the accuracy watch's worst values.
CheckpointExtra ShearRun::extras() const {
  CheckpointExtra x = history_.save();
  x.doubles["watch_worst"] = watch_.worst_values();
  x.doubles["path_watch"] = path_watch_.save();
  if (summary_.left_path()) x.strings["path_failure"] = summary_.reason;
  return x;
}

// Whether the loop of run() has something to do after step s: the end, a row, a snapshot, a
// checkpoint, a stop or a progress line.
bool ShearRun::event_due(std::uint64_t s, double eps1) {
  return finished(s, eps1) || s % o_.series_interval == 0 ||
         (o_.snapshot_interval > 0 && s % o_.snapshot_interval == 0) || checkpoint_due(o_, s, timer_) ||
         plan_.options.stop_due(s, step0_) || progress_due();
}

void ShearRun::run() {
  t0_ = Clock::now();
  step0_ = world_->state().clock.step;
  last_progress_ = Clock::now();
  for (;;) {
    // Steps until the body below has something to do: one call for many steps is bitwise the
    // same as one call per step, and faster (World::step_until).
    world_->step_until(std::numeric_limits<std::uint64_t>::max(), [&](Cell& cell, const sandcell::Clock& clock) {
      return event_due(clock.step, axial_strain(cell));
    });
    State& st = world_->state();
    const std::uint64_t s = st.clock.step;
    const double eps1 = axial_strain(st.cell);
    const bool done = finished(s, eps1);
    if (s % o_.series_interval == 0 || done) {
      row();
      if (h_.stop_at_critical) check_critical(eps1);
    }
    if (o_.snapshot_interval > 0 && s % o_.snapshot_interval == 0) results_->write_snapshot(st);
    if (done || summary_.critical || (summary_.left_path() && plan_.config.watch.stop)) break;
    checkpoint_or_stop(s);
    if (progress_due()) report_progress(s, eps1);
  }
}

// shear.stop_at_critical: marks the summary (which ends the loop) when the history has reached
// critical state (critical.hpp).
void ShearRun::check_critical(double eps1) {
  if (const CriticalCheck c = history_.critical(h_); c.reached) {
    summary_.critical = true;
    log_.line(test_.name + ": critical state at eps1 = " + num(100.0 * eps1, "%.2f") + " %: over the last " +
              num(100.0 * h_.critical_window, "%g") + " % (" + std::to_string(c.rows) +
              " rows) the fitted lines change eta by " + num(100.0 * c.change_eta, "%.2f") + " %, p by " +
              num(100.0 * c.change_p, "%.2f") + " %, e by " + num(c.change_e, "%.4f"));
  }
}

// A checkpoint when one is due; on a stop request (--stop-after, a signal) a checkpoint, then
// Interrupted.
void ShearRun::checkpoint_or_stop(std::uint64_t s) {
  const State& st = world_->state();
  if (checkpoint_due(o_, s, timer_)) {
    results_->flush();
    save(ckpt_, st, extras(), timer_);
  }
  if (plan_.options.stop_due(s, step0_)) {
    results_->flush();
    save(ckpt_, st, extras(), timer_);
    throw Interrupted(test_.name + ": stopped at step " + std::to_string(s) + " (" + Options::stop_reason() +
                      "), checkpoint written");
  }
}

// The progress line (a terminal only): the last row's measures, the speed and the time left.
void ShearRun::report_progress(std::uint64_t s, double eps1) {
  last_progress_ = Clock::now();
  const double speed = double(s - step0_) / std::chrono::duration<double>(Clock::now() - t0_).count();
  const double rate = -world_->state().cell.rate[0];  // 1/s, the axial rate now
  const double left = test_.path != ShearPath::strain
                          ? (rate > 0.0 ? (max_strain_ - eps1) / (rate * world_->model().dt) / speed : 0.0)
                          : double(h_.steps - s) / speed;
  log_.progress(test_.name + " step " + std::to_string(s) + "  eps1 " + num(100 * eps1, "%.2f") + " %  p " +
                    num(m_.inv.p / 1e6, "%.4f") + " MPa  q " + num(m_.inv.q / 1e6, "%.4f") + " MPa  e " +
                    num(m_.void_ratio, "%.4f") + "  I " + num(m_.inertial_number, "%.1e") + "  unbal " +
                    num(m_.unbalanced, "%.3f") + "  " + num(speed, "%.0f") + " steps/s  ETA " + num(left, "%.0f") +
                    " s",
                plan_.config.parallel == 1);
}

void ShearRun::finish() {
  State& st = world_->state();
  if (o_.snapshot_interval == 0 || st.clock.step % o_.snapshot_interval != 0) results_->write_snapshot(st);
  // A test that ended before its first full window (shorter than the ramp and a window) was not
  // judged: its errors are NaN in the file and index.csv, and the log says so.
  summary_.set_path_errors(path_watch_);
  const bool judged = std::isfinite(summary_.path_error);
  // The verdict in the file itself: analyze leaves a failed test out of every fit.
  results_->set_attribute("/", "status", summary_.left_path() ? "failed" : "done");
  results_->set_attribute("/", "status_reason", summary_.reason);
  results_->set_attribute("/", "path_error", summary_.path_error);
  results_->set_attribute("/", "b_error", summary_.b_error);
  results_->set_attribute("/", "rotation_deg", summary_.rotation);
  results_->close();
  CheckpointExtra extra = extras();
  extra.integers["complete"] = {1};
  save(ckpt_, st, extra, timer_);

  const auto peak = std::max_element(history_.q.begin(), history_.q.end()) - history_.q.begin();
  summary_.peak_eta = history_.q[peak] / history_.p[peak];
  summary_.peak_strain = history_.eps1[peak];
  summary_.final_eta = m_.inv.eta;
  summary_.final_e = m_.void_ratio;
  summary_.final_p = m_.inv.p;
  summary_.final_strain = m_.strain[0];
  summary_.steps = st.clock.step;
  summary_.wall = timer_.elapsed();
  if (!judged && test_.path != ShearPath::strain)
    log_.line(test_.name + ": its stress path was not judged: it ended at eps1 = " + num(100 * m_.strain[0], "%.2f") +
              " %, before the watchdog's first window (" + num(100 * h_.ramp_strain, "%g") + " % of ramp and " +
              num(100 * plan_.config.watch.tolerance.window, "%g") + " %)");
  summary_.status = summary_.left_path() ? "failed" : summary_.critical ? "done (critical state)" : "done";
  log_.line(test_.name + (summary_.left_path() ? ": failed (left its stress path) at step " : ": done at step ") +
            std::to_string(st.clock.step) +
            ", eps1 = " + num(100 * m_.strain[0], "%.2f") + " %: peak q/p = " + num(summary_.peak_eta, "%.4f") +
            " at eps1 = " + num(100 * summary_.peak_strain, "%.2f") + " %, final q/p = " + num(m_.inv.eta, "%.4f") +
            ", p = " + num(m_.inv.p / 1e6, "%.4f") + " MPa, b = " + num(m_.inv.b, "%.3f") +
            ", e = " + num(m_.void_ratio, "%.4f") + ", wall " + num(summary_.wall, "%.1f") + " s; " + watch_.worst() +
            "; path error " + num(100.0 * path_watch_.worst_path(), "%.2f") + " %, b error " +
            num(path_watch_.worst_b(), "%.3f") + ", rotation " + num(path_watch_.worst_rotation(), "%.1f") + " deg");
}

void ShearRun::plot() const {
  // The plot is a convenience: a missing python3/matplotlib is a warning, not a failure.
  const fs::path script = script_path("plot_triaxial.py");
  const fs::path png = plan_.out / (test_.name + ".png");
  if (!script.empty()) {
    const std::string cmd =
        "'" + python() + "' '" + script.string() + "' '" + path_.string() + "' '" + png.string() + "' 2>&1";
    if (std::system(cmd.c_str()) == 0)
      log_.line(test_.name + ": plot " + png.string());
    else
      log_.line(test_.name + ": warning: no plot (needs python3 with h5py and matplotlib: " + cmd + ")");
  }
}

void Runner::shear(const TestSpec& test, Summary& summary) {
  summary.name = test.name;
  FileLock job;
  const fs::path lock = plan_.out / ".locks" / (test.name + ".lock");
  if (!job.try_lock(lock, FileLock::Mode::exclusive)) throw InUse(in_use_message(lock, "test " + test.name));
  ShearRun run(plan_, log_, test, summary);
  if (!run.open(*this, sample_path(test.p0))) return;  // complete in an earlier run
  run.run();
  run.finish();
  if (plan_.config.output.plot) run.plot();
}

// ---- planning -----------------------------------------------------------------------------------

// The first pair of spheres of a packing that overlap by more than a tenth of the smaller radius
// ("" when none): such a start blows up in the first steps ("went unstable ... lower dt"), which
// blames the time step for what is the file's fault. Periodic box; a grid of cells >= 2 r_max.
std::string deep_overlap(const Packing& pk) {
  const std::size_t n = pk.position.size();
  const double r_max = *std::max_element(pk.radius.begin(), pk.radius.end());
  Vec3 cells_f = (pk.box / (2.0 * r_max)).array().floor().max(1.0).min(256.0);
  const int nx = int(cells_f[0]), ny = int(cells_f[1]), nz = int(cells_f[2]);
  std::vector<std::vector<std::uint32_t>> grid(static_cast<std::size_t>(nx) * ny * nz);
  const auto cell_of = [&](const Vec3& x, int c[3]) {
    const int dims[3] = {nx, ny, nz};
    for (int a = 0; a < 3; ++a) {
      const double f = x[a] / pk.box[a] - std::floor(x[a] / pk.box[a]);
      c[a] = std::min(dims[a] - 1, static_cast<int>(f * dims[a]));
    }
  };
  for (std::size_t k = 0; k < n; ++k) {
    int c[3];
    cell_of(pk.position[k], c);
    grid[(static_cast<std::size_t>(c[2]) * ny + c[1]) * nx + c[0]].push_back(static_cast<std::uint32_t>(k));
  }
  for (std::size_t k = 0; k < n; ++k) {
    int c[3];
    cell_of(pk.position[k], c);
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const std::size_t cell = (static_cast<std::size_t>((c[2] + dz + nz) % nz) * ny + (c[1] + dy + ny) % ny) * nx +
                                   (c[0] + dx + nx) % nx;
          for (std::uint32_t q : grid[cell]) {
            if (q <= k) continue;
            Vec3 d = pk.position[k] - pk.position[q];
            for (int a = 0; a < 3; ++a) d[a] -= pk.box[a] * std::nearbyint(d[a] / pk.box[a]);
            const double overlap = pk.radius[k] + pk.radius[q] - d.norm();
            if (overlap > 0.1 * std::min(pk.radius[k], pk.radius[q]))
              return "spheres " + std::to_string(k + 1) + " and " + std::to_string(q + 1) +
                     " (in file order) overlap by " + num(overlap / std::min(pk.radius[k], pk.radius[q]), "%.3g") +
                     " of the smaller radius (allowed: up to 0.1; coincident spheres?)";
          }
        }
  }
  return "";
}

// The sample's diameters: the packing file's (read into plan.packing, checked for coincident
// spheres), else those [sample] generates. Throws ConfigError.
std::vector<double> sample_sizes(Plan& plan) {
  const std::string& src = plan.config.source;
  const SampleConfig& sc = plan.config.sample;
  std::vector<double> diameters;
  if (!sc.packing_file.empty()) {
    try {
      plan.packing = read_packing(sc.packing_file);
    } catch (const std::exception& e) {
      throw ConfigError(src + ": sample.file = \"" + sc.packing_file + "\": " + e.what());
    }
    if (plan.packing.position.size() < 2)
      throw ConfigError(src + ": sample.file = \"" + sc.packing_file + "\": needs at least 2 spheres");
    plan.from_file = true;
    for (double r : plan.packing.radius) diameters.push_back(2.0 * r);
    if (const std::string pair = deep_overlap(plan.packing); !pair.empty())
      throw ConfigError(src + ": sample.file = \"" + sc.packing_file + "\": " + pair);
  } else {
    diameters = sample_diameters(sc.generation.sizes, sc.generation.count, sc.generation.seed);
  }
  return diameters;
}

// The shear stage's model (material, contact settings, skin, dt) and the time units of the
// preparation and the servos, from the smallest radius.
void derive_model(Plan& plan) {
  const Config& config = plan.config;
  Model& m = plan.base;
  m.materials = {config.material};
  m.contact = config.contact;
  if (m.contact.skin == 0.0) m.contact.skin = 0.2 * plan.r_min;  // 0.1 x the smallest diameter
  m.dt = config.dt_fraction * rayleigh_time(plan.r_min, config.material);
  plan.servo_time = std::max(m.dt, k_servo_time_fraction * rayleigh_time(plan.r_min, config.material));
  // The preparation may take its own step: frictionless, it has no tangential or rolling springs,
  // whose stiff rotational modes bound the shearing step at high pressure (docs/reproducing-the-study.md).
  plan.prepare_dt =
      config.prepare.dt_fraction > 0.0 ? config.prepare.dt_fraction * rayleigh_time(plan.r_min, config.material) : m.dt;
  plan.prepare_servo_time =
      std::max(plan.prepare_dt, k_servo_time_fraction * rayleigh_time(plan.r_min, config.material));
}

// The cell must stay wider than 2 r_max + skin through the test: at a dense random packing
// (solid fraction <= 0.64) after preparation, then shortened by the axial strain. Throws
// ConfigError naming the key at fault.
void check_cell_width(const Plan& plan, const std::vector<double>& diameters, double max_strain) {
  const Config& config = plan.config;
  const Model& m = plan.base;
  double solid = 0.0;
  for (double d : diameters) solid += std::numbers::pi / 6.0 * d * d * d;
  const double side = std::cbrt(solid / 0.64);
  double narrowest = side;
  for (const TestSpec& t : config.tests) {
    if (t.path == ShearPath::strain) {
      const Vec3 r = config.shear.strain_rates;
      narrowest = std::min(narrowest, side * std::exp(-r.maxCoeff() * m.dt * double(config.shear.steps)));
    } else {
      narrowest = std::min(narrowest, side * std::exp(-max_strain));
    }
  }
  const double cutoff = 2.0 * plan.r_max + m.contact.skin;
  if (narrowest > cutoff) return;
  const double needed = static_cast<double>(diameters.size()) * std::pow(cutoff / narrowest, 3.0);
  // The key at fault first: a skin wider than the spheres, a packing file's huge sphere, a
  // strain path that collapses the cell; else the sample is too small.
  std::string key = "sample.count = " + std::to_string(diameters.size());
  if (m.contact.skin > 2.0 * plan.r_max)
    key = "contact.skin = " + num(m.contact.skin) + " m (wider than the largest sphere)";
  else if (plan.from_file && 2.0 * plan.r_max > 0.25 * side)
    key = "sample.file = \"" + config.sample.packing_file + "\": its largest radius " + num(plan.r_max) + " m";
  else if (narrowest < side * std::exp(-max_strain) && config.shear.steps > 0)
    key = "shear.steps = " + std::to_string(config.shear.steps) + " (with shear.strain_rates)";
  throw ConfigError(config.source + ": " + key + ": the cell would narrow to " + num(narrowest) +
                    " m (dense sample, then the axial strain), not wider than 2 r_max + skin = " + num(cutoff) +
                    " m; allowed: more than " + num(std::ceil(needed), "%.0f") +
                    " spheres, or a smaller shear.max_axial_strain");
}

// Runs that cannot end in any reasonable time (a 1e308 Pa modulus made dt 1e-155 s) or whose
// servo acts too seldom to control anything are refused, naming the key.
void check_run_lengths(const Plan& plan, double max_strain) {
  const Config& config = plan.config;
  const std::string& src = config.source;
  const Model& m = plan.base;
  for (const TestSpec& t : config.tests) {
    if (t.path == ShearPath::strain) continue;
    const double rate = axial_rate(plan, t.p0);
    const double steps = max_strain / (rate * m.dt);
    if (!(steps < 1e10))
      throw ConfigError(
          src + ": " +
          (m.dt < 1e-12
               ? "material.young = " + num(config.material.young) + " Pa (dt = " + num(m.dt) + " s)"
               : std::string(config.shear.inertial_number > 0.0 ? "shear.inertial_number" : "shear.strain_rate")) +
          ": the test at p0 = " + num(t.p0) + " Pa would take " + num(steps, "%.2g") +
          " steps; allowed: up to 1e10 (a stiffer time step or a faster rate)");
    const double strain_per_update = rate * m.dt * config.shear.servo_interval;
    if (strain_per_update > 1e-3)
      throw ConfigError(src + ": shear.servo_interval = " + std::to_string(config.shear.servo_interval) +
                        ": the servo would act only every " + num(strain_per_update, "%.2g") +
                        " of axial strain; allowed: at most 1e-3 (here " +
                        num(std::max(1.0, std::floor(1e-3 / (rate * m.dt))), "%.0f") + " steps)");
  }
  {
    // The preparation compresses the cloud at prepare.max_rate at most: ln(0.64 / solid fraction) / 3 per axis.
    const double phi0 = plan.from_file ? 0.3 : config.sample.generation.solid_fraction;
    const double steps = std::log(0.64 / phi0) / 3.0 / (config.prepare.max_rate * plan.prepare_dt);
    if (!(steps < 1e10))
      throw ConfigError(src + ": " +
                        (plan.prepare_dt < 1e-12 ? "material.young = " + num(config.material.young) + " Pa"
                                                 : "prepare.max_rate = " + num(config.prepare.max_rate)) +
                        ": the preparation would take more than " + num(steps, "%.2g") + " steps; allowed: up to 1e10");
  }
}

// At most 1e-3 of strain a step (the bound of a servo update, check_run_lengths): faster, the cell
// outruns the contacts within a step. Checked before the cell width, which a too fast strain path
// also breaks (1e308 1/s was blamed on shear.steps). Throws ConfigError naming the rate's key.
void check_strain_per_step(const Plan& plan) {
  constexpr double k_max_strain_per_step = 1e-3;
  const Config& config = plan.config;
  const double dt = plan.base.dt;
  const std::string allowed = ": allowed: at most " + num(k_max_strain_per_step) +
                              " of strain a step (at dt = " + num(dt) + " s: a rate up to " +
                              num(k_max_strain_per_step / dt, "%.3g") + " 1/s)";
  for (const TestSpec& t : config.tests) {
    if (t.path == ShearPath::strain) {
      for (int a = 0; a < 3; ++a)
        if (std::abs(config.shear.strain_rates[a]) * dt > k_max_strain_per_step)
          throw ConfigError(config.source + ": shear.strain_rates[" + std::to_string(a) +
                            "] = " + num(config.shear.strain_rates[a]) + " 1/s" + allowed);
    } else if (const double rate = axial_rate(plan, t.p0); rate * dt > k_max_strain_per_step) {
      const std::string key = config.shear.inertial_number > 0.0
                                  ? "shear.inertial_number = " + num(config.shear.inertial_number) + " (" + num(rate) +
                                        " 1/s at p0 = " + num(t.p0) + " Pa)"
                                  : "shear.strain_rate = " + num(rate) + " 1/s";
      throw ConfigError(config.source + ": " + key + allowed);
    }
  }
}

// The size of the results files, estimated before anything runs (measured: 300 and 1,200 spheres,
// a snapshot every 10 steps, within 5 % above): a snapshot is 14 doubles a sphere
// (ResultsFile::write_snapshot) and ~4 KiB of HDF5 headers (2.2 KiB) and XDMF entry (1.6 KiB); a
// series row 46 doubles; a file ~1 MiB of first chunks (32 KiB for each of ~29 datasets). A test
// runs to max_axial_strain (+ ramp_strain for the ramp) at its rate at p0 (shear.steps on path
// "strain"), an upper bound with stop_at_critical; a preparation at least the shrink of its cloud
// at prepare.max_rate. Above output.max_size_gib the run is refused naming the interval that
// costs most; above 1 GiB it is warned about at the start. Throws ConfigError.
void estimate_output(Plan& plan, std::size_t spheres, double max_strain) {
  constexpr double k_snapshot_sphere = 14 * 8, k_snapshot_header = 4096, k_row = 46 * 8, k_file = 1 << 20;
  constexpr double k_warn = double(1 << 30);  // 1 GiB
  const Config& config = plan.config;
  const OutputConfig& o = config.output;
  double snapshot_bytes = 0.0, row_bytes = 0.0, longest = 0.0;  // longest: steps of the longest test
  for (const TestSpec& t : config.tests) {
    const double steps = t.path == ShearPath::strain
                             ? double(config.shear.steps)
                             : (max_strain + config.shear.ramp_strain) / (axial_rate(plan, t.p0) * plan.base.dt);
    longest = std::max(longest, steps);
    const double snapshots = 2.0 + (o.snapshot_interval > 0 ? std::floor(steps / double(o.snapshot_interval)) : 0.0);
    snapshot_bytes += snapshots * (k_snapshot_sphere * double(spheres) + k_snapshot_header);
    row_bytes += k_file + (2.0 + std::floor(steps / double(o.series_interval))) * k_row;
  }
  const double phi0 = plan.from_file ? 0.3 : config.sample.generation.solid_fraction;
  for (double p0 : plan.p0) {
    const double steps =
        plan.chained_from(p0) > 0.0 ? 0.0 : std::log(0.64 / phi0) / 3.0 / (config.prepare.max_rate * plan.prepare_dt);
    snapshot_bytes += k_snapshot_sphere * double(spheres) + k_snapshot_header;
    row_bytes += k_file + (1.0 + std::floor(steps / double(o.series_interval))) * k_row;
  }
  plan.output_bytes = snapshot_bytes + row_bytes;
  const bool snapshots = snapshot_bytes >= row_bytes;
  const std::string key = snapshots ? "output.snapshot_interval = " + std::to_string(o.snapshot_interval)
                                    : "output.series_interval = " + std::to_string(o.series_interval);
  const std::string gib = num(plan.output_bytes / k_warn, "%.3g") + " GiB";
  const std::string what = std::to_string(config.tests.size()) + " test(s) x " + num(longest, "%.3g") + " steps x " +
                           std::to_string(spheres) + " spheres";
  if (plan.output_bytes > o.max_size_gib * k_warn) {
    // The interval that gives ~100 snapshots (~1000 rows) a test, when that is a larger one.
    const double interval = std::ceil(longest / (snapshots ? 100.0 : 1000.0));
    const double now = double(snapshots ? o.snapshot_interval : o.series_interval);
    if ((snapshots && o.snapshot_interval == 0) || interval <= now)  // no interval to blame: the limit
      throw ConfigError(config.source + ": output.max_size_gib = " + num(o.max_size_gib) + ": below the ~" + gib +
                        " of results the output intervals as set write (estimated: " + what +
                        "); allowed: a larger output.max_size_gib");
    throw ConfigError(config.source + ": " + key + ": ~" + gib + " of results (estimated: " + what +
                      "); allowed: <= output.max_size_gib = " + num(o.max_size_gib) + " GiB: raise the interval to " +
                      num(interval, "%.0f") + " (~" + (snapshots ? "100 snapshots" : "1000 rows") +
                      " a test) or the limit");
  }
  if (plan.output_bytes > k_warn)
    plan.output_note = "~" + gib + " of results (estimated: " + what + ", " + key +
                       "), above 1 GiB; refused above output.max_size_gib = " + num(o.max_size_gib) + " GiB";
}

Plan make_plan(Config config_in, const Options& options) {
  Plan plan;
  plan.options = options;
  plan.config = std::move(config_in);
  const Config& config = plan.config;
  const std::vector<double> diameters = sample_sizes(plan);
  plan.r_min = 0.5 * *std::min_element(diameters.begin(), diameters.end());
  plan.r_max = 0.5 * *std::max_element(diameters.begin(), diameters.end());
  {
    std::vector<double> radii(diameters.size());
    for (std::size_t k = 0; k < diameters.size(); ++k) radii[k] = 0.5 * diameters[k];
    plan.d50 = median_diameter(radii);
  }
  derive_model(plan);
  const double max_strain = options.max_axial_strain > 0.0 ? options.max_axial_strain : config.shear.max_axial_strain;
  check_strain_per_step(plan);
  check_cell_width(plan, diameters, max_strain);
  for (const TestSpec& t : config.tests)
    if (std::find(plan.p0.begin(), plan.p0.end(), t.p0) == plan.p0.end()) plan.p0.push_back(t.p0);
  if (config.prepare.chain) std::sort(plan.p0.begin(), plan.p0.end());
  check_run_lengths(plan, max_strain);
  estimate_output(plan, diameters.size(), max_strain);
  // Servo settings are checked here, before anything is written.
  try {
    validate(prepare_model(plan, plan.p0.front()).servo);
    for (const TestSpec& t : config.tests) {
      const Model sm = shear_model(plan, t);
      if (sm.servo.enabled) validate(sm.servo);
    }
  } catch (const std::invalid_argument& e) {
    throw ConfigError(config.source + ": " + e.what());
  }
  const int total = options.threads > 0 ? options.threads : available_cpus();
  plan.job_threads = std::max(1, total / std::max(1, config.parallel));
  plan.prepare_threads = config.prepare.chain ? total : plan.job_threads;
  plan.partition = partition_from_name(options.partition).value();  // CLI11 let only the names through
  return plan;
}

// The files a run writes into the output directory: all of them, or (selected) those of the
// selected tasks (the shared index.csv and samples.csv are merged, never replaced whole).
std::vector<fs::path> run_files(const Plan& plan, const std::vector<char>& run_prep, const std::vector<char>& run_test,
                                bool selected) {
  std::vector<fs::path> files;
  if (!selected) files = {plan.out / "index.csv", plan.out / "samples.csv"};
  for (std::size_t k = 0; k < plan.p0.size(); ++k) {
    if (selected && !run_prep[k]) continue;
    const std::string tag = p0_tag(plan.p0[k]);
    for (const char* f : {"sample-", "prepare-"}) files.push_back(plan.out / (f + tag + ".h5"));
    files.push_back(plan.out / ("prepare-" + tag + ".xdmf"));
    files.push_back(plan.out / ("prepare-" + tag + ".checkpoint.h5"));
  }
  for (std::size_t k = 0; k < plan.config.tests.size(); ++k) {
    if (selected && !run_test[k]) continue;
    for (const char* ext : {".h5", ".xdmf", ".checkpoint.h5", ".png"})
      files.push_back(plan.out / (plan.config.tests[k].name + ext));
  }
  return files;
}

// Parses --task values (K, A-B, K,L,...) into sorted distinct task indices below n; returns the
// message of the first bad value, or "" when all are good.
std::string parse_tasks(const std::vector<std::string>& specs, std::size_t n, std::vector<std::size_t>& tasks) {
  const auto index = [&](const std::string& text, std::size_t& v) {
    if (text.empty() || text.find_first_not_of("0123456789") != std::string::npos || text.size() > 9) return false;
    v = std::stoul(text);
    return true;
  };
  const std::string allowed = "allowed: indices 0-" + std::to_string(n - 1) + " of --list, as K, A-B or K,L,...";
  for (const std::string& spec : specs) {
    std::stringstream items(spec);
    for (std::string item; std::getline(items, item, ',');) {
      const std::size_t dash = item.find('-');
      std::size_t a = 0, b = 0;
      const bool ok = dash == std::string::npos ? index(item, a) && index(item, b)
                                                : index(item.substr(0, dash), a) && index(item.substr(dash + 1), b);
      if (!ok || a > b) return "= " + item + ": not an index or range; " + allowed;
      if (b >= n) return "= " + item + ": out of range (the campaign has " + std::to_string(n) + " tasks); " + allowed;
      for (std::size_t k = a; k <= b; ++k) tasks.push_back(k);
    }
  }
  std::sort(tasks.begin(), tasks.end());
  tasks.erase(std::unique(tasks.begin(), tasks.end()), tasks.end());
  return "";
}

// Writes `name` in the output directory through a temporary file renamed over it, so a reader
// never sees half a file.
template <class Write>
void write_replacing(const Plan& plan, const std::string& name, Write write) {
  const fs::path path = plan.out / name;
  const fs::path tmp = plan.out / (name + ".tmp" + std::to_string(::getpid()));
  std::ofstream out(tmp);
  write(out);
  out.close();
  if (!out) {  // a full disk or an I/O error: the earlier file stays, no empty one replaces it
    const std::string why = std::strerror(errno);
    std::error_code ec;
    fs::remove(tmp, ec);
    throw std::runtime_error(path.string() + ": not written (" + why + "); the earlier file is kept");
  }
  fs::rename(tmp, path);
}

// A CSV field: quoted (quotes doubled) when it holds a comma, a quote or a line break.
std::string csv_field(const std::string& v) {
  if (v.find_first_of(",\"\n") == std::string::npos) return v;
  std::string out = "\"";
  for (char c : v) out += c == '"' ? std::string("\"\"") : std::string(1, c);
  return out + "\"";
}

void write_index(const Plan& plan, const std::vector<Summary>& prep, const std::vector<Summary>& tests) {
  write_replacing(plan, "index.csv", [&](std::ostream& out) {
    out << "test,path,b,p0_Pa,file,status,e0,Z0,peak_eta,eps1_at_peak,final_eta,final_p_Pa,final_e,final_eps1,steps,wall_s,"
           "path_error,b_error,rotation_deg,reason\n";
    for (std::size_t k = 0; k < tests.size(); ++k) {
      const TestSpec& t = plan.config.tests[k];
      const Summary& s = tests[k];
      out << t.name << ',' << path_name(t.path) << ',' << num(t.b) << ',' << num(t.p0) << ',' << t.name << ".h5,"
          << s.status << ',' << num(s.e0) << ',' << num(s.z0) << ',' << num(s.peak_eta) << ',' << num(s.peak_strain)
          << ',' << num(s.final_eta) << ',' << num(s.final_p) << ',' << num(s.final_e) << ',' << num(s.final_strain)
          << ',' << s.steps << ',' << num(s.wall) << ',' << num(s.path_error) << ',' << num(s.b_error) << ','
          << num(s.rotation) << ',' << csv_field(s.reason) << '\n';
    }
  });
  // One row per sample: the preparation's end state, which every test on it starts from.
  write_replacing(plan, "samples.csv", [&](std::ostream& out) {
    out << "sample,p0_Pa,file,status,p_Pa,e0,Z,Z_mech,unbalanced,steps,wall_s,from\n";
    for (std::size_t k = 0; k < prep.size(); ++k) {
      const Summary& s = prep[k];
      const std::string tag = p0_tag(plan.p0[k]);
      out << "sample-" << tag << ',' << num(plan.p0[k]) << ",sample-" << tag << ".h5," << s.status << ','
          << num(s.final_p) << ',' << num(s.e0) << ',' << num(s.z0) << ',' << num(s.z_mech) << ',' << num(s.unbalanced)
          << ',' << s.steps << ',' << num(s.wall) << ',' << s.from << '\n';
    }
  });
}

// Runs fn(k) for k in [0, n) on `workers` threads.
template <class Fn>
void run_parallel(std::size_t n, int workers, Fn&& fn) {
  std::atomic<std::size_t> next{0};
  const auto work = [&] {
    for (std::size_t k; (k = next.fetch_add(1)) < n;) fn(k);
  };
  std::vector<std::thread> pool;
  for (int w = 1; w < std::min<int>(workers, static_cast<int>(n)); ++w) pool.emplace_back(work);
  work();
  for (std::thread& t : pool) t.join();
}

// This process's share of a campaign (run_campaign): the selected preparations, then the selected
// tests, `parallel` at once, with their summaries and the failures and stops counted.
class Campaign {
 public:
  Campaign(const Plan& plan, Log& log, const std::vector<char>& run_prep, const std::vector<char>& run_test)
      : plan_(plan),
        log_(log),
        run_prep_(run_prep),
        run_test_(run_test),
        runner_(plan, log),
        prep_(plan.p0.size()),
        tests_(plan.config.tests.size()),
        prepared_(plan.p0.size(), 0) {}

  /// The preparations; chained ones run in order of p0, each after the one it starts from.
  void prepare_samples();
  /// The tests, each on its sample (prepared here or found in the directory).
  void shear_tests();
  /// index.csv and samples.csv: what this process did, and for the rest what the directory holds
  /// (other tasks' finished samples and tests), merged under a lock.
  void write_indices();
  int failures() const { return failures_; }
  /// 0 done, 1 a job failed, 2 a job in use by another process, 3 stopped (a signal or --stop-after).
  int exit_code() const { return failures_ ? 1 : in_use_ ? 2 : interrupted_ ? 3 : 0; }

 private:
  void failed(const std::string& what, const std::exception& e);
  void prepare_sample(std::size_t k);
  void shear_test(std::size_t k);

  const Plan& plan_;
  Log& log_;
  const std::vector<char>& run_prep_;
  const std::vector<char>& run_test_;
  Runner runner_;
  std::vector<Summary> prep_, tests_;
  std::vector<char> prepared_;
  int failures_ = 0, interrupted_ = 0, in_use_ = 0;
  std::mutex failure_mutex_;
};

// A job that threw: a stop (Interrupted) or a failure, counted, with its line.
void Campaign::failed(const std::string& what, const std::exception& e) {
  std::lock_guard lock(failure_mutex_);
  if (dynamic_cast<const Interrupted*>(&e)) {
    ++interrupted_;
    log_.line(std::string(e.what()) + "; continue with --resume");
    return;
  }
  if (dynamic_cast<const InUse*>(&e)) {  // another process runs it: what the directory says goes in the index
    ++in_use_;
    log_.line("triaxial: " + std::string(e.what()));
    return;
  }
  ++failures_;
  log_.line("triaxial: " + what + ": " + e.what());
}

void Campaign::prepare_samples() {
  run_parallel(plan_.p0.size(), plan_.config.prepare.chain ? 1 : plan_.config.parallel,
               [&](std::size_t k) { prepare_sample(k); });
}

void Campaign::prepare_sample(std::size_t k) {
  const std::string name = "prepare-" + p0_tag(plan_.p0[k]);
  if (!run_prep_[k]) return;
  if (stop_requested()) {
    prep_[k].name = name;
    prep_[k].status = "interrupted";
    return;
  }
  try {
    // A chained preparation needs the lower sample: prepared by an earlier task, or here.
    if (const double from = plan_.chained_from(plan_.p0[k]); from > 0.0 && !runner_.ensure_sample(from)) {
      prep_[k].name = name;
      prep_[k].status = "skipped (sample-" + p0_tag(from) + " failed)";
      return;
    }
    prepared_[k] = runner_.prepare(plan_.p0[k], prep_[k]);
  } catch (const std::exception& e) {
    prep_[k].name = name;
    prep_[k].status = dynamic_cast<const Interrupted*>(&e) ? "interrupted" : "failed";
    failed(name, e);
  }
}

void Campaign::shear_tests() {
  run_parallel(plan_.config.tests.size(), plan_.config.parallel, [&](std::size_t k) { shear_test(k); });
}

void Campaign::shear_test(std::size_t k) {
  const TestSpec& t = plan_.config.tests[k];
  tests_[k].name = t.name;
  if (!run_test_[k]) return;
  if (stop_requested()) {
    tests_[k].status = "interrupted";
    std::lock_guard lock(failure_mutex_);
    ++interrupted_;
    return;
  }
  const std::size_t sample = std::find(plan_.p0.begin(), plan_.p0.end(), t.p0) - plan_.p0.begin();
  if (run_prep_[sample] && !prepared_[sample]) {  // its preparation failed in this process
    tests_[k].status = "skipped (sample failed)";
    return;
  }
  try {
    if (!runner_.ensure_sample(t.p0)) {
      tests_[k].status = "skipped (sample failed)";
      return;
    }
    runner_.shear(t, tests_[k]);
    if (tests_[k].left_path()) {  // a test that left its stress path is a failed test (its line is logged)
      std::lock_guard lock(failure_mutex_);
      ++failures_;
    }
  } catch (const std::exception& e) {
    tests_[k].status = dynamic_cast<const Interrupted*>(&e) ? "interrupted"
                       : dynamic_cast<const InUse*>(&e)     ? "in use"
                                                            : "failed";
    failed(t.name, e);
  }
}

void Campaign::write_indices() {
  try {
    FileLock index_lock;
    index_lock.lock(plan_.out / ".locks" / "index.csv.lock", FileLock::Mode::exclusive);
    for (std::size_t k = 0; k < prep_.size(); ++k)
      if (!run_prep_[k] || prep_[k].status == "not run") {
        if (fs::exists(runner_.sample_path(plan_.p0[k])))
          prep_[k] = runner_.sample_summary(plan_.p0[k]);
        else
          prep_[k].name = "prepare-" + p0_tag(plan_.p0[k]);
      }
    for (std::size_t k = 0; k < tests_.size(); ++k)
      if (!run_test_[k] || tests_[k].status == "in use")
        tests_[k] = runner_.test_summary_on_disk(plan_.config.tests[k]);
    write_index(plan_, prep_, tests_);
  } catch (const std::exception& e) {
    failed("index.csv", e);
  }
}

}  // namespace

// `triaxial analyze|study|localization|calibrate ...`: runs the Python script <command>.py with the remaining arguments;
// the script's usage lines name "triaxial <command>", and the study finds this binary through
// SANDCELL_TRIAXIAL.
static int script_main(const std::string& command, int argc, const char* const* argv, std::ostream& err) {
  const std::string prog = "triaxial " + command;
  const fs::path script = script_path(command + ".py");
  if (script.empty()) {
    err << prog << ": " << command << ".py not found (looked in <prefix>/share/sandcell and " << SANDCELL_SCRIPT_DIR
        << ")\n";
    return 2;
  }
  const std::string py = python();
  std::vector<std::string> args{py, script.string()};
  for (int k = 1; k < argc; ++k) args.emplace_back(argv[k]);
  std::vector<char*> cargs;
  for (std::string& a : args) cargs.push_back(a.data());
  cargs.push_back(nullptr);
  std::error_code ec;
  const fs::path self = fs::read_symlink("/proc/self/exe", ec);
  std::cout.flush();
  const pid_t pid = ::fork();
  if (pid < 0) {
    err << prog << ": cannot start " << py << '\n';
    return 1;
  }
  if (pid == 0) {
    ::setenv("SANDCELL_ANALYZE_PROG", prog.c_str(), 1);  // its usage lines name this command
    if (!ec) ::setenv("SANDCELL_TRIAXIAL", self.c_str(), 1);
    ::execvp(cargs[0], cargs.data());
    std::fprintf(stderr, "%s: cannot run %s (needs python3 with numpy, scipy, matplotlib, h5py; set SANDCELL_PYTHON)\n",
                 prog.c_str(), cargs[0]);
    std::_Exit(127);
  }
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  return WIFEXITED(status) ? WEXITSTATUS(status) : 1;
}

// A message for one line of at most ~300 characters: newlines become spaces; a longer one keeps its
// head and tail (the key and what is allowed) around "...".
static std::string one_line(std::string m) {
  std::replace(m.begin(), m.end(), '\n', ' ');
  constexpr std::size_t k_max = 280;  // with "triaxial: " in front, under 300
  if (m.size() > k_max) m = m.substr(0, 170) + " ... " + m.substr(m.size() - 105);
  return m;
}

// Reads and plans a config file for a subcommand; throws ConfigError.
static Plan plan_from_file(const std::string& path, const Options& options) {
  std::ifstream in(path);
  if (!in || fs::is_directory(path)) throw ConfigError(path + ": cannot read the configuration file");
  std::ostringstream buffer;
  buffer << in.rdbuf();
  return make_plan(parse_config(buffer.str(), path), options);
}

// The values of --time and --partition that go into the scripts. Returns 0, or 2 after a one-line message.
static int check_slurm_options(const SlurmCampaign& c, std::ostream& err) {
  const auto time_ok = [](const std::string& t) {
    int d = 0, h = 0, m = 0, sec = 0;
    char tail = 0;
    return (std::sscanf(t.c_str(), "%d-%d:%d:%d%c", &d, &h, &m, &sec, &tail) == 4 ||
            std::sscanf(t.c_str(), "%d:%d:%d%c", &h, &m, &sec, &tail) == 3) &&
           d >= 0 && h >= 0 && m >= 0 && m < 60 && sec >= 0 && sec < 60;
  };
  if (!time_ok(c.time)) {
    err << "triaxial slurm: --time = " << c.time << ": allowed: HH:MM:SS or D-HH:MM:SS\n";
    return 2;
  }
  if (c.partition.find_first_of(" \t\n'\"$`\\") != std::string::npos) {
    err << "triaxial slurm: --partition = " << c.partition << ": allowed: a partition name (no spaces or quotes)\n";
    return 2;
  }
  return 0;
}

// `triaxial slurm CONFIG --out DIR ...`: the campaign as Slurm job arrays (slurm.hpp).
static int slurm_main(int argc, const char* const* argv, std::ostream& out, std::ostream& err) {
  SlurmCampaign c;
  std::string config, dir;
  bool submit = false;
  CLI::App app{"sandcell triaxial slurm: a campaign as Slurm job arrays (preparations, tests, analysis)"};
  app.add_option("config", config, "TOML configuration of the campaign")->required();
  app.add_option("--out", dir, "output directory of the campaign (scripts in DIR/slurm)")->required();
  app.add_option("--cpus-per-task", c.cpus_per_task, "CPUs (threads) of each task")->check(CLI::Range(1, 4096));
  app.add_option("--time", c.time, "time limit of each task, HH:MM:SS or D-HH:MM:SS (default 24:00:00)");
  app.add_option("--partition", c.partition, "partition (default: the cluster's)");
  app.add_option("--thread-partition", c.thread_partition,
                 "passed on to every task: how its threads share each pass (triaxial --help; default adaptive)")
      ->check(partition_names());
  app.add_option("--max-running", c.max_running, "tasks of an array running at once (0: no limit)")
      ->check(CLI::Range(0, 100000));
  app.add_flag("--submit", submit, "submit the scripts with sbatch after writing them");
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp&) {
    out << app.help();
    return 0;
  } catch (const CLI::ParseError& e) {
    err << "triaxial slurm: " << e.what() << " (see --help)\n";
    return 2;
  }
  if (const int code = check_slurm_options(c, err); code != 0) return code;
  Plan plan;
  std::string text;
  try {
    plan = plan_from_file(config, Options{});
    text = plan.config.text;
  } catch (const ConfigError& e) {
    err << "triaxial slurm: " << e.what() << '\n';
    return 2;
  }
  if (plan.config.tests.size() < 2) {
    err << "triaxial slurm: " << config << " has one test, not a campaign; run it with `triaxial " << config << "`\n";
    return 2;
  }
  if (submit && std::system("command -v sbatch >/dev/null 2>&1") != 0) {
    err << "triaxial slurm: --submit: sbatch is not on PATH (run on a Slurm login node, or leave out --submit to only write the scripts)\n";
    return 2;
  }
  std::error_code ec;
  c.out = fs::absolute(dir, ec);
  c.config = c.out / "campaign.toml";
  c.triaxial = fs::read_symlink("/proc/self/exe", ec);
  c.preparations = plan.p0.size();
  c.tests = plan.config.tests.size();
  c.chained = plan.config.prepare.chain;
  // The campaign's config is kept beside its results; another campaign's is not replaced.
  if (fs::exists(c.config)) {
    std::ifstream in(c.config);
    std::ostringstream held;
    held << in.rdbuf();
    if (held.str() != text) {
      err << "triaxial slurm: --out = " << dir << ": holds another campaign (" << c.config.string() << " differs from "
          << config << "); allowed: another --out\n";
      return 2;
    }
  }
  try {
    fs::create_directories(c.out);
    if (!fs::exists(c.config)) std::ofstream(c.config) << text;
    write_slurm_scripts(c);
  } catch (const std::exception& e) {
    err << "triaxial slurm: " << e.what() << '\n';
    return 1;
  }
  out << "triaxial slurm: " << c.preparations << " preparation(s) " << (c.chained ? "(one chained job)" : "(array)")
      << ", " << c.tests << " tests (array"
      << (c.max_running > 0 ? ", " + std::to_string(c.max_running) + " at once" : "") << "), analysis; scripts in "
      << (c.out / "slurm").string() << "\n";
  if (!submit) {
    out << "submit with: " << (c.out / "slurm" / "submit.sh").string() << "\n";
    return 0;
  }
  return submit_slurm_scripts(c, out, err);
}

// --task: a selected job whose lock another process holds (the same task run twice at once) is
// refused before anything runs or is removed. Each lock is taken and released; a job another
// process starts after this probe is caught when its own lock is taken (InUse).
static int check_jobs_free(const Plan& plan, const std::vector<char>& run_prep, const std::vector<char>& run_test,
                           std::ostream& err) {
  std::vector<std::pair<std::string, std::string>> jobs;  // (lock file name, job)
  for (std::size_t k = 0; k < plan.p0.size(); ++k)
    if (run_prep[k]) jobs.emplace_back("prepare-" + p0_tag(plan.p0[k]), "preparation prepare-" + p0_tag(plan.p0[k]));
  for (std::size_t k = 0; k < plan.config.tests.size(); ++k)
    if (run_test[k]) jobs.emplace_back(plan.config.tests[k].name, "test " + plan.config.tests[k].name);
  for (const auto& [name, job] : jobs) {
    const fs::path lock = plan.out / ".locks" / (name + ".lock");
    FileLock probe;
    try {
      if (probe.try_lock(lock, FileLock::Mode::exclusive)) continue;
    } catch (const std::exception& e) {
      err << "triaxial: " << one_line(e.what()) << '\n';
      return 1;
    }
    err << "triaxial: --task: " << one_line(in_use_message(lock, job)) << '\n';
    return 2;
  }
  return 0;
}

// --resume and --task shear the samples they find in --out: one prepared with other values of the
// keys that shape a sample (a copied sample, an earlier config) is refused, naming the first key
// and both values, unless --allow-change names every such key. `replaced`: the files --overwrite
// removes (their samples are prepared again). A sample that cannot be read is left to the job,
// which fails naming it (exit 1).
static int check_samples(const Plan& plan, const Options& options, const std::vector<fs::path>& replaced,
                         std::ostream& err) {
  for (double p0 : plan.p0) {
    const fs::path sample = plan.out / ("sample-" + p0_tag(p0) + ".h5");
    if (!fs::exists(sample) ||
        (options.overwrite && std::find(replaced.begin(), replaced.end(), sample) != replaced.end()))
      continue;
    CheckpointExtra extra;
    std::size_t count = 0;
    try {
      count = read_checkpoint(sample, &extra).particles.size();
    } catch (const std::exception&) {
      continue;
    }
    std::vector<KeyChange> changes;
    if (const auto it = extra.strings.find("config"); it != extra.strings.end()) {
      try {
        changes = sample_changes(it->second, plan.config);
      } catch (const std::exception& e) {
        err << "triaxial: " << sample.string() << ": cannot read the config it was prepared with ("
            << one_line(e.what()) << ")\n";
        return 1;
      }
    } else if (!plan.from_file && count != plan.config.sample.generation.count) {  // a sample without its config
      changes.push_back({"sample.count", std::to_string(count), std::to_string(plan.config.sample.generation.count)});
    }
    std::vector<KeyChange> refused;
    for (const KeyChange& c : changes)
      if (std::find(options.allow_change.begin(), options.allow_change.end(), c.key) == options.allow_change.end())
        refused.push_back(c);
    if (refused.empty()) continue;
    std::string keys;
    for (const KeyChange& c : refused) keys += (keys.empty() ? "" : " ") + c.key;
    const KeyChange& c = refused.front();
    err << "triaxial: "
        << one_line(sample.string() + " was prepared with " + c.key + " = " + c.before + ", not " + c.after +
                    (refused.size() > 1 ? " (differing too: " + keys.substr(c.key.size() + 1) + ")" : "") +
                    "; allowed: the sample's values, another --out, or --allow-change " + keys +
                    " to shear it as it is")
        << '\n';
    return 2;
  }
  return 0;
}

// Makes the output directory this run's: refuses to replace an earlier run's files unless asked,
// takes the directory's lock (held in `dir_lock` for the run), checks a resumed run's config
// against the one it was made with, applies --overwrite and records the config. Returns 0, or
// the exit code after a one-line message.
static int claim_directory(const Plan& plan, const Options& options, bool selected, const std::vector<char>& run_prep,
                           const std::vector<char>& run_test, FileLock& dir_lock, std::ostream& err) {
  // Nothing of an earlier run is replaced unless asked: a whole run looks at every file, a run of
  // selected tasks at theirs.
  const std::vector<fs::path> files = run_files(plan, run_prep, run_test, selected);
  if (!options.resume) {
    std::vector<fs::path> existing;
    for (const fs::path& f : files)
      if (fs::exists(f)) existing.push_back(f);
    if (!existing.empty() && !options.overwrite) {
      err << "triaxial: --out = " << plan.out.string() << ": holds the results of an earlier run ("
          << existing.front().string()
          << (existing.size() > 1 ? " and " + std::to_string(existing.size() - 1) + " more" : "")
          << "); allowed: --resume to continue it, --overwrite to replace it, or another --out\n";
      return 2;
    }
  }
  std::error_code ec;
  fs::create_directories(plan.out, ec);
  if (ec) {
    err << "triaxial: --out = " << plan.out.string() << ": cannot create the directory: " << ec.message() << '\n';
    return 2;
  }
  // One live whole run per directory; runs of selected tasks share it with each other (lock.hpp).
  const fs::path dir_lock_path = plan.out / ".sandcell.lock";
  try {
    if (!dir_lock.try_lock(dir_lock_path, selected ? FileLock::Mode::shared : FileLock::Mode::exclusive)) {
      err << "triaxial: --out = " << plan.out.string() << ": in use by a live run (" << FileLock::holder(dir_lock_path)
          << "); allowed: wait for it to end, stop it (it checkpoints on SIGTERM), or another --out\n";
      return 2;
    }
  } catch (const std::exception& e) {
    err << "triaxial: --out = " << plan.out.string() << ": " << e.what() << '\n';
    return 2;
  }
  fs::create_directories(plan.out / ".locks", ec);
  // The config a directory's run was made with: a resume (or a task) with other physics would give
  // tests computed half with one setting and half with another.
  const fs::path stored_config = plan.out / ".config.toml";
  if ((options.resume || selected) && !options.overwrite && fs::exists(stored_config)) {
    std::ifstream in(stored_config);
    std::ostringstream before;
    before << in.rdbuf();
    std::vector<std::string> keys;
    try {
      keys = changed_keys(before.str(), plan.config.text);
    } catch (const std::exception& e) {
      err << "triaxial: " << stored_config.string() << ": cannot read the run's config (" << e.what() << ")\n";
      return 2;
    }
    std::vector<std::string> refused;
    for (const std::string& k : keys)
      if (std::find(options.allow_change.begin(), options.allow_change.end(), k) == options.allow_change.end())
        refused.push_back(k);
    if (!refused.empty()) {
      std::string list;
      for (const std::string& k : refused) list += (list.empty() ? "" : ", ") + k;
      err << "triaxial: " << plan.config.source << " differs from the run in " << plan.out.string()
          << " (.config.toml) in " << list
          << "; allowed: the run's values, changes to output.*, tests.* and shear.max_axial_strain, or "
          << "--allow-change KEY for a change you mean\n";
      return 2;
    }
  }
  if (selected)
    if (const int code = check_jobs_free(plan, run_prep, run_test, err); code != 0) return code;
  if (options.resume || selected)
    if (const int code = check_samples(plan, options, files, err); code != 0) return code;
  if (options.overwrite)
    for (const fs::path& f : files) fs::remove(f, ec);
  try {
    if (!fs::exists(stored_config) || options.overwrite || !options.allow_change.empty() || !selected)
      write_replacing(plan, ".config.toml", [&](std::ostream& o) { o << plan.config.text; });
  } catch (const std::exception& e) {
    err << "triaxial: " << e.what() << '\n';
    return 1;
  }
  return 0;
}

// The first lines of a run: what runs where, and the warnings that concern every stage.
static void log_campaign_start(Log& log, const Plan& plan, const Options& options) {
  log.line("sandcell triaxial: " + plan.config.source + " -> " + plan.out.string() + ": " +
           std::to_string(plan.config.tests.size()) + " test(s), " + std::to_string(plan.p0.size()) + " sample(s), " +
           std::to_string(plan.config.parallel) + " at once x " + std::to_string(plan.job_threads) + " thread(s)");
  if (options.threads > available_cpus())
    log.line("warning: --threads " + std::to_string(options.threads) + " > the " + std::to_string(available_cpus()) +
             " CPUs this process may use (SLURM_CPUS_PER_TASK, else its affinity mask): threads will share cores");
  // Once per run: it concerns every stage. The speed/accuracy study (docs/study) moved the peak
  // q/p by 1e-4 from dt = 0.05 to 0.5 t_R; beyond that nothing is measured.
  if (plan.config.dt_fraction > 0.5)
    log.line(
        "warning: time.dt_fraction = " + num(plan.config.dt_fraction) +
        " > 0.5 of the Rayleigh time (the largest the speed/accuracy study validated): contact collisions resolved by few steps");
  if (plan.config.prepare.dt_fraction > 0.5)
    log.line("warning: prepare.dt_fraction = " + num(plan.config.prepare.dt_fraction) +
             " > 0.5 of the Rayleigh time: contact collisions resolved by few steps");
  if (!plan.output_note.empty()) log.line("warning: output: " + plan.output_note);
}

// Runs the selected preparations and tests (all of a whole run) and writes the campaign's index.
// Returns the exit code: 0 done, 1 a job failed, 3 stopped (a signal or --stop-after).
static int run_campaign(const Plan& plan, const Options& options, const std::vector<char>& run_prep,
                        const std::vector<char>& run_test, std::ostream& out) {
  Log log(out, options.progress);
  log_campaign_start(log, plan, options);
  Campaign campaign(plan, log, run_prep, run_test);
  campaign.prepare_samples();
  campaign.shear_tests();
  campaign.write_indices();
  const int failures = campaign.failures();
  log.line("results: " + (plan.out / "index.csv").string() +
           (failures ? " (" + std::to_string(failures) + " failed)" : ""));
  return campaign.exit_code();
}

// The command line of a run: the options the jobs see, and the flags that end the process early.
struct CommandLine {
  Options options;
  bool print_default = false;
  bool check_only = false;
};

// The options of `triaxial [CONFIG] ...` (--help lists them in this order).
static void add_run_options(CLI::App& app, CommandLine& cl) {
  Options& options = cl.options;
  app.footer(
      "Analysis of results (critical state line, M(theta), dilatancy; report and figures):\n"
      "  triaxial analyze RESULTS.h5|DIR... [--out DIR]   (triaxial analyze --help for its options)\n"
      "Speed versus accuracy (timestep, inertial number, stiffness, restitution, N; table and Pareto figure):\n"
      "  triaxial study [CONFIG] [--preset quick|inertia|full|size] [--out DIR]   (triaxial study --help)\n"
      "Strain localization (shear bands) from the particle snapshots of results files:\n"
      "  triaxial localization RESULTS.h5... [--out DIR] [--grid G] [--whole] [--slabs K]   (triaxial localization --help)\n"
      "Calibration of micro-parameters against macroscopic targets (surrogate, posterior, check run):\n"
      "  triaxial calibrate CONFIG --targets FILE --param KEY=LO:HI... [--budget N] [--out DIR] [--resume]   "
      "(triaxial calibrate --help)");
  app.add_option("config", options.config_path, "TOML configuration (none: the embedded default)");
  app.add_option(
         "--threads", options.threads,
         "worker threads in all (default: the CPUs this process may use: SLURM_CPUS_PER_TASK, else its affinity mask)")
      ->check(CLI::Range(1, 1024));
  // Not a config key: like --threads it says how this host runs the job, never what it computes
  // (every partition gives bitwise the same results), so a resume may change it.
  app.add_option("--thread-partition", options.partition,
                 "how the threads share each pass: adaptive (default: owner or dynamic, whichever runs this "
                 "host's steps faster, timed during the run), owner (each thread keeps its particles), dynamic "
                 "(work stealing) or fixed; the results are bitwise the same for all")
      ->check(partition_names());
  app.add_option("--out", options.out, "output directory (default: results/<config name>)");
  app.add_flag("--resume", options.resume, "continue a killed run from its checkpoints");
  app.add_flag("--overwrite", options.overwrite, "replace the results of an earlier run in the output directory");
  app.add_option("--max-axial-strain", options.max_axial_strain, "override shear.max_axial_strain (short runs)")
      ->check(CLI::Range(1e-9, 2.0));
  app.add_flag("--prepare-only", options.prepare_only, "prepare the campaign's samples and stop (no test is sheared)");
  app.add_flag("--list", options.list,
               "print the campaign's tasks (preparations, then tests: index, kind, name) and exit");
  app.add_option(
         "--task", options.task_specs,
         "run only these tasks of --list: K, A-B or K,L,... (repeatable); a test finds its sample in --out or prepares it")
      ->take_all();
  app.add_option("--allow-change", options.allow_change,
                 "with --resume or --task: let these config keys (section.key) differ from the run's (.config.toml)")
      ->take_all();
  app.add_flag("--print-default", cl.print_default, "print the embedded default configuration and exit");
  app.add_flag("--check", cl.check_only,
               "check the configuration (and plan the campaign) and exit; nothing is written");
  // Checked as written: CLI11 would read -1 into the unsigned count as 2^64 - 1 (never stops).
  app.add_option("--stop-after", options.stop_after,
                 "stop every job after N steps with a checkpoint, as if killed (to test --resume)")
      ->check(CLI::Validator(
          [](std::string& text) {
            const bool digits =
                !text.empty() && text.size() <= 19 && text.find_first_not_of("0123456789") == std::string::npos;
            return digits && std::stoull(text) >= 1 ? std::string() : text + ": allowed: an integer >= 1 (steps)";
          },
          "N >= 1"));
}

// Parses the command line of a run into `cl`. Returns the exit code when the process ends here
// (--help: 0; a bad option: 2, after a one-line message), else nothing.
static std::optional<int> parse_command_line(int argc, const char* const* argv, CommandLine& cl, std::ostream& out,
                                             std::ostream& err) {
  CLI::App app{"sandcell triaxial: true triaxial DEM tests in a stress-controlled periodic cell"};
  add_run_options(app, cl);
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    out << app.help();
    return 0;
  } catch (const CLI::ParseError& e) {
    err << "triaxial: " << e.what() << " (see --help)\n";
    return 2;
  }
  return std::nullopt;
}

// The checks of the options that CLI11 does not make. Returns 0, or 2 after a one-line message.
static int check_options(const Options& options, std::ostream& err) {
  if (options.resume && options.overwrite) {
    err << "triaxial: --resume and --overwrite exclude each other\n";
    return 2;
  }
  // A setting that would have no effect is refused: --allow-change lets a resumed run's config differ
  // from the one it was made with, and only --resume and --task resume one.
  if (!options.allow_change.empty() && !options.resume && options.task_specs.empty()) {
    err << "triaxial: --allow-change " << options.allow_change.front()
        << (options.allow_change.size() > 1 ? " ..." : "")
        << ": has no effect without --resume or --task (it lets their config differ from the run's); allowed: add "
           "--resume, or leave it out\n";
    return 2;
  }
  if (std::isnan(options.max_axial_strain)) {
    err << "triaxial: --max-axial-strain = nan: allowed: a number in (0, 2]\n";
    return 2;
  }
  // Path limits of Linux: 4096 bytes in all, 255 a name (a longer one fails every file call).
  std::size_t longest = 0;
  for (const auto& part : fs::path(options.out)) longest = std::max(longest, part.native().size());
  if (options.out.size() > 3800 || longest > 255) {
    err << "triaxial: --out = " << options.out.substr(0, 40) << "... (" << options.out.size()
        << " characters): allowed: a path under 3800 characters, each name under 256\n";
    return 2;
  }
  return 0;
}

// The run's configuration (the file named, else the embedded default), parsed and planned.
// Throws ConfigError, or a file system error on an unreadable path.
static Plan load_plan(const Options& options) {
  std::string text, source = "<embedded default>";
  if (options.config_path.empty()) {
    text = k_default_config;
  } else {
    std::ifstream in(options.config_path);
    if (!in || fs::is_directory(options.config_path))
      throw ConfigError(options.config_path + ": cannot read the configuration file" +
                        (fs::is_directory(options.config_path) ? " (a directory)" : ""));
    std::ostringstream buffer;
    buffer << in.rdbuf();
    text = buffer.str();
    source = options.config_path;
  }
  return make_plan(parse_config(text, source), options);
}

// --out, else results/<config name> (results/default for the embedded default).
static fs::path output_directory(const Options& options) {
  return !options.out.empty()          ? fs::path(options.out)
         : options.config_path.empty() ? fs::path("results/default")
                                       : fs::path("results") / fs::path(options.config_path).stem();
}

// --list: the tasks in a stable order, preparations by p0 (as prepared), then the tests.
static void list_tasks(const Plan& plan, std::ostream& out) {
  const std::size_t n_prep = plan.p0.size();
  for (std::size_t k = 0; k < plan.p0.size(); ++k) out << k << " prepare prepare-" << p0_tag(plan.p0[k]) << '\n';
  for (std::size_t k = 0; k < plan.config.tests.size(); ++k)
    out << n_prep + k << " test " << plan.config.tests[k].name << '\n';
}

// --task: runs only the tasks named (indices of --list), marked in run_prep and run_test.
// Returns 0, or 2 after a one-line message.
static int select_tasks(const Plan& plan, const std::vector<std::string>& specs, std::vector<char>& run_prep,
                        std::vector<char>& run_test, std::ostream& err) {
  const std::size_t n_prep = plan.p0.size(), n_tasks = plan.p0.size() + plan.config.tests.size();
  if (plan.config.tests.size() < 2) {
    err << "triaxial: --task: " << plan.config.source << " has one test, not a campaign; run it without --task\n";
    return 2;
  }
  std::vector<std::size_t> tasks;
  if (std::string bad = parse_tasks(specs, n_tasks, tasks); !bad.empty()) {
    err << "triaxial: --task " << bad << '\n';
    return 2;
  }
  std::fill(run_prep.begin(), run_prep.end(), 0);
  std::fill(run_test.begin(), run_test.end(), 0);
  for (std::size_t t : tasks) (t < n_prep ? run_prep[t] : run_test[t - n_prep]) = 1;
  return 0;
}

int triaxial_main(int argc, const char* const* argv, std::ostream& out, std::ostream& err) {
  // `triaxial analyze RESULTS... [--out DIR]`: the critical-state and dilatancy analysis (analyze.py).
  if (argc >= 2 && std::string(argv[1]) == "analyze") return script_main("analyze", argc - 1, argv + 1, err);
  // `triaxial study CONFIG [--preset quick|inertia|full|size]`: the speed-accuracy study (study.py).
  if (argc >= 2 && std::string(argv[1]) == "study") return script_main("study", argc - 1, argv + 1, err);
  // `triaxial localization RESULTS.h5... [--out DIR] [--grid G] [--whole] [--slabs K]`: strain fields between snapshots (localization.py).
  if (argc >= 2 && std::string(argv[1]) == "localization") return script_main("localization", argc - 1, argv + 1, err);
  // `triaxial calibrate CONFIG --targets FILE --param KEY=LO:HI...`: micro-parameters against targets (calibrate.py).
  if (argc >= 2 && std::string(argv[1]) == "calibrate") return script_main("calibrate", argc - 1, argv + 1, err);
  // `triaxial slurm CONFIG --out DIR [--submit]`: the campaign as Slurm job arrays (slurm.hpp).
  if (argc >= 2 && std::string(argv[1]) == "slurm") return slurm_main(argc - 1, argv + 1, out, err);
  CommandLine cl;
  if (const std::optional<int> code = parse_command_line(argc, argv, cl, out, err)) return *code;
  Options& options = cl.options;
  if (cl.print_default) {
    out << k_default_config;
    return 0;
  }
  if (const int code = check_options(options, err); code != 0) return code;
  options.progress = ::isatty(STDOUT_FILENO) && &out == &std::cout;

  Plan plan;
  try {
    plan = load_plan(options);
  } catch (const ConfigError& e) {
    err << "triaxial: " << one_line(e.what()) << '\n';
    return 2;
  } catch (const std::exception& e) {  // e.g. a file system error on an unreadable path
    err << "triaxial: " << one_line(e.what()) << '\n';
    return 2;
  }
  if (cl.check_only) {
    out << "triaxial: " << plan.config.source << ": valid: " << plan.config.tests.size() << " test(s), "
        << plan.p0.size() << " sample(s), dt = " << num(plan.base.dt) << " s, results ~"
        << num(plan.output_bytes / double(1 << 30), "%.3g") << " GiB (estimated)\n";
    if (!plan.output_note.empty()) out << "warning: output: " << plan.output_note << '\n';
    return 0;
  }
  plan.out = output_directory(options);
  if (options.list) {
    list_tasks(plan, out);
    return 0;
  }
  // --task: which tasks this process runs (all when not given).
  std::vector<char> run_prep(plan.p0.size(), 1), run_test(plan.config.tests.size(), options.prepare_only ? 0 : 1);
  const bool selected = !options.task_specs.empty();
  if (selected)
    if (const int code = select_tasks(plan, options.task_specs, run_prep, run_test, err); code != 0) return code;

  FileLock dir_lock;  // held until the campaign ends
  if (const int code = claim_directory(plan, options, selected, run_prep, run_test, dir_lock, err); code != 0)
    return code;
  install_stop_handlers();
  return run_campaign(plan, options, run_prep, run_test, out);
}

}  // namespace sandcell::triaxial
