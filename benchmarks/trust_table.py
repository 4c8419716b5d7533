"""Run nnphd.user.assess.assess on every constructed case (tests/fixtures/cases.py) and print a table.

Config (documented "moderate" default): every case simulated with RK4 from random initial conditions
(8 trajectories, the case's T and dt; `--single` adds one-trajectory variants with 2T), assess(steps=1000 per λ and per
extra round, width 64, λ ∈ {0.05, 0.1, 0.2, 0.5, 2, 5, 10}, n_seeds=2, long_factor=3, a quarter of the trajectories
held out). The naive verdict is the package's own pipeline as run_sweep does it for trajectory data: train.sweep on
all the data (standardised inputs, the paper's 13 λ, same steps and width), L_e evaluated on the training data (the
paper's protocol), detect.verdict. "naive(held-out)" is the ratio of assess's own sweep on held-out trajectories.

    .venv/bin/python benchmarks/trust_table.py [--steps 1000] [--width 64] [--seeds 2] [--single] [--cases a,b]
"""

import argparse
import os
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

import nnphd

nnphd.configure()  # float64 and the XLA:CPU setting, as the CLI

from nnphd.engine.models import ModelConfig  # noqa: E402
from nnphd.engine.train import PAPER_LAMBDAS, SweepSchedule, TrainConfig, sweep
from nnphd.engine.verdict import force_norm, verdict
from nnphd.io.results import write_json
from nnphd.user.assess import AssessSettings, assess
from tests.fixtures.cases import CASES, make_case

ap = argparse.ArgumentParser()
ap.add_argument("--steps", type=int, default=1000)
ap.add_argument("--width", type=int, default=64)
ap.add_argument("--seeds", type=int, default=2)
ap.add_argument("--seed", type=int, default=0)
ap.add_argument("--ntraj", type=int, default=8)
ap.add_argument("--single", action="store_true", help="also one-trajectory variants (T doubled)")
ap.add_argument("--only-single", action="store_true")
ap.add_argument("--cases", default=None)
ap.add_argument("--json", default="/tmp/trust_table.json")
ap.add_argument(
    "--no-naive", action="store_true", help="skip the naive paper sweep (its code is not nnphd.user.assess)"
)
args = ap.parse_args()

names = args.cases.split(",") if args.cases else list(CASES)
runs = []
if not args.only_single:
    runs += [(n, args.ntraj, None) for n in names]
if args.single or args.only_single:
    runs += [(n, 1, 2 * CASES[n].T) for n in names]


def naive_paper(d, seed):
    cfg = ModelConfig(n=d.n, lnn_widths=(args.width,) * 2, uan_widths=(args.width,) * 2).standardized(d.q, d.qd, d.t)
    pts = sweep(d, cfg, TrainConfig(steps=args.steps), SweepSchedule(PAPER_LAMBDAS), seed=seed, keep_params=False)
    return verdict(pts, force_norm(d.qdd, 1.0))


def _write_json(rows):
    """Write the rows so far (a temporary file renamed over the target: a stopped run leaves a whole file)."""
    doc = {
        "config": {
            "steps": args.steps,
            "width": args.width,
            "n_seeds": args.seeds,
            "seed": args.seed,
            "ntraj": args.ntraj,
            "naive": not args.no_naive,
        },
        "rows": rows,
    }
    write_json(args.json, doc)  # numpy values as numbers; anything else JSON cannot hold is an error, not a string


hdr = (
    f"{'case':20s} {'K':>2s} {'truth':>9s} {'fn/f':>6s} | {'naive':>5s} {'ratio':>6s} {'ho-ratio':>8s} | "
    f"{'status':12s} {'call':5s} {'conf':>4s} {'stat':>5s} {'drift':>6s} {'t-gain':>6s} {'gap_tr':>6s} | "
    f"{'time':>5s}"
)
print(hdr)
print("-" * len(hdr))
out, reasons = [], []
for name, K, T in runs:
    c = CASES[name]
    d, traj = make_case(name, n_traj=K, seed=args.seed, T=T)
    frac = float(np.mean(np.abs(d.fn)) / np.mean(np.abs(d.qdd)))
    t0 = time.perf_counter()
    nv = (
        naive_paper(d, args.seed) if not args.no_naive else type("NV", (), {"new_physics": None, "ratio": float("nan")})
    )
    t_naive = time.perf_counter() - t0
    t0 = time.perf_counter()
    r = assess(d, traj, AssessSettings(seed=args.seed, steps=args.steps, width=args.width, n_seeds=args.seeds)).report
    t_assess = time.perf_counter() - t0
    ch = r["checks"]
    ho = np.median([x for x in ch["naive"]["ratio"] if x is not None])
    truth = "cons" if c.conservative else "NON-cons"
    ok = (r["status"] != "detected") if c.conservative else (r["status"] == "detected")
    row = (
        f"{name:20s} {K:2d} {truth:>9s} {frac:6.3f} | {('NEW' if nv.new_physics else ('no' if nv.new_physics is not None else '—')):>5s} {nv.ratio:6.2f} "
        f"{ho:8.2f} | {r['status']:12s} {r['new_physics']!s:5s} {r['confidence']:4.2f} "
        f"{(r['statistic']['value'] if r['statistic']['value'] is not None else float('nan')):5.2f} {np.median(ch['drift']['magnitude_median']):6.3f} "
        f"{np.median(ch['time']['gain']):6.2f} {np.median(ch['gap']['gap_train']):6.2f} | "
        f"{t_assess:4.0f}s {'ok' if ok else 'WRONG'}"
    )
    print(row, flush=True)
    reasons.append((name, K, r["reasons"]))
    out.append(
        {
            "case": name,
            "n_traj": K,
            "conservative": c.conservative,
            "fn_fraction": frac,
            "naive_paper": {"new_physics": nv.new_physics, "ratio": nv.ratio, "time_s": t_naive},
            "naive_heldout_ratio": ho,
            "status": r["status"],
            "new_physics": r["new_physics"],
            "confidence": r["confidence"],
            "statistic": r["statistic"]["value"],
            "reasons": r["reasons"],
            "checks": {k: v for k, v in ch.items() if k != "per_seed"},
            "table": r["table"],
            "time_s": t_assess,
            "correct": ok,
        }
    )
    _write_json(out)
print()
for name, K, rs in reasons:
    print(f"{name} (K={K}):")
    for x in rs:
        print("    " + x)
_write_json(out)
print(
    f"\nconfig: steps={args.steps} width={args.width} n_seeds={args.seeds} seed={args.seed} ntraj={args.ntraj}; "
    f"correct {sum(o['correct'] for o in out)}/{len(out)}",
    file=sys.stderr,
)
