// The shear stage of a triaxial run: one test from its prepared sample (or checkpoint) to its
// finished results file (ShearRun), its summary, and the runner's shearing of a test.
#include "app.hpp"

#include "protocol/accuracy.hpp"
#include "protocol/critical.hpp"
#include "protocol/series.hpp"

#include "engine/fnv1a.hpp"
#include "engine/hdf5.hpp"
#include "engine/version.hpp"
#include "engine/results.hpp"
#include "systems/broadphase.hpp"
#include "systems/catalogue.hpp"
#include "systems/homogenizer.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <optional>

namespace sandcell::triaxial {

// The series rows of the test, for the critical-state test (critical.hpp) and the peak.
struct History {
  std::vector<double> eps1, p, q, e;
  std::vector<double> eps_q, z_mech, fabric;  // fabric: its anisotropy F_a (critical.hpp)
  CriticalCheck critical(const ShearConfig& h) const {
    return check_critical(CriticalSeries{eps_q, p, q, e, z_mech, fabric},
                          CriticalTest{.window = h.critical_window,
                                       .tolerance = h.critical_tolerance,
                                       .tolerance_e = h.critical_tolerance_e,
                                       .tolerance_fabric = h.critical_tolerance_fabric});
  }
  CheckpointExtra save() const {
    CheckpointExtra x;
    x.doubles = {{"history_eps1", eps1},     {"history_p", p},           {"history_q", q},
                 {"history_e", e},           {"history_eps_q", eps_q},   {"history_z_mech", z_mech},
                 {"history_fabric_anisotropy", fabric}};
    return x;
  }
  void pop_back() {
    for (std::vector<double>* v : {&eps1, &p, &q, &e, &eps_q, &z_mech, &fabric}) v->pop_back();
  }
  void load(CheckpointExtra& x) {
    eps1 = x.doubles["history_eps1"];
    p = x.doubles["history_p"];
    q = x.doubles["history_q"];
    e = x.doubles["history_e"];
    // A checkpoint from before these columns: NaN rows, which no critical-state window accepts, so
    // a resumed test is judged on rows it has measured since.
    for (auto [name, v] : {std::pair{"history_eps_q", &eps_q}, std::pair{"history_z_mech", &z_mech},
                           std::pair{"history_fabric_anisotropy", &fabric}})
      *v = x.doubles.count(name) ? x.doubles[name] : std::vector<double>(eps1.size(), std::nan(""));
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
        watch_(test.name, [&log](const std::string& line) { log.line(line); }),
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
  /// The PNG of q and eps_v (python3 -m sandcell_analysis plot); a missing python3/matplotlib is a warning.
  void plot() const;

 private:
  void resume(const State& state, CheckpointExtra& extra);
  /// Whether a complete test goes on: its end has been moved beyond where it stopped and it ended
  /// there (not by leaving its path, at critical state or as a cyclic test).
  bool continues(const Model& model, const State& state, CheckpointExtra& extra) const;
  /// --resume of a complete test that continues(): as resume(), with the results file's verdict
  /// removed and its run record brought to the new end.
  void extend(const Model& model, const State& state, CheckpointExtra& extra);
  State start_from_sample(const fs::path& sample);
  void row();
  CheckpointExtra extras() const;
  /// The path's travel (what its end, its rows and its watch count): the axial strain, the simple
  /// shears' gamma = -F_xz (soil convention), the rotation's angle turned (rad).
  double travel(const Cell& cell, const sandcell::Clock& clock) const {
    switch (test_.path) {
      case ShearPath::simple_shear:
      case ShearPath::simple_shear_cv: return -cell.deformation()(0, 2);
      case ShearPath::rotation: {
        const RotationConfig& r = plan_.config.rotation;
        return std::max(0.0, clock.time - r.ramp_time) * r.rate * std::numbers::pi / 180.0;
      }
      default: return -std::log(cell.length[0] / cell.length0[0]);
    }
  }
  /// A travel as the log writes it (systems/path_watch.hpp).
  std::string travel_text(double v) const { return sandcell::travel_text(world_->model().servo.path, v); }
  /// Where the test ends, for the log.
  std::string goal() const {
    switch (test_.path) {
      case ShearPath::strain: return "for " + std::to_string(h_.steps) + " steps";
      case ShearPath::simple_shear:
      case ShearPath::simple_shear_cv: return "to shear strain " + num(h_.max_shear_strain);
      case ShearPath::rotation: return "through " + num(plan_.config.rotation.angle) + " deg";
      default:
        return "to axial strain " + num(max_strain_) +
               (h_.max_deviatoric_strain > 0.0 ? " or deviatoric strain " + num(h_.max_deviatoric_strain) : "");
    }
  }
  bool finished(std::uint64_t s, double eps1, const Cell& cell) const {
    if (cyclic_ && cyclic_->finished()) return true;  // cyclic.cycles or cyclic.max_strain reached
    switch (test_.path) {
      case ShearPath::strain: return s >= h_.steps;
      case ShearPath::simple_shear:
      case ShearPath::simple_shear_cv: return eps1 >= h_.max_shear_strain;
      case ShearPath::rotation: return eps1 >= plan_.config.rotation.angle * std::numbers::pi / 180.0;
      default:
        return eps1 >= max_strain_ ||
               (h_.max_deviatoric_strain > 0.0 && deviatoric_strain(cell) >= h_.max_deviatoric_strain);
    }
  }
  bool progress_due() const {
    return plan_.options.progress && std::chrono::duration<double>(Clock::now() - last_progress_).count() > 1.0;
  }
  bool event_due(std::uint64_t s, double eps1, const Cell& cell);
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
  const CyclicPath* cyclic_ = nullptr;  // a cyclic test's path (its memory: the world's model's)
  std::vector<double> cyclic_memory_;    // its memory from the checkpoint of a resumed test
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
      if (!continues(model, state, extra)) {
        summary_ = runner.test_summary(test_, state, extra);
        return false;
      }
      extend(model, state, extra);
    } else {
      resume(state, extra);
    }
  } else {
    state = start_from_sample(sample);
  }
  world_.emplace(model, std::move(state), systems_for(model),
                 ExecutorConfig{Backend::tbb, plan_.job_threads, plan_.partition}, false);
  cyclic_ = cyclic_path(world_->model());
  if (cyclic_ && !cyclic_memory_.empty()) cyclic_->restore(cyclic_memory_);  // a resumed cyclic test
  mo_.d50 = median_diameter(world_->state().particles);
  mo_.density = plan_.config.material.density;
  log_.line(test_.name + ": " + path_name(test_.path) +
            (test_.path == ShearPath::strain ? "" : ", b = " + num(test_.b)) + ", p0 = " + num(test_.p0 / 1e6) +
            " MPa, e0 = " + num(summary_.e0, "%.4f") + ", " + goal() + ", servo gain " +
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
  if (extra.doubles.count("cyclic_path")) cyclic_memory_ = extra.doubles["cyclic_path"];
  results_.emplace(ResultsFile::reopen(path_, state.clock.step));
  resumed_ = true;
  log_.line(test_.name + ": resumed at step " + std::to_string(state.clock.step));
}

// A finished test continued to a larger strain: shear.max_deviatoric_strain, shear.max_axial_strain
// (both allowed to change on --resume) or --max-axial-strain raised beyond where it stopped. Only a
// test that ended at its end goes on; one that left its path stays failed, one stopped at critical
// state (shear.stop_at_critical) stays there, and a cyclic test ends by its cycles: each says so.
bool ShearRun::continues(const Model& model, const State& state, CheckpointExtra& extra) const {
  if (finished(state.clock.step, travel(state.cell, state.clock), state.cell)) return false;
  std::string ended = extra.strings.count("ended") ? extra.strings["ended"] : "";
  if (ended.empty()) {  // a checkpoint from before this record: what ended it, from what it holds
    if (extra.strings.count("path_failure")) {
      ended = "failed";
    } else if (h_.stop_at_critical) {
      History h;
      h.load(extra);
      ended = h.critical(h_).reached ? "critical" : "end";  // it stopped at the first row that passed
    } else {
      ended = "end";
    }
  }
  if (cyclic_path(model)) ended = "cyclic";
  if (ended == "end") return true;
  const std::string why = ended == "failed"     ? "it left its stress path"
                          : ended == "critical" ? "it stopped at critical state (shear.stop_at_critical)"
                                                : "a cyclic test ends by its cycles";
  log_.line(test_.name + ": complete, not continued " + goal() + ": " + why);
  return false;
}

// The state, series and watches as at the end, the results file cut back so that it holds what an
// uninterrupted run to the new end would: the last row and snapshot were written because the test
// ended there, so each goes unless it falls on its interval (the row's measures stay in the path
// and accuracy watches, which cannot forget one: their worst values may include it). The file's
// verdict goes (a stopped continuation is "unfinished", as any running test), and its run record
// (config, settings, command-line override) becomes the new end's, so `triaxial verify` re-runs it
// from its sample straight to the new end; the attribute `extended` lists each continuation.
void ShearRun::extend(const Model& model, const State& state, CheckpointExtra& extra) {
  const std::uint64_t s = state.clock.step;
  std::string before;
  {
    const h5::File f = h5::File::open(path_, h5::File::Mode::read);
    if (f.root().has_attribute("extended")) before = f.root().get_string("extended") + "; ";
  }
  history_.load(extra);
  watch_.restore(extra.doubles["watch_worst"]);
  if (extra.doubles.count("path_watch")) path_watch_.restore(extra.doubles["path_watch"]);
  const bool row_on = s % o_.series_interval == 0;
  const bool snapshot_on = o_.snapshot_interval > 0 && s % o_.snapshot_interval == 0;
  if (!row_on) history_.pop_back();
  results_.emplace(ResultsFile::reopen(path_, row_on ? s : s - 1, snapshot_on ? s : s - 1));
  for (const char* key : {"status", "status_reason", "path_error", "b_error", "rotation_deg"})
    results_->remove_attribute("/", key);
  results_->set_attribute("/", "config", plan_.config.text);
  results_->set_attribute("/", "settings", resolved_settings(plan_, test_));
  if (plan_.options.max_axial_strain > 0.0)
    results_->set_attribute("/", "max_axial_strain_override", num(plan_.options.max_axial_strain, "%.17g"));
  else
    results_->remove_attribute("/", "max_axial_strain_override");
  const std::string from = sandcell::travel_text(model.servo.path, travel(state.cell, state.clock));
  results_->set_attribute("/", "extended",
                          before + "from step " + std::to_string(s) + " (" + from + ") " + goal() + " by sandcell " +
                              std::string(version()));
  results_->flush();
  resumed_ = true;
  log_.line(test_.name + ": complete at step " + std::to_string(s) + " (" + from + "), continued " + goal());
}

// A new test: the prepared sample with its clock, strains and servo state reset and the first
// rates set; a new results file.
State ShearRun::start_from_sample(const fs::path& sample) {
  State state = read_checkpoint(sample, nullptr);
  const std::string digest = hex_digest(particle_digest(state));
  start_test(plan_, test_, state);
  // The run record (docs/physics.md section 8): what `triaxial verify` needs to re-run the test from
  // its sample and to say first when the build differs.
  std::map<std::string, std::string> attrs = {{"job", test_.name},
                                              {"stage", "shear"},
                                              {"path", path_name(test_.path)},
                                              {"b", num(test_.b)},
                                              {"p0", num(test_.p0)},
                                              {"sample_file", sample.filename().string()},
                                              {"sample_digest", digest},
                                              {"settings", resolved_settings(plan_, test_)}};
  // The command line's one override of a result (the others choose threads, tasks and stops).
  if (plan_.options.max_axial_strain > 0.0) attrs["max_axial_strain_override"] = num(plan_.options.max_axial_strain, "%.17g");
  results_.emplace(ResultsFile::create(path_, plan_.config.text, attrs));
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
  const double travelled = travel(world_->state().cell, world_->state().clock);
  const auto failure = path_watch_.add(
      {step, travelled, m_.stress, m_.max_overlap_ratio, m_.unbalanced, world_->state().clock.time});
  if (failure && !summary_.left_path()) {  // (a resumed watch.stop = false run keeps its first reason)
    summary_.reason = failure->message;
    log_.line(test_.name + ": failed: " + failure->message +
              (plan_.config.watch.stop ? "; stopped" : "; runs on (watch.stop = false)"));
  }
  history_.eps1.push_back(travelled);  // the axial strain on the axial paths (the same expression)
  history_.p.push_back(m_.inv.p);
  history_.q.push_back(m_.inv.q);
  history_.e.push_back(m_.void_ratio);
  history_.eps_q.push_back(m_.eps_q);
  history_.z_mech.push_back(m_.z_mech);
  history_.fabric.push_back(fabric_anisotropy(m_.fabric));
  if (++rows_ % o_.flush_interval == 0) results_->flush();
}

// What a checkpoint keeps besides the state: the history and the accuracy watch's worst values.
CheckpointExtra ShearRun::extras() const {
  CheckpointExtra x = history_.save();
  x.doubles["watch_worst"] = watch_.worst_values();
  x.doubles["path_watch"] = path_watch_.save();
  if (cyclic_) x.doubles["cyclic_path"] = cyclic_->save();
  if (summary_.left_path()) x.strings["path_failure"] = summary_.reason;
  return x;
}

// Whether the loop of run() has something to do after step s: the end, a row, a snapshot, a
// checkpoint, a stop or a progress line.
bool ShearRun::event_due(std::uint64_t s, double eps1, const Cell& cell) {
  return finished(s, eps1, cell) || s % o_.series_interval == 0 ||
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
      return event_due(clock.step, travel(cell, clock), cell);
    });
    State& st = world_->state();
    const std::uint64_t s = st.clock.step;
    const double eps1 = travel(st.cell, st.clock);
    const bool done = finished(s, eps1, st.cell);
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
    const auto pc = [](const Trend& t) { return num(100.0 * t.change, "%.2f") + " +- " + num(100.0 * t.se, "%.2f") + " %"; };
    log_.line(test_.name + ": critical state at eps1 = " + num(100.0 * eps1, "%.2f") + " %, eps_q = " +
              num(100.0 * history_.eps_q.back(), "%.2f") + " %: over the last " + num(100.0 * h_.critical_window, "%g") +
              " % of eps_q (" + std::to_string(c.rows) + " rows) the fitted lines change eta by " + pc(c.eta) +
              ", p by " + pc(c.p) + ", Z_mech by " + pc(c.z) + ", F_a by " + pc(c.fabric) + ", e by " +
              num(c.e.change, "%.4f") + " +- " + num(c.e.se, "%.4f") + " (1 SE)");
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
  // What ended it: a test that ended at its end may be continued to a larger one (continues()).
  extra.strings["ended"] = summary_.left_path() ? "failed" : summary_.critical ? "critical" : "end";
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
  const double travelled = travel(st.cell, st.clock);
  if (!judged && test_.path != ShearPath::strain)
    log_.line(test_.name + ": its stress path was not judged: it ended at " + travel_text(travelled) + ", before the watchdog's first window (" + num(100 * h_.ramp_strain, "%g") + " % of ramp and " +
              num(100 * plan_.config.watch.tolerance.window, "%g") + " %)");
  summary_.status = summary_.left_path() ? "failed" : summary_.critical ? "done (critical state)" : "done";
  log_.line(test_.name + (summary_.left_path() ? ": failed (left its stress path) at step " : ": done at step ") +
            std::to_string(st.clock.step) + ", " + travel_text(travelled) +
            ": peak q/p = " + num(summary_.peak_eta, "%.4f") + " at " + travel_text(summary_.peak_strain) +
            ", final q/p = " + num(m_.inv.eta, "%.4f") +
            ", p = " + num(m_.inv.p / 1e6, "%.4f") + " MPa, b = " + num(m_.inv.b, "%.3f") +
            ", e = " + num(m_.void_ratio, "%.4f") + ", wall " + num(summary_.wall, "%.1f") + " s; " + watch_.worst() +
            "; path error " + num(100.0 * path_watch_.worst_path(), "%.2f") + " %, b error " +
            num(path_watch_.worst_b(), "%.3f") + ", rotation " + num(path_watch_.worst_rotation(), "%.1f") + " deg" +
            "; neighbour list built " + std::to_string(list_builds(world_->scratch())) +
            " times (the first as this process began) in its " +
            std::to_string(st.clock.step - step0_) + " steps");
}

void ShearRun::plot() const {
  // The plot is a convenience: a missing python3/matplotlib is a warning, not a failure.
  const fs::path png = plan_.out / (test_.name + ".png");
  const std::string pythonpath = analysis_pythonpath();
  const std::string cmd = (pythonpath.empty() ? "" : "PYTHONPATH='" + pythonpath + "' ") + "'" + python() +
                          "' -m sandcell_analysis plot '" + path_.string() + "' '" + png.string() + "' 2>&1";
  if (std::system(cmd.c_str()) == 0)
    log_.line(test_.name + ": plot " + png.string());
  else
    log_.line(test_.name + ": warning: no plot (needs python3 with h5py and matplotlib: " + cmd + ")");
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

}  // namespace sandcell::triaxial
