#pragma once
// `triaxial slurm CONFIG --out DIR ...`: a campaign as Slurm job arrays. Writes, into DIR/slurm/,
// batch scripts a person can read and edit before submitting, and (with --submit) submits them:
//   prepare.sbatch  the preparations: one job running them in order of p0 when they are chained
//                   (prepare.chain), else an array with one task per sample;
//   tests.sbatch    an array with one task per test (throttled to --max-running at once), after
//                   the preparations (afterok);
//   analyze.sbatch  `triaxial analyze` on the directory, after every test (afterok);
//   submit.sh       the three sbatch calls with their dependencies (what --submit runs).
// Every task runs `triaxial CONFIG --out DIR --resume --task K`, so a requeued task continues from
// its checkpoint; on SIGUSR1 (sent 120 s before the time limit), SIGTERM or SIGINT triaxial writes a
// checkpoint and exits 3, and the task requeues itself. index.csv is merged by each task under a lock.
#include <cstddef>
#include <filesystem>
#include <iosfwd>
#include <string>

namespace sandcell::triaxial {

struct SlurmCampaign {
  std::filesystem::path triaxial;  // absolute path of this binary
  std::filesystem::path config;    // absolute path of the campaign's config (a copy kept in DIR)
  std::filesystem::path out;       // absolute output directory
  std::size_t preparations = 0;    // tasks 0 .. preparations-1 of --list
  std::size_t tests = 0;           // tasks preparations .. preparations+tests-1
  bool chained = false;            // preparations depend on each other (one job, in order)
  int cpus_per_task = 1;
  std::string time = "24:00:00";  // per task, HH:MM:SS (or D-HH:MM:SS)
  std::string partition;          // empty: the cluster's default
  std::string thread_partition;   // triaxial --thread-partition of every task; empty: its default
  int max_running = 0;            // array throttle (%M); 0: none
};

/// Writes DIR/slurm/{prepare,tests,analyze}.sbatch and submit.sh. Throws std::runtime_error on I/O errors.
void write_slurm_scripts(const SlurmCampaign& campaign);

/// Runs DIR/slurm/submit.sh; returns its exit status (its output goes to `out`).
int submit_slurm_scripts(const SlurmCampaign& campaign, std::ostream& out, std::ostream& err);

}  // namespace sandcell::triaxial
