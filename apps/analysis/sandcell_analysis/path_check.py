"""The stress-path check of a shearing test, from its series: the rules of the app's watchdog
(systems/path_watch.hpp, docs/physics.md section 6.2), so that a results file written before the
watchdog, or by another program, is judged the same way.

The cell's axes are the intended principal axes (sigma1 on x, sigma2 on y, sigma3 on z). Every
quantity is taken from the mean stress tensor over a trailing window of axial strain (the sum of
|d eps_1| over the rows, so a window also works where eps_1 turns back), counted from `start`
(the end of the ramp): a single row of a small sample fluctuates by several per cent, a window
mean by a fraction of that. Per row, once the window is full:
  p          constant p:       |p - p*| / p*
  sigma3     constant sigma3:  |S_zz - sigma3*| / sigma3*
  b          both paths:       |(S_yy - S_zz)/(S_xx - S_zz) - b*|, where S_xx - S_zz >= 0.1 p
             (b is undefined near an isotropic state)
  rotation   the principal axes' turn off the cell axes, degrees: 1/2 asin(2 |tau| / (s1 - s3)),
             |tau| = sqrt(S_xy^2 + S_xz^2 + S_yz^2), where s1 - s3 >= 0.1 p (the exact angle of a
             turn in one principal plane; beside a pair of equal principal stresses the shear
             stress that splits them counts the same way)
  shear      the largest |shear stress| over p
  unbalanced the window mean of the unbalanced force ratio
  overlap    the row's largest overlap / radius (no window: a bound of the contact model)
A test has left its path at the first row where one of them is beyond its tolerance; a window of
fewer than `rows` (5) rows is no mean, and such a test fails as "rows" (its path cannot be judged).
"""
import math

import numpy as np

# The watchdog's defaults (apps/triaxial/README.md, [watch]; argued in docs/physics.md section 6.2).
DEFAULTS = {
    "stress": 0.02,
    "b": 0.03,
    "rotation": 5.0,
    "shear": 0.15,
    "window": 0.01,
    "overlap": 0.2,
    "unbalanced": 1.0,
    "rows": 5,
}
MIN_DEVIATOR = 0.1  # b and the rotation are judged where the deviator s1 - s3 >= 0.1 p

QUANTITIES = ("p", "sigma3", "b", "rotation", "shear", "unbalanced", "overlap")


def tensor(stress6):
    """[n, 6] (xx yy zz xy xz yz) -> [n, 3, 3]."""
    s = np.asarray(stress6, float)
    t = np.empty((s.shape[0], 3, 3))
    t[:, 0, 0], t[:, 1, 1], t[:, 2, 2] = s[:, 0], s[:, 1], s[:, 2]
    t[:, 0, 1] = t[:, 1, 0] = s[:, 3]
    t[:, 0, 2] = t[:, 2, 0] = s[:, 4]
    t[:, 1, 2] = t[:, 2, 1] = s[:, 5]
    return t


def rotation_deg(t):
    """The principal axes' turn off the cell axes of one tensor, degrees (0 near an isotropic state)."""
    lam = np.linalg.eigvalsh(t)
    p = lam.mean()
    span = lam[-1] - lam[0]
    if not (span >= MIN_DEVIATOR * abs(p)) or span <= 0:
        return 0.0
    tau = math.sqrt(t[0, 1] ** 2 + t[0, 2] ** 2 + t[1, 2] ** 2)
    return 0.5 * math.degrees(math.asin(min(1.0, 2.0 * tau / span)))


def shear_ratio(t):
    """Largest |shear stress| over p of one tensor."""
    p = np.trace(t) / 3.0
    return max(abs(t[0, 1]), abs(t[0, 2]), abs(t[1, 2])) / abs(p) if p != 0 else math.inf


