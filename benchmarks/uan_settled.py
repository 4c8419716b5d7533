"""Does the UAN's output settle below λ = 1 on ``--mode fast``'s first chain? (the rule ``UAN_SETTLED``)

Theorem 1: at every λ < 1 the minimiser's UAN carries exactly f_n, so its output L_b is the same at each of them. The
fast mode's first chain (4 λ, warm) counts a claimed jump as close when L_b below λ = 1 varies ×1.5 or more between
its λ values. This script runs the chain on the cases the threshold was set on and prints, per case, the chain's
verdict, its L_e ratio and max/min of L_b below λ = 1; it writes benchmarks/results/uan_settled.json.

    .venv/bin/python benchmarks/uan_settled.py [--only ho+mf]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_speed import machine_info, write_json

# (system, seed, steps per λ, train = test samples): the paper's size, and the smaller runs of the tests
CASES = [
    ("ho+ld", 0, 2000, 1000),
    ("ho+cd", 0, 2000, 1000),
    ("ho+pf", 0, 2000, 1000),
    ("gw", 0, 2000, 1000),
    ("double-pendulum", 0, 2000, 1000),
    ("neptune", 0, 2000, 1000),
    *[(s, seed, 800, 300) for s in ("ho+ld", "ho+pf", "ho+cd") for seed in (0, 1, 2)],
    ("ho+mf", 0, 800, 300),
]
CONSERVATIVE = {"ho+mf", "ho+cg"}


def one(system: str, seed: int, steps: int, samples: int) -> dict:
    from nnphd.paper.sweep import SweepSettings, run_sweep

    t0 = time.perf_counter()
    res = run_sweep(system, SweepSettings(seed=seed, mode="fast", n_train=samples, n_test=samples, steps=steps))
    pr = res.protocol
    below = [c["L_b"] for c in pr["chain"] if c["lambda"] < 1]
    return {
        "system": system,
        "seed": seed,
        "steps": steps,
        "samples": samples,
        "truth_new_physics": system not in CONSERVATIVE,
        "chain": pr["chain"],
        "chain_verdict": pr["chain_verdict"],
        "lb_ratio": max(below) / max(min(below), 1e-300),
        "doubts": pr["doubts"],
        "ran_paper_protocol": pr["ran_paper_protocol"],
        "final": {"new_physics": bool(res.new_physics), "ratio": float(res.le_ratio)},
        "wall_s": time.perf_counter() - t0,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--only", default=None, help="comma-separated systems")
    a = ap.parse_args()
    import nnphd

    nnphd.configure()
    from nnphd.engine.adaptive import UAN_SETTLED

    rows = []
    for system, seed, steps, samples in CASES:
        if a.only and system not in a.only.split(","):
            continue
        r = one(system, seed, steps, samples)
        rows.append(r)
        cv = r["chain_verdict"]
        print(
            f"{system:<16} seed {seed} {steps:>5} steps {samples:>5} samples | chain: new physics {cv['new_physics']!s:5} "
            f"×{cv['ratio']:<8.3g} L_b max/min below 1 ×{r['lb_ratio']:.3g} | final {r['final']['new_physics']!s:5} "
            f"×{r['final']['ratio']:.3g} ({r['wall_s']:.0f} s)",
            flush=True,
        )
    path = Path(__file__).resolve().parent / "results" / "uan_settled.json"
    if not a.only:
        write_json(
            path,
            {
                "machine": machine_info(),
                "threshold": UAN_SETTLED,
                "rows": rows,
                "timestamp": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
            },
        )
        print(f"wrote {path}")


if __name__ == "__main__":
    main()
