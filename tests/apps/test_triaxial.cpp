// The triaxial app, run in-process: bad input (one case per class of mistake) exits 2 with one line
// naming the key and leaves the output directory untouched; a run stopped and resumed (with other
// thread counts) is bitwise identical to an uninterrupted one; the embedded default runs end to end
// and its results file holds the documented datasets.
#include "engine/checkpoint.hpp"
#include "engine/hdf5.hpp"
#include "config.hpp"
#include "lock.hpp"
#include "run.hpp"
#include "app_run.hpp"
#include "signals.hpp"
#include "support/affinity.hpp"

#include <doctest/doctest.h>
#include <hdf5.h>

#include <sched.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <optional>
#include <string>
#include <thread>
#include <vector>

using namespace sandcell;
namespace fs = std::filesystem;

using namespace app_test;

namespace {


}  // namespace

TEST_CASE("triaxial: each class of bad input exits 2 naming the key, and clobbers nothing") {
  const fs::path dir = fresh_dir("bad");
  write(dir / "index.csv", "results of an earlier run\n");  // must survive every failed call
  struct Case {
    const char* what;
    std::string config;
    const char* expect;  // in the one-line message
  };
  const std::string base = k_small;
  const auto with = [&](const std::string& section, const std::string& line) {
    std::string c = base;
    const std::string head = "[" + section + "]\n";
    c.insert(c.find(head) + head.size(), line + "\n");
    return c;
  };
  const auto replaced = [](std::string c, const std::string& from, const std::string& to) {
    return c.replace(c.find(from), from.size(), to);
  };
  const Case cases[] = {
      {"syntax", base + "[output\n", "TOML syntax error"},
      {"unknown key", with("material", "yuong = 1e9"), "material.yuong"},
      {"unknown section", base + "[materials]\ndensity = 1\n", "[materials]: unknown section"},
      {"wrong type", with("shear", "critical_window = \"lots\""),
       "shear.critical_window = \"lots\": expected a number"},
      {"out of range", with("tests", "parallel = 0"), "tests.parallel = 0"},
      {"cell narrower than 2 r_max + skin",
       std::string(base).replace(base.find("max_axial_strain = 0.03"), 23, "max_axial_strain = 2.0"),
       "sample.count = 300: the cell would narrow to"},
      {"dt above the stability limit", with("time", "dt_fraction = 1.5"), "time.dt_fraction = 1.5"},
      // E = 1 MPa at p0 = 0.1 MPa: a mean overlap of ~0.8 R by Hertz (protocol/config.cpp).
      {"overlap beyond the Hertz law", std::string(base).replace(base.find("young = 1.0e9"), 13, "young = 1.0e6"),
       "tests.p0[0] = 100000: with material.young = 1e+06 Pa the mean contact overlap would be ~0.77"},
      {"bad gradation", with("sample", "distribution = \"gradation\"\ngradation = [[0.005, 0], [0.004, 100]]"),
       "diameters must increase"},
      {"missing packing file", with("sample", "file = \"/nonexistent/packing.txt\""), "sample.file"},
      {"unregistered normal law", base + "[contact]\nnormal = \"hook\"\n",
       "contact.normal = \"hook\": allowed: \"hertz\" \"hooke\""},
      {"hooke without its velocity", base + "[contact]\nnormal = \"hooke\"\n",
       "contact.characteristic_velocity = (none): required with normal = \"hooke\""},
      {"a hooke parameter for hertz", base + "[contact]\ncharacteristic_velocity = 1.0\n",
       "contact.characteristic_velocity = 1: only with normal = \"hooke\""},
      {"ramp longer than the test", with("shear", "ramp_strain = 0.05"),
       "shear.ramp_strain = 0.05: must be below shear.max_axial_strain = 0.03"},
      // Each of the following hung, ran forever or ran meaninglessly before these checks.
      {"a gradation over 9 decades", with("sample", "distribution = \"gradation\"\ngradation = [[1e-9, 0], [1, 100]]"),
       "spans too wide a range to sample"},
      {"a gradation the uniform distribution would ignore", with("sample", "gradation = [[0.005, 0], [0.004, 100]]"),
       "sample.gradation = (2 rows): given with distribution = \"uniform\""},
      {"a modulus that makes dt vanish", std::string(base).replace(base.find("young = 1.0e9"), 13, "young = 1e308"),
       "material.young = 1e+308 Pa (dt = "},
      {"a servo acting once per test", with("shear", "servo_interval = 1000000"),
       "shear.servo_interval = 1000000: the servo would act only every"},
      {"a value 100 kB long", with("material", "density = \"" + std::string(100000, 'x') + "\""),
       "material.density = \"xxx"},
      {"a skin wider than the spheres",
       std::string(base).replace(base.find("[material]"), 10, "[contact]\nskin = 1.0\n[material]"),
       "contact.skin = 1 m (wider than the largest sphere)"},
      {"both an axial rate and an inertial number", with("shear", "inertial_number = 2e-3"),
       "shear.strain_rate = 2 and shear.inertial_number = 0.002: give exactly one of the two"},
      {"a non-positive inertial number",
       std::string(base).replace(base.find("strain_rate = 2.0"), 17, "inertial_number = 0.0"),
       "shear.inertial_number = 0: must be in (0, 0.1]"},
      // Measured: at 0.3 and 0.5 t_R a preparation with friction never came to rest (protocol/config.cpp).
      {"a frictional preparation at a long step", with("prepare", "friction = 0.25\ndt_fraction = 0.5"),
       "prepare.dt_fraction = 0.5 with prepare.friction = 0.25: a frictional preparation needs prepare.dt_fraction <= 0.2"},
      {"neither an axial rate nor an inertial number",
       std::string(base).replace(base.find("strain_rate = 2.0"), 17, ""),
       "shear.strain_rate and shear.inertial_number: neither is given"},
      // Found by the reliability audit (issue 42): each was accepted, or blamed another key.
      // stop_at_critical tests critical state only after window + 0.2 of eps_q (critical.hpp).
      {"a critical window with no room before the end", with("shear", "stop_at_critical = true"),
       "shear.critical_window = 0.1 with shear.max_axial_strain = 0.03: shear.stop_at_critical"},
      {"a density that makes dt vanish", with("material", "density = 1e-300"),
       "material.density = 1e-300: must be in [1, 1e10] kg/m^3"},
      {"a strain path rate of 1e308",
       replaced(replaced(base, "strain_rate = 2.0", "strain_rates = [1e308, 0, 0]\nsteps = 100"),
                "path = \"constant_p\"", "path = \"strain\""),
       "shear.strain_rates[0] = 1e+308: must be in [-1e6, 1e6] 1/s"},
      // 1e-3 of strain a step at most (the servo update's bound); dt = 4.46e-6 s here.
      {"an axial rate beyond 1e-3 of strain a step",
       std::string(base).replace(base.find("strain_rate = 2.0"), 17, "strain_rate = 1e308"),
       "shear.strain_rate = 1e+308 1/s: allowed: at most 0.001 of strain a step"},
      // A snapshot every step: 3,368 snapshots of 300 spheres x (112 B + 4 KiB) ~ 0.12 GiB, above a
      // limit of 0.05 GiB (the default limit, 64 GiB, is checked below on the embedded default).
      {"snapshots above output.max_size_gib", with("output", "snapshot_interval = 1\nmax_size_gib = 0.05"),
       "output.snapshot_interval = 1: ~0.121 GiB of results (estimated: 1 test(s) x 3.37e+03 steps x 300 spheres); "
       "allowed: <= output.max_size_gib = 0.05 GiB: raise the interval to 34"},
      {"a size limit below what the intervals as set write", with("output", "max_size_gib = 1e-6"),
       "output.max_size_gib = 1e-06: below the ~"},
      // The shearing cell (issue 44): each key must act on some test, and the paths need theirs.
      {"a cell shear that is neither fixed nor free", base + "[cell]\nshear = \"loose\"\n",
       "cell.shear = \"loose\": allowed: \"fixed\" \"free\""},
      {"a free cell with no servo to hold it",
       replaced(replaced(base, "strain_rate = 2.0", "strain_rates = [1.0, 0, 0]\nsteps = 100"),
                "path = \"constant_p\"\nb = 0.5", "path = \"strain\"") +
           "[cell]\nshear = \"free\"\n",
       "cell.shear: no test of tests.path lets the cell's shear components be fixed or free"},
      {"a simple shear without its end", replaced(base, "path = \"constant_p\"\nb = 0.5", "path = \"simple_shear\""),
       "shear.max_shear_strain: not given; the simple shear paths need it"},
      {"a shear strain end no test reaches", with("shear", "max_shear_strain = 1.0"),
       "shear.max_shear_strain = 1: only the simple shear paths stop at a shear strain"},
      {"a deviatoric strain end on a path without an axial strain",
       replaced(with("shear", "max_shear_strain = 1.0\nmax_deviatoric_strain = 0.5"),
                "path = \"constant_p\"\nb = 0.5", "path = \"simple_shear\""),
       "shear.max_deviatoric_strain = 0.5: only the axial stress paths"},
      {"a rotation without its rate", replaced(base, "path = \"constant_p\"", "path = \"rotation\"") +
                                          "[rotation]\neta = 0.3\nramp_time = 0.01\n",
       "rotation.eta = 0.3, rotation.rate = 0, rotation.ramp_time = 0.01: tests.path = \"rotation\" needs all three"},
      {"shear rates on a path with a servo", with("shear", "shear_rates = [0, 1, 0]"),
       "shear.shear_rates: only path \"strain\" sets the cell's shear rates"},
      {"a rotation table with no rotation test", base + "[rotation]\neta = 0.3\n",
       "[rotation]: no test of tests.path is \"rotation\""},
      {"a Rayleigh fraction with the stiffness step", base + "[time]\nstep = \"stiffness\"\ndt_fraction = 0.2\n",
       "time.dt_fraction = given: acts only with time.step = \"rayleigh\""},
      {"a stiffness setting with the Rayleigh step", base + "[time]\nsafety = 0.8\n",
       "time.safety = given: acts only with time.step = \"stiffness\""},
      {"a safety factor above the stability limit", base + "[time]\nstep = \"stiffness\"\nsafety = 2.0\n",
       "time.safety = 2: must be in [0.001, 1.414]"},
      {"an unknown time step rule", base + "[time]\nstep = \"adaptive\"\n", "time.step = \"adaptive\""},
      {"a servo cap of the fixed rate alone with no fixed rate", with("shear", "max_rate_ratio = 0.0"),
       "shear.max_rate_ratio = 0 (the fixed shear.max_rate alone) without a shear.max_rate"},
      {"a negative servo cap ratio", with("shear", "max_rate_ratio = -2.0"), "shear.max_rate_ratio = -2: must be >= 0"},
  };
  for (const Case& c : cases) {
    const std::string what = c.what;
    CAPTURE(what);
    // The [time] table may be missing from the base config: add it for the dt case.
    std::string config = c.config;
    if (std::string(c.what) == "dt above the stability limit") config = base + "[time]\ndt_fraction = 1.5\n";
    write(dir / "bad.toml", config);
    const Result r = run({(dir / "bad.toml").string(), "--out", dir.string()});
    INFO(r.err);
    CHECK(r.code == 2);
    CHECK(r.err.find(c.expect) != std::string::npos);
    CHECK(std::count(r.err.begin(), r.err.end(), '\n') == 1);  // one line
    CHECK(read(dir / "index.csv") == "results of an earlier run\n");
  }
  // Every message above is one line under 300 characters, the 100 kB value cut (checked in the loop
  // for one line; here the length).
  for (const Case& c : cases) {
    write(dir / "bad.toml", c.config);
    const Result r = run({(dir / "bad.toml").string(), "--out", dir.string()});
    CHECK(r.err.size() < 300);
  }
  // Bad command line: unknown option, --threads out of range, a NaN strain, a directory as the
  // config (it ran the embedded default), an --out too long for the file system (it aborted).
  CHECK(run({"--frobnicate"}).code == 2);
  CHECK(run({"--max-axial-strain", "nan", "--out", dir.string()}).err.find("--max-axial-strain = nan") !=
        std::string::npos);
  const Result as_dir = run({dir.string(), "--out", (dir / "x").string()});
  CHECK(as_dir.code == 2);
  CHECK(as_dir.err.find("(a directory)") != std::string::npos);
  // A packing file with two coincident spheres: named, instead of "went unstable ... lower dt".
  write(dir / "packing.txt", "0.05 0.05 0.05 3\n0.01 0.01 0.01 0.003\n0.03 0.03 0.03 0.003\n0.01 0.01 0.01 0.003\n");
  write(dir / "packed.toml",
        "[sample]\nfile = \"" + (dir / "packing.txt").string() + "\"\n[shear]\nstrain_rate = 1.0\n");
  const Result coincident = run({(dir / "packed.toml").string(), "--out", (dir / "x").string()});
  CHECK(coincident.code == 2);
  CHECK(coincident.err.find("spheres 1 and 3 (in file order) overlap by 2 of the smaller radius") != std::string::npos);
  const Result long_out = run({"--out", std::string(5000, 'o')});
  CHECK(long_out.code == 2);
  CHECK(long_out.err.find("--out = ooo") != std::string::npos);
  CHECK(!fs::exists(dir / "x"));
  write(dir / "good.toml", base);
  // A setting that would have no effect: --allow-change without --resume or --task; --stop-after
  // below 1 (CLI11 read -1 into the unsigned count as 2^64 - 1, a run that never stops).
  const Result allow =
      run({(dir / "good.toml").string(), "--out", (dir / "x").string(), "--allow-change", "sample.count"});
  CHECK(allow.code == 2);
  CHECK(allow.err.find("--allow-change sample.count: has no effect without --resume or --task") != std::string::npos);
  for (const char* n : {"-1", "0"}) {
    const Result stop = run({(dir / "good.toml").string(), "--out", (dir / "x").string(), "--stop-after", n});
    CHECK(stop.code == 2);
    CHECK(stop.err.find(std::string("--stop-after: ") + n + ": allowed: an integer >= 1") != std::string::npos);
  }
  CHECK(!fs::exists(dir / "x"));
  const Result t = run({"--threads", "0"});
  CHECK(t.code == 2);
  CHECK(t.err.find("--threads") != std::string::npos);
  const Result part = run({"--thread-partition", "static"});
  CHECK(part.code == 2);
  CHECK(part.err.find("--thread-partition") != std::string::npos);
  CHECK(part.err.find("static") != std::string::npos);
  CHECK(part.err.find("adaptive") != std::string::npos);  // what is allowed
  // A valid config into a directory holding an earlier run: refused unless --resume or --overwrite.
  write(dir / "good.toml", base);
  const Result e = run({(dir / "good.toml").string(), "--out", dir.string()});
  CHECK(e.code == 2);
  CHECK(e.err.find("--resume") != std::string::npos);
  CHECK(read(dir / "index.csv") == "results of an earlier run\n");
  fs::remove_all(dir);
}

