// A campaign in one process: the output directory claimed, the selected preparations and tests run
// (`parallel` at once), and index.csv and samples.csv written.
#include "app.hpp"

#include <algorithm>
#include <atomic>
#include <sstream>
#include <thread>

namespace sandcell::triaxial {

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
  /// 0 done, 1 a job failed, 2 a job in use by another process or a target the preparation cannot
  /// reach (prepare.target_e0), 3 stopped (a signal or --stop-after).
  int exit_code() const { return unreachable_ ? 2 : failures_ ? 1 : in_use_ ? 2 : interrupted_ ? 3 : 0; }

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
  int failures_ = 0, interrupted_ = 0, in_use_ = 0, unreachable_ = 0;
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
  if (dynamic_cast<const UnreachableTarget*>(&e)) ++unreachable_;
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

// --task: a selected job whose lock another process holds (the same task run twice at once) is
// refused before anything runs or is removed. Each lock is taken and released; a job another
// process starts after this probe is caught when its own lock is taken (InUse).
int check_jobs_free(const Plan& plan, const std::vector<char>& run_prep, const std::vector<char>& run_test,
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
int check_samples(const Plan& plan, const Options& options, const std::vector<fs::path>& replaced,
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
int claim_directory(const Plan& plan, const Options& options, bool selected, const std::vector<char>& run_prep,
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
          << "; allowed: the run's values, changes to output.*, tests.*, shear.max_axial_strain and "
          << "shear.max_deviatoric_strain, or --allow-change KEY for a change you mean\n";
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
void log_campaign_start(Log& log, const Plan& plan, const Options& options) {
  log.line("sandcell triaxial: " + plan.config.source + " -> " + plan.out.string() + ": " +
           std::to_string(plan.config.tests.size()) + " test(s), " + std::to_string(plan.p0.size()) + " sample(s), " +
           std::to_string(plan.config.parallel) + " at once x " + std::to_string(plan.job_threads) + " thread(s)");
  if (options.threads > available_cpus())
    log.line("warning: --threads " + std::to_string(options.threads) + " > the " + std::to_string(available_cpus()) +
             " CPUs this process may use (SLURM_CPUS_PER_TASK, else its affinity mask): threads will share cores");
  // Once per run: it concerns every stage. The speed/accuracy study (experiments/2026-11-21-study-quick) moved the peak
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
int run_campaign(const Plan& plan, const Options& options, const std::vector<char>& run_prep,
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

}  // namespace sandcell::triaxial
