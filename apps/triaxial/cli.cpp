// The command line of `triaxial`: a run's options and checks (triaxial_main), and the subcommands
// that run the Python scripts (analyze, study, localization, calibrate).
#include "app.hpp"
#include "run.hpp"


#include <CLI/CLI.hpp>

#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <optional>
#include <sstream>

#ifndef SANDCELL_ANALYSIS_DIR
#define SANDCELL_ANALYSIS_DIR ""
#endif

namespace sandcell::triaxial {

fs::path analysis_root() {
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    const fs::path installed = exe.parent_path().parent_path() / "share" / "sandcell";
    if (fs::exists(installed / "sandcell_analysis" / "__main__.py")) return installed;
  }
  const fs::path source = fs::path(SANDCELL_ANALYSIS_DIR);
  if (!source.empty() && fs::exists(source / "sandcell_analysis" / "__main__.py")) return source;
  return {};
}

std::string analysis_pythonpath() {
  const fs::path root = analysis_root();
  const char* env = std::getenv("PYTHONPATH");
  const std::string rest = env && *env ? env : "";
  if (root.empty()) return rest;
  return rest.empty() ? root.string() : root.string() + ":" + rest;
}

std::string python() {
  const char* env = std::getenv("SANDCELL_PYTHON");
  if (env && *env) return env;
  return fs::exists("/usr/bin/python3") ? "/usr/bin/python3" : "python3";
}

std::vector<std::string> partition_name_list() {
  return std::vector<std::string>(k_partition_names.begin(), k_partition_names.end());
}

namespace {

// `triaxial analyze|study|localization|calibrate ...`: runs `python3 -m sandcell_analysis <command>` with the
// remaining arguments, the package found beside an installed binary or in the source tree (PYTHONPATH, else
// wherever Python finds it); the usage lines name "triaxial <command>", and the study finds this binary
// through SANDCELL_TRIAXIAL.
int script_main(const std::string& command, int argc, const char* const* argv, std::ostream& err) {
  const std::string prog = "triaxial " + command;
  const std::string py = python();
  const std::string pythonpath = analysis_pythonpath();
  std::vector<std::string> args{py, "-m", "sandcell_analysis", command};
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
    if (!pythonpath.empty()) ::setenv("PYTHONPATH", pythonpath.c_str(), 1);
    if (!ec) ::setenv("SANDCELL_TRIAXIAL", self.c_str(), 1);
    ::execvp(cargs[0], cargs.data());
    std::fprintf(stderr,
                 "%s: cannot run %s (needs python3 with numpy, scipy, matplotlib, h5py and the package "
                 "sandcell_analysis; set SANDCELL_PYTHON)\n",
                 prog.c_str(), cargs[0]);
    std::_Exit(127);
  }
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  return WIFEXITED(status) ? WEXITSTATUS(status) : 1;
}

// The command line of a run: the options the jobs see, and the flags that end the process early.
struct CommandLine {
  Options options;
  bool print_default = false;
  bool check_only = false;
};