TEST_CASE("triaxial: stop and --resume (other threads, partitions) is bitwise identical to an uninterrupted run") {
  const fs::path dir = fresh_dir("resume");
  write(dir / "small.toml", k_small);
  const fs::path a = dir / "a", b = dir / "b";
  const Result whole = run({(dir / "small.toml").string(), "--out", a.string(), "--threads", "1"});
  REQUIRE(whole.code == 0);
  // The same run, stopped every 1000 steps of a job (as if killed right after a checkpoint) and
  // resumed with 2, then 3, then 2 ... threads until done, under the owner, then the dynamic, then
  // the owner ... partition (the first part under the default, adaptive). Both the preparation and
  // the shear stage are interrupted at least once (each needs more than 1000 steps: checked below).
  Result r = run({(dir / "small.toml").string(), "--out", b.string(), "--threads", "2", "--stop-after", "1000"});
  int stops = 0;
  while (r.code == 3 && stops < 100) {
    ++stops;
    r = run({(dir / "small.toml").string(), "--out", b.string(), "--resume", "--threads", stops % 2 ? "3" : "2",
             "--thread-partition", stops % 2 ? "owner" : "dynamic", "--stop-after", "1000"});
  }
  REQUIRE(r.code == 0);
  const std::string test = "p-b0.50-p0_100kPa";
  CheckpointExtra xa, xb;
  const State sa = read_checkpoint(a / (test + ".checkpoint.h5"), &xa);
  const State sb = read_checkpoint(b / (test + ".checkpoint.h5"), &xb);
  const State pa = read_checkpoint(a / "sample-p0_100kPa.h5");
  MESSAGE("preparation steps ", pa.clock.step, ", shear steps ", sa.clock.step, ", stops ", stops);
  CHECK(pa.clock.step > 1000);
  CHECK(sa.clock.step > 1000);
  CHECK(stops >= 2);
  CHECK(first_difference(sa.particles, sb.particles) == "");
  CHECK(first_difference(sa.contacts, sb.contacts) == "");
  CHECK(sa.cell.length == sb.cell.length);
  CHECK(sa.cell.rate == sb.cell.rate);
  // The worst accuracy indicators cover the whole test, not the part after the last resume.
  CHECK(xa.doubles["watch_worst"] == xb.doubles["watch_worst"]);
  const auto worst_line = [](const std::string& log) { return log.substr(log.rfind("; max I")); };
  CHECK(worst_line(whole.out).substr(0, 60) == worst_line(r.out).substr(0, 60));
  // samples.csv: the resumed run found its sample prepared and reports the same end state, read
  // back from the sample file, as the run that prepared it.
  const auto sample_row = [](const fs::path& csv) {
    std::istringstream in(read(csv));
    std::string header, row;
    std::getline(in, header);
    std::getline(in, row);
    std::vector<std::string> fields;
    std::istringstream cells(row);
    for (std::string cell; std::getline(cells, cell, ',');) fields.push_back(cell);
    return fields;
  };
  const std::vector<std::string> ra = sample_row(a / "samples.csv"), rb = sample_row(b / "samples.csv");
  REQUIRE(ra.size() == 12);
  REQUIRE(rb.size() == 12);
  CHECK(ra[0] == "sample-p0_100kPa");
  CHECK(ra[3] == "done");
  CHECK(rb[3] == "done (earlier run)");
  for (int f : {0, 1, 2, 4, 5, 6, 7, 8, 9}) {  // all but the status and the wall time
    CAPTURE(f);
    CHECK(ra[f] == rb[f]);
  }
  CHECK(ra[9] == std::to_string(pa.clock.step));
  CHECK(std::stod(ra[4]) == doctest::Approx(1e5).epsilon(0.01));  // the preparation's criterion: 1 %
  CHECK(sa.clock.step == sb.clock.step);
  CHECK(first_difference(pa.particles, read_checkpoint(b / "sample-p0_100kPa.h5").particles) == "");
  // The results series too (wall time aside), row for row.
  for (const char* name : {"/series/step", "/series/stress", "/series/e", "/series/Z", "/series/strain"}) {
    CAPTURE(name);
    CHECK(dataset(a / (test + ".h5"), name) == dataset(b / (test + ".h5"), name));
    CHECK(dataset(a / "prepare-p0_100kPa.h5", name) == dataset(b / "prepare-p0_100kPa.h5", name));
  }
  fs::remove_all(dir);
}

