#include "slurm.hpp"

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

}  // namespace sandcell::triaxial
