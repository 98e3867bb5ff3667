"""Reading sandcell results: the one reader of the results files (<test>.h5, written by `triaxial`)
and of a run folder's index.csv and samples.csv, used by every part of the analysis.

HDF5 file locking is switched off on import, so that the files of a running job can be read; the
datasets of /series are then cut to their common length.
"""
import os

os.environ["HDF5_USE_FILE_LOCKING"] = "FALSE"  # read files a running job is still writing

import csv  # noqa: E402
import math  # noqa: E402

import numpy as np  # noqa: E402

from .m_theta import lode_from_b  # noqa: E402

NAN = float("nan")
# the app's tests.path names, in the order of its registry (apps/triaxial/protocol/paths.cpp)
PATHS = ("constant_p", "constant_sigma3", "strain", "undrained", "cyclic",
         "simple_shear", "simple_shear_cv", "rotation")


class InputError(Exception):
    """Bad input: reported as one line, exit status 2."""


def open_results(path):
    """The results file, open for reading (h5py.File); InputError "cannot read PATH: why" if it is not
    one."""
    import h5py
    try:
        return h5py.File(path, "r")
    except Exception as exc:  # h5py raises OSError, sometimes others, for non-HDF5 files
        why = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise InputError(f"cannot read {path}: {why}") from None


def read_columns(path, names, optional=()):
    """Float arrays of the /series datasets `names` (required) and `optional` (left out when absent),
    cut to their common length (a running job's datasets may differ by a row); a 2-D dataset keeps
    its columns. InputError naming the file and what is missing."""
    with open_results(path) as f:
        if "series" not in f:
            raise InputError(f"cannot read {path}: no /series group")
        s = f["series"]
        missing = [k for k in names if k not in s]
        if missing:
            raise InputError(f"cannot read {path}: /series lacks {', '.join(missing)}")
        cols = {k: np.asarray(s[k][...], float) for k in (*names, *optional) if k in s}
    n = min(v.shape[0] for v in cols.values())
    return {k: v[:n] for k, v in cols.items()}


def read_job(path):
    """The root attribute `job` of a results file (its test name), '' if absent."""
    with open_results(path) as f:
        title = attr(f, "job")
    return "" if title is None else str(title)


def read_csv_rows(path):
    """The rows of a CSV file with a header (index.csv, samples.csv) as dicts of strings; [] when the
    file does not exist."""
    if not os.path.exists(path):
        return []
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def write_series_csv(path, columns, digits=9):
    """Series kept in git instead of their results file: COLUMNS (name -> 1-D array, or 2-D [n, k]
    written as name_0 .. name_{k-1}, in the given order) into PATH as a gzip-compressed CSV, `digits`
    significant digits, no time stamp or file name in the gzip header (the same series gives the same
    bytes, so re-exporting churns nothing), through a temporary file (a reader never sees half of it).
    Returns the number of rows."""
    import gzip
    import io
    head, parts = [], []
    for name, v in columns.items():
        a = np.asarray(v, float)
        if a.ndim == 1:
            head.append(name)
            parts.append(a[:, None])
        else:
            head += [f"{name}_{c}" for c in range(a.shape[1])]
            parts.append(a.reshape(a.shape[0], -1))
    lengths = {name: len(np.asarray(v)) for name, v in columns.items()}
    if len(set(lengths.values())) > 1:
        raise ValueError(f"{path}: the columns differ in length ({lengths}); a series needs one row count")
    n = parts[0].shape[0] if parts else 0
    table = np.hstack(parts) if parts else np.zeros((0, 0))
    tmp = path + ".tmp"
    with open(tmp, "wb") as raw, gzip.GzipFile(filename="", mode="wb", fileobj=raw, mtime=0) as gz, \
            io.TextIOWrapper(gz, newline="") as fh:
        fh.write(",".join(head) + "\n")
        for row in table:
            fh.write(",".join(f"{v:.{digits}g}" for v in row) + "\n")
    os.replace(tmp, path)
    return n


def read_series_csv(path, tensors=()):
    """A series written by write_series_csv as {name: array}; the names in TENSORS come back as 2-D
    arrays from their name_0, name_1, ... columns."""
    import gzip
    with gzip.open(path, "rt", newline="") as fh:
        head = fh.readline().strip().split(",")
        data = np.loadtxt(fh, delimiter=",", ndmin=2)
    flat = {name: data[:, k] for k, name in enumerate(head)}
    out = {}
    for t in tensors:
        cols = []
        while f"{t}_{len(cols)}" in flat:
            cols.append(flat.pop(f"{t}_{len(cols)}"))
        if cols:
            out[t] = np.column_stack(cols)
    out.update(flat)
    return out


def read_index(folder):
    """The rows of a run folder's index.csv (one per test: test, status, file, steps, ...)."""
    return read_csv_rows(os.path.join(folder, "index.csv"))


