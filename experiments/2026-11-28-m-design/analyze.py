"""m identified by a design that can (issue 45 item 3): samples spanning psi0 at one p, their m.

    PYTHONPATH=apps/analysis /usr/bin/python3 experiments/2026-11-28-m-design/analyze.py RUN_ROOT \
        [--out experiments/2026-11-28-m-design]

RUN_ROOT holds one run folder per target void ratio, e<e0> (fixed cell) and e<e0>-free (the same
sample, cell.shear = "free"): 4,000 spheres prepared at 0.5 MPa to e0 = 0.55 .. 0.79
(prepare.target_e0), sheared at constant p and b = 0 to eps_q = 0.6 (config.toml). Writes states.csv
(per test: e0, its end window, whether e, p, Z_mech and F_a are steady there, its characteristic
state) and m.json (the fit per cell; "both" pools the two cells' tests of the same samples, which are
not independent: reported, not a verdict).

Method, fixed before the data (the package's functions, as `triaxial analyze` uses them):
- e_c(0.5 MPa): the mean end-window (last 0.1 of eps_q) void ratio of the tests (either cell) that
  held their path and whose e, p, Z_mech and F_a are steady there (critical.detect_critical without eta: see
  experiments/2026-11-28-critical-v2 for why eta's 2 % cannot be shown at these sizes); M: their mean
  q/p. All tests sit at p = 0.5 MPa (constant p), so psi = e - e_c needs no CSL slope.
- plastic dilatancy (dilatancy.plastic_dilatancy: the elastic parts dp/K and dq/3G removed with each
  test's own moduli, strain-adaptive local quadratics, no strain cut);
- each test's characteristic state: its phase transformation (d = 0) where d turns before the peak
  of eta (after it d fluctuates about 0 at the critical state), else its peak stress ratio with
  eta* = eta - d/s, s the initial d-eta slope of the densest tests (as analyze.s
  characteristic_state, which does not yet restrict the phase transformation to the pre-peak
  branch);
- m by dilatancy.fit_m_pt (ln(eta*/M) = c + m psi; the 95 % profile-likelihood interval; the
  verdict "identified" only when the interval is narrower than 4.57, else "not identifiable").
"""
import argparse
import csv
import json
import math
import os
import sys

import numpy as np

from sandcell_analysis import critical, dilatancy, results