def window_values(m, path, b_target, target):
    """The error of each quantity for one window-mean tensor m (NaN where undefined)."""
    p = np.trace(m) / 3.0
    out = {}
    if path == "constant_p":
        out["p"] = abs(p - target) / abs(target)
    elif path == "constant_sigma3":
        out["sigma3"] = abs(m[2, 2] - target) / abs(target)
    if path in ("constant_p", "constant_sigma3"):
        d = m[0, 0] - m[2, 2]
        out["b"] = abs((m[1, 1] - m[2, 2]) / d - b_target) if d >= MIN_DEVIATOR * abs(p) else math.nan
    out["rotation"] = rotation_deg(m)
    out["shear"] = shear_ratio(m)
    return out


def check(eps1, stress6, path, b_target, target, start=0.0, overlap=None, unbalanced=None, tolerances=None):
    """Judges a test's series against its path.

    eps1: [n] axial strain; stress6: [n, 6] Pa; path: "constant_p" or "constant_sigma3" (any other:
    only the rotation, shear, unbalanced and overlap); b_target; target: p* or sigma3*, Pa; start:
    axial strain (travel) where the checks begin; overlap, unbalanced: [n] or None.
    Returns a dict: worst (quantity -> largest error over the checked rows), failure (None, or a dict
    quantity, value, tolerance, row, eps1), rows_checked."""
    tol = dict(DEFAULTS)
    tol.update(tolerances or {})
    eps1 = np.asarray(eps1, float)
    t = tensor(stress6)
    n = len(eps1)
    travel = np.concatenate([[0.0], np.cumsum(np.abs(np.diff(eps1)))])  # sum of |d eps1|
    worst = {k: 0.0 for k in QUANTITIES}
    failure = None
    checked = 0
    begin = first = None

    def fail(q, value, limit, i):
        nonlocal failure
        if failure is None and value > limit:
            failure = dict(quantity=q, value=float(value), tolerance=float(limit), row=i, eps1=float(eps1[i]))

    for i in range(1, n):  # row 0 is the sample before any step
        if overlap is not None:
            worst["overlap"] = max(worst["overlap"], float(overlap[i]))
            fail("overlap", overlap[i], tol["overlap"], i)
        if begin is None:
            if travel[i] < start:
                continue
            begin = first = i
        while travel[i] - travel[first] > tol["window"]:
            first += 1
        if travel[i] < start + tol["window"]:
            continue  # the first window is not full yet
        if i - first + 1 < tol["rows"]:
            if failure is None:
                failure = dict(quantity="rows", value=float(i - first + 1), tolerance=float(tol["rows"]), row=i,
                               eps1=float(eps1[i]))
            continue
        values = window_values(t[first:i + 1].mean(axis=0), path, b_target, target)
        if unbalanced is not None:
            values["unbalanced"] = float(np.mean(unbalanced[first:i + 1]))
        checked += 1
        for q, v in values.items():
            if not math.isfinite(v):
                continue
            worst[q] = max(worst[q], v)
            fail(q, v, tol["stress"] if q in ("p", "sigma3") else tol[q], i)
    return {"worst": worst, "failure": failure, "rows_checked": checked}


def check_file(path, start=0.0, tolerances=None):
    """check() on a results file (its /series and root attributes path, b, p0)."""
    from .results import attr, open_results
    with open_results(path) as f:
        s = f["series"]
        stress = np.asarray(s["stress"][...], float)
        strain = np.asarray(s["strain"][...], float)
        ov = np.asarray(s["max_overlap_ratio"][...], float) if "max_overlap_ratio" in s else None
        ub = np.asarray(s["unbalanced_force_ratio"][...], float) if "unbalanced_force_ratio" in s else None
        kind = attr(f, "path")
        b = float(attr(f, "b") or 0.0)
        p0 = float(attr(f, "p0") or 0.0)
    n = min(len(stress), len(strain), *(len(x) for x in (ov, ub) if x is not None))
    return check(strain[:n, 0], stress[:n], str(kind), b, p0, start=start,
                 overlap=None if ov is None else ov[:n], unbalanced=None if ub is None else ub[:n],
                 tolerances=tolerances)
