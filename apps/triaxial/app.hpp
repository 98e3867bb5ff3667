#pragma once
// The triaxial app's pieces, shared by its translation units (not installed, not an API): the
// command line's options, the plan of a run, the log, the jobs' summaries and the runner of the
// two stages. The protocol itself (what a config derives to) is protocol/protocol.hpp.
//   prepare_run.cpp  the preparation stage (PrepareRun)
//   shear_run.cpp    the shear stage (ShearRun)
//   plan.cpp         the plan of a run and its checks before anything runs
//   campaign.cpp     the output directory, the jobs in parallel, index.csv and samples.csv
//   cli.cpp          the command line (triaxial_main) and the Python subcommands
//   slurm.cpp        the campaign as Slurm job arrays
#include "lock.hpp"
#include "signals.hpp"
#include "protocol/config.hpp"
#include "protocol/protocol.hpp"
#include "protocol/text.hpp"

#include "engine/checkpoint.hpp"
#include "engine/world.hpp"

#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <mutex>
#include <ostream>
#include <stdexcept>
#include <string>
#include <vector>

namespace sandcell::triaxial {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

/// Where the analysis package (sandcell_analysis) is: beside an installed binary (<prefix>/share/sandcell),
/// else in the source tree the binary was built from (apps/analysis); empty: wherever Python finds it.
fs::path analysis_root();
/// PYTHONPATH for `python3 -m sandcell_analysis`: analysis_root() before the caller's PYTHONPATH.
std::string analysis_pythonpath();
/// The interpreter: $SANDCELL_PYTHON, else Debian's python3 (it has h5py, numpy, scipy, matplotlib).
std::string python();
/// The names of the thread partitions (--thread-partition).
std::vector<std::string> partition_name_list();

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

// prepare.target_e0 outside the e0 range the preparation reaches: bad input (exit 2), found by trials.
struct UnreachableTarget : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// A job whose lock another process holds (the same --task run twice): bad input, not a failed test.
struct InUse : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// The message of a job found in use: the job, its lock file and the holder's PID and host.
inline std::string in_use_message(const fs::path& lock, const std::string& job) {
  return job + " is in use: " + lock.string() + " is held by " + FileLock::holder(lock) +
         "; not started twice; allowed: wait for it to end, or run another task";
}

// Everything derived from the config before anything runs: the protocol (protocol/protocol.hpp)
// and how this process runs it.
struct Plan : Protocol {
  Options options;
  fs::path out;
  int job_threads = 1;      // threads of one test (the budget split between `parallel` tests)
  int prepare_threads = 1;  // threads of one preparation (all of them when chained ones run one by one)
  Partition partition = Partition::adaptive;  // --thread-partition
  double output_bytes = 0.0;                  // estimated size of the run's results files (estimate_output)
  std::string output_note;                    // the estimate, for the warning above 1 GiB ("" below)
};

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

// Wall time and checkpoint timing of a job.
struct Timer {
  Clock::time_point start = Clock::now();
  double before = 0.0;  // s of earlier segments of a resumed job
  Clock::time_point last_checkpoint = Clock::now();
  double elapsed() const { return before + std::chrono::duration<double>(Clock::now() - start).count(); }
};

inline bool checkpoint_due(const OutputConfig& o, std::uint64_t step, Timer& timer) {
  if (o.checkpoint_interval > 0 && step % o.checkpoint_interval == 0) return true;
  if (o.checkpoint_minutes > 0.0 &&
      std::chrono::duration<double>(Clock::now() - timer.last_checkpoint).count() > 60.0 * o.checkpoint_minutes)
    return true;
  return false;
}

inline void save(const fs::path& path, const State& state, CheckpointExtra extra, Timer& timer) {
  extra.doubles["wall_time"] = {timer.elapsed()};
  write_checkpoint(path, state, extra);
  timer.last_checkpoint = Clock::now();
}

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
  /// prepare.target_e0: the search for the preparation's friction (prepare_run.cpp).
  bool prepare_to_target(double p0, Summary& summary, const fs::path& sample);
  const Plan& plan_;
  Log& log_;
  bool single_job() const { return plan_.config.parallel == 1; }
};


// A message for one line of at most ~300 characters: newlines become spaces; a longer one keeps its
// head and tail (the key and what is allowed) around "...".
inline std::string one_line(std::string m) {
  std::replace(m.begin(), m.end(), '\n', ' ');
  constexpr std::size_t k_max = 280;  // with "triaxial: " in front, under 300
  if (m.size() > k_max) m = m.substr(0, 170) + " ... " + m.substr(m.size() - 105);
  return m;
}

/// The plan of a config (protocol/protocol.hpp, then this process's checks: cell width, run
/// lengths, strain per step, output size, servos). Throws ConfigError.
Plan make_plan(Config config, const Options& options);
/// Reads and plans a config file for a subcommand; throws ConfigError.
Plan plan_from_file(const std::string& path, const Options& options);
/// The files a run writes into the output directory: all of them, or (selected) those of the
/// selected tasks (the shared index.csv and samples.csv are merged, never replaced whole).
std::vector<fs::path> run_files(const Plan& plan, const std::vector<char>& run_prep, const std::vector<char>& run_test,
                                bool selected);
/// Parses --task values (K, A-B, K,L,...) into sorted distinct task indices below n; returns the
/// message of the first bad value, or "" when all are good.
std::string parse_tasks(const std::vector<std::string>& specs, std::size_t n, std::vector<std::size_t>& tasks);

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

/// Claims the output directory for this process (its lock in dir_lock): refuses a directory in use or
/// holding another run, checks --resume/--task against it, clears what --overwrite replaces and
/// stores the config. Returns 0, or an exit code after a one-line message.
int claim_directory(const Plan& plan, const Options& options, bool selected, const std::vector<char>& run_prep,
                    const std::vector<char>& run_test, FileLock& dir_lock, std::ostream& err);
/// Runs the selected preparations and tests (all of a whole run) and writes the campaign's index.
/// Returns the exit code: 0 done, 1 a job failed, 2 a job in use, 3 stopped (a signal or --stop-after).
int run_campaign(const Plan& plan, const Options& options, const std::vector<char>& run_prep,
                 const std::vector<char>& run_test, std::ostream& out);
/// `triaxial slurm CONFIG --out DIR ...`: the campaign as Slurm job arrays (slurm.hpp).
int slurm_main(int argc, const char* const* argv, std::ostream& out, std::ostream& err);
/// `triaxial verify RESULTS.h5 [--rows K..L] [--threads T] [--keep DIR]`: re-runs a shear test from
/// its run record and compares the results bitwise (verify.cpp). 0 verified, 1 differs, 2 cannot.
int verify_main(int argc, const char* const* argv, std::ostream& out, std::ostream& err);

}  // namespace sandcell::triaxial
