// The preparation stage of a triaxial run: one sample's isotropic compression to p0 (PrepareRun),
// its summary, and the runner's preparation of a sample (chained ones first).
#include "app.hpp"

#include "protocol/series.hpp"

#include "engine/fnv1a.hpp"
#include "engine/generate.hpp"
#include "engine/packing.hpp"
#include "engine/results.hpp"
#include "systems/catalogue.hpp"
#include "systems/homogenizer.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <map>
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
                                       {{"job", name_},
                                        {"stage", "prepare"},
                                        {"from", "sample-" + p0_tag(from_)},
                                        {"initial_digest", hex_digest(particle_digest(state))}}));
  return state;
}

// The packing file's spheres, or the cloud generated from [sample] (the same seed: the same cloud).
State PrepareRun::start_from_cloud(const Model& model) {
  Packing packing = plan_.packing;
  if (!plan_.from_file && plan_.config.sample.generation.count > 100'000)  // the placement takes a while
    log_.line(name_ + ": placing " + std::to_string(plan_.config.sample.generation.count) + " spheres at random");
  if (!plan_.from_file) packing = generate_packing(plan_.config.sample.generation);
  State state = make_state(model, packing);
  // The run record of a preparation: the input (a packing file's bytes, or the generated cloud) by digest.
  std::map<std::string, std::string> attrs = {{"job", name_}, {"stage", "prepare"},
                                              {"initial_digest", hex_digest(particle_digest(state))}};
  if (plan_.from_file) {
    attrs["packing_file"] = plan_.config.sample.packing_file;
    std::ifstream in(plan_.config.sample.packing_file, std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    Fnv1a f;
    f.bytes(bytes.data(), bytes.size());
    attrs["packing_digest"] = hex_digest(f.h);
  }
  results_.emplace(ResultsFile::create(series_, plan_.config.text, attrs));
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
  extra.doubles["prepare_friction"] = {pc_.friction};  // the one prepare.target_e0 found, or as set
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

namespace {

// One preparation of the target_e0 search: its friction, its spheres and the e0 it reached.
struct Trial {
  double friction = 0.0;
  std::size_t count = 0;
  double e0 = 0.0;
  fs::path sample;  // its sample file
};

}  // namespace

// prepare.target_e0: the preparation's friction f that gives e0 = target at p0. e0 grows with f (a
// frictional cloud jams looser), so the search brackets the target between f = 0 (the densest
// e0 this compression reaches) and f = prepare.max_friction (the loosest), and narrows the bracket by
// regula falsi (the Illinois variant: the retained end's weight halved, so it never stalls) on
// trial preparations of prepare.trial_count spheres (the sample's own spheres when it has no more),
// until a trial lands within half the tolerance. A sample larger than its trials is then prepared
// at that friction; if its e0 misses the tolerance, the trials are searched again for the target
// shifted by the full-size miss (below), up to four full-size preparations in all. The trials
// (directory target_e0-<p0>/, and target_e0-<p0>.csv: friction, spheres, e0) stay as the record.
// A target outside the range the two ends reach (by more than the tolerance) throws
// UnreachableTarget naming the key and the range: bad input, exit 2.
bool Runner::prepare_to_target(double p0, Summary& summary, const fs::path& sample) {
  const PrepareConfig& pc = plan_.config.prepare;
  const double target = pc.target_for(p0, plan_.p0), tol = pc.target_tolerance;
  const std::size_t count = plan_.from_file ? plan_.packing.radius.size() : plan_.config.sample.generation.count;
  const std::size_t trial_count = plan_.from_file ? count : std::min<std::size_t>(count, pc.trial_count);
  const std::string tag = p0_tag(p0);
  const fs::path dir = plan_.out / ("target_e0-" + tag);
  fs::create_directories(dir);
  std::vector<Trial> trials;
  const auto run_trial = [&](double friction, std::size_t n) -> Trial {
    Config c = plan_.config;
    c.prepare.friction = friction;
    c.prepare.target_e0.clear();
    if (!plan_.from_file) c.sample.generation.count = n;
    Options o = plan_.options;
    o.resume = false;
    Plan trial = make_plan(c, o);
    trial.out = dir;
    trial.prepare_threads = plan_.prepare_threads;
    trial.partition = plan_.partition;
    Summary s;
    s.name = "trial-" + std::to_string(trials.size());
    PrepareRun run(trial, log_, p0, s);
    run.open(*this);
    run.run();
    const fs::path file = dir / (s.name + ".sample.h5");
    run.finish(file);
    trials.push_back({friction, n, s.e0, file});
    log_.line("prepare-" + tag + ": target e0 = " + num(target, "%.4f") + ": trial " + std::to_string(trials.size() - 1) +
              ", friction " + num(friction, "%.5f") + ", " + std::to_string(n) + " spheres: e0 = " +
              num(s.e0, "%.4f"));
    std::ofstream csv(plan_.out / ("target_e0-" + tag + ".csv"));
    csv << "trial,friction,spheres,e0,target\n";
    for (std::size_t k = 0; k < trials.size(); ++k)
      csv << k << ',' << num(trials[k].friction, "%.17g") << ',' << trials[k].count << ','
          << num(trials[k].e0, "%.17g") << ',' << num(target, "%.17g") << '\n';
    return trials.back();
  };
  Trial lo = run_trial(0.0, trial_count), hi = run_trial(pc.max_friction, trial_count);
  if (target < lo.e0 - tol || target > hi.e0 + tol || !(hi.e0 > lo.e0))
    throw UnreachableTarget("prepare.target_e0 = " + num(target) + " at p0 = " + num(p0 / 1e6) +
                            " MPa: outside the reachable range e0 = " + num(lo.e0, "%.4f") + " .. " +
                            num(hi.e0, "%.4f") + " (prepare.friction 0 .. prepare.max_friction = " +
                            num(pc.max_friction) + ", " + std::to_string(trial_count) +
                            "-sphere trials in " + dir.string() + "); allowed: a target in that range, or a larger "
                            "prepare.max_friction (or prepare.rolling_friction) for looser samples");
  // Regula falsi (Illinois) on g(f) = e0(f) - t over the trials of trial size, for a trial-size target
  // t: the bracket is the tightest the trials so far give (the largest friction below t, the smallest
  // above it), the result the trial closest to t (within half the tolerance unless the bracket
  // closed or 12 steps passed).
  const auto search = [&](double t) -> Trial {
    const Trial* below = nullptr;
    const Trial* above = nullptr;
    for (const Trial& x : trials)
      if (x.count == trial_count && x.e0 < t && (!below || x.friction > below->friction)) below = &x;
    for (const Trial& x : trials)
      if (x.count == trial_count && x.e0 >= t && (!below || x.friction > below->friction) &&
          (!above || x.friction < above->friction))
        above = &x;
    Trial best_t{};
    bool any = false;
    for (const Trial& x : trials)
      if (x.count == trial_count && (!any || std::abs(x.e0 - t) < std::abs(best_t.e0 - t))) best_t = x, any = true;
    if (!below || !above) return best_t;  // t beyond the trials' range: the nearest end
    Trial lo = *below, hi = *above;
    double wlo = 1.0, whi = 1.0;  // Illinois weights of the two ends
    int side = 0;                 // which end the last step replaced (-1 lo, +1 hi)
    for (int k = 0; k < 12 && std::abs(best_t.e0 - t) > 0.5 * tol && hi.friction - lo.friction > 1e-4; ++k) {
      const double glo = wlo * (lo.e0 - t), ghi = whi * (hi.e0 - t);
      double f = (lo.friction * ghi - hi.friction * glo) / (ghi - glo);
      f = std::clamp(f, lo.friction + 0.02 * (hi.friction - lo.friction), hi.friction - 0.02 * (hi.friction - lo.friction));
      const Trial x = run_trial(f, trial_count);
      if (std::abs(x.e0 - t) < std::abs(best_t.e0 - t)) best_t = x;
      if (x.e0 < t) {
        lo = x;
        wlo = 1.0;
        if (side == -1) whi *= 0.5;
        side = -1;
      } else {
        hi = x;
        whi = 1.0;
        if (side == +1) wlo *= 0.5;
        side = +1;
      }
    }
    return best_t;
  };
  Trial best = search(target);
  // Full size: a larger cell's e0 differs from a trial's at the same friction by a few 1e-3 (the
  // size effect and another packing). Each full-size preparation measures that shift at its
  // friction, and the next friction is the trials' for the target less the shift; once full-size
  // samples bracket the target, the interpolation between the two nearest. Up to four full-size
  // preparations; a friction already prepared at full size is not prepared again (the same bits):
  // the search stops there.
  double shift = 0.0;  // full-size e0 minus trial-size e0 at the same friction
  std::vector<Trial> full;
  double closest = best.e0;  // the full-size e0 nearest the target (the trial's while there is none)
  for (int k = 0; k < 4 && best.count < count; ++k) {
    const Trial* below = nullptr;
    const Trial* above = nullptr;
    for (const Trial& x : full)
      if (x.e0 < target && (!below || x.friction > below->friction)) below = &x;
    for (const Trial& x : full)
      if (x.e0 >= target && (!below || x.friction > below->friction) && (!above || x.friction < above->friction))
        above = &x;
    const double f = k == 0             ? best.friction
                     : below && above ? below->friction + (target - below->e0) * (above->friction - below->friction) /
                                                               (above->e0 - below->e0)
                                      : search(target - shift).friction;
    if (std::any_of(full.begin(), full.end(), [&](const Trial& x) { return std::abs(x.friction - f) <= 1e-9; })) break;
    // The trial-size e0 at f: the trial there if any (the search's result), else none (no shift update).
    const auto at = std::find_if(trials.begin(), trials.end(),
                                 [&](const Trial& x) { return x.count == trial_count && x.friction == f; });
    const double e_trial = at == trials.end() ? std::nan("") : at->e0;
    const Trial t = run_trial(f, count);
    full.push_back(t);
    if (std::abs(t.e0 - target) <= tol) {  // a full-size sample within tolerance ends the search
      best = t;
      break;
    }
    if (full.size() == 1 || std::abs(t.e0 - target) < std::abs(closest - target)) closest = t.e0;
    if (std::isfinite(e_trial)) shift = t.e0 - e_trial;
  }
  if (best.count < count || std::abs(best.e0 - target) > tol)
    throw SimulationError("prepare-" + tag + ": prepare.target_e0 = " + num(target) + " not reached within " +
                          num(tol) + " after " + std::to_string(trials.size()) + " preparations (closest e0 = " +
                          num(closest, "%.4f") + (best.count < count ? " at full size" : "") + "; trials in " + (plan_.out / ("target_e0-" + tag + ".csv")).string() +
                          "); allowed: a larger prepare.target_e0_tolerance or prepare.trial_count");
  fs::copy_file(best.sample, sample, fs::copy_options::overwrite_existing);
  summary = sample_summary(p0);
  summary.status = "done";
  log_.line("prepare-" + tag + ": target e0 = " + num(target, "%.4f") + " reached: e0 = " + num(best.e0, "%.4f") +
            " at prepare.friction = " + num(best.friction, "%.5f") + " (" + std::to_string(trials.size()) +
            " preparations)");
  return true;
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
  if (!plan_.config.prepare.target_e0.empty()) return prepare_to_target(p0, summary, sample);
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
