"""`triaxial analyze` (python -m sandcell_analysis analyze): verdicts, and the
whole pipeline on small synthetic results files written here with h5py, and its bad-input errors."""
import json
import os
import subprocess
import tempfile
import unittest

import h5py
import numpy as np

from helpers import CSL_TRUE, D0_TRUE, K_TRUE, M_TRUE, MC_TRUE, caricature, command, write_results
from sandcell_analysis import analyze
from sandcell_analysis import csl

ANALYZE = command("analyze")  # what `triaxial analyze` runs


class Verdicts(unittest.TestCase):
    def test_compare(self):
        self.assertEqual(analyze.compare(0.65, 0.01, 0.619, 0.15), "reproduced")  # within 15 %
        self.assertEqual(analyze.compare(0.70, 0.05, 0.619, 0.05), "reproduced")  # within 2 SE
        self.assertEqual(analyze.compare(1.0, 0.01, 0.619, 0.15), "not reproduced")
        self.assertEqual(analyze.compare(5.0, 100.0, 0.619, 0.15), "not testable")  # undetermined
        self.assertEqual(analyze.compare(float("nan"), 0.1, 0.619, 0.15), "not testable")

    def test_spearman(self):
        self.assertAlmostEqual(analyze.spearman([0, 0.5, 1], [3, 2, 1]), -1.0)
        self.assertTrue(np.isnan(analyze.spearman([0, 1], [3, 2])))  # fewer than 3 b values
        self.assertTrue(np.isnan(analyze.spearman([0, 0.5, 1], [2, 2, 2])))  # constant