TEST_CASE("triaxial: the embedded default runs end to end and writes the documented datasets") {
  // The default (2000 spheres, 0.5 MPa, constant p, b = 0.5), shortened to 1.5 % axial strain.
  const fs::path dir = fresh_dir("default");
  const Result r = run({"--out", dir.string(), "--max-axial-strain", "0.015"});
  INFO(r.out, r.err);
  REQUIRE(r.code == 0);
  // The default stays inside every validated range: no accuracy warning (the inertial number
  // peaked at 1.8e-3 in the (eps_dot_1 - eps_dot_3) form in the first 1.5 % and warned before).
  CHECK(r.out.find("warning") == std::string::npos);
  CHECK(r.err.find("warning") == std::string::npos);
  const fs::path results = dir / "p-b0.50-p0_500kPa.h5";
  for (const char* name : {"time",
                           "step",
                           "strain",
                           "stress",
                           "principal_stress",
                           "p",
                           "q",
                           "eta",
                           "b",
                           "theta",
                           "eps_v",
                           "eps_q",
                           "e",
                           "Z",
                           "Z_mech",
                           "fabric",
                           "kinetic_energy",
                           "elastic_energy",
                           "max_overlap_ratio",
                           "unbalanced_force_ratio",
                           "inertial_number",
                           "wall_time"}) {
    CAPTURE(name);
    CHECK(has_link(results, std::string("/series/") + name));
  }
  CHECK(has_link(results, "/snapshots"));
  CHECK(fs::exists(dir / "p-b0.50-p0_500kPa.xdmf"));
  CHECK(fs::exists(dir / "sample-p0_500kPa.h5"));
  CHECK(read(dir / "index.csv").find("p-b0.50-p0_500kPa,constant_p,0.5,500000") != std::string::npos);
  // Physics sanity of what was written: the prepared sample is at p0 (tolerance 1 % per axis, the
  // preparation's criterion), and p stays within 2 % of its target after the first 1 % of axial
  // strain (the servo's criterion).
  const std::vector<double> p = dataset(results, "/series/p");
  const std::vector<double> strain = dataset(results, "/series/strain");  // (rows, 3)
  CHECK(p.front() == doctest::Approx(0.5e6).epsilon(0.01));
  int checked = 0;
  for (std::size_t k = 0; k < p.size(); ++k)
    if (strain[3 * k] >= 0.01) {
      CHECK(p[k] == doctest::Approx(0.5e6).epsilon(0.02));
      ++checked;
    }
  CHECK(checked >= 3);
  // The run record names the servo's cap: 20 x the axial rate by default (protocol.cpp
  // k_max_rate_ratio), and its floor, 20 x the rate at p0 (the default config's 1 /s).
  {
    const std::string settings = h5::File::open(results, h5::File::Mode::read).root().get_string("settings");
    INFO(settings);
    CHECK(settings.find("servo.max_rate_ratio = 20\n") != std::string::npos);
    CHECK(settings.find("servo.max_rate = 20\n") != std::string::npos);
  }

  // triaxial verify: the file re-runs bitwise from its run record (its sample, its config text and
  // the --max-axial-strain it was run with), on another thread count.
  const Result v = run({"verify", results.string(), "--threads", "2"});
  INFO(v.out, v.err);
  CHECK(v.code == 0);
  CHECK(v.out.find("verified: rows 0..") != std::string::npos);
  // A copy with one snapshot value moved by one ulp: the snapshot named, exit 1. Rows up to that
  // snapshot's only (the re-run stops there).
  const fs::path copy = fresh_dir("default_tampered");
  for (const char* f : {"p-b0.50-p0_500kPa.h5", "sample-p0_500kPa.h5"}) fs::copy_file(dir / f, copy / f);
  const fs::path tampered = copy / "p-b0.50-p0_500kPa.h5";
  std::string snapshot;
  std::size_t snapshot_row = 0;
  {
    const std::vector<double> steps = dataset(tampered, "/series/step");
    // The second snapshot (the first is the initial state): its step's row.
    const std::vector<std::string> names =
        h5::File::open(tampered, h5::File::Mode::read).root().open_group("snapshots").children();
    const hid_t file = H5Fopen(tampered.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
    REQUIRE(file >= 0);
    REQUIRE(names.size() >= 2);
    snapshot = names[1];
    const double step = std::stod(snapshot);
    while (snapshot_row < steps.size() && steps[snapshot_row] < step) ++snapshot_row;
    REQUIRE(snapshot_row < steps.size());
    const hid_t set = H5Dopen2(file, ("/snapshots/" + snapshot + "/position").c_str(), H5P_DEFAULT);
    const hid_t space = H5Dget_space(set);
    std::vector<double> x(static_cast<std::size_t>(H5Sget_simple_extent_npoints(space)));
    H5Sclose(space);
    H5Dread(set, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, x.data());
    x[7] = std::nextafter(x[7], 1.0);
    H5Dwrite(set, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, x.data());
    H5Dclose(set);
    H5Fclose(file);
  }
  const Result t = run({"verify", tampered.string(), "--rows", "0.." + std::to_string(snapshot_row)});
  INFO(t.out, t.err);
  CHECK(t.code == 1);
  CHECK(t.out.find("differs: the snapshot at step " + std::to_string(std::stoull(snapshot)) + ": position") !=
        std::string::npos);
  // A config key edited in the file (the material's friction): the first row after the start differs.
  {
    h5::File file = h5::File::open(tampered, h5::File::Mode::read_write);
    std::string text = file.root().get_string("config");
    file.root().set_string("config", text.replace(text.find("friction = 0.5"), 14, "friction = 0.45"));
  }
  const Result c = run({"verify", tampered.string(), "--rows", "0..3"});
  INFO(c.out, c.err);
  CHECK(c.code == 1);
  CHECK(c.out.find("differs: row 1 ") != std::string::npos);
  // A file from before the run record (no sample attributes, no state digest): its sample is found by
  // its p0 and the series and snapshots are compared; it verifies, saying so.
  fs::copy_file(results, tampered, fs::copy_options::overwrite_existing);
  {
    h5::File file = h5::File::open(tampered, h5::File::Mode::read_write);
    file.root().remove_attribute("sample_file");
    file.root().remove_attribute("sample_digest");
    file.root().open_group("series").remove("state_digest");
  }
  const Result o = run({"verify", tampered.string(), "--rows", "0..3"});
  INFO(o.out, o.err);
  CHECK(o.code == 0);
  CHECK(o.out.find("note: no run record") != std::string::npos);
  CHECK(o.out.find("verified: rows 0..3") != std::string::npos);
  // A column a later build added when it resumed the file has NaN in its leading rows (ResultsFile::
  // reopen pads it): those rows are skipped, the rest compared bitwise. A NaN after a written row
  // is no padding: it differs (a check that could not fail if verify skipped every NaN cell).
  const auto set_nan = [&](const std::string& series, std::initializer_list<std::size_t> rows_nan) {
    std::vector<double> v = dataset(tampered, "/series/" + series);
    for (std::size_t r : rows_nan) v.at(r) = std::numeric_limits<double>::quiet_NaN();
    const hid_t file = H5Fopen(tampered.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
    REQUIRE(file >= 0);
    const hid_t set = H5Dopen2(file, ("/series/" + series).c_str(), H5P_DEFAULT);
    REQUIRE(set >= 0);
    H5Dwrite(set, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data());
    H5Dclose(set);
    H5Fclose(file);
  };
  set_nan("kinetic_energy", {0, 1});
  const Result pad = run({"verify", tampered.string(), "--rows", "0..3"});
  INFO(pad.out, pad.err);
  CHECK(pad.code == 0);
  CHECK(pad.out.find("verified: rows 0..3") != std::string::npos);
  set_nan("kinetic_energy", {3});
  const Result hole = run({"verify", tampered.string(), "--rows", "0..3"});
  INFO(hole.out, hole.err);
  CHECK(hole.code == 1);
  CHECK(hole.out.find("differs: row 3 ") != std::string::npos);
  CHECK(hole.out.find("kinetic_energy = nan (file)") != std::string::npos);
  fs::remove_all(copy);
  fs::remove_all(dir);
}

TEST_CASE("triaxial: shear.ramp_strain raises the axial rate linearly: eps1 = rate t^2 / 2T, then rate (t - T/2)") {
  // ramp_strain 0.01 at rate 2 /s: T = 2 x 0.01 / 2 = 0.01 s. The servo sets the rate at the end
  // of a step, from the clock time then, for the next step: the strain is a sum over steps that
  // lags the integral by 1.5 steps, a relative error of -3 / n after n steps during the ramp (as
  // measured) and less after it. Bound: 4 / n (n >= 100 at the first row, so 4 % at most).
  const fs::path dir = fresh_dir("ramp");
  std::string config = k_small;
  config.insert(config.find("strain_rate = 2.0"), "ramp_strain = 0.01\n");
  write(dir / "ramp.toml", config);
  const Result r = run({(dir / "ramp.toml").string(), "--out", dir.string()});
  INFO(r.out, r.err);
  REQUIRE(r.code == 0);
  const fs::path results = dir / "p-b0.50-p0_100kPa.h5";
  const std::vector<double> time = dataset(results, "/series/time");
  const std::vector<double> step = dataset(results, "/series/step");
  const std::vector<double> strain = dataset(results, "/series/strain");  // (rows, 3), logarithmic
  const double rate = 2.0, ramp = 0.01;
  int during = 0, after = 0;
  for (std::size_t k = 1; k < time.size(); ++k) {
    const double t = time[k], eps1 = strain[3 * k];
    const double expected = t < ramp ? rate * t * t / (2.0 * ramp) : rate * (t - ramp / 2.0);
    CAPTURE(t);
    CHECK(std::abs(eps1 - expected) <= 4.0 / step[k] * expected);
    (t < ramp ? during : after) += 1;
  }
  CHECK(during >= 3);
  CHECK(after >= 3);
  fs::remove_all(dir);
}

TEST_CASE("triaxial: shear.max_deviatoric_strain ends a test at the first step whose eps_q reaches it") {
  // b = 0.5 at constant p: eps_q ~ 1.15 eps1, so eps_q = 0.015 comes at eps1 ~ 0.013, before
  // max_axial_strain = 0.03. The end is tested every step: the last row is at most one step's
  // increment of eps_q past the end (bound 1.5 increments: the rate varies by far less than 50 %
  // between the last two rows), and the row before it is below the end.
  const fs::path dir = fresh_dir("eps_q_end");
  std::string config = k_small;
  config.insert(config.find("max_axial_strain"), "max_deviatoric_strain = 0.015\n");
  write(dir / "end.toml", config);
  const Result r = run({(dir / "end.toml").string(), "--out", dir.string()});
  INFO(r.out, r.err);
  REQUIRE(r.code == 0);
  const fs::path results = dir / "p-b0.50-p0_100kPa.h5";
  const std::vector<double> eps_q = dataset(results, "/series/eps_q");
  const std::vector<double> step = dataset(results, "/series/step");
  const std::vector<double> strain = dataset(results, "/series/strain");
  const std::size_t n = eps_q.size();
  REQUIRE(n >= 3);
  const double per_step = (eps_q[n - 1] - eps_q[n - 2]) / (step[n - 1] - step[n - 2]);
  CHECK(eps_q[n - 1] >= 0.015);
  CHECK(eps_q[n - 2] < 0.015);
  CHECK(eps_q[n - 1] - 0.015 <= 1.5 * per_step);
  CHECK(strain[3 * (n - 1)] < 0.03);  // it was eps_q that ended the test
  fs::remove_all(dir);
}

TEST_CASE(
    "triaxial: --resume with a larger end continues a finished test into the file an uninterrupted run writes") {
  // A test run to eps_q = 0.012, then resumed with the end at 0.02 (stopped once on the way, as if
  // killed), against one run straight to 0.02: every series column but the wall time and every
  // snapshot bitwise the same, so the continued file is what the longer run would have written,
  // and `triaxial verify` re-runs it from its sample. The first end's row and snapshot fall off
  // their intervals (checked), so they are the ones the continuation must drop.
  const fs::path dir = fresh_dir("extend");
  std::string base = k_small;
  base.insert(base.find("plot = false"), "snapshot_interval = 300\n");
  std::string short_run = base, long_run = base;
  short_run.insert(short_run.find("max_axial_strain"), "max_deviatoric_strain = 0.012\n");
  long_run.insert(long_run.find("max_axial_strain"), "max_deviatoric_strain = 0.02\n");
  write(dir / "short.toml", short_run);
  write(dir / "long.toml", long_run);
  const fs::path a = dir / "a", b = dir / "b";
  const std::string test = "p-b0.50-p0_100kPa";
  const Result whole = run({(dir / "long.toml").string(), "--out", a.string(), "--threads", "2"});
  REQUIRE(whole.code == 0);
  const Result first = run({(dir / "short.toml").string(), "--out", b.string(), "--threads", "1"});
  INFO(first.out, first.err);
  REQUIRE(first.code == 0);
  const std::vector<double> short_steps = dataset(b / (test + ".h5"), "/series/step");
  const auto end_step = static_cast<std::uint64_t>(short_steps.back());
  REQUIRE(end_step % 100 != 0);  // the first end's row and snapshot are off their intervals
  REQUIRE(end_step % 300 != 0);
  CHECK(string_attribute(b / (test + ".h5"), "status") == "done");
  // Continued, stopped 200 steps on (exit 3), resumed: an extension is resumed as any running test.
  const Result stopped =
      run({(dir / "long.toml").string(), "--out", b.string(), "--resume", "--threads", "3", "--stop-after", "200"});
  INFO(stopped.out, stopped.err);
  REQUIRE(stopped.code == 3);
  CHECK(stopped.out.find(test + ": complete at step " + std::to_string(end_step)) != std::string::npos);
  CHECK(string_attribute(b / (test + ".h5"), "status") == "");  // no verdict while it runs: "unfinished"
  const Result rest = run({(dir / "long.toml").string(), "--out", b.string(), "--resume", "--threads", "2"});
  INFO(rest.out, rest.err);
  REQUIRE(rest.code == 0);
  const fs::path fa = a / (test + ".h5"), fb = b / (test + ".h5");
  CHECK(string_attribute(fb, "status") == "done");
  CHECK(string_attribute(fb, "extended").find("from step " + std::to_string(end_step)) != std::string::npos);
  CHECK(string_attribute(fb, "config") == long_run);
  const auto children = [](const fs::path& file, const char* group) {
    return h5::File::open(file, h5::File::Mode::read).root().open_group(group).children();
  };
  const std::vector<std::string> columns = children(fa, "series");
  CHECK(columns == children(fb, "series"));
  CHECK(dataset(fa, "/series/step").size() > short_steps.size());
  for (const std::string& name : columns) {
    if (name == "wall_time") continue;
    CAPTURE(name);
    CHECK(dataset(fa, "/series/" + name) == dataset(fb, "/series/" + name));
  }
  const std::vector<std::string> snapshots = children(fa, "snapshots");
  CHECK(snapshots == children(fb, "snapshots"));
  for (const std::string& g : snapshots)
    for (const char* name : {"position", "velocity", "angular_velocity", "force"}) {
      CAPTURE(g);
      CAPTURE(name);
      CHECK(dataset(fa, "/snapshots/" + g + "/" + name) == dataset(fb, "/snapshots/" + g + "/" + name));
    }
  const Result v = run({"verify", fb.string()});
  INFO(v.out, v.err);
  CHECK(v.code == 0);
  CHECK(v.out.find("verified: rows 0..") != std::string::npos);
  // Resumed again at the same end: nothing to do, the test is the earlier run's.
  const Result again = run({(dir / "long.toml").string(), "--out", b.string(), "--resume"});
  CHECK(again.code == 0);
  CHECK(again.out.find("continued") == std::string::npos);
  CHECK(read(b / "index.csv").find(",done (earlier run),") != std::string::npos);
  fs::remove_all(dir);
}

TEST_CASE("triaxial: shear.inertial_number holds eps_dot_1 d50 sqrt(rho/p) at its target as p changes") {
  // Constant p and constant sigma3 (where p grows by ~20 % over 3 % strain, so a fixed axial rate
  // would let I drift by ~10 %), with the rate ramped over 0.5 % strain. The servo sets the axial
  // rate from the stress it measured in the step before; p moves by far less than 1 % per step, so
  // a 10 % bound is loose against a law that holds. Also the series' axial rate must be
  // I sqrt(p/rho) / d50 with the d50 of the sample: the same law, read independently.
  const fs::path dir = fresh_dir("inertial");
  std::string config = k_small;
  config.replace(config.find("strain_rate = 2.0"), 17, "inertial_number = 2e-3\nramp_strain = 0.005");
  config.replace(config.find("path = \"constant_p\""), 19, "path = [\"constant_p\", \"constant_sigma3\"]");
  write(dir / "inertial.toml", config);
  const Result r = run({(dir / "inertial.toml").string(), "--out", dir.string()});
  INFO(r.out, r.err);
  REQUIRE(r.code == 0);
  const double target = 2e-3;
  for (const char* name : {"p-b0.50-p0_100kPa.h5", "s3-b0.50-p0_100kPa.h5"}) {
    CAPTURE(name);
    const std::vector<double> inertial = dataset(dir / name, "/series/inertial_number_axial");
    const std::vector<double> strain = dataset(dir / name, "/series/strain");  // (rows, 3)
    const std::vector<double> p = dataset(dir / name, "/series/p");
    int after = 0;
    double p_min = p.front(), p_max = p.front();
    for (std::size_t k = 0; k < inertial.size(); ++k) {
      if (strain[3 * k] < 0.005) continue;  // the ramp
      CAPTURE(strain[3 * k]);
      CHECK(std::abs(inertial[k] - target) <= 0.1 * target);
      p_min = std::min(p_min, p[k]);
      p_max = std::max(p_max, p[k]);
      ++after;
    }
    CHECK(after >= 10);
    if (std::string(name).starts_with("s3")) CHECK(p_max / p_min > 1.1);  // the law was exercised
  }
  fs::remove_all(dir);
}

TEST_CASE("triaxial: prepare.chain compresses the lower p0's sample on to the next p0") {
  // Two p0; the 0.2 MPa sample continues the 0.1 MPa one: its preparation starts at p ~ 0.1 MPa
  // (within the 1 % criterion the lower sample met), ends at 0.2 MPa (1 % per axis) and is denser
  // (the same skeleton under twice the pressure compresses: e falls). samples.csv says so.
  const fs::path dir = fresh_dir("chain");
  std::string config = k_small;
  config.replace(config.find("p0 = 0.1e6"), 10, "p0 = [0.2e6, 0.1e6]");
  config.insert(config.find("[prepare]\n") + 10, "chain = true\n");
  config.replace(config.find("max_axial_strain = 0.03"), 23, "max_axial_strain = 0.002");
  write(dir / "chain.toml", config);
  const Result r = run({(dir / "chain.toml").string(), "--out", dir.string()});
  INFO(r.out, r.err);
  REQUIRE(r.code == 0);
  const std::vector<double> p = dataset(dir / "prepare-p0_200kPa.h5", "/series/p");
  CHECK(p.front() == doctest::Approx(0.1e6).epsilon(0.01));
  const std::vector<double> e_low = dataset(dir / "prepare-p0_100kPa.h5", "/series/e");
  const std::vector<double> e_high = dataset(dir / "prepare-p0_200kPa.h5", "/series/e");
  // The lower preparation's last row is at most series_interval steps before its converged end.
  CHECK(e_high.front() == doctest::Approx(e_low.back()).epsilon(1e-3));
  CHECK(e_high.back() < e_low.back());
  const std::string samples = read(dir / "samples.csv");
  CHECK(samples.find("sample-p0_100kPa,100000,sample-p0_100kPa.h5,done") != std::string::npos);
  CHECK(samples.find(",cloud\n") != std::string::npos);
  CHECK(samples.find(",sample-p0_100kPa\n") != std::string::npos);
  const State sample = read_checkpoint(dir / "sample-p0_200kPa.h5");
  CHECK(sample.particles.size() == 300);
  fs::remove_all(dir);
}

TEST_CASE("triaxial: the default thread count is the CPUs of the affinity mask (taskset -c 0: 1 thread)") {
  std::optional<test::OneCpu> one(std::in_place);
  REQUIRE(one->ok());
  const fs::path dir = fresh_dir("affinity");
  std::string config = k_small;
  config.replace(config.find("max_axial_strain = 0.03"), 23, "max_axial_strain = 0.001");
  write(dir / "one.toml", config);
  const Result r = run({(dir / "one.toml").string(), "--out", (dir / "a").string()});
  const Result over = run({(dir / "one.toml").string(), "--out", (dir / "b").string(), "--threads", "2"});
  one.reset();  // the whole mask again
  INFO(r.out, r.err);
  REQUIRE(r.code == 0);
  CHECK(r.out.find("1 at once x 1 thread(s)") != std::string::npos);
  CHECK(r.out.find("warning") == std::string::npos);
  // More threads than the mask allows: run, with a warning naming both counts.
  CHECK(over.code == 0);
  CHECK(over.out.find("warning: --threads 2 > the 1 CPUs this process may use") != std::string::npos);
  fs::remove_all(dir);
}

TEST_CASE(
    "triaxial: a stop signal sets the stop request; a second one within 1 s is the same request, a later one exits at once") {
  // In a child process, so the test runner keeps its own handlers.
  const pid_t pid = ::fork();
  REQUIRE(pid >= 0);
  if (pid == 0) {
    triaxial::clear_stop_request();
    triaxial::install_stop_handlers();
    ::raise(SIGUSR1);  // the first: a request, the process goes on
    if (!triaxial::stop_requested() || triaxial::stop_signal() != SIGUSR1) ::_exit(10);
    ::raise(SIGTERM);  // the same request delivered twice (a batch script passing it on)
    if (triaxial::stop_signal() != SIGUSR1) ::_exit(12);
    ::usleep(1'100'000);
    ::raise(SIGTERM);  // a second request: out at once
    ::_exit(11);       // not reached when the handler works
  }
  int status = 0;
  REQUIRE(::waitpid(pid, &status, 0) == pid);
  REQUIRE(WIFEXITED(status));
  CHECK(WEXITSTATUS(status) == 128 + SIGTERM);
}

TEST_CASE("triaxial: --list, --task and the cluster subcommand: bad input exits 2 with one line, clobbering nothing") {
  const fs::path dir = fresh_dir("tasks");
  std::string campaign = k_small;
  campaign.replace(campaign.find("b = 0.5"), 7, "b = [0.5, 1.0]");
  write(dir / "campaign.toml", campaign);
  write(dir / "single.toml", k_small);
  const std::string c = (dir / "campaign.toml").string(), out = (dir / "out").string();
  // --list: preparations, then tests, with stable indices; nothing written.
  const Result list = run({c, "--list", "--out", out});
  CHECK(list.code == 0);
  CHECK(list.out == "0 prepare prepare-p0_100kPa\n1 test p-b0.50-p0_100kPa\n2 test p-b1.00-p0_100kPa\n");
  CHECK(!fs::exists(out));
  fs::create_directories(out);
  write(dir / "out" / "index.csv", "results of an earlier run\n");
  struct Case {
    std::vector<std::string> args;
    const char* expect;
  };
  const std::string single = (dir / "single.toml").string();
  const Case cases[] = {
      {{c, "--out", out, "--task", "3"}, "--task = 3: out of range (the campaign has 3 tasks)"},
      {{c, "--out", out, "--task", "1-x"}, "--task = 1-x: not an index or range"},
      {{c, "--out", out, "--task", "2-1"}, "--task = 2-1: not an index or range"},
      {{single, "--out", out, "--task", "0"}, "has one test, not a campaign"},
      {{"slurm", single, "--out", out}, "has one test, not a campaign"},
      {{"slurm", c, "--out", out, "--time", "90"}, "--time = 90: allowed: HH:MM:SS or D-HH:MM:SS"},
      {{"slurm", c, "--out", out, "--thread-partition", "static"},
       "--thread-partition: static not in {owner,dynamic,fixed,adaptive}"},
  };
  for (const Case& k : cases) {
    const Result r = run(k.args);
    INFO(r.err);
    CHECK(r.code == 2);
    CHECK(r.err.find(k.expect) != std::string::npos);
    CHECK(std::count(r.err.begin(), r.err.end(), '\n') == 1);
    CHECK(read(dir / "out" / "index.csv") == "results of an earlier run\n");
  }
  // --submit without sbatch on PATH.
  const char* path_env = std::getenv("PATH");
  const std::string saved = path_env ? path_env : "";
  ::setenv("PATH", "/nonexistent", 1);
  const Result no_sbatch = run({"slurm", c, "--out", (dir / "cluster").string(), "--submit"});
  ::setenv("PATH", saved.c_str(), 1);
  CHECK(no_sbatch.code == 2);
  CHECK(no_sbatch.err.find("--submit: sbatch is not on PATH") != std::string::npos);
  CHECK(!fs::exists(dir / "cluster"));
  // A directory held by a live run (its lock taken here as another run would hold it): refused,
  // for --resume and --overwrite alike, and nothing is deleted.
  {
    triaxial::FileLock live;
    REQUIRE(live.try_lock(dir / "out" / ".sandcell.lock", triaxial::FileLock::Mode::exclusive));
    for (const char* mode : {"--resume", "--overwrite"}) {
      const Result r = run({c, "--out", out, mode});
      INFO(r.err);
      CHECK(r.code == 2);
      CHECK(r.err.find("in use by a live run (PID " + std::to_string(::getpid())) != std::string::npos);
      CHECK(read(dir / "out" / "index.csv") == "results of an earlier run\n");
    }
  }
  // Without --submit the scripts are written for a person to read: the test array's size and
  // its task offset, the chained or arrayed preparation, the dependencies.
  const Result scripts = run(
      {"slurm", c, "--out", (dir / "cluster").string(), "--max-running", "4", "--thread-partition", "owner"});
  INFO(scripts.err);
  REQUIRE(scripts.code == 0);
  const std::string tests = read(dir / "cluster" / "slurm" / "tests.sbatch");
  CHECK(tests.find("#SBATCH --array=0-1%4") != std::string::npos);
  CHECK(tests.find("--resume --thread-partition owner --task \"$((1 + SLURM_ARRAY_TASK_ID))\"") != std::string::npos);
  CHECK(read(dir / "cluster" / "slurm" / "prepare.sbatch").find("#SBATCH --array=0-0%4") != std::string::npos);
  CHECK(read(dir / "cluster" / "slurm" / "submit.sh").find("--dependency=afterok:") != std::string::npos);
  // the analysis runs after every test has ended, also when one left its stress path (exit 1)
  CHECK(read(dir / "cluster" / "slurm" / "submit.sh").find("--dependency=afterany:${tests") != std::string::npos);
  CHECK(read(dir / "cluster" / "campaign.toml") == campaign);
  fs::remove_all(dir);
}

TEST_CASE("triaxial: a full disk is exit 1 naming the file, with no crash and no empty index") {
  // --out on a 2 MiB tmpfs (root only): before, a segmentation fault inside HDF5's close on the
  // error path, an unreadable results file and 0-byte index.csv/samples.csv.
  const fs::path dir = fresh_dir("full");
  const fs::path mnt = dir / "tmpfs";
  fs::create_directories(mnt);
  if (::geteuid() != 0 ||
      std::system(("mount -t tmpfs -o size=2m tmpfs '" + mnt.string() + "' 2>/dev/null").c_str()) != 0) {
    MESSAGE(
        "not root (or no tmpfs): the full-disk run is not exercised (tests/engine/test_io.cpp injects write failures)");
    return;
  }
  write(dir / "small.toml", k_small);
  const Result r = run({(dir / "small.toml").string(), "--out", (mnt / "out").string()});
  const std::string index = read(mnt / "out" / "index.csv");
  std::system(("umount '" + mnt.string() + "'").c_str());
  INFO(r.out, r.err);
  CHECK(r.code == 1);
  CHECK(r.out.find("disk full") != std::string::npos);
  CHECK(r.out.find((mnt / "out").string()) != std::string::npos);
  CHECK(index.find("prepare") == std::string::npos);  // the index: a header and the test's row
  CHECK(index.find("p-b0.50-p0_100kPa") != std::string::npos);
  fs::remove_all(dir);
}

TEST_CASE("triaxial: contact.normal = \"hooke\" runs the linear spring-dashpot law end to end") {
  // The config selects the law (systems/laws/hooke.hpp, tested against its analytic collision and
  // LIGGGHTS in test_hooke.cpp); here: the app passes it and its parameter to the engine (which
  // refuses hooke without the parameter, so a run that completes had it) and runs a test to the end.
  const fs::path dir = fresh_dir("hooke");
  write(dir / "hooke.toml", k_small + "[contact]\nnormal = \"hooke\"\ncharacteristic_velocity = 0.5\n");
  const Result r = run({(dir / "hooke.toml").string(), "--out", (dir / "out").string()});
  REQUIRE(r.code == 0);
  const std::string index = read(dir / "out" / "index.csv");
  CHECK(index.find(",done,") != std::string::npos);
  CHECK(index.find(",failed") == std::string::npos);
}

TEST_CASE("triaxial: --resume with a config whose physics changed is refused, listing the keys") {
  // Before: friction 0.5 -> 0.9 resumed silently, one test computed with both frictions while its
  // file said 0.5.
  const fs::path dir = fresh_dir("changed");
  std::string config = k_small;
  config.replace(config.find("max_axial_strain = 0.03"), 23, "max_axial_strain = 0.002");
  write(dir / "run.toml", config);
  const std::string out = (dir / "out").string();
  REQUIRE(run({(dir / "run.toml").string(), "--out", out, "--stop-after", "200"}).code == 3);
  const std::string index = read(dir / "out" / "index.csv");
  std::string changed = config;
  changed.replace(changed.find("young = 1.0e9"), 13, "young = 1.0e9\nfriction = 0.9");
  changed.replace(changed.find("count = 300"), 11, "count = 400");
  write(dir / "changed.toml", changed);
  const Result r = run({(dir / "changed.toml").string(), "--out", out, "--resume"});
  CHECK(r.code == 2);
  CHECK(r.err.find("in material.friction, sample.count;") != std::string::npos);
  CHECK(std::count(r.err.begin(), r.err.end(), '\n') == 1);
  CHECK(read(dir / "out" / "index.csv") == index);  // nothing ran
  // --allow-change for the keys meant; a safe key (output.*) needs nothing.
  const Result allowed = run({(dir / "changed.toml").string(), "--out", out, "--resume", "--stop-after", "1",
                              "--allow-change", "material.friction", "sample.count"});
  CHECK(allowed.code == 3);
  std::string safe = changed;
  safe.replace(safe.find("series_interval = 100"), 21, "series_interval = 50");
  write(dir / "safe.toml", safe);
  const Result ok = run({(dir / "safe.toml").string(), "--out", out, "--resume"});
  INFO(ok.err);
  CHECK(ok.code == 0);
  fs::remove_all(dir);
}

TEST_CASE(
    "triaxial: the results' size is estimated before the run: refused above output.max_size_gib, warned above 1 GiB") {
  const fs::path dir = fresh_dir("output_size");
  // The embedded default (2,000 spheres to 20 % at dt = 5.3e-7 s: 3.75e5 steps) with a snapshot
  // every step: ~80 GiB, above the default limit of 64 GiB. Refused, nothing written.
  std::string every = triaxial::k_default_config;
  every.replace(every.find("series_interval = 1000"), 22, "series_interval = 1000\nsnapshot_interval = 1");
  write(dir / "every.toml", every);
  const Result r = run({(dir / "every.toml").string(), "--out", (dir / "out").string()});
  INFO(r.err);
  CHECK(r.code == 2);
  CHECK(r.err.find(
            "output.snapshot_interval = 1: ~79.8 GiB of results (estimated: 1 test(s) x 3.75e+05 steps x 2000 "
            "spheres); allowed: <= output.max_size_gib = 64 GiB: raise the interval to 3755 (~100 snapshots a test) or "
            "the limit") != std::string::npos);
  CHECK(!fs::exists(dir / "out"));
  // The audit's case, 200 spheres to 3 % with a snapshot every step (1.4 GB written): under the
  // limit, so it runs, with a warning; the default config stays quiet.
  write(
      dir / "audit.toml",
      "[sample]\ncount = 200\n[shear]\nstrain_rate = 1.0\nmax_axial_strain = 0.03\n[output]\nsnapshot_interval = 1\n");
  const Result audit = run({(dir / "audit.toml").string(), "--check"});
  CHECK(audit.code == 0);
  CHECK(audit.out.find("warning: output: ~1.39 GiB of results (estimated: 1 test(s) x 5.63e+04 steps x 200 spheres, "
                       "output.snapshot_interval = 1), above 1 GiB") != std::string::npos);
  const Result quiet = run({"--check"});
  CHECK(quiet.code == 0);
  CHECK(quiet.out.find("warning") == std::string::npos);
  // The estimate against the files a run writes (the test's and the preparation's results and
  // XDMF), with a snapshot every 10 steps: 337 snapshots of 300 spheres. It rounds each snapshot's
  // headers up to 4 KiB (measured 3.8) and a file's start up to 1 MiB (measured 0.95): above by
  // 5 % here, by at most 15 % (the files of a run with no interval snapshots).
  std::string snapshots = k_small;
  snapshots.replace(snapshots.find("series_interval = 100"), 21, "series_interval = 100\nsnapshot_interval = 10");
  write(dir / "snapshots.toml", snapshots);
  const Result check = run({(dir / "snapshots.toml").string(), "--check"});
  REQUIRE(check.code == 0);
  const std::size_t at = check.out.find("results ~");
  REQUIRE(at != std::string::npos);
  const double estimate = std::stod(check.out.substr(at + 9)) * double(1 << 30);
  REQUIRE(run({(dir / "snapshots.toml").string(), "--out", (dir / "run").string()}).code == 0);
  double written = 0.0;
  for (const char* f :
       {"p-b0.50-p0_100kPa.h5", "p-b0.50-p0_100kPa.xdmf", "prepare-p0_100kPa.h5", "prepare-p0_100kPa.xdmf"})
    written += double(fs::file_size(dir / "run" / f));
  MESSAGE("estimated ", estimate, " B, written ", written, " B");
  CHECK(estimate >= written);
  CHECK(estimate <= 1.15 * written);
  fs::remove_all(dir);
}

TEST_CASE(
    "triaxial: --resume or --task refuses a sample prepared with other sample keys, naming the key and both values") {
  // Before: a directory holding only a copied sample (as `triaxial study` makes them) was resumed
  // with sample.count changed; the old sample was sheared and the new count recorded.
  const fs::path dir = fresh_dir("sample_keys");
  write(dir / "run.toml", k_small);
  REQUIRE(run({(dir / "run.toml").string(), "--out", (dir / "a").string(), "--prepare-only"}).code == 0);
  const std::string sample = "sample-p0_100kPa.h5";
  const std::string prepared = read(dir / "a" / sample);
  const auto copied = [&](const std::string& name) {
    fs::create_directories(dir / name);
    fs::copy_file(dir / "a" / sample, dir / name / sample);
    return (dir / name).string();
  };
  const auto config = [&](const std::string& name, const std::string& from, const std::string& to) {
    std::string c = k_small;
    c.replace(c.find(from), from.size(), to);
    write(dir / name, c);
    return (dir / name).string();
  };
  const std::string count = config("count.toml", "count = 300", "count = 200");
  const std::string out = copied("b");
  const Result r = run({count, "--out", out, "--resume"});
  INFO(r.err);
  CHECK(r.code == 2);
  CHECK(r.err.find(sample + " was prepared with sample.count = 300, not 200") != std::string::npos);
  CHECK(r.err.find("--allow-change sample.count") != std::string::npos);
  CHECK(std::count(r.err.begin(), r.err.end(), '\n') == 1);
  CHECK(read(dir / "b" / sample) == prepared);  // nothing lost or clobbered, nothing sheared
  CHECK(!fs::exists(dir / "b" / "index.csv"));
  CHECK(!fs::exists(dir / "b" / "p-b0.50-p0_100kPa.h5"));
  // The preparation's step (time.dt_fraction when prepare.dt_fraction is not given) and the
  // restitution shape the sample too: the first is named, the other listed.
  std::string both = k_small + "[time]\ndt_fraction = 0.1\n";
  both.replace(both.find("young = 1.0e9"), 13, "young = 1.0e9\nrestitution = 0.9");
  write(dir / "both.toml", both);
  const Result r2 = run({(dir / "both.toml").string(), "--out", out, "--resume"});
  INFO(r2.err);
  CHECK(r2.code == 2);
  CHECK(r2.err.find("was prepared with material.restitution = 0.5") != std::string::npos);
  CHECK(r2.err.find("(differing too: prepare.dt_fraction)") != std::string::npos);
  // A run of selected tasks is checked the same way.
  std::string campaign = k_small;
  campaign.replace(campaign.find("b = 0.5"), 7, "b = [0.5, 1.0]");
  campaign.replace(campaign.find("count = 300"), 11, "count = 200");
  write(dir / "campaign.toml", campaign);
  const Result task = run({(dir / "campaign.toml").string(), "--out", copied("c"), "--task", "2"});
  CHECK(task.code == 2);
  CHECK(task.err.find("was prepared with sample.count = 300") != std::string::npos);
  CHECK(!fs::exists(dir / "c" / "p-b1.00-p0_100kPa.h5"));
  // --allow-change names a change meant (the documented way to shear this sample as it is); a key
  // that does not shape the sample (material.friction) needs nothing.
  CHECK(run({count, "--out", out, "--resume", "--allow-change", "sample.count", "--stop-after", "1"}).code == 3);
  CHECK(run({config("friction.toml", "young = 1.0e9", "young = 1.0e9\nfriction = 0.3"), "--out", copied("d"),
             "--resume", "--stop-after", "1"})
            .code == 3);
  fs::remove_all(dir);
}

TEST_CASE(
    "triaxial: the same --task run twice at once: the second exits 2 naming the job and its lock, no test failed") {
  const fs::path dir = fresh_dir("in_use");
  std::string campaign = k_small;
  campaign.replace(campaign.find("b = 0.5"), 7, "b = [0.5, 1.0]");
  write(dir / "campaign.toml", campaign);
  const std::string c = (dir / "campaign.toml").string(), out = (dir / "out").string();
  const std::string test = "p-b1.00-p0_100kPa";
  const fs::path lock = dir / "out" / ".locks" / (test + ".lock");
  // A test whose job lock another process holds (taken here as that process would hold it):
  // refused before anything runs, the lock and the holder named.
  fs::create_directories(lock.parent_path());
  {
    triaxial::FileLock held;
    REQUIRE(held.try_lock(lock, triaxial::FileLock::Mode::exclusive));
    const Result r = run({c, "--out", out, "--task", "2"});
    INFO(r.err);
    CHECK(r.code == 2);
    CHECK(r.err.find("--task: test " + test + " is in use: " + lock.string() + " is held by PID " +
                     std::to_string(::getpid())) != std::string::npos);
    CHECK(std::count(r.err.begin(), r.err.end(), '\n') == 1);
    CHECK(!fs::exists(dir / "out" / "index.csv"));
    CHECK(!fs::exists(dir / "out" / "sample-p0_100kPa.h5"));
  }
  // Two runs of the task at once, as two array tasks would start: both find the lock free, one
  // prepares the sample while the other waits for it, then the first shears and the second finds
  // the test's lock held. The shearing (3,366 steps) takes ~0.15 s, 100 times the milliseconds the
  // second needs to reach the lock once the sample is there.
  // (Two threads of this process stand for the two processes: each run holds its locks on its own
  // open files, which exclude each other as two processes' do; the run's config is recorded first,
  // as the directory's first run would have, so that they do not both write it.)
  fs::create_directories(dir / "out2");
  write(dir / "out2" / ".config.toml", campaign);
  const std::string out2 = (dir / "out2").string();
  const std::string shorter = "p-b0.50-p0_100kPa";
  Result first, second;
  std::thread a([&] { first = run({c, "--out", out2, "--task", "1", "--resume", "--threads", "1"}); });
  std::thread b([&] { second = run({c, "--out", out2, "--task", "1", "--resume", "--threads", "1"}); });
  a.join();
  b.join();
  const Result& loser = first.code == 2 ? first : second;
  const Result& winner = first.code == 2 ? second : first;
  INFO(first.out, first.err, second.out, second.err);
  CHECK(winner.code == 0);
  CHECK(loser.code == 2);
  // Found in use when its lock is taken (in the log), or already by the check before the run.
  const std::string said = loser.out + loser.err;
  CHECK(said.find("test " + shorter + " is in use: " + (dir / "out2" / ".locks" / (shorter + ".lock")).string() +
                  " is held by ") != std::string::npos);
  CHECK(said.find("failed") == std::string::npos);
  const std::string index = read(dir / "out2" / "index.csv");
  CHECK(index.find(shorter + ",constant_p,0.5,100000," + shorter + ".h5,done,") != std::string::npos);
  fs::remove_all(dir);
}

TEST_CASE("triaxial: the shipped configs parse, and default.toml is the embedded default") {
  const fs::path dir = fs::path(SANDCELL_SOURCE_DIR) / "apps/triaxial/configs";
  CHECK(read(dir / "default.toml") == triaxial::k_default_config);
  const triaxial::Config paper = triaxial::parse_config(read(dir / "paper.toml"), "paper.toml");
  CHECK(paper.tests.size() == 60);  // 6 p0 x 2 paths x 5 b
  CHECK(paper.sample.generation.count == 19436);
  // The fast protocol: the same campaign and sample, at a set inertial number, chained preparations.
  const triaxial::Config fast = triaxial::parse_config(read(dir / "paper-fast.toml"), "paper-fast.toml");
  CHECK(fast.tests.size() == 60);
  CHECK(fast.sample.generation.count == 19436);
  CHECK(fast.shear.inertial_number > 0.0);
  CHECK(fast.shear.strain_rate == 0.0);
  CHECK(fast.prepare.chain);
  // The faster protocol: paper-fast's campaign, samples and rates, with the stiffness step and a cell
  // free to shear (its text says what differs and why).
  const triaxial::Config faster = triaxial::parse_config(read(dir / "paper-faster.toml"), "paper-faster.toml");
  CHECK(faster.tests.size() == 60);
  CHECK(faster.sample.generation.count == fast.sample.generation.count);
  CHECK(faster.shear.inertial_number == fast.shear.inertial_number);
  CHECK(faster.shear.max_deviatoric_strain == fast.shear.max_deviatoric_strain);
  CHECK(faster.prepare.chain);
  CHECK(faster.dt_rule == TimeStepRule::stiffness);
  CHECK(faster.dt_safety == 0.8);
  CHECK(faster.cell.free);
  CHECK(!fast.cell.free);
}

TEST_CASE("triaxial: a campaign runs tests at once from one prepared sample, each as if alone") {
  // Two tests (b = 0.5 and 1) from one sample, two at once with one thread each, against the b = 0.5
  // test run alone with two threads: the shared sample and the split thread budget change no bit.
  const fs::path dir = fresh_dir("campaign");
  std::string campaign = k_small;
  campaign.replace(campaign.find("b = 0.5"), 7, "b = [0.5, 1.0]\nparallel = 2");
  write(dir / "campaign.toml", campaign);
  write(dir / "alone.toml", k_small);
  REQUIRE(run({(dir / "campaign.toml").string(), "--out", (dir / "c").string(), "--threads", "2"}).code == 0);
  REQUIRE(run({(dir / "alone.toml").string(), "--out", (dir / "a").string(), "--threads", "2"}).code == 0);
  const std::string index = read(dir / "c" / "index.csv");
  CHECK(index.find("p-b0.50-p0_100kPa,constant_p,0.5") != std::string::npos);
  CHECK(index.find("p-b1.00-p0_100kPa,constant_p,1") != std::string::npos);
  CHECK(std::count(index.begin(), index.end(), '\n') == 3);  // header + 2 tests
  const State together = read_checkpoint(dir / "c" / "p-b0.50-p0_100kPa.checkpoint.h5");
  const State alone = read_checkpoint(dir / "a" / "p-b0.50-p0_100kPa.checkpoint.h5");
  CHECK(first_difference(together.particles, alone.particles) == "");
  CHECK(first_difference(together.contacts, alone.contacts) == "");
  // b = 1 is extension: the servo holds S_yy = S_xx. Checked on the cell axes it controls (the
  // series' b comes from principal values, which in a 300-sphere sample the shear stresses of the
  // fabric split by ~0.15 when s1 = s2); 0.02 is the tolerance on b the constant-b paths are held to (tests/systems/test_servo.cpp).
  const std::vector<double> st = dataset(dir / "c" / "p-b1.00-p0_100kPa.h5", "/series/stress");  // (rows, 6)
  const double* last = st.data() + st.size() - 6;
  CHECK((last[1] - last[2]) / (last[0] - last[2]) == doctest::Approx(1.0).epsilon(0.02));
  fs::remove_all(dir);
}

TEST_CASE("triaxial: time.step = stiffness: the step follows the contacts, and stop and --resume stay bitwise") {
  const fs::path dir = fresh_dir("resume_stiffness");
  // interval 37: the stops every 1000 steps of a job fall between updates of the step.
  write(dir / "small.toml", k_small + "[time]\nstep = \"stiffness\"\ninterval = 37\n");
  const fs::path a = dir / "a", b = dir / "b";
  const Result whole = run({(dir / "small.toml").string(), "--out", a.string(), "--threads", "1"});
  INFO(whole.err);
  REQUIRE(whole.code == 0);
  Result r = run({(dir / "small.toml").string(), "--out", b.string(), "--threads", "2", "--stop-after", "1000"});
  int stops = 0;
  while (r.code == 3 && stops < 100) {
    ++stops;
    r = run({(dir / "small.toml").string(), "--out", b.string(), "--resume", "--threads", stops % 2 ? "3" : "1",
             "--stop-after", "1000"});
  }
  REQUIRE(r.code == 0);
  CHECK(stops >= 2);
  const std::string test = "p-b0.50-p0_100kPa";
  const State sa = read_checkpoint(a / (test + ".checkpoint.h5"));
  const State sb = read_checkpoint(b / (test + ".checkpoint.h5"));
  CHECK(first_difference(sa.particles, sb.particles) == "");
  CHECK(first_difference(sa.contacts, sb.contacts) == "");
  CHECK(sa.clock.time == sb.clock.time);
  CHECK(sa.clock.dt == sb.clock.dt);
  for (const char* name : {"/series/step", "/series/dt", "/series/stress", "/series/e"}) {
    CAPTURE(name);
    CHECK(dataset(a / (test + ".h5"), name) == dataset(b / (test + ".h5"), name));
  }
  // The series holds the step of each row: the rule's from the first row on (set when the shear
  // stage's World is built), moving with the contacts as the sample shears.
  const std::vector<double> dt = dataset(a / (test + ".h5"), "/series/dt");
  REQUIRE(dt.size() > 3);
  const double lo = *std::min_element(dt.begin(), dt.end()), hi = *std::max_element(dt.begin(), dt.end());
  CHECK(lo > 0.0);
  CHECK(hi > lo);  // it adapted during the test
  CHECK(sa.clock.dt == dt.back());
  fs::remove_all(dir);
}
