"""Speed-up of the Dask execution layer (nnphd.parallel) on this machine: the same work with 1 worker (in this
process) and with N local worker processes, in one run; checks that the numbers are identical.

.venv/bin/python benchmarks/bench_workers.py lambda-p [--steps 2000] [--workers 2]
.venv/bin/python benchmarks/bench_workers.py reproduce [--quick] [--workers 2]
.venv/bin/python benchmarks/bench_workers.py detect [--workers 2] [--detect-steps 1000]   # 8 noisy cases: batch vs one by one

Prints the wall times and their ratio and writes benchmarks/results/workers_<what>.json.
"""

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import nnphd

nnphd.configure()

CASES = [
    "morse",
    "pendulum",
    "kepler2d-eccentric",
    "magnetic2d",
    "anharmonic+drag",
    "kepler2d+drag",
    "anharmonic+drive",
    "vanderpol",
]


def _lambda_p(workers: int, steps: int, out: Path) -> tuple[float, dict]:
    from nnphd.paper.lambda_p import LambdaPSettings, lambda_p_study

    t0 = time.perf_counter()
    r = lambda_p_study(LambdaPSettings(steps=steps, seed=0), out=out, workers=workers)
    return time.perf_counter() - t0, {f"{v.system} p={v.p}": [v.ratio, v.new_physics] for v in r.verdicts}


def _reproduce(workers: int, quick: bool, out: Path) -> tuple[float, dict]:
    from nnphd.paper.reproduce import reproduce

    t0 = time.perf_counter()
    s = reproduce(out=out, quick=quick, seed=0, workers=workers)
    assert not s["failed"], s["failed"]
    return time.perf_counter() - t0, {c["claim"]: [c["ours"], c["met"]] for c in s["claims"]}


def _write_cases(d: Path) -> list[Path]:
    import numpy as np

    from tests.fixtures.cases import make_case

    paths = []
    for name in CASES:  # as benchmarks/detect_noisy_cases.py: 8 trajectories, 0.1 % noise on the positions
        data, traj = make_case(name, n_traj=8, seed=3)
        rng = np.random.default_rng(1)
        q = data.q + 1e-3 * data.q.std(axis=0) * rng.standard_normal(data.q.shape)
        cols = [f"q{i + 1}" for i in range(data.n)]
        p = d / f"{name}.csv"
        with open(p, "w") as fh:
            fh.write("traj,t," + ",".join(cols) + "\n")
            fh.writelines(
                f"{k},{ti:.6f}," + ",".join(f"{v:.10g}" for v in row) + "\n" for k, ti, row in zip(traj, data.t, q)
            )
        paths.append(p)
    return paths


def _detect(workers: int, paths: list[Path], out: Path, steps: int) -> tuple[float, dict]:
    from nnphd.user.batch import detect_batch
    from nnphd.user.detect import detect_file

    t0 = time.perf_counter()
    if workers == 1:  # one by one, as a user would call nnphd detect per file
        res = {}
        for p in paths:
            r = detect_file(p, out / p.stem, sr_time=0, steps=steps)
            res[p.stem] = [r["status"], r["confidence"], r["statistic"]["value"]]
    else:
        s = detect_batch(paths, out, workers=workers, sr_time=0, steps=steps)
        res = {}
        for row in s["rows"]:
            r = json.loads((out / row["name"] / "report.json").read_text())
            res[row["name"]] = [r["status"], r["confidence"], r["statistic"]["value"]]
    return time.perf_counter() - t0, res


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("what", choices=["lambda-p", "reproduce", "detect"])
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--detect-steps", type=int, default=1000, help="nnphd detect's --steps")
    a = ap.parse_args()
    tmp = Path(tempfile.mkdtemp(prefix="nnphd-bench-workers-"))
    runs = {}
    if a.what == "detect":
        (tmp / "cases").mkdir()
    paths = _write_cases(tmp / "cases") if a.what == "detect" else []
    for w in (1, a.workers):
        out = tmp / f"w{w}"
        if a.what == "lambda-p":
            wall, nums = _lambda_p(w, a.steps, out)
        elif a.what == "reproduce":
            wall, nums = _reproduce(w, a.quick, out)
        else:
            wall, nums = _detect(w, paths, out, a.detect_steps)
        runs[w] = {"wall_s": wall, "numbers": nums}
        print(f"{a.what}: {w} worker(s): {wall:.1f} s", flush=True)
    same = runs[1]["numbers"] == runs[a.workers]["numbers"]
    ratio = runs[1]["wall_s"] / runs[a.workers]["wall_s"]
    print(f"speed-up {a.workers} workers vs 1: {ratio:.2f}x; identical numbers: {same}")
    if a.what == "detect":  # each file's own time (its report's wall_time_s), one by one and in the batch
        for w, run in runs.items():
            run["file_s"] = {
                p.stem: json.loads((tmp / f"w{w}" / p.stem / "report.json").read_text())["wall_time_s"] for p in paths
            }
            print(f"per file, {w} worker(s): " + ", ".join(f"{k} {v:.1f} s" for k, v in run["file_s"].items()))
    res = {
        "what": a.what,
        "settings": {"workers": a.workers, "steps": a.steps, "quick": a.quick, "detect_steps": a.detect_steps},
        "cores": os.cpu_count(),
        "wall_s": {str(k): v["wall_s"] for k, v in runs.items()},
        "speedup": ratio,
        "identical_numbers": same,
        "numbers": {str(k): v["numbers"] for k, v in runs.items()},
        **({"file_s": {str(k): v["file_s"] for k, v in runs.items()}} if a.what == "detect" else {}),
    }
    name = f"workers_{a.what}{'_quick' if a.quick else ''}.json"
    (ROOT / "benchmarks" / "results" / name).write_text(json.dumps(res, indent=1, default=str))


if __name__ == "__main__":
    main()
