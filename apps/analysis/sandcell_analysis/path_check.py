"""The stress-path check of a shearing test, from its series: the same rules as the app's watchdog
(systems/path_watch.hpp), so that a results file written before the watchdog, or by another
program, can be judged the same way.

Every quantity is taken from the mean stress tensor over a trailing window of axial strain (the
sum of |d eps_1| over the rows, so the window also works where eps_1 turns back), counted from
`start` (the end of the ramp): a single row of a small sample fluctuates by several per cent, the
window mean by a fraction of that. Per row, once the window is full:
  p error        constant p:       (p_mean - p*) / p*
  sigma3 error   constant sigma3:  (lambda3 - sigma3*) / sigma3*, lambda3 the minor principal stress
  b error        both paths:       b of the window-mean principal stresses minus b*, where
                                   lambda1 - lambda3 >= min_deviator p_mean (b is undefined in an
                                   isotropic state)
  rotation       the angle between each principal direction whose principal stress is at least
                 `min_gap` (lambda1 - lambda3) away from the other two and the cell axis it belongs
                 to (the cell axes ordered by their normal stresses), degrees, largest of them
  shear          the largest |shear stress| of the window mean, over p_mean
  unbalanced     the window mean of the unbalanced force ratio
  overlap        the row's largest overlap / radius (no window: a physical bound)
A test has left its path at the first row where one of them is beyond its tolerance.
"""
import math

import numpy as np

# The watchdog's defaults (apps/triaxial/README.md, [watch]); argued there from measured runs.
DEFAULTS = {
    "stress": 0.02,
    "b": 0.03,
    "rotation": 5.0,
    "shear": 0.05,
    "window": 0.01,
    "overlap": 0.2,
    "unbalanced": 1.0,
}
MIN_DEVIATOR = 0.1  # b and rotation are checked where lambda1 - lambda3 >= 0.1 p
MIN_GAP = 0.2       # a principal direction counts where its stress is 0.2 (lambda1 - lambda3) from the others

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


def principal(t):
    """Principal stresses (descending) and their directions (columns) of one symmetric 3x3 tensor."""
    w, v = np.linalg.eigh(t)
    order = np.argsort(w)[::-1]
    return w[order], v[:, order]


def rotation_deg(t, min_deviator=MIN_DEVIATOR, min_gap=MIN_GAP):
    """Largest angle (degrees) between a well-separated principal direction of t and its cell axis;
    0 where no direction is separated (an isotropic state)."""
    lam, vec = principal(t)
    p = lam.mean()
    span = lam[0] - lam[2]
    if not (span >= min_deviator * abs(p)) or span <= 0:
        return 0.0
    axes = np.argsort(np.diag(t))[::-1]  # cell axis of principal stress 1, 2, 3
    worst = 0.0
    for i in range(3):
        gap = min(abs(lam[i] - lam[j]) for j in range(3) if j != i)
        if gap < min_gap * span:
            continue
        c = min(1.0, abs(vec[axes[i], i]))
        worst = max(worst, math.degrees(math.acos(c)))
    return worst


def shear_ratio(t):
    """Largest |shear stress| over p of one tensor."""
    p = np.trace(t) / 3.0
    return max(abs(t[0, 1]), abs(t[0, 2]), abs(t[1, 2])) / abs(p) if p != 0 else math.inf


def check(eps1, stress6, path, b_target, p0, start=0.0, overlap=None, unbalanced=None, tolerances=None):
    """Judges a test's series against its path.

    eps1: [n] axial strain; stress6: [n, 6] Pa; path: "constant_p" or "constant_sigma3" (others: only
    rotation, shear, unbalanced and overlap); b_target, p0 (Pa: p* or sigma3*); start: axial strain
    where the checks begin; overlap, unbalanced: [n] or None.
    Returns a dict: worst (quantity -> largest |error| over the checked rows), failure (None, or a
    dict quantity, value, target, row, eps1, tolerance), rows_checked."""
    tol = dict(DEFAULTS)
    tol.update(tolerances or {})
    eps1 = np.asarray(eps1, float)
    t = tensor(stress6)
    n = len(eps1)
    travel = np.concatenate([[0.0], np.cumsum(np.abs(np.diff(eps1)))])  # sum of |d eps1|
    begin = None  # first row at or past start (by travel from the start of the test)
    worst = {k: 0.0 for k in QUANTITIES}
    failure = None
    checked = 0
    first = 0  # first row of the current window
    running = np.zeros((3, 3))
    run_unb = 0.0
    for i in range(n):
        if begin is None:
            if travel[i] < start:
                continue
            begin = first = i
        running += t[i]
        if unbalanced is not None:
            run_unb += unbalanced[i]
        if overlap is not None and i > 0:
            worst["overlap"] = max(worst["overlap"], float(overlap[i]))
            if failure is None and overlap[i] > tol["overlap"]:
                failure = dict(quantity="overlap", value=float(overlap[i]), target=tol["overlap"], row=i,
                               eps1=float(eps1[i]), tolerance=tol["overlap"])
        while travel[i] - travel[first] > tol["window"]:
            running -= t[first]
            if unbalanced is not None:
                run_unb -= unbalanced[first]
            first += 1
        if travel[i] - travel[begin] < tol["window"]:
            continue  # the window is not full yet
        m = running / (i - first + 1)
        values = window_values(m, path, b_target, p0)
        if unbalanced is not None:
            values["unbalanced"] = (run_unb / (i - first + 1), tol["unbalanced"])
        checked += 1
        for q, (v, target) in values.items():
            if not math.isfinite(v):
                continue
            if q in ("p", "sigma3"):
                err = abs(v - target) / abs(target)
            elif q == "b":
                err = abs(v - target)
            else:
                err = v
            worst[q] = max(worst[q], err)
            limit = tol["stress"] if q in ("p", "sigma3") else tol[q]
            if failure is None and err > limit:
                failure = dict(quantity=q, value=float(v), target=float(target), row=i, eps1=float(eps1[i]),
                               tolerance=limit)
    return {"worst": worst, "failure": failure, "rows_checked": checked}


def window_values(m, path, b_target, p0):
    """(value, target) of each checked quantity for one window-mean tensor m. For rotation, shear and
    unbalanced the target is the tolerance's counterpart 0 (the value itself is the error)."""
    lam, _ = principal(m)
    p = lam.mean()
    out = {}
    if path == "constant_p":
        out["p"] = (p, p0)
    elif path == "constant_sigma3":
        out["sigma3"] = (lam[2], p0)
    if path in ("constant_p", "constant_sigma3"):
        span = lam[0] - lam[2]
        b = (lam[1] - lam[2]) / span if span >= MIN_DEVIATOR * abs(p) and span > 0 else math.nan
        out["b"] = (b, b_target)
    out["rotation"] = (rotation_deg(m), 0.0)
    out["shear"] = (shear_ratio(m), 0.0)
    return out


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
