"""Time to a verdict: the paper's protocol (13 λ × 2000 steps, warm start) against ``--mode fast`` (each λ until
converged, 4 λ first, the paper protocol itself when that verdict is close), on every toy system and the three Table I
systems, in one run, one after the other in this process.

.venv/bin/python benchmarks/time_to_verdict.py [--systems ho+mf,ho+ld,...] [--seeds 0] [--chunk 100] [--rel-tol 0.02]

Prints, per system and seed: the verdict and L_e ratio of both, their wall times (compilation included) and training
steps, and the totals; writes benchmarks/results/time_to_verdict.json. Goal (issue 14): fast total time ≤ 1/3 of
the paper protocol's, with the same verdict everywhere.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_speed import machine_info, write_json

from nnphd.engine.adaptive import StopRule, fast_sweep
from nnphd.engine.systems import get_system
from nnphd.engine.train import PAPER_LAMBDAS, SweepSchedule, sweep
from nnphd.engine.verdict import force_norm, verdict
from nnphd.paper.sweep import SweepSettings, plan_sweep

SYSTEMS = ["ho+mf", "ho+cg", "ho+ld", "ho+cd", "ho+pf", "double-pendulum", "neptune", "gw"]


def one(system: str, seed: int, mode: str, rule: StopRule) -> dict:
    sysm = get_system(system)
    t0 = time.perf_counter()
    plan = plan_sweep(sysm, SweepSettings(seed=seed, mode="warm"))
    common = dict(seed=seed, test_data=plan.test)
    if mode == "fast":
        points, info = fast_sweep(plan.train, plan.cfg, plan.tcfg, PAPER_LAMBDAS, rule=rule, **common)
        steps = info.to_dict()["steps_total"]
        extra = {"lambdas": [p.lam for p in points], "doubts": info.doubts, "ran_paper_protocol": info.paper_protocol}
    else:
        points = sweep(
            plan.train, plan.cfg, plan.tcfg, SweepSchedule(PAPER_LAMBDAS, "warm"), keep_params=False, **common
        )
        steps, extra = plan.tcfg.steps * len(PAPER_LAMBDAS), {}
    ev = plan.test if plan.test is not None else plan.train
    v = verdict(points, force_norm(ev.qdd, plan.tcfg.p))
    return {
        "new_physics": v.new_physics,
        "ratio": v.ratio,
        "relative_size": v.relative_size,
        "wall_s": time.perf_counter() - t0,
        "steps": steps,
        **extra,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--systems", default=",".join(SYSTEMS))
    ap.add_argument("--seeds", default="0", help="comma-separated seeds")
    ap.add_argument("--chunk", type=int, default=StopRule().chunk)
    ap.add_argument("--rel-tol", type=float, default=StopRule().rel_tol)
    ap.add_argument("--only-fast", action="store_true", help="skip the paper protocol (for tuning)")
    a = ap.parse_args()
    import nnphd

    nnphd.configure()
    rule = StopRule(a.chunk, a.rel_tol)
    info = machine_info()
    print(f"machine: {info['cpu_model']}, nproc={info['nproc']}, load {info['loadavg_1min']:.2f}; {rule}")
    print(
        f"{'system':<16} {'seed':>4} | {'paper: verdict':>14} {'ratio':>8} {'s':>6} {'steps':>6} | "
        f"{'fast: verdict':>13} {'ratio':>8} {'s':>6} {'steps':>6} {'λ':>3}  same"
    )
    rows = []
    for system in a.systems.split(","):
        for seed in (int(s) for s in a.seeds.split(",")):
            paper = None if a.only_fast else one(system, seed, "warm", rule)
            fast = one(system, seed, "fast", rule)
            same = None if paper is None else paper["new_physics"] == fast["new_physics"]
            rows.append({"system": system, "seed": seed, "paper": paper, "fast": fast, "same_verdict": same})
            pv = (
                f"{str(paper['new_physics']):>14} {paper['ratio']:>8.3g} {paper['wall_s']:>6.1f} {paper['steps']:>6}"
                if paper
                else f"{'-':>14} {'':>8} {'':>6} {'':>6}"
            )
            print(
                f"{system:<16} {seed:>4} | {pv} | {str(fast['new_physics']):>13} {fast['ratio']:>8.3g} "
                f"{fast['wall_s']:>6.1f} {fast['steps']:>6} {len(fast['lambdas']):>3}  {same}",
                flush=True,
            )
    tot = {k: sum(r[k]["wall_s"] for r in rows if r[k]) for k in ("paper", "fast")}
    summary = {
        "paper_s": tot["paper"],
        "fast_s": tot["fast"],
        "fast_over_paper": tot["fast"] / tot["paper"] if tot["paper"] else None,
        "all_same_verdict": all(r["same_verdict"] for r in rows) if not a.only_fast else None,
    }
    if not a.only_fast:
        print(
            f"\ntotal: paper {tot['paper']:.1f} s, fast {tot['fast']:.1f} s = {summary['fast_over_paper']:.2f} of the "
            f"paper's (goal ≤ 0.33); same verdict everywhere: {summary['all_same_verdict']}"
        )
    path = Path(__file__).resolve().parent / "results" / "time_to_verdict.json"
    if not a.only_fast:
        write_json(
            path,
            {
                "machine": info,
                "args": vars(a),
                "rows": rows,
                "summary": summary,
                "timestamp": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
            },
        )
        print(f"wrote {path}")


if __name__ == "__main__":
    main()