def read_samples(folder):
    """The rows of a run folder's samples.csv (one per prepared sample: steps, wall_s, ...)."""
    return read_csv_rows(os.path.join(folder, "samples.csv"))


def attr(f, key):
    v = f.attrs.get(key)
    if v is None:
        return None
    if isinstance(v, np.ndarray):
        v = v.item() if v.size == 1 else v.tolist()
    if isinstance(v, bytes):
        v = v.decode("utf-8", "replace")
    return v


def to_float(v, default=NAN):
    try:
        return float(v)
    except (TypeError, ValueError):
        return default


def collect_files(inputs):
    """The .h5 files named or found in the input directories (sample and checkpoint files out).

    Returns a list of (path, named): named is False for a file found in a directory."""
    files, seen = [], set()
    for item in inputs:
        if os.path.isdir(item):
            for name in sorted(os.listdir(item)):
                if (not name.endswith(".h5") or name.startswith("sample-")
                        or name.endswith(".checkpoint.h5")):
                    continue
                path = os.path.join(item, name)
                if os.path.isfile(path) and os.path.realpath(path) not in seen:
                    seen.add(os.path.realpath(path))
                    files.append((path, False))
        elif os.path.isfile(item):
            if os.path.realpath(item) not in seen:
                seen.add(os.path.realpath(item))
                files.append((item, True))
        else:
            raise InputError(f"no such file or directory: {item}")
    if not files:
        raise InputError("no results files (*.h5) in " + ", ".join(inputs))
    return files


def read_test(path):
    """Read a results file. Returns (test dict, None) or (None, why it is not a shear test)."""
    f = open_results(path)
    try:
        with f:
            stage = attr(f, "stage")
            if stage != "shear":
                return None, f"stage {stage!r}" if stage else "no 'stage' attribute"
            if "series" not in f:
                raise InputError(f"cannot read {path}: no /series group")
            s = f["series"]

            def get(name):
                return np.asarray(s[name][...], float) if name in s else None

            strain = get("strain")
            cols = {"p": get("p"), "q": get("q"), "e": get("e"), "eps_v": get("eps_v")}
            missing = [k for k, v in (("strain", strain), *cols.items()) if v is None]
            if missing:
                raise InputError(f"cannot read {path}: /series lacks {', '.join(missing)}")
            if strain.ndim != 2 or strain.shape[1] < 3:
                raise InputError(f"cannot read {path}: /series/strain is not [n, 3]")
            for name in ("eta", "theta", "b", "eps_q", "time", "stress", "Z_mech", "fabric"):
                cols[name] = get(name)
            ps = get("principal_stress")
            attrs = {k: attr(f, k) for k in ("job", "path", "b", "p0")}
    except InputError:
        raise
    except Exception as exc:
        why = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise InputError(f"cannot read {path}: {why}") from None
    for name in ("stress", "fabric"):
        if cols[name] is not None and (cols[name].ndim != 2 or cols[name].shape[1] != 6):
            cols[name] = None
    lengths = [strain.shape[0]] + [v.shape[0] for v in cols.values() if v is not None]
    if ps is not None and ps.ndim == 2 and ps.shape[1] == 3:
        lengths.append(ps.shape[0])
    else:
        ps = None
    n = min(lengths)
    strain = strain[:n, :3]
    cols = {k: (v[:n] if v is not None else None) for k, v in cols.items()}
    if cols["eta"] is None:
        with np.errstate(divide="ignore", invalid="ignore"):
            cols["eta"] = cols["q"] / cols["p"]
    if cols["eps_q"] is None:
        a, b_, c = strain[:, 0], strain[:, 1], strain[:, 2]
        cols["eps_q"] = math.sqrt(2) / 3 * np.sqrt((a - b_) ** 2 + (b_ - c) ** 2 + (c - a) ** 2)
    if ps is not None:
        ps = np.sort(ps[:n], axis=1)[:, ::-1]
        with np.errstate(divide="ignore", invalid="ignore"):
            if cols["b"] is None:
                cols["b"] = (ps[:, 1] - ps[:, 2]) / (ps[:, 0] - ps[:, 2])
            if cols["theta"] is None:
                cols["theta"] = lode_from_b(cols["b"])
    for k in ("b", "theta"):
        if cols[k] is None:
            cols[k] = np.full(n, NAN)
    eps1 = strain[:, 0]
    good = np.isfinite(eps1)
    for k in ("p", "q", "e", "eps_v", "eps_q"):
        good &= np.isfinite(cols[k])
    test = {k: v[good] for k, v in cols.items() if v is not None}
    test["eps1"] = eps1[good]
    test["strain"] = strain[good]
    name = attrs["job"] or os.path.splitext(os.path.basename(path))[0]
    path_kind = attrs["path"] or "unknown"
    test.update(file=path, name=str(name), path=str(path_kind), rows=int(np.sum(good)),
                b_nominal=to_float(attrs["b"]), p0=to_float(attrs["p0"]))
    if path_kind == "strain":
        test["b_nominal"] = NAN  # b is not controlled on a strain path
    if not np.isfinite(test["p0"]) and test["rows"]:
        test["p0"] = float(test["p"][0])
    return test, None


