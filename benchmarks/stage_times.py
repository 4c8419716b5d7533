"""Where ``nnphd detect`` spends its time (issue 31): each file run twice through the CLI in a fresh process at its
default settings (no genetic symbolic regression, as benchmarks/real_friction.py) — first with an empty persistent
compilation cache (cold), then again with the cache the first run filled (warm) — and the per-stage table of its
report.json (``timings``: wall and JAX-compile seconds per stage, :mod:`nnphd.io.timing`).

    .venv/bin/python benchmarks/stage_times.py [--cases name,...] [--real name,...] [--seed 0] [--json out.json]
                                               [--workers N]

Cases: the look-alikes of tests/fixtures/friction.py (default: viscous-dry, heavy-damping, jitter-clock,
linear-quadratic) and the real recordings of benchmarks/results/friction_reference.json (default:
servo_sts3250_drop, seismometer_blow; file names without .csv). Prints per file and run the wall seconds per stage, of them compiling, and the totals;
the same verdict cold and warm is checked (the same seed gives the same numbers). A stage marked ∥ ran on another
thread beside the others (the law table on the conservative library beside the training, the figures of the
training beside the law table): its seconds overlap theirs.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from tests.fixtures.friction import NAMES, make  # noqa: E402

STAGES = (
    "reading the file",
    "derivatives",
    "training and trust checks",
    "law table: pointwise fits",
    "law table: trajectory-level fits",
    "law table: rests, stops and envelope",
    "law table: a tie fitted over the whole record",
    "law table: the envelope picture",
    "law table: library base (alongside training)",
    "law table: library base, waited for",
    "blind formula",
    "figures (alongside the law table)",
    "figures",
)
SHORT = {
    "reading the file": "read",
    "derivatives": "deriv.",
    "training and trust checks": "training",
    "law table: pointwise fits": "law pw",
    "law table: trajectory-level fits": "law traj",
    "law table: rests, stops and envelope": "law rest",
    "law table: a tie fitted over the whole record": "whole rec.",
    "law table: the envelope picture": "envelope pic.",
    "law table: library base (alongside training)": "library ∥",
    "law table: library base, waited for": "library wait",
    "blind formula": "blind",
    "figures (alongside the law table)": "figures ∥",
    "figures": "figures",
}


def _real(name: str) -> tuple[str, list[str]]:
    """(path, angle columns) of a real recording named in results/friction_reference.json, as
    benchmarks/real_friction.py reads it."""
    with open(os.path.join(ROOT, "benchmarks", "results", "friction_reference.json")) as f:
        refs = json.load(f)["recordings"]
    ref = next((r for r in refs if os.path.splitext(os.path.basename(r["file"]))[0] == name), None)
    if ref is None:
        names = ", ".join(os.path.splitext(os.path.basename(r["file"]))[0] for r in refs)
        raise SystemExit(f"error: unknown real recording {name!r}; expected one of {names}")
    path = ref["file"] if os.path.isabs(ref["file"]) else os.path.join(ROOT, ref["file"])
    if not os.path.exists(path):
        raise SystemExit(f"error: {path} is not here (../shared beside the checkout)")
    return path, [ref["coordinate"]] if ref["model"] == "pendulum" else []


def _run(path: str, angles: list[str], seed: int, cache: str, out: str, workers: str = "") -> tuple[dict, float]:
    cmd = [
        sys.executable,
        "-c",
        "import sys; from nnphd.cli import main; sys.exit(main())",
        "detect",
        path,
        "--out",
        out,
        "--seed",
        str(seed),
        "--sr-time",
        "0",
    ]
    if angles:
        cmd += ["--angles", ",".join(angles)]
    if workers:
        cmd += ["--workers", workers]
    env = dict(os.environ, NNPHD_COMPILE_CACHE=cache, PYTHONPATH=os.path.join(ROOT, "src"))
    t0 = time.perf_counter()
    r = subprocess.run(cmd, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if r.returncode != 0:
        raise RuntimeError(f"{path}: nnphd detect exited {r.returncode}: {r.stderr.strip()[-300:]}")
    with open(os.path.join(out, "report.json")) as f:
        return json.load(f), wall


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cases", default="viscous-dry,heavy-damping,jitter-clock,linear-quadratic")
    ap.add_argument("--real", default="servo_sts3250_drop,seismometer_blow")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", default=None)
    ap.add_argument("--workers", default="", help="nnphd detect's --workers (default: its own, one per core)")
    a = ap.parse_args()
    work = tempfile.mkdtemp(prefix="nnphd-stages-")
    files = []
    for name in [n for n in a.cases.split(",") if n]:
        if name not in NAMES:
            raise SystemExit(f"error: unknown case {name!r}; expected some of {', '.join(NAMES)}")
        rec = make(name, seed=a.seed)
        files.append((name, rec.write_csv(os.path.join(work, f"{name}.csv")), list(rec.angles), rec.n_samples))
    for name in [n for n in a.real.split(",") if n]:
        path, angles = _real(name)
        with open(path) as f:
            rows = sum(1 for line in f if line.strip() and not line.startswith("#")) - 1
        files.append((name, path, angles, rows))
    head = " | ".join(SHORT[s] for s in STAGES)
    print(f"| file | rows | cache | verdict | total s (process) | compile s | {head} |")
    print("|---" * (6 + len(STAGES)) + "|", flush=True)
    out = []
    for name, path, angles, rows in files:
        cache = os.path.join(work, f"cache-{name}")  # empty: cold; the second run finds what the first compiled
        runs = {}
        for kind in ("cold", "warm"):
            rep, wall = _run(path, angles, a.seed, cache, os.path.join(work, f"out-{name}-{kind}"), a.workers)
            tm = rep["timings"]
            by = {s["stage"]: s for s in tm["stages"]}
            cells = " | ".join(f"{by[s]['s']:.1f} ({by[s]['compile_s']:.1f})" if s in by else "—" for s in STAGES)
            print(f"| {name} | {rows} | {kind} | {rep['status']} | {tm['total_s']:.1f} ({wall:.1f}) | "
                  f"{tm['compile_s']:.1f} | {cells} |", flush=True)  # fmt: skip
            runs[kind] = {
                "status": rep["status"],
                "law": (rep.get("law") or {}).get("status"),
                "total_s": tm["total_s"],
                "process_s": wall,
                "compile_s": tm["compile_s"],
                "compile_parts_s": tm.get("compile_parts_s"),  # of this process (the seeds' workers: in per_seed)
                "stages": tm["stages"],
                "per_seed": tm["per_seed"],
            }
        same = runs["cold"]["status"] == runs["warm"]["status"] and runs["cold"]["law"] == runs["warm"]["law"]
        out.append({"file": name, "rows": rows, "angles": angles, "seed": a.seed, "workers": a.workers or "default",
                    "same_verdict": same, **runs})  # fmt: skip
        if a.json:
            with open(a.json + ".tmp", "w") as f:
                json.dump(out, f, indent=1)
            os.replace(a.json + ".tmp", a.json)
    for kind in ("cold", "warm"):
        tot = sorted(r[kind]["total_s"] for r in out)
        comp = sum(r[kind]["compile_s"] for r in out)
        med = tot[len(tot) // 2] if len(tot) % 2 else 0.5 * (tot[len(tot) // 2 - 1] + tot[len(tot) // 2])
        print(f"\n{kind}: median {med:.1f} s, max {tot[-1]:.1f} s per file; compiling {comp:.0f} of "
              f"{sum(tot):.0f} s in all")  # fmt: skip
    print(f"same verdict and law cold and warm: {sum(r['same_verdict'] for r in out)} of {len(out)}")


if __name__ == "__main__":
    main()
