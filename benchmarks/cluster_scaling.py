"""What a cluster buys (issue 31): the makespan of a batch of ``nnphd detect`` files — and of the units of
``nnphd reproduce`` when its results.json is given — on 1, 2, 4, 16 and 64 workers, simulated from unit durations
measured on this machine (a list schedule, largest first, as nnphd.parallel.run_units hands units to Dask:
:func:`nnphd.parallel.list_schedule`), plus the overhead of Dask measured here: the start of a local cluster and
the cost per unit of a worker (trivial units through run_units on 2 workers: 8 and 512, medians of 3).

    .venv/bin/python benchmarks/cluster_scaling.py [--repeat 1,32] [--reproduce out/reproduce/results.json]
                                                   [--json benchmarks/results/cluster_scaling.json]

Unit durations: each file's wall time in benchmarks/results/workers_detect.json (8 constructed cases, one by one in
one process: ``file_s["1"]``) and, when present, the warm-cache totals of benchmarks/results/stage_times.json;
``--repeat k``: the batch is those files k times over (a batch of 8k files). Every machine this project runs on has
2 cores, so only 1 and 2 workers are ever measured; the rest is this simulation, which assumes each worker its own
core(s) like the one the durations were measured on, and the same unit times.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from nnphd.parallel import Unit, list_schedule, run_units  # noqa: E402

RESULTS = os.path.join(ROOT, "benchmarks", "results")
WORKERS = (1, 2, 4, 16, 64)


def measure_overhead(n_small: int = 8, n_large: int = 512, repeats: int = 3) -> dict:
    """Dask's own cost here: trivial units (``dict(i=i)``) through run_units on 2 local workers, a few and many, each
    ``repeats`` times (medians) — the difference gives the cost per unit of a worker, the rest the start (and stop)
    of the cluster."""
    import statistics

    walls = {n_small: [], n_large: []}
    for _ in range(repeats):
        for n in (n_small, n_large):
            t0 = time.perf_counter()
            outs = run_units([Unit(f"u{i}", dict, {"i": i}) for i in range(n)], workers=2)
            walls[n].append(time.perf_counter() - t0)
            assert all(o.ok for o in outs.values())
    med = {n: statistics.median(v) for n, v in walls.items()}
    per_unit = max((med[n_large] - med[n_small]) * 2 / (n_large - n_small), 0.0)  # 2 workers side by side
    startup = max(med[n_small] - per_unit * n_small / 2, 0.0)
    return {"startup_s": startup, "per_unit_s": per_unit, "walls_s": {str(k): v for k, v in walls.items()}}


def _batches() -> dict[str, list[float]]:
    out = {}
    p = os.path.join(RESULTS, "workers_detect.json")
    if os.path.exists(p):
        with open(p) as f:
            out["detect: 8 constructed cases (300 steps)"] = list(json.load(f)["file_s"]["1"].values())
    p = os.path.join(RESULTS, "stage_times.json")
    if os.path.exists(p):
        with open(p) as f:
            rows = json.load(f)
        out[f"detect: {len(rows)} files of stage_times.json (defaults, warm cache)"] = [
            r["warm"]["total_s"] for r in rows
        ]
    return out


def _reproduce_units(path: str) -> list[float]:
    with open(path) as f:
        runs = json.load(f)["runs"]
    return [r["compute_time_s"] for r in runs.values() if "compute_time_s" in r]


def simulate(durations: list[float], overhead: dict) -> list[dict]:
    base = None
    rows = []
    for w in WORKERS:
        s = list_schedule(durations, w, overhead["per_unit_s"] if w > 1 else 0.0)
        makespan = s["makespan_s"] + (overhead["startup_s"] if w > 1 else 0.0)
        base = base or makespan
        rows.append({
            "workers": w,
            "makespan_s": makespan,
            "speedup": base / makespan,
            "efficiency": sum(durations) / (w * makespan),
        })  # fmt: skip
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", default="1,32", help="comma-separated: each batch k times over")
    ap.add_argument("--reproduce", default=None, help="a results.json of nnphd reproduce (its units' times)")
    ap.add_argument("--json", default=None)
    a = ap.parse_args()
    overhead = measure_overhead()
    print(f"Dask here: a local cluster starts (and stops) in {overhead['startup_s']:.1f} s; a worker's cost per "
          f"unit {1000 * overhead['per_unit_s']:.0f} ms")  # fmt: skip
    sets = {}
    for name, d in _batches().items():
        for k in [int(x) for x in a.repeat.split(",") if x]:
            sets[f"{name} × {k} = {k * len(d)} files"] = d * k
    if a.reproduce:
        sets["reproduce: its units"] = _reproduce_units(a.reproduce)
    if not sets:
        sys.exit("error: no measured unit durations (benchmarks/results/workers_detect.json, stage_times.json)")
    out = {"overhead": overhead, "workers": list(WORKERS), "sets": {}}
    for name, d in sets.items():
        rows = simulate(d, overhead)
        out["sets"][name] = {"n_units": len(d), "work_s": sum(d), "longest_s": max(d), "rows": rows}
        print(f"\n{name}: {len(d)} units, {sum(d):.0f} s of work, the longest {max(d):.0f} s")
        print("| workers | makespan s | speed-up | efficiency |\n|---|---|---|---|")
        for r in rows:
            print(f"| {r['workers']} | {r['makespan_s']:.0f} | {r['speedup']:.2f} | {r['efficiency']:.2f} |")
    if a.json:
        with open(a.json + ".tmp", "w") as f:
            json.dump(out, f, indent=1)
        os.replace(a.json + ".tmp", a.json)


if __name__ == "__main__":
    main()