def read(folder):
    name = "p-b0.00-p0_500kPa"
    path = os.path.join(folder, name + ".h5")
    if not os.path.exists(path):
        return None
    status = {r["test"]: r["status"] for r in results.read_csv_rows(os.path.join(folder, "index.csv"))} \
        if os.path.exists(os.path.join(folder, "index.csv")) else {}
    cols = results.read_columns(path, ["eps_q", "eps_v", "p", "q", "eta", "e", "Z_mech", "fabric", "stress"])
    return {"status": status.get(name, "running"), **cols}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("root")
    ap.add_argument("--out", default=os.path.dirname(os.path.abspath(__file__)))
    a = ap.parse_args(argv)
    tests = []
    for folder in sorted(os.listdir(a.root)):
        full = os.path.join(a.root, folder)
        if not (folder.startswith("e0.") and os.path.isdir(full)):
            continue
        t = read(full)
        if t is None:
            continue
        series = {k: t[k] for k in ("p", "q", "eta", "e", "Z_mech", "fabric", "stress")}
        chk = critical.detect_critical(t["eps_q"], series, tol_eta=None)
        cell = "free" if folder.endswith("-free") else "fixed"
        tests.append({"folder": folder, "cell": cell, "e0": float(t["e"][0]), "t": t, "check": chk,
                      "steady": bool(chk["reached"]) and t["status"].startswith("done")})
    rows, fits = [], {}
    # e_c and M: one material's, from every steady test of either cell (the same samples).
    steady = [x for x in tests if x["steady"]]
    if not steady:
        print("no test is steady at its end: e_c unknown", file=sys.stderr)
        return 1
    e_c = float(np.mean([x["check"]["point"]["e"] for x in steady]))
    M = float(np.mean([x["check"]["point"]["eta"] for x in steady]))
    for cell in ("fixed", "free", "both"):
        group = [x for x in tests if cell == "both" or x["cell"] == cell]
        dil = {}
        for x in group:
            t = x["t"]
            dl = dilatancy.plastic_dilatancy(t["eps_v"], t["eps_q"], t["p"], t["q"],
                                             others={"eta": t["eta"], "e": t["e"], "p": t["p"]})
            dl["psi"] = dl["e"] - e_c
            dil[x["folder"]] = dl
        # the initial d-eta slope of the two densest samples (their pre-peak branch)
        dense = sorted(group, key=lambda x: x["e0"])[:2]
        slopes = [dilatancy.initial_linear_part(dil[x["folder"]]["eta"], dil[x["folder"]]["d"],
                                                dil[x["folder"]]["mask"])[1] for x in dense]
        s = float(np.nanmean(slopes)) if np.any(np.isfinite(slopes)) else math.nan
        psi, eta_star = [], []
        for x in group:
            dl = dil[x["folder"]]
            idx = np.nonzero(dl["mask"])[0]
            peak = int(idx[int(np.nanargmax(dl["eta"][idx]))]) if idx.size else None
            pt = dilatancy.phase_transformation(dl["d"], dl["mask"], {"eta": dl["eta"], "psi": dl["psi"]},
                                                end=peak)
            if pt is not None:
                state = {"kind": "phase transformation", "eta": pt["eta"], "psi": pt["psi"], "eta_star": pt["eta"]}
            elif idx.size and math.isfinite(s) and s < 0:
                k = idx[int(np.nanargmax(dl["eta"][idx]))]
                star = float(dl["eta"][k] - dl["d"][k] / s)
                state = {"kind": "peak", "eta": float(dl["eta"][k]), "psi": float(dl["psi"][k]),
                         "eta_star": star if star > 0 else math.nan}
            else:
                state = {"kind": "none", "eta": math.nan, "psi": math.nan, "eta_star": math.nan}
            ok = x["t"]["status"].startswith("done")
            if ok and math.isfinite(state["eta_star"]):
                psi.append(state["psi"])
                eta_star.append(state["eta_star"])
            if cell != "both":
                rows.append({"folder": x["folder"], "cell": cell, "status": x["t"]["status"], "e0": x["e0"],
                             "psi0": x["e0"] - e_c, "steady_end": x["steady"],
                             "e_end": x["check"]["point"]["e"], "eta_end": x["check"]["point"]["eta"],
                             "state": state["kind"], "eta_state": state["eta"], "psi_state": state["psi"],
                             "eta_star": state["eta_star"]})
        fit = dilatancy.fit_m_pt(psi, eta_star, M)
        fits[cell] = {"e_c": e_c, "M": M, "initial_slope": s, "n_steady": len(steady), **fit}
        if cell == "both":
            fits[cell]["verdict"] = "(pooled: the same samples in two cells, not independent; no verdict)"
    with open(os.path.join(a.out, "states.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0].keys()) if rows else ["folder"])
        w.writeheader()
        for r in rows:
            w.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in r.items()})
    with open(os.path.join(a.out, "m.json"), "w") as f:
        json.dump(fits, f, indent=1, sort_keys=True, default=float)
    for r in rows:
        print(f"{r['folder']:10s} {r['status']:22s} e0 {r['e0']:.4f} psi0 {r['psi0']:+.3f} {r['state']:20s} "
              f"eta* {r['eta_star']:.3f} psi {r['psi_state']:+.3f} steady end {r['steady_end']}")
    for cell, fit in fits.items():
        print(f"{cell}: e_c {fit['e_c']:.4f} M {fit['M']:.3f}: m = {fit['m']:.3g}, 95 % [{fit['interval'][0]:.3g}, "
              f"{fit['interval'][1]:.3g}] (n {fit['n']}, psi span {fit['psi_span']:.3f}): {fit['verdict']} "
              f"{fit['note']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
