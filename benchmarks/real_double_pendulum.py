"""Issue 30 on the real chaotic double pendulum: the verdict of ``nnphd detect`` on each run of
../shared/data/real/ibm_double_pendulum_runs5-20.csv (IBM "Double Pendulum Chaotic", a high-speed camera; absolute
angles, unwrapped through whole turns; it loses most of its energy over each run: the right verdict is "detected").

    .venv/bin/python benchmarks/real_double_pendulum.py [--runs 5,6,...] [--stride 4] [--seconds 12] [--seed 0]
                                                       [--json out.json]

Each run is taken every ``stride``-th frame (the nominal 400 Hz / 4 = 100 Hz) over its first ``seconds`` (0: the
whole run, ~45 s, ~9 min a run here) and given to ``nnphd detect`` as one file with both angles declared (default
settings except no genetic symbolic regression, as benchmarks/real_friction.py). Prints, per run: the verdict, its
confidence, each seed's energy-trend z and shooting-probe d ± se (or why it is not valid), the law's status, the
seconds; and the share of runs "detected". The JSON adds each run's stage seconds, and the thinning of a dense record
(``--stride 1``: the full 400 Hz, one row in 4 used once the derivatives are estimated).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

import nnphd

nnphd.configure()  # float64 and the XLA:CPU setting, as the CLI

from nnphd.user.detect import detect_file

DATA = os.path.join(os.path.dirname(ROOT), "shared", "data", "real", "ibm_double_pendulum_runs5-20.csv")


def _probe(checks: dict, k: int) -> str:
    s = checks["shooting"]
    if not s["valid"][k]:
        return "not valid"
    return f"{s['d_mean'][k]:.3g} ± {s['se_d_mean'][k]:.2g} (z {s['z'][k]:.1f})"


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", default="")
    ap.add_argument("--stride", type=int, default=4)
    ap.add_argument("--seconds", type=float, default=12.0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", default=None)
    a = ap.parse_args()
    if not os.path.exists(DATA):
        sys.exit(f"error: {DATA} is not here (../shared beside the checkout)")
    d = np.genfromtxt(DATA, delimiter=",", names=True)
    runs = [int(r) for r in np.unique(d["traj"])]
    if a.runs:
        runs = [r for r in runs if str(r) in a.runs.split(",")]
    print("| run | rows | verdict (confidence) | energy z per seed | shooting d per seed | law | s |")
    print("|---|---|---|---|---|---|---|")
    out = []
    with tempfile.TemporaryDirectory() as tmp:
        for run in runs:
            m = d["traj"] == run
            t, a1, a2 = d["t"][m][:: a.stride], d["theta1"][m][:: a.stride], d["theta2"][m][:: a.stride]
            t = t - t[0]
            keep = t <= a.seconds if a.seconds > 0 else np.ones(len(t), bool)
            path = os.path.join(tmp, f"run{run}.csv")
            np.savetxt(path, np.c_[t[keep], a1[keep], a2[keep]], delimiter=",", header="t,theta1,theta2",
                       comments="", fmt="%.6f")  # fmt: skip
            t0 = time.perf_counter()
            rep = detect_file(path, None, angles=("theta1", "theta2"), seed=a.seed, sr_time=0)
            wall = time.perf_counter() - t0
            c = rep["checks"]
            seeds = range(len(c["energy_trend"]["z"]))
            ez = ", ".join(f"{z:.1f}" if v else "—" for z, v in zip(c["energy_trend"]["z"], c["energy_trend"]["valid"]))
            sd = "; ".join(_probe(c, k) for k in seeds)
            law = rep["law"]
            print(f"| {run} | {int(keep.sum())} | {rep['status']} ({rep['confidence']:.2f}) | {ez} | {sd} | "
                  f"{law.get('status', 'none')} | {wall:.0f} |", flush=True)  # fmt: skip
            out.append(
                {
                    "run": run,
                    "rows": int(keep.sum()),
                    "stride": a.stride,
                    "seconds": a.seconds,
                    "seed": a.seed,
                    "status": rep["status"],
                    "confidence": rep["confidence"],
                    "reasons": rep["reasons"],
                    "energy_trend": {k: c["energy_trend"][k] for k in ("z", "rate", "valid")},
                    "shooting": {k: c["shooting"][k] for k in ("d_mean", "se_d_mean", "z", "valid")},
                    "shooting_reason": [p.get("shooting", {}).get("reason") for p in c.get("per_seed", [])],
                    "shooting_windows": [p.get("shooting", {}).get("window_periods") for p in c.get("per_seed", [])],
                    "law_status": law.get("status"),
                    "law_reason": law.get("reason"),
                    "wall_s": wall,
                    "thinned": rep["data"].get("thinned"),
                    "stages_s": {st["stage"]: st["s"] for st in rep["timings"]["stages"]},
                    "compile_s": rep["timings"]["compile_s"],
                }
            )
            if a.json:
                with open(a.json + ".tmp", "w") as f:
                    json.dump(out, f, indent=1)
                os.replace(a.json + ".tmp", a.json)
    det = sum(r["status"] == "detected" for r in out)
    print(f"\ndetected: {det} of {len(out)} runs; {sum(r['wall_s'] for r in out):.0f} s in all")


if __name__ == "__main__":
    main()
