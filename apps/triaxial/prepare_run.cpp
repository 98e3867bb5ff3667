// The preparation stage of a triaxial run: one sample's isotropic compression to p0 (PrepareRun),
// its summary, and the runner's preparation of a sample (chained ones first).
#include "app.hpp"

#include "protocol/series.hpp"

#include "engine/generate.hpp"
#include "engine/packing.hpp"
#include "engine/results.hpp"
#include "systems/catalogue.hpp"
#include "systems/homogenizer.hpp"

#include <cmath>
#include <optional>

namespace sandcell::triaxial {

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
  finish_preparation(st);  // strains of the tests count from the prepared sample
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

bool Runner::ensure_sample(double p0) {
  if (fs::exists(sample_path(p0))) return true;
  if (const double from = plan_.chained_from(p0); from > 0.0 && !ensure_sample(from)) return false;
  Summary summary;
  return prepare(p0, summary);
}

}  // namespace sandcell::triaxial