// The options of `triaxial [CONFIG] ...` (--help lists them in this order).
void add_run_options(CLI::App& app, CommandLine& cl) {
  Options& options = cl.options;
  app.footer(
      "Analysis of results (critical state line, M(theta), dilatancy; report and figures):\n"
      "  triaxial analyze RESULTS.h5|DIR... [--out DIR]   (triaxial analyze --help for its options)\n"
      "Speed versus accuracy (timestep, inertial number, stiffness, restitution, N; table and Pareto figure):\n"
      "  triaxial study [CONFIG] [--preset quick|inertia|full|size] [--out DIR]   (triaxial study --help)\n"
      "Strain localization (shear bands) from the particle snapshots of results files:\n"
      "  triaxial localization RESULTS.h5... [--out DIR] [--grid G] [--whole] [--slabs K] [--void-ratios]\n"
      "      (triaxial localization --help)\n"
      "Calibration of micro-parameters against macroscopic targets (surrogate, posterior, check run):\n"
      "  triaxial calibrate CONFIG --targets FILE --param KEY=LO:HI... [--budget N] [--out DIR] [--resume]   "
      "(triaxial calibrate --help)\n"
      "Verify a published test: re-run it from its sample and compare its results file bitwise:\n"
      "  triaxial verify RESULTS.h5 [--rows K..L] [--threads T] [--keep DIR]   (triaxial verify --help)");
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
      ->check(CLI::IsMember(partition_name_list()));
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
std::optional<int> parse_command_line(int argc, const char* const* argv, CommandLine& cl, std::ostream& out,
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
int check_options(const Options& options, std::ostream& err) {
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
Plan load_plan(const Options& options) {
  return make_plan(options.config_path.empty() ? parse_config(k_default_config, "<embedded default>")
                                               : load_config(options.config_path),
                   options);
}

// --out, else results/<config name> (results/default for the embedded default).
fs::path output_directory(const Options& options) {
  return !options.out.empty()          ? fs::path(options.out)
         : options.config_path.empty() ? fs::path("results/default")
                                       : fs::path("results") / fs::path(options.config_path).stem();
}

// --list: the tasks in a stable order, preparations by p0 (as prepared), then the tests.
void list_tasks(const Plan& plan, std::ostream& out) {
  const std::size_t n_prep = plan.p0.size();
  for (std::size_t k = 0; k < plan.p0.size(); ++k) out << k << " prepare prepare-" << p0_tag(plan.p0[k]) << '\n';
  for (std::size_t k = 0; k < plan.config.tests.size(); ++k)
    out << n_prep + k << " test " << plan.config.tests[k].name << '\n';
}

// --task: runs only the tasks named (indices of --list), marked in run_prep and run_test.
// Returns 0, or 2 after a one-line message.
int select_tasks(const Plan& plan, const std::vector<std::string>& specs, std::vector<char>& run_prep,
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

}  // namespace

int triaxial_main(int argc, const char* const* argv, std::ostream& out, std::ostream& err) {
  // `triaxial analyze RESULTS... [--out DIR]`: the critical-state and dilatancy analysis (analyze.py).
  if (argc >= 2 && std::string(argv[1]) == "analyze") return script_main("analyze", argc - 1, argv + 1, err);
  // `triaxial study CONFIG [--preset quick|inertia|full|size]`: the speed-accuracy study (study.py).
  if (argc >= 2 && std::string(argv[1]) == "study") return script_main("study", argc - 1, argv + 1, err);
  // `triaxial localization RESULTS.h5... [--out DIR] [--grid G] [--whole] [--slabs K] [--void-ratios]`: strain fields between snapshots (localization.py).
  if (argc >= 2 && std::string(argv[1]) == "localization") return script_main("localization", argc - 1, argv + 1, err);
  // `triaxial calibrate CONFIG --targets FILE --param KEY=LO:HI...`: micro-parameters against targets (calibrate.py).
  if (argc >= 2 && std::string(argv[1]) == "calibrate") return script_main("calibrate", argc - 1, argv + 1, err);
  // `triaxial slurm CONFIG --out DIR [--submit]`: the campaign as Slurm job arrays (slurm.hpp).
  if (argc >= 2 && std::string(argv[1]) == "slurm") return slurm_main(argc - 1, argv + 1, out, err);
  // `triaxial verify RESULTS.h5 [--rows K..L] [--threads T]`: re-run a test, compare bitwise (verify.cpp).
  if (argc >= 2 && std::string(argv[1]) == "verify") return verify_main(argc - 1, argv + 1, out, err);
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
        << plan.p0.size() << " sample(s), "
        << (plan.config.dt_rule == TimeStepRule::stiffness ? "dt from the contacts, at most " : "dt = ")
        << num(plan.base.dt) << " s, results ~"
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
