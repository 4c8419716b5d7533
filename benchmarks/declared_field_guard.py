"""A declared uniform field that is wrong: is it believed?

``nnphd detect --field uniform`` lets the fit of the positions beside a uniform field decide a throw. Along one arc a
field that varies over the record, fitted as uniform, leaves a remainder that a candidate law can fit — so a wrong
declaration could turn into a confident "detected". A drag opposes the velocity; that remainder does not
(``nnphd.user.rules.DRAG_ALONG_MIN``). This runs ``detect`` at its defaults with ``field="uniform"`` on

- the throw look-alike of ``benchmarks/friction_laws.py`` (quadratic drag c = 0.021 /m): truth "detected";
- the same throw without drag: truth "none";
- the same throw in a 1/r² field about a centre R = 5, 20, 100 m below the release (g = 9.81 there), no drag: the
  declaration is wrong and there is no non-conservative force, so "none" or "inconclusive" is right (one arc cannot
  tell a varying field from a drag) and "detected" is wrong;

on seeds 0, 1, 2 (noise draw and model seed), and prints per run the verdict, the law, the share of its force that
opposes the velocity, and the time.

    python benchmarks/declared_field_guard.py [--seeds 0,1,2] [--json results/declared_field_guard.json]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import tempfile
import time

import numpy as np
from scipy.integrate import solve_ivp

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

import nnphd  # noqa: E402
from nnphd.user.detect import detect_file  # noqa: E402

G = 9.81
START, SPEED, ANGLE, DURATION, FS, NOISE = (0.0, 2.0), 6.5, 55.0, 1.2, 60.0, 0.003  # as the throw-2d look-alike
CASES = {  # name: (centre distance R below the release, m (inf: uniform); drag c, 1/m; the right status
    # ("not-detected": none or inconclusive))
    "throw-drag": (math.inf, 0.021, "detected"),
    "throw-no-drag": (math.inf, 0.0, "none"),
    "arc-R5": (5.0, 0.0, "not-detected"),
    "arc-R20": (20.0, 0.0, "not-detected"),
    "arc-R100": (100.0, 0.0, "not-detected"),
}


def arc(R: float, c: float, seed: int):
    """(t, noisy positions (N, 2)) of the throw in a field g·(R/r)² towards a centre R below the release."""
    gm = G * R * R

    def rhs(_t, y):
        v = y[2:]
        if math.isinf(R):
            acc = np.array([0.0, -G])
        else:
            d = np.array([y[0] - START[0], y[1] - START[1] + R])
            acc = -gm * d / np.linalg.norm(d) ** 3
        return np.concatenate([v, acc - c * math.hypot(v[0], v[1]) * v])

    a = math.radians(ANGLE)
    t = np.arange(int(round(DURATION * FS)) + 1) / FS
    sol = solve_ivp(rhs, (0, t[-1]), [*START, SPEED * math.cos(a), SPEED * math.sin(a)], t_eval=t, method="DOP853",
                    rtol=1e-11, atol=1e-12)  # fmt: skip
    q = sol.y[:2].T
    return t, q + NOISE * np.random.default_rng(seed).standard_normal(q.shape)


def run(name: str, seed: int, folder: str) -> dict:
    R, c, truth = CASES[name]
    t, q = arc(R, c, seed)
    path = os.path.join(folder, f"{name}-{seed}.csv")
    np.savetxt(path, np.c_[t, q], delimiter=",", header="t,x,y", comments="", fmt="%.6f")
    t0 = time.perf_counter()
    rep = detect_file(path, seed=seed, sr_time=0, field="uniform")
    wall = time.perf_counter() - t0
    lw = rep.get("law") or {}
    law = lw.get("law") or lw.get("candidate_law") or {}
    return {
        "case": name,
        "seed": seed,
        "truth": truth,
        "status": rep["status"],
        "right": rep["status"] in ("none", "inconclusive") if truth == "not-detected" else rep["status"] == truth,
        "law": law.get("law"),
        "law_status": lw.get("status"),
        "params": law.get("params"),
        "against_velocity": rep["field"].get("against_velocity"),
        "g": rep["field"].get("g"),
        "reason": rep["reasons"][0] if rep["reasons"] else "",
        "seconds": round(wall, 1),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", default="0,1,2")
    ap.add_argument("--cases", default=",".join(CASES))
    ap.add_argument("--json", default=None)
    a = ap.parse_args()
    nnphd.configure()
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        for name in a.cases.split(","):
            for s in (int(x) for x in a.seeds.split(",")):
                r = run(name, s, folder)
                rows.append(r)
                along = "—" if r["against_velocity"] is None else f"{100 * r['against_velocity']:.0f}%"
                print(f"{name:14s} seed {s}  truth {r['truth']:12s} got {r['status']:12s} law {r['law'] or '—':16s} "
                      f"opposes v: {along:>5s}  {r['seconds']:6.1f} s", flush=True)  # fmt: skip
    right = sum(r["right"] for r in rows)
    print(
        f"right: {right}/{len(rows)}; wrong 'detected': {sum(r['status'] == 'detected' and not r['right'] for r in rows)}"
    )
    if a.json:
        out = {"cases": {k: {"R": v[0] if math.isfinite(v[0]) else None, "c": v[1], "truth": v[2]}
                         for k, v in CASES.items()}, "rows": rows, "right": right, "n": len(rows)}  # fmt: skip
        tmp = a.json + ".tmp"
        with open(tmp, "w") as f:
            json.dump(out, f, indent=1, ensure_ascii=False)
        os.replace(tmp, a.json)


if __name__ == "__main__":
    main()