def b_key(t):
    return round(t["b_nominal"], 3) if np.isfinite(t["b_nominal"]) else NAN


def read_series(f, path):
    """/series/step, strain, eta and e (those present) of an open results file, cut to their common length."""
    if "series" not in f or "step" not in f["series"] or "strain" not in f["series"]:
        raise InputError(f"{path}: no /series/step and /series/strain: not a triaxial results file")
    s = f["series"]
    names = [k for k in ("step", "strain", "eta", "e") if k in s]
    n = min(s[k].shape[0] for k in names)  # a running job's datasets may differ by a row
    return {k: np.asarray(s[k][:n], float) for k in names}


def snapshot_names(f, path, whole=False):
    """The particle snapshots of an open results file, in step order (with whole: the first and the last)."""
    names = sorted(f["snapshots"].keys(), key=int) if "snapshots" in f else []
    if len(names) < 2:
        raise InputError(f"{path}: {len(names)} particle snapshot(s); localization needs at least 2: set "
                         "output.snapshot_interval (steps between snapshots, e.g. 1 % of axial strain) and run the "
                         "test again")
    # The stage's end is written as well as the interval's snapshots: a few steps after the last
    # of them, it would make an increment of noise. It then replaces that last one.
    if whole:
        return [names[0], names[-1]]
    if len(names) >= 3:
        gaps = np.diff([int(k) for k in names])
        if gaps[-1] < 0.5 * np.median(gaps[:-1]):
            del names[-2]
    return names


def read_snapshot(f, name, path):
    """(step, ids, positions [n, 3], cell) of one particle snapshot. The cell is its lengths [3] when the cell is
    orthorhombic (no tilts and no flips: what the analysis then computes is exactly what it computed before the cell
    could shear), else the 3 x 3 upper triangular C = H N (docs/physics.md section 1: H the lattice basis of lengths
    and tilts xy, xz, yz, N the flips, so that C deforms affinely with the particles). The tilts and flips are the
    snapshot's `cell_tilt` and `cell_flip` attributes; a snapshot written before the writer recorded them (its cell
    sheared: /series/cell_tilt not all zero) takes the tilts of the series row at its step and no flips (a flip
    would show as a jump of a tilt by a cell length in the series: such a file is refused)."""
    g = f["snapshots"][name]
    missing = [k for k in ("id", "position") if k not in g] + ([] if "cell_length" in g.attrs else ["cell_length"])
    if missing:
        raise InputError(f"{path}: snapshot {name} lacks {', '.join(missing)}")
    step = int(g.attrs.get("step", int(name)))
    length = np.asarray(g.attrs["cell_length"], float)
    if "cell_tilt" in g.attrs:
        tilt = np.asarray(g.attrs["cell_tilt"], float)
        flip = np.asarray(g.attrs["cell_flip"], float) if "cell_flip" in g.attrs else np.zeros(3)
    else:
        tilt, flip = series_tilt(f, step, path, length), np.zeros(3)
    cell = length
    if np.any(tilt != 0.0) or np.any(flip != 0.0):
        H = np.array([[length[0], tilt[0], tilt[1]], [0.0, length[1], tilt[2]], [0.0, 0.0, length[2]]])
        N = np.array([[1.0, flip[0], flip[1]], [0.0, 1.0, flip[2]], [0.0, 0.0, 1.0]])
        cell = H @ N
    return step, g["id"][:], np.asarray(g["position"][:], float), cell


def series_tilt(f, step, path, length):
    """The cell's tilts at `step` from /series/cell_tilt (zeros when the file has none or they are all zero), for
    snapshots that do not record them (length: the snapshot's, the scale of a flip's jump). InputError when the step
    has no series row or the series shows a flip."""
    s = f["series"] if "series" in f else None
    if s is None or "cell_tilt" not in s or "step" not in s:
        return np.zeros(3)
    n = min(s["cell_tilt"].shape[0], s["step"].shape[0])
    tilts, steps = np.asarray(s["cell_tilt"][:n], float), np.asarray(s["step"][:n], float)
    if not np.any(tilts != 0.0):
        return np.zeros(3)
    if n > 1 and np.any(np.abs(np.diff(tilts, axis=0)) > 0.25 * length[[0, 0, 1]]):  # a flip: by L_1, L_1, L_2
        raise InputError(f"{path}: its cell flipped (a tilt jumps by a cell length in /series/cell_tilt) and its "
                         "snapshots do not record the flips (cell_flip): the snapshots cannot be read")
    row = np.flatnonzero(steps == step)
    if not row.size:
        raise InputError(f"{path}: the snapshot at step {step} records no cell tilts and /series has no row at that "
                         "step: its sheared cell is unknown")
    return tilts[row[0]]
