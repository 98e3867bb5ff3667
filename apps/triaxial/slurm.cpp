#include "slurm.hpp"

#include "app.hpp"

#include <CLI/CLI.hpp>

#include <sys/wait.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <ostream>
#include <sstream>
#include <stdexcept>
#include <string>

namespace sandcell::triaxial {

namespace fs = std::filesystem;

namespace {

// Single-quoted for the shell.
std::string quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

void write_file(const fs::path& path, const std::string& text, bool executable) {
  const fs::path tmp = path.string() + ".tmp";
  {
    std::ofstream f(tmp);
    f << text;
    f.close();
    if (!f) throw std::runtime_error(tmp.string() + ": cannot write: " + std::strerror(errno));
  }
  fs::rename(tmp, path);
  if (executable)
    fs::permissions(path, fs::perms::owner_exec | fs::perms::group_exec | fs::perms::others_exec,
                    fs::perm_options::add);
}

// The #SBATCH lines every script shares.
std::string header(const SlurmCampaign& c, const std::string& name, const std::string& log) {
  std::ostringstream s;
  s << "#!/bin/bash\n"
    << "#SBATCH --job-name=" << name << "\n"
    << "#SBATCH --cpus-per-task=" << c.cpus_per_task << "\n"
    << "#SBATCH --time=" << c.time << "\n";
  if (!c.partition.empty()) s << "#SBATCH --partition=" << c.partition << "\n";
  s << "#SBATCH --output=" << (c.out / "slurm" / "logs" / log).string() << "\n"
    << "#SBATCH --open-mode=append\n";
  return s.str();
}

// Runs one or more tasks; on a stop signal forwards it to triaxial, which checkpoints and exits 3,
// and the job requeues itself to continue from that checkpoint.
std::string task_body(const SlurmCampaign& c, const std::string& args) {
  std::ostringstream s;
  s << "#SBATCH --requeue\n"
    << "#SBATCH --signal=B:USR1@120\n"
    << "set -u\n"
    << "TRIAXIAL=" << quote(c.triaxial.string()) << "\n"
    << "CONFIG=" << quote(c.config.string()) << "\n"
    << "OUT=" << quote(c.out.string()) << "\n"
    << "\"$TRIAXIAL\" \"$CONFIG\" --out \"$OUT\" --resume "
    << (c.thread_partition.empty() ? std::string() : "--thread-partition " + c.thread_partition + " ") << args << " &\n"
    << "pid=$!\n"
    << "# Slurm signals this shell (B:): pass it on; triaxial checkpoints and exits 3.\n"
    << "trap 'kill -USR1 \"$pid\" 2>/dev/null' USR1 TERM INT\n"
    << "rc=0\n"
    << "wait \"$pid\" || rc=$?\n"
    << "while kill -0 \"$pid\" 2>/dev/null; do rc=0; wait \"$pid\" || rc=$?; done\n"
    << "if [ \"$rc\" -eq 3 ]; then\n"
    << "  echo \"stopped with a checkpoint: requeued\"\n"
    << "  scontrol requeue \"${SLURM_ARRAY_JOB_ID:-$SLURM_JOB_ID}${SLURM_ARRAY_TASK_ID:+_$SLURM_ARRAY_TASK_ID}\"\n"
    << "fi\n"
    << "exit \"$rc\"\n";
  return s.str();
}

}  // namespace

void write_slurm_scripts(const SlurmCampaign& c) {
  const fs::path dir = c.out / "slurm";
  fs::create_directories(dir / "logs");
  const std::string throttle = c.max_running > 0 ? "%" + std::to_string(c.max_running) : "";

  std::string prepare = header(c, "sandcell-prepare", c.chained ? "prepare-%j.out" : "prepare-%A_%a.out");
  if (c.chained) {
    prepare += "# The samples are chained (each higher p0 from the next lower one): one job, in order.\n" +
               task_body(c, "--prepare-only");
  } else {
    prepare += "#SBATCH --array=0-" + std::to_string(c.preparations - 1) + throttle + "\n" +
               task_body(c, "--task \"$SLURM_ARRAY_TASK_ID\"");
  }
  write_file(dir / "prepare.sbatch", prepare, false);

  std::string tests = header(c, "sandcell-tests", "tests-%A_%a.out");
  tests += "#SBATCH --array=0-" + std::to_string(c.tests - 1) + throttle + "\n" + "# Array task K runs task " +
           std::to_string(c.preparations) + " + K of `triaxial CONFIG --list`.\n" +
           task_body(c, "--task \"$((" + std::to_string(c.preparations) + " + SLURM_ARRAY_TASK_ID))\"");
  write_file(dir / "tests.sbatch", tests, false);

  std::ostringstream analyze;
  analyze << header(c, "sandcell-analyze", "analyze-%j.out") << "set -eu\n"
          << quote(c.triaxial.string()) << " analyze " << quote(c.out.string()) << " --out "
          << quote((c.out / "analysis").string()) << "\n";
  write_file(dir / "analyze.sbatch", analyze.str(), false);

  std::ostringstream submit;
  submit << "#!/bin/bash\n"
         << "# Submits the campaign: preparations, then the tests (afterok), then the analysis (afterany:\n"
         << "# a test that left its stress path exits 1, and the analysis lists it and fits the others).\n"
         << "# Resubmitting after a failure is safe: every task resumes from what the directory holds.\n"
         << "set -eu\n"
         << "cd " << quote(dir.string()) << "\n"
         << "prepare=$(sbatch --parsable prepare.sbatch)\n"
         << "tests=$(sbatch --parsable --dependency=afterok:${prepare%%;*} tests.sbatch)\n"
         << "analyze=$(sbatch --parsable --dependency=afterany:${tests%%;*} analyze.sbatch)\n"
         << "echo \"prepare ${prepare%%;*} tests ${tests%%;*} analyze ${analyze%%;*}\"\n";
  write_file(dir / "submit.sh", submit.str(), true);
}

int submit_slurm_scripts(const SlurmCampaign& c, std::ostream& out, std::ostream& err) {
  const std::string cmd = "/bin/bash " + quote((c.out / "slurm" / "submit.sh").string()) + " 2>&1";
  FILE* pipe = ::popen(cmd.c_str(), "r");
  if (!pipe) {
    err << "triaxial slurm: cannot run " << cmd << '\n';
    return 1;
  }
  char buf[512];
  while (std::fgets(buf, sizeof buf, pipe)) out << buf;
  const int status = ::pclose(pipe);
  return WIFEXITED(status) ? WEXITSTATUS(status) : 1;
}

namespace {

// The values of --time and --partition that go into the scripts. Returns 0, or 2 after a one-line message.
int check_slurm_options(const SlurmCampaign& c, std::ostream& err) {
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
}  // namespace

int slurm_main(int argc, const char* const* argv, std::ostream& out, std::ostream& err) {
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
      ->check(CLI::IsMember(partition_name_list()));
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

}  // namespace sandcell::triaxial
