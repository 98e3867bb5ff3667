// The plan of a triaxial run: the protocol of its config and the checks made before anything is
// written (the cell's width, the run lengths, the strain per step, the size of the output), the
// files it writes and the tasks of --task.
#include "app.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>

namespace sandcell::triaxial {

namespace {

// The steps a test takes, estimated: shear.steps (path strain); the rotation's ramp and turn; the
// simple shears' gamma (and the axial paths' strain), plus the ramp, at the rate at p0.
double test_steps(const Plan& plan, const TestSpec& t, double max_strain) {
  const Config& c = plan.config;
  const double dt = plan.base.dt;
  switch (t.path) {
    case ShearPath::strain: return double(c.shear.steps);
    case ShearPath::rotation: return (c.rotation.ramp_time + c.rotation.angle / c.rotation.rate) / dt;
    case ShearPath::simple_shear:
    case ShearPath::simple_shear_cv:
      return (c.shear.max_shear_strain + c.shear.ramp_strain) / (axial_rate(plan, t.p0) * dt);
    default: return (max_strain + c.shear.ramp_strain) / (axial_rate(plan, t.p0) * dt);
  }
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
    } else if (t.path == ShearPath::simple_shear || t.path == ShearPath::simple_shear_cv ||
               t.path == ShearPath::rotation) {
      // A sheared cube whose tilts the flips keep within half a length: its faces at least 1/sqrt(1.25)
      // of the side apart (one tilt; the rotation's cell deforms by its own response, checked as it runs).
      narrowest = std::min(narrowest, side / std::sqrt(1.25));
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
    const double rate = t.path == ShearPath::rotation ? 0.0 : axial_rate(plan, t.p0);
    const double steps = test_steps(plan, t, max_strain) -
                         (t.path == ShearPath::rotation ? 0.0 : config.shear.ramp_strain / (rate * m.dt));
    if (t.path == ShearPath::rotation && !(steps < 1e10))
      throw ConfigError(src + ": rotation.rate = " + num(config.rotation.rate) + " degrees/s: the test would take " +
                        num(steps, "%.2g") + " steps; allowed: up to 1e10");
    if (t.path == ShearPath::rotation) continue;
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
    if (t.path == ShearPath::rotation) continue;  // stress controlled: its rates are the servo's, capped
    if (t.path == ShearPath::strain) {
      for (int a = 0; a < 3; ++a) {
        if (std::abs(config.shear.strain_rates[a]) * dt > k_max_strain_per_step)
          throw ConfigError(config.source + ": shear.strain_rates[" + std::to_string(a) +
                            "] = " + num(config.shear.strain_rates[a]) + " 1/s" + allowed);
        if (std::abs(config.shear.shear_rates[a]) * dt > k_max_strain_per_step)
          throw ConfigError(config.source + ": shear.shear_rates[" + std::to_string(a) +
                            "] = " + num(config.shear.shear_rates[a]) + " 1/s" + allowed);
      }
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
// series row 99 doubles; a file ~1.3 MiB of first chunks (32 KiB for each of ~40 datasets). A test
// runs to max_axial_strain (+ ramp_strain for the ramp) at its rate at p0 (shear.steps on path
// "strain"), an upper bound with stop_at_critical; a preparation at least the shrink of its cloud
// at prepare.max_rate. Above output.max_size_gib the run is refused naming the interval that
// costs most; above 1 GiB it is warned about at the start. Throws ConfigError.
void estimate_output(Plan& plan, std::size_t spheres, double max_strain) {
  constexpr double k_snapshot_sphere = 14 * 8, k_snapshot_header = 4096, k_row = 99 * 8, k_file = 1.3 * (1 << 20);
  constexpr double k_warn = double(1 << 30);  // 1 GiB
  const Config& config = plan.config;
  const OutputConfig& o = config.output;
  double snapshot_bytes = 0.0, row_bytes = 0.0, longest = 0.0;  // longest: steps of the longest test
  for (const TestSpec& t : config.tests) {
    const double steps = test_steps(plan, t, max_strain);
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

}  // namespace

Plan make_plan(Config config_in, const Options& options) {
  Plan plan;
  static_cast<Protocol&>(plan) = make_protocol(std::move(config_in));
  plan.options = options;
  const Config& config = plan.config;
  const double max_strain = options.max_axial_strain > 0.0 ? options.max_axial_strain : config.shear.max_axial_strain;
  check_strain_per_step(plan);
  check_cell_width(plan, plan.diameters, max_strain);
  check_run_lengths(plan, max_strain);
  estimate_output(plan, plan.diameters.size(), max_strain);
  validate_servos(plan);  // before anything is written
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

Plan plan_from_file(const std::string& path, const Options& options) { return make_plan(load_config(path), options); }

}  // namespace sandcell::triaxial
