// `triaxial verify RESULTS.h5 [--rows K..L] [--threads T] [--keep DIR]`: re-runs a shear test from
// the sample its results file names, with the config text the file holds, and compares the new file
// with it row by row (the state digest and every series column but the wall time) and snapshot by
// snapshot, bitwise. Exit 0: verified; 1: a row, a snapshot or the run's length differs (the first
// named); 2: it cannot be verified (no run record, the sample missing or not the one the run
// started from, bad arguments).
#include "app.hpp"
#include "run.hpp"

#include "engine/build_arch.hpp"
#include "engine/checkpoint.hpp"
#include "engine/fnv1a.hpp"
#include "engine/hdf5.hpp"
#include "engine/version.hpp"

#include <CLI/CLI.hpp>

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <map>
#include <sstream>

namespace sandcell::triaxial {

namespace {

struct Opened {
  std::map<std::string, std::string> attrs;  // the root's string attributes used here
  std::map<std::string, std::vector<double>> series;
  std::map<std::string, std::size_t> width;
  std::vector<std::string> snapshots;  // group names, ascending step
};

Opened read_results(const fs::path& path) {
  Opened r;
  const h5::File f = h5::File::open(path, h5::File::Mode::read);
  const h5::Group root = f.root();
  if (root.has_attribute("format")) r.attrs["format"] = root.get_string("format");
  if (!root.has("series")) return r;  // not a results file: the caller names it
  for (const char* key : {"format", "stage", "job", "config", "software_version", "software_arch", "software_compiler",
                          "sample_file", "sample_digest", "status", "max_axial_strain_override", "p0"})
    if (root.has_attribute(key)) r.attrs[key] = root.get_string(key);
  const h5::Group series = root.open_group("series");
  for (const std::string& name : series.children()) {
    const h5::Dataset d = series.open_dataset(name);
    const auto shape = d.shape();
    r.series[name] = d.read<double>();
    r.width[name] = shape.size() > 1 ? shape[1] : 1;
  }
  if (root.has("snapshots")) r.snapshots = root.open_group("snapshots").children();
  return r;
}

// The first dataset of snapshot `group` whose bytes differ between the two files ("" when none).
std::string snapshot_difference(const fs::path& a, const fs::path& b, const std::string& group) {
  const h5::File fa = h5::File::open(a, h5::File::Mode::read), fb = h5::File::open(b, h5::File::Mode::read);
  const h5::Group ga = fa.root().open_group("snapshots").open_group(group);
  if (!fb.root().open_group("snapshots").has(group)) return "missing in the re-run";
  const h5::Group gb = fb.root().open_group("snapshots").open_group(group);
  for (const std::string& name : ga.children()) {
    if (!gb.has(name)) return name + " missing in the re-run";
    const h5::Dataset da = ga.open_dataset(name), db = gb.open_dataset(name);
    if (da.shape() != db.shape()) return name + " (shape)";
    if (da.stores(h5::Scalar::f64)) {
      if (da.read<double>() != db.read<double>()) return name;
    } else if (da.read<std::uint32_t>() != db.read<std::uint32_t>()) {
      return name;
    }
  }
  return "";
}

// Row `row` of a state_digest series (two exact 32-bit halves) as the digest's hex.
std::string row_digest(const std::vector<double>& d, std::size_t row) {
  return hex_digest((static_cast<std::uint64_t>(d[2 * row]) << 32) | static_cast<std::uint64_t>(d[2 * row + 1]));
}

}  // namespace

int verify_main(int argc, const char* const* argv, std::ostream& out, std::ostream& err) {
  std::string file, rows, keep;
  int threads = 1;
  CLI::App app{"sandcell triaxial verify: re-run a shear test from its sample and compare its results file bitwise"};
  app.add_option("results", file, "a shear test's results file (p-*.h5)")->required();
  app.add_option("--rows", rows, "K..L: compare series rows K to L only (the re-run stops after row L)");
  app.add_option("--threads", threads, "threads of the re-run (results are bitwise the same for any count)")
      ->check(CLI::Range(1, 4096));
  app.add_option("--keep", keep, "keep the re-run in this new directory (default: a temporary one, removed)");
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp&) {
    out << app.help();
    return 0;
  } catch (const CLI::ParseError& e) {
    err << "triaxial verify: " << e.what() << " (see --help)\n";
    return 2;
  }
  const fs::path path = fs::absolute(file);
  Opened a;
  try {
    a = read_results(path);
  } catch (const std::exception& e) {
    err << "triaxial verify: " << file << ": " << one_line(e.what()) << "\n";
    return 2;
  }
  if (a.attrs["format"] != "sandcell results") {
    err << "triaxial verify: " << file << ": format = \"" << a.attrs["format"]
        << "\": not a results file (a sample or checkpoint?); allowed: a test's results file (p-*.h5)\n";
    return 2;
  }
  if (a.attrs["stage"] != "shear") {
    err << "triaxial verify: " << file << ": stage = \"" << a.attrs["stage"]
        << "\": verify re-runs shear tests (p-*.h5); allowed: a test's results file\n";
    return 2;
  }
  // A file from before the run record (2026-11-28): its sample found by its p0 beside it, unchecked,
  // and the files compared on what they both hold (no state digest).
  const bool recorded = a.attrs.count("sample_file") && a.attrs.count("sample_digest") && a.series.count("state_digest");
  if (!recorded) {
    if (!a.attrs.count("p0")) {
      err << "triaxial verify: " << file << ": no run record and no p0 to find its sample by; re-run the test\n";
      return 2;
    }
    a.attrs["sample_file"] = "sample-" + p0_tag(std::stod(a.attrs["p0"])) + ".h5";
    out << "note: no run record (written before it): the sample found by p0 (" << a.attrs["sample_file"]
        << ", not checked against the file), the files compared on their series and snapshots; a difference may "
        << "also come from a command-line override the file does not record\n";
  }
  // The build first: another version or compiler may round differently.
  const std::string made = a.attrs["software_version"] + ", " + a.attrs["software_arch"] + ", " +
                           (a.attrs.count("software_compiler") ? a.attrs["software_compiler"] : "compiler unknown");
  const std::string here = std::string(version()) + ", " + std::string(build_arch()) + ", " + std::string(compiler());
  if (made != here)
    out << "note: the file was written by sandcell " << made << "; this is " << here
        << ": a difference below may come from the build\n";
  // The rows to compare.
  const std::vector<double>& steps = a.series["step"];
  const std::size_t n_rows = steps.size();
  std::size_t first = 0, last = n_rows == 0 ? 0 : n_rows - 1;
  if (!rows.empty()) {
    unsigned long long k = 0, l = 0;
    char tail = 0;
    if (std::sscanf(rows.c_str(), "%llu..%llu%c", &k, &l, &tail) != 2 || k > l || l >= n_rows) {
      err << "triaxial verify: --rows = " << rows << ": allowed K..L with 0 <= K <= L < " << n_rows
          << " (the file's rows)\n";
      return 2;
    }
    first = k;
    last = l;
  }
  // The sample, beside the file, as the run found it.
  const fs::path sample = path.parent_path() / a.attrs["sample_file"];
  CheckpointExtra sample_extra;
  try {
    const State s = read_checkpoint(sample, &sample_extra);
    const std::string d = hex_digest(particle_digest(s));
    if (recorded && a.attrs["sample_digest"] != d) {
      err << "triaxial verify: " << sample.string() << ": not the sample the run started from (state digest " << d
          << ", the file's record " << a.attrs["sample_digest"] << ")\n";
      return 2;
    }
  } catch (const std::exception& e) {
    err << "triaxial verify: the run's sample: " << one_line(e.what()) << "\n";
    return 2;
  }
  // The re-run: the file's config, its sample, this test only.
  const fs::path dir = keep.empty() ? fs::temp_directory_path() / ("sandcell-verify-" + std::to_string(::getpid()))
                                    : fs::absolute(keep);
  if (fs::exists(dir) && !fs::is_empty(dir)) {
    err << "triaxial verify: --keep = " << dir.string() << ": exists and is not empty; allowed: a new directory\n";
    return 2;
  }
  fs::create_directories(dir);
  const auto cleanup = [&] {
    if (keep.empty()) fs::remove_all(dir);
  };
  std::vector<std::string> args = {"triaxial", (dir / "config.toml").string(), "--out", (dir / "out").string(),
                                   "--threads", std::to_string(threads), "--resume"};
  try {
    { std::ofstream(dir / "config.toml") << a.attrs["config"]; }
    fs::create_directories(dir / "out");
    fs::copy_file(sample, dir / "out" / sample.filename());
    const Plan plan = plan_from_file((dir / "config.toml").string(), Options{});
    std::size_t index = plan.config.tests.size();
    for (std::size_t k = 0; k < plan.config.tests.size(); ++k)
      if (plan.config.tests[k].name == a.attrs["job"]) index = k;
    if (index == plan.config.tests.size()) {
      err << "triaxial verify: " << file << ": job = \"" << a.attrs["job"] << "\" is not a test of its own config\n";
      cleanup();
      return 2;
    }
    if (plan.config.tests.size() > 1) {
      args.push_back("--task");
      args.push_back(std::to_string(plan.p0.size() + index));
    }
    // The keys the sample was prepared with otherwise, as the original run was allowed to.
    if (const auto it = sample_extra.strings.find("config"); it != sample_extra.strings.end())
      for (const KeyChange& c : sample_changes(it->second, plan.config)) {
        args.push_back("--allow-change");
        args.push_back(c.key);
      }
    if (a.attrs.count("max_axial_strain_override")) {  // the original's command line
      args.push_back("--max-axial-strain");
      args.push_back(a.attrs["max_axial_strain_override"]);
    }
    if (!rows.empty() && last + 1 < n_rows) {  // stop once row `last` is written
      args.push_back("--stop-after");
      args.push_back(std::to_string(static_cast<std::uint64_t>(steps[last]) + 1));
    }
  } catch (const std::exception& e) {
    err << "triaxial verify: " << one_line(e.what()) << "\n";
    cleanup();
    return 2;
  }
  std::vector<const char*> argv2;
  for (const std::string& s : args) argv2.push_back(s.c_str());
  std::ostringstream run_out, run_err;
  const int code = triaxial_main(static_cast<int>(argv2.size()), argv2.data(), run_out, run_err);
  const fs::path rerun = dir / "out" / (a.attrs["job"] + ".h5");
  if ((code != 0 && code != 1 && code != 3) || !fs::exists(rerun)) {
    // Its own words: the error line, else the log's last line (a job that failed names why there).
    std::string said = run_err.str();
    if (said.find_first_not_of(" \n") == std::string::npos) {
      const std::string log = run_out.str();
      const std::size_t end = log.find_last_not_of('\n');
      said = end == std::string::npos ? "" : log.substr(log.rfind('\n', end) + 1, end - log.rfind('\n', end));
    }
    err << "triaxial verify: the re-run did not run (exit " << code << "): " << one_line(said) << "\n";
    cleanup();
    return 2;
  }
  Opened b;
  try {
    b = read_results(rerun);
  } catch (const std::exception& e) {
    err << "triaxial verify: the re-run's results: " << one_line(e.what()) << "\n";
    cleanup();
    return 2;
  }
  // A column a later build added when it resumed the file has NaN in the rows before (ResultsFile::
  // reopen pads it): those rows are not compared. A column NaN throughout was written so: compared.
  std::map<std::string, std::size_t> padded_rows;
  for (const auto& [name, values] : a.series) {
    const std::size_t w = a.width[name];
    std::size_t k = 0;
    while (k < n_rows && std::all_of(values.begin() + k * w, values.begin() + (k + 1) * w,
                                     [](double v) { return std::isnan(v); }))
      ++k;
    padded_rows[name] = k == n_rows ? 0 : k;
  }
  // Row by row: the state digest, then every column (the wall time aside), in the file's order.
  const std::size_t b_rows = b.series["step"].size();
  int result = 0;
  for (std::size_t r = first; r <= last && result == 0; ++r) {
    if (r >= b_rows) {
      out << "differs: the re-run ended at row " << (b_rows ? b_rows - 1 : 0) << " (step "
          << (b_rows ? static_cast<std::uint64_t>(b.series["step"][b_rows - 1]) : 0) << "); the file goes on to row "
          << last << "\n";
      result = 1;
      break;
    }
    std::string what;
    if (recorded && row_digest(a.series["state_digest"], r) != row_digest(b.series["state_digest"], r))
      what = "state_digest " + row_digest(a.series["state_digest"], r) + " (file) != " +
             row_digest(b.series["state_digest"], r) + " (re-run)";
    for (const auto& [name, values] : a.series) {
      if (!what.empty()) break;
      if (name == "wall_time") continue;
      const std::size_t w = a.width[name];
      const auto it = b.series.find(name);
      if (it == b.series.end() || b.width[name] != w) {
        what = name + " missing in the re-run";
        break;
      }
      const std::size_t padded = padded_rows[name];
      for (std::size_t c = 0; c < w; ++c) {
        const double x = values[r * w + c], y = it->second[r * w + c];
        if (std::memcmp(&x, &y, sizeof x) == 0 || r < padded) continue;  // bitwise: a NaN written equals itself
        what = name + (w > 1 ? "[" + std::to_string(c) + "]" : "") + " = " + num(x, "%.17g") + " (file) != " +
               num(y, "%.17g") + " (re-run)";
        break;
      }
    }
    if (!what.empty()) {
      out << "differs: row " << r << " (step " << static_cast<std::uint64_t>(steps[r]) << "): " << what << "\n";
      result = 1;
    }
  }
  // The snapshots up to the last compared row.
  if (result == 0)
    for (const std::string& g : a.snapshots) {
      const std::uint64_t step = std::stoull(g);
      if (step < static_cast<std::uint64_t>(steps[first]) || step > static_cast<std::uint64_t>(steps[last])) continue;
      if (const std::string d = snapshot_difference(path, rerun, g); !d.empty()) {
        out << "differs: the snapshot at step " << step << ": " << d << "\n";
        result = 1;
        break;
      }
    }
  if (result == 0 && rows.empty() && b_rows != n_rows) {
    out << "differs: the re-run has " << b_rows << " rows, the file " << n_rows << "\n";
    result = 1;
  }
  if (result == 0)
    out << "verified: rows " << first << ".." << last << " (steps " << static_cast<std::uint64_t>(steps[first])
        << ".." << static_cast<std::uint64_t>(steps[last]) << ") bitwise identical: "
        << (recorded ? "state digests, every series column" : "every series column the file holds")
        << " but the wall time, and the snapshots between\n";
  cleanup();
  return result;
}

}  // namespace sandcell::triaxial
