"""float32 against float64 training (what a GPU user may choose): the λ-sweep verdict of every toy system
(HO+MF … HO+PF) and of the three Table I systems, at the paper's settings, in both precisions, in one run.

.venv/bin/python benchmarks/float32_accuracy.py [--steps 2000] [--systems ho+mf,ho+ld,...] [--workers 2]
.venv/bin/python benchmarks/float32_accuracy.py --table2 [--steps 2000] [--workers 2]

Prints a table (system, verdict and L_e ratio across λ = 1 in float64 and float32, the largest relative difference
of L_e over the λ grid) and writes benchmarks/results/float32.json. Each (system, precision) sweep is one unit of
nnphd.parallel.run_units.

``--table2``: ``nnphd discover`` of the three Table I systems (the detection sweep, the constrained Lagrangian + UAN,
the law fitted jointly with it; no genetic regression) in both precisions: the Table II rows, each against the goal
of the paper's table, and the verdicts; writes benchmarks/results/float32_table2.json.
"""

import argparse
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import nnphd

nnphd.configure()

from nnphd.engine.models import ModelConfig
from nnphd.engine.systems import get_system
from nnphd.paper.discover import DISCOVERY_SYSTEMS, DiscoverSettings, discover
from nnphd.paper.sweep import SweepSettings, run_sweep
from nnphd.parallel import Unit, run_units

SYSTEMS = ["ho+mf", "ho+cg", "ho+ld", "ho+cd", "ho+pf", "double-pendulum", "neptune", "gw"]


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--systems", default=",".join(SYSTEMS))
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--table2", action="store_true", help="Table II (nnphd discover) in both precisions")
    a = ap.parse_args()
    if a.table2:
        return table2(a.steps, a.workers)
    systems = a.systems.split(",")
    units = [
        Unit(
            f"{s}/{dt}",
            run_sweep,
            dict(
                system=s,
                settings=SweepSettings(steps=a.steps, seed=0, model_cfg=ModelConfig(n=get_system(s).n, dtype=dt)),
            ),
        )
        for s in systems
        for dt in ("float64", "float32")
    ]
    outs = run_units(units, workers=a.workers, progress=lambda d, t, m: print(f"[{d}/{t}] {m}", flush=True))
    rows = []
    print(f"{'system':16s} {'float64':>22s} {'float32':>22s} {'max rel. diff of L_e':>22s}")
    for s in systems:
        r64, r32 = outs[f"{s}/float64"].value, outs[f"{s}/float32"].value
        le64 = [x.L_e for x in r64.table]
        le32 = [x.L_e for x in r32.table]
        diff = max(abs(x - y) / abs(x) for x, y in zip(le64, le32))
        row = {
            "system": s,
            "truth_conservative": r64.truth_conservative,
            "float64": {"new_physics": r64.new_physics, "ratio": r64.le_ratio},
            "float32": {"new_physics": r32.new_physics, "ratio": r32.le_ratio},
            "same_verdict": r64.new_physics == r32.new_physics,
            "max_rel_diff_L_e": diff,
            "wall_s": {"float64": outs[f"{s}/float64"].wall_time_s, "float32": outs[f"{s}/float32"].wall_time_s},
        }
        rows.append(row)
        v = lambda r: f"{'new' if r['new_physics'] else 'none'} ×{r['ratio']:.3g}"  # noqa: E731
        print(f"{s:16s} {v(row['float64']):>22s} {v(row['float32']):>22s} {diff:>22.3g}")
    print(f"same verdict on {sum(r['same_verdict'] for r in rows)} of {len(rows)} systems")
    out = {"steps": a.steps, "rows": rows}
    (ROOT / "benchmarks" / "results" / "float32.json").write_text(json.dumps(out, indent=1))


def table2(steps: int, workers: int | None) -> None:
    units = [
        Unit(
            f"{s}/{dt}",
            discover,
            dict(system=s, settings=DiscoverSettings(steps=steps, sweep_steps=steps, seed=0, sr_time=0.0, dtype=dt)),
        )
        for s in DISCOVERY_SYSTEMS
        for dt in ("float64", "float32")
    ]
    outs = run_units(units, workers=workers, progress=lambda d, t, m: print(f"[{d}/{t}] {m}", flush=True))
    rows, systems = [], []
    print(f"{'system':16s} {'quantity':9s} {'truth':>9s} {'float64 ± se':>22s} {'float32 ± se':>22s}  goal: met 64/32")
    for s in DISCOVERY_SYSTEMS:
        r64, r32 = outs[f"{s}/float64"].value, outs[f"{s}/float32"].value
        systems.append(
            {
                "system": s,
                "new_physics": {"float64": r64["new_physics"], "float32": r32["new_physics"]},
                "ratio": {"float64": r64["verdict"]["ratio"], "float32": r32["verdict"]["ratio"]},
                "law_winner": {"float64": r64["law_winner"], "float32": r32["law_winner"]},
                "wall_s": {"float64": r64["wall_time_s"], "float32": r32["wall_time_s"]},
            }
        )
        for x64, x32 in zip(r64["table2"], r32["table2"]):
            rows.append(
                {
                    "system": s,
                    **{k: x64[k] for k in ("quantity", "truth", "paper", "goal")},
                    "float64": x64,
                    "float32": x32,
                }
            )
            pm = lambda x: f"{x['ours']:.6g} ± {x['stderr']:.2g}"  # noqa: E731
            met = lambda x: "yes" if x["goal_met"] else "NO"  # noqa: E731
            print(
                f"{s:16s} {x64['quantity']:9s} {x64['truth']:>9.4g} {pm(x64):>22s} {pm(x32):>22s}  "
                f"{x64['goal']}: {met(x64)}/{met(x32)}"
            )
    for r in systems:
        print(
            f"{r['system']}: verdict {r['new_physics']['float64']}/{r['new_physics']['float32']}, ratio "
            f"{r['ratio']['float64']:.3g}/{r['ratio']['float32']:.3g}, law {r['law_winner']['float64']}/"
            f"{r['law_winner']['float32']}, {r['wall_s']['float64']:.0f}/{r['wall_s']['float32']:.0f} s"
        )
    n64 = sum(r["float64"]["goal_met"] for r in rows)
    n32 = sum(r["float32"]["goal_met"] for r in rows)
    print(f"Table II goals met: float64 {n64} of {len(rows)}, float32 {n32} of {len(rows)}")
    out = {"steps": steps, "rows": rows, "systems": systems}
    (ROOT / "benchmarks" / "results" / "float32_table2.json").write_text(json.dumps(out, indent=1, default=str))


if __name__ == "__main__":
    main()
