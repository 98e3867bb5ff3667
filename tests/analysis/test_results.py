"""The reader (sandcell_analysis.results) on synthetic results files: what it derives when a dataset
is absent (identities of the strain and stress invariants), the common length of a running job's
datasets, what it skips, and its one-line errors."""
import math
import os

import h5py
import numpy as np
import pytest

from helpers import caricature, write_results
from sandcell_analysis import m_theta, results

SHEAR = {"job": b"t", "stage": b"shear", "path": b"constant_p", "b": b"0.5", "p0": "2e+06"}


def test_derived_columns_are_the_invariants_of_the_stored_ones(tmp_path):
    # Without eps_q, eta, b and theta the reader derives them from strain, q/p and the principal
    # stresses. The caricature's strain is eps_v/3 + eps_q (cos(theta - 2 pi k/3))_k, whose
    # deviatoric invariant sqrt(2)/3 sqrt(sum of squared differences) is eps_q exactly, and its
    # principal stresses are those of b exactly: round-off alone, 1e-12.
    s = caricature(2e6, 0.5, rows=101)
    full = dict(s)
    for k in ("eps_q", "eta", "b", "theta"):
        del s[k]
    path = tmp_path / "t.h5"
    write_results(path, s, SHEAR)
    t, why = results.read_test(str(path))
    assert why is None
    assert np.allclose(t["eps_q"], full["eps_q"], rtol=0, atol=1e-12)
    assert np.allclose(t["eta"], full["q"] / full["p"], rtol=1e-15, atol=0)
    # Row 0 is isotropic (q = 0): s1 = s3, b undefined.
    assert math.isnan(t["b"][0]) and math.isnan(t["theta"][0])
    assert np.allclose(t["b"][1:], 0.5, rtol=0, atol=1e-12)
    assert np.allclose(t["theta"][1:], m_theta.lode_from_b(0.5), rtol=0, atol=1e-12)
    assert t["name"] == "t" and t["path"] == "constant_p" and t["b_nominal"] == 0.5 and t["p0"] == 2e6
    assert t["rows"] == 101 and np.array_equal(t["eps1"], s["strain"][:, 0])


def test_a_running_jobs_datasets_are_cut_to_their_common_length(tmp_path):
    s = caricature(2e6, 0.0, rows=101)
    s["q"] = np.append(s["q"], 1.0)  # a job between two dataset writes: q one row ahead
    path = tmp_path / "t.h5"
    write_results(path, s, SHEAR)
    t, _ = results.read_test(str(path))
    assert t["rows"] == 101 and all(len(t[k]) == 101 for k in ("p", "q", "e", "eps_v", "eps1"))
    cols = results.read_columns(str(path), ("strain", "q"))
    assert cols["q"].shape == (101,) and cols["strain"].shape == (101, 3)


def test_preparation_files_are_skipped_with_the_reason(tmp_path):
    path = tmp_path / "prepare.h5"
    write_results(path, caricature(0.5e6, 0.0, rows=11), {"stage": b"prepare"})
    t, why = results.read_test(str(path))
    assert t is None and why == "stage 'prepare'"


def test_bad_files_give_one_line_naming_the_file(tmp_path):
    path = tmp_path / "x.h5"
    path.write_text("not HDF5\n")
    with pytest.raises(results.InputError, match=r"^cannot read .*x\.h5: [^\n]*$"):
        results.read_test(str(path))
    with h5py.File(tmp_path / "y.h5", "w") as f:
        f.attrs["stage"] = "shear"
        f.create_group("series").create_dataset("p", data=np.ones(3))
    with pytest.raises(results.InputError, match="lacks strain, q, e, eps_v"):
        results.read_test(str(tmp_path / "y.h5"))
    with pytest.raises(results.InputError, match="/series lacks wall_time"):
        results.read_columns(str(tmp_path / "y.h5"), ("p", "wall_time"))
    with pytest.raises(results.InputError, match="no such file or directory"):
        results.collect_files([str(tmp_path / "none")])


def test_collect_files_leaves_out_samples_and_checkpoints(tmp_path):
    for name in ("a.h5", "sample-p0.h5", "a.checkpoint.h5", "notes.txt"):
        (tmp_path / name).write_text("")
    files = results.collect_files([str(tmp_path), str(tmp_path / "a.h5")])
    assert files == [(os.path.join(str(tmp_path), "a.h5"), False)]  # once, though named twice


def test_index_and_samples_rows(tmp_path):
    (tmp_path / "index.csv").write_text("test,status,file\nt1,done (critical state),t1.h5\n")
    assert results.read_index(str(tmp_path)) == [{"test": "t1", "status": "done (critical state)", "file": "t1.h5"}]
    assert results.read_samples(str(tmp_path)) == []  # no samples.csv: no rows


def test_b_key_rounds_the_nominal_b():
    assert results.b_key({"b_nominal": 0.2500001}) == 0.25
    assert math.isnan(results.b_key({"b_nominal": math.nan}))


def test_series_kept_as_csv_come_back_to_their_digits_and_the_same_bytes(tmp_path, monkeypatch):
    # write_series_csv keeps a series in git: 9 significant digits, so every value comes back within
    # half a unit of the 9th digit (relative 5e-9); 2-D columns as name_0.. and back as [n, k]; the
    # gzip header holds no time stamp, so writing the same series twice gives the same bytes.
    rng = np.random.default_rng(7)
    n = 257
    cols = {"step": np.arange(n) * 50.0, "e": 0.7 + 0.01 * rng.standard_normal(n),
            "stress": rng.standard_normal((n, 6)) * 1e6, "strain": rng.standard_normal((n, 3)) * 1e-3}
    a, b = str(tmp_path / "a.csv.gz"), str(tmp_path / "b.csv.gz")
    assert results.write_series_csv(a, cols) == n
    # The second write at another clock time (gzip stamps time.time() unless told not to).
    import gzip
    import types
    monkeypatch.setattr(gzip, "time", types.SimpleNamespace(time=lambda: 1.0e9))
    results.write_series_csv(b, cols)
    with open(a, "rb") as fa, open(b, "rb") as fb:
        assert fa.read() == fb.read()
    back = results.read_series_csv(a, tensors=("stress", "strain"))
    assert set(back) == {"step", "e", "stress", "strain"}
    assert back["stress"].shape == (n, 6) and back["strain"].shape == (n, 3)
    for k, v in cols.items():
        assert np.allclose(back[k], v, rtol=5e-9, atol=0), k
    assert np.array_equal(back["step"], cols["step"])  # integers below 1e9 are exact
    # Without tensors, the flat columns by name; a wrong digit count would fail the tolerance above.
    flat = results.read_series_csv(a)
    assert np.array_equal(flat["stress_5"], back["stress"][:, 5])
    results.write_series_csv(b, cols, digits=4)
    coarse = results.read_series_csv(b, tensors=("stress", "strain"))
    assert not np.allclose(coarse["e"], cols["e"], rtol=5e-9, atol=0)
    # Columns of unequal length are refused, naming them, rather than cut to the shortest.
    with pytest.raises(ValueError, match="differ in length"):
        results.write_series_csv(b, {"step": np.arange(3.0), "e": np.arange(2.0)})