class CommandLine(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.TemporaryDirectory()
        cls.dir = os.path.join(cls.tmp.name, "run")
        os.makedirs(cls.dir)
        rng = np.random.default_rng(10)
        for p0 in (0.5e6, 2e6, 8e6):
            for b in (0.0, 0.5, 1.0):
                name = f"p-b{b:.2f}-p0_{p0 / 1e3:g}kPa"
                attrs = {"job": name.encode(), "stage": b"shear", "path": b"constant_p",
                         "b": str(b).encode(), "p0": f"{p0:g}", "config": "[tests]\n"}
                write_results(os.path.join(cls.dir, name + ".h5"),
                              caricature(p0, b, rng=rng, eps_end=0.6, rows=1201),
                              attrs)
        # files the tool must skip
        write_results(os.path.join(cls.dir, "prepare-p0_500kPa.h5"), caricature(0.5e6, 0.0),
                      {"stage": "prepare", "job": "prepare-p0_500kPa"})
        with h5py.File(os.path.join(cls.dir, "sample-p0_500kPa.h5"), "w") as f:
            f.attrs["format"] = b"sandcell checkpoint"
        # a file found in a directory that cannot be read (a job creating it) is skipped with a
        # warning, not an error, so that a running campaign can be analysed
        with open(os.path.join(cls.dir, "p-b0.25-p0_500kPa.h5"), "wb") as f:
            f.write(b"\x89HDF\r\n")
        cls.out = os.path.join(cls.tmp.name, "analysis")
        # --moduli none: the caricature has no elastic part (its stress ratio hardens from the first
        # row); to 60 % of eps_1, where it is critical (psi within ~0.001 of 0, which the groups'
        # CSLs, fitted through the end windows, take as 0).
        cls.proc = subprocess.run([*ANALYZE, cls.dir, "--out", cls.out, "--moduli", "none"],
                                  capture_output=True, text=True, timeout=120)
        cls.summary = None
        if cls.proc.returncode == 0:
            with open(os.path.join(cls.out, "summary.json")) as fh:
                cls.summary = json.load(fh)

    @classmethod
    def tearDownClass(cls):
        cls.tmp.cleanup()

    def setUp(self):
        self.assertEqual(self.proc.returncode, 0, self.proc.stderr)

    def test_writes_report_summary_and_figures(self):
        self.assertTrue(os.path.getsize(os.path.join(self.out, "report.md")) > 1000)
        stems = [f"stress_strain-constant_p-p0_{p}kPa" for p in (500, 2000, 8000)]
        stems += ["csl", "pi_plane", "dilatancy-constant_p"]
        for stem in stems:
            for ext in ("png", "svg"):
                path = os.path.join(self.out, f"{stem}.{ext}")
                self.assertTrue(os.path.isfile(path) and os.path.getsize(path) > 1000, path)
                self.assertIn(f"{stem}.{ext}", self.summary["figures"])
        self.assertEqual(len(self.summary["tests"]), 9)  # prepare and sample files skipped
        self.assertEqual(len(self.summary["skipped"]), 2)
        self.assertIn("warning: skipping", self.proc.stderr)
        with open(os.path.join(self.out, "report.md")) as fh:
            report = fh.read()
        for word in ("reproduced", "Critical state line", "Table 3", "phi_c"):
            self.assertIn(word, report)

    def test_every_test_critical_and_csl_recovered(self):
        s = self.summary
        self.assertTrue(all(t["critical"] for t in s["tests"]),
                        [t["reasons"] for t in s["tests"]])
        fit = s["csl"]
        self.assertEqual(fit["mode"], "full")
        # The caricature ends at psi ~ -0.001 (not exactly 0), so the critical points sit that
        # far below the generating CSL: the fitted curve must be within 0.003 of it over the
        # tested range, and the parameters close (3 pressure levels fix the 3 parameters).
        p = np.geomspace(0.5e6, 8e6, 20)
        par = fit["params"]
        curve = csl.csl_e(p, par["e_gamma"], par["lambda"], par["xi"])
        self.assertLess(np.max(np.abs(curve - csl.csl_e(p, *CSL_TRUE))), 0.003)
        self.assertAlmostEqual(par["e_gamma"], CSL_TRUE[0], delta=0.01)
        self.assertAlmostEqual(par["lambda"], CSL_TRUE[1], delta=0.002)
        self.assertAlmostEqual(par["xi"], CSL_TRUE[2], delta=0.03)

    def test_m_theta_dilatancy_and_trends(self):
        s = self.summary
        m = s["m_theta"]
        # critical eta = M(theta) exp(-2 psi_end) (1 +- 0.3 % noise): within 1 % of M(theta)
        self.assertAlmostEqual(m["params"]["M_c"], MC_TRUE, delta=0.012)
        self.assertAlmostEqual(m["params"]["K"], K_TRUE, delta=0.015)
        ld = s["li_dafalias"]
        self.assertEqual(ld["path"], "constant_p")
        self.assertEqual(len(ld["tests"]), 3)
        # d is the generating Li form, recovered through the strain-adaptive smoothing and the
        # groups' CSLs: measured 1 % off on d0 and m (0.808, 5.05); the 10 % bounds are kept.
        self.assertAlmostEqual(ld["params"]["d0"], D0_TRUE, delta=0.1 * D0_TRUE)
        self.assertAlmostEqual(ld["params"]["m"], M_TRUE, delta=0.1 * M_TRUE)
        self.assertLess(ld["mse"], 1e-4)  # d spans ~0.3: a 3 % fit at worst
        self.assertTrue(s["g_form"]["fitted"])
        bs = sorted({r["b"] for r in s["mse"]})
        self.assertEqual(bs, [0.0, 0.5, 1.0])
        trends = {t["name"]: t for t in s["trends"]}
        self.assertEqual(trends["peak_eta_falls"]["verdict"], "reproduced")
        self.assertEqual(trends["peak_q_falls"]["verdict"], "reproduced")
        self.assertEqual(trends["critical_M_falls"]["verdict"], "reproduced")
        self.assertEqual(trends["csl_unique"]["verdict"], "reproduced")
        for v in s["verdicts"]:
            self.assertIn(v["verdict"], ("reproduced", "not reproduced", "not testable", "not identifiable")
                          if v["key"] != "surface" else (v["verdict"],))


class BadInput(unittest.TestCase):
    def run_cli(self, *args):
        return subprocess.run([*ANALYZE, *args], capture_output=True, text=True,
                              timeout=60)

    def check_error(self, proc, words):
        self.assertEqual(proc.returncode, 2, proc.stderr)
        lines = proc.stderr.strip().splitlines()
        self.assertEqual(len(lines), 1, proc.stderr)  # one line, no traceback
        self.assertIn(words, lines[0])

    def test_no_files(self):
        with tempfile.TemporaryDirectory() as d:
            self.check_error(self.run_cli(d, "--out", os.path.join(d, "o")), "no results files")
            self.assertFalse(os.path.exists(os.path.join(d, "o")))

    def test_not_hdf5(self):
        with tempfile.TemporaryDirectory() as d:
            path = os.path.join(d, "x.h5")
            with open(path, "w") as fh:
                fh.write("not an HDF5 file\n")
            self.check_error(self.run_cli(path, "--out", os.path.join(d, "o")), "cannot read")

    def test_missing_path_no_argument_and_no_shear_test(self):
        self.check_error(self.run_cli("/nonexistent/run"), "no such file")
        self.check_error(self.run_cli(), "no results given")
        self.check_error(self.run_cli("x.h5", "--window", "-1"), "--window")
        with tempfile.TemporaryDirectory() as d:
            write_results(os.path.join(d, "prepare-p0_500kPa.h5"), caricature(0.5e6, 0.0, rows=11),
                          {"stage": b"prepare"})
            self.check_error(self.run_cli(d), "no shear tests")


class FailedTestsLeftOut(unittest.TestCase):
    """A test that left its stress path (the app's verdict in the file, or the series itself off its
    path in a file written before the watchdog) and a test without a verdict (still running) enter
    no fit: listed in summary.json and report.md, absent from the fits' inputs."""

    def test_failed_and_unfinished_tests_are_listed_and_not_fitted(self):
        rng = np.random.default_rng(11)
        with tempfile.TemporaryDirectory() as tmp:
            run = os.path.join(tmp, "run")
            os.makedirs(run)
            names = []
            for p0 in (0.5e6, 2e6, 8e6):
                for b in (0.0, 0.5, 1.0):
                    name = f"p-b{b:.2f}-p0_{p0 / 1e3:g}kPa"
                    names.append(name)
                    series = caricature(p0, b, rng=rng)
                    attrs = {"job": name, "stage": "shear", "path": "constant_p", "b": str(b), "p0": f"{p0:g}",
                             "config": "[tests]\n"}
                    if name == "p-b0.50-p0_500kPa":  # the app's verdict
                        attrs.update(status="failed", status_reason="left its stress path: rotation 6.1 deg")
                    if name == "p-b0.00-p0_2000kPa":  # written before the watchdog, p 5 % high from 10 % on
                        late = series["strain"][:, 0] > 0.1
                        for k in ("p", "q"):
                            series[k] = np.where(late, 1.05 * series[k], series[k])
                        series["stress"] = np.where(late[:, None], 1.05 * series["stress"], series["stress"])
                    if name == "p-b1.00-p0_8000kPa":  # of the watchdog's time, without a verdict: running
                        series["rotation"] = np.zeros(len(series["p"]))
                    elif "rotation" not in series and name != "p-b0.00-p0_2000kPa":
                        series["rotation"] = np.zeros(len(series["p"]))
                        attrs.setdefault("status", "done")
                    write_results(os.path.join(run, name + ".h5"), series, attrs)
            out = os.path.join(tmp, "analysis")
            proc = subprocess.run([*ANALYZE, run, "--out", out, "--moduli", "none"],
                                  capture_output=True, text=True, timeout=120)
            self.assertEqual(proc.returncode, 0, proc.stderr)
            with open(os.path.join(out, "summary.json")) as fh:
                s = json.load(fh)
            left_out = {"p-b0.50-p0_500kPa", "p-b0.00-p0_2000kPa", "p-b1.00-p0_8000kPa"}
            self.assertEqual(set(s["excluded"]), left_out)
            fitted = {os.path.splitext(os.path.basename(f))[0] for f in s["inputs"]}
            self.assertEqual(fitted, set(names) - left_out)
            self.assertEqual(s["csl"]["n"], 6)  # the critical points of the 6 tests on their path
            status = {t["name"]: t["status"] for t in s["path_checks"]}
            self.assertEqual(status["p-b0.50-p0_500kPa"], "failed")
            self.assertEqual(status["p-b0.00-p0_2000kPa"], "failed")  # judged on its series
            self.assertEqual(status["p-b1.00-p0_8000kPa"], "unfinished")
            report = open(os.path.join(out, "report.md")).read()
            self.assertIn("| p-b0.50-p0_500kPa | failed |", report)
            self.assertIn("left its stress path: p", report)
            for name in left_out:
                self.assertTrue(any(name in w for w in s["warnings"]), name)
