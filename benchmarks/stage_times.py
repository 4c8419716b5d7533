"""Where ``nnphd detect`` spends its time (issue 31): each file run twice through the CLI in a fresh process at its
default settings (no genetic symbolic regression, as benchmarks/real_friction.py) — first with an empty persistent
compilation cache (cold), then again with the cache the first run filled (warm) — and the per-stage table of its
report.json (``timings``: wall and JAX-compile seconds per stage, :mod:`nnphd.io.timing`).

    .venv/bin/python benchmarks/stage_times.py [--cases name,...] [--real name,...] [--seed 0] [--json out.json]
                                               [--workers N] [--sr-time S] [--other-length F]
    .venv/bin/python benchmarks/stage_times.py --records held-out --sr-time 10 --other-length 0.8

``--records held-out``: issue 57's eleven records of other kinds (:data:`HELD_OUT`: 2-D look-alikes, a camera
double pendulum, a 2-D throw under a declared vertical field, the whole real IBM double-pendulum run 6 at 100 Hz,
real 1-D records with mixed friction); ``--records kind:name,...`` any of them (friction:, laws:, recordings:,
real:, ibm:RUN). ``--other-length F``: after the warm run, a copy of the file with its first F of rows is run with the
same cache — what a second file of another length still compiles. Results of the held-out set:
results/stage_times_held_out.json (two runs merged: ibm:6, laws:anisotropic-damping and real:servo_sts3250_drop at
--sr-time 10, the rest at 0).

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

from tests.fixtures import laws, recordings  # noqa: E402
from tests.fixtures.friction import NAMES, make  # noqa: E402

REAL = os.path.join(os.path.dirname(ROOT), "shared", "data", "real")
# issue 57's held-out set: records of other kinds than the ones the settings were tuned on — 2-coordinate look-alikes
# (a 2-D drag, a camera double pendulum in pixels, a 2-D throw under a declared vertical field), a 1-D Coulomb
# oscillator, a string pendulum in air, and real recordings (the IBM double pendulum at 100 Hz, the servo drop, an
# encoder pendulum, a seismometer, a video-tracked string pendulum)
HELD_OUT = (
    "laws:quadratic-drag-2d,recordings:double-pendulum-camera,friction:throw-2d,ibm:6,real:servo_sts3250_drop,"
    "real:encoder_pendulum_free_swing,real:seismometer_blow,real:video_string_pendulum_lab1,laws:dry-friction,"
    "friction:linear-quadratic,laws:anisotropic-damping"
)

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


def _ibm(run: int, path: str) -> tuple[str, list[str], int]:
    """Run ``run`` of the real IBM double pendulum (../shared/data/real), the whole run (about 45 s) at 100 Hz (every
    4th row of the 400 Hz record), written to ``path``."""
    import numpy as np

    d = np.genfromtxt(os.path.join(REAL, "ibm_double_pendulum_runs5-20.csv"), delimiter=",", names=True)
    m = d["traj"] == run
    t, a1, a2 = d["t"][m][::4], d["theta1"][m][::4], d["theta2"][m][::4]
    np.savetxt(path, np.c_[t - t[0], a1, a2], delimiter=",", header="t,theta1,theta2", comments="", fmt="%.6f")
    return path, ["theta1", "theta2"], int(t.size)


def record(spec: str, work: str, seed: int) -> tuple[str, str, list[str], int, list[str]]:
    """(name, path, angle columns, rows, extra detect options) of ``kind:name`` — friction:, laws:, recordings:
    (the look-alikes of tests/fixtures, written as CSV with ``seed``), real: (a recording of
    results/friction_reference.json) or ibm:RUN (the real double pendulum)."""
    kind, _, name = spec.partition(":")
    extra = ["--field", "vertical"] if spec == "friction:throw-2d" else []
    path = os.path.join(work, f"{kind}-{name}.csv")
    if kind in ("friction", "laws", "recordings"):
        maker, names = {"friction": (make, NAMES), "laws": (laws.make, laws.NAMES),
                        "recordings": (recordings.make, recordings.NAMES)}[kind]  # fmt: skip
        if name not in names:
            raise SystemExit(f"error: unknown {kind} case {name!r}; expected one of {', '.join(names)}")
        rec = maker(name, seed)
        rec.write_csv(path)
        angles = list(getattr(rec, "angles", None) or getattr(getattr(rec, "spec", None), "angles", ()))
        return name, path, angles, int(getattr(rec, "n_samples", 0) or len(rec.t)), extra
    if kind == "ibm":
        return (f"ibm-run{name}", *_ibm(int(name), path), extra)
    if kind == "real":
        real, angles = _real(name)
        with open(real) as f:
            rows = sum(1 for line in f if line.strip() and not line.startswith("#")) - 1
        return name, real, angles, rows, extra
    raise SystemExit(f"error: unknown record kind {kind!r} in {spec!r}; expected friction:, laws:, recordings:, "
                     "real: or ibm:")  # fmt: skip


def _run(path: str, angles: list[str], seed: int, cache: str, out: str, workers: str = "", extra=(), sr_time="0"):
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
        sr_time,
    ]
    if angles:
        cmd += ["--angles", ",".join(angles)]
    if workers:
        cmd += ["--workers", workers]
    cmd += list(extra)
    env = dict(os.environ, NNPHD_COMPILE_CACHE=cache, PYTHONPATH=os.path.join(ROOT, "src"))
    t0 = time.perf_counter()
    r = subprocess.run(cmd, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if r.returncode != 0:
        raise RuntimeError(f"{path}: nnphd detect exited {r.returncode}: {r.stderr.strip()[-300:]}")
    with open(os.path.join(out, "report.json")) as f:
        return json.load(f), wall


def shortened(path: str, frac: float, out: str) -> tuple[str, int]:
    """A copy of the CSV ``path`` with its first ``frac`` of data rows (comments and header kept): a file of the same
    kind and another length, for the compile time of a second file (its shapes differ from the first's)."""
    with open(path) as f:
        lines = f.readlines()
    head = [i for i, line in enumerate(lines) if line.strip() and not line.startswith("#")][0]
    data = [line for line in lines[head + 1 :] if line.strip() and not line.startswith("#")]
    keep = data[: max(2, round(frac * len(data)))]
    with open(out, "w") as f:
        f.writelines(lines[: head + 1] + keep)
    return out, len(keep)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cases", default="viscous-dry,heavy-damping,jitter-clock,linear-quadratic")
    ap.add_argument("--real", default="servo_sts3250_drop,seismometer_blow")
    ap.add_argument("--records", default=None,
                    help=f"kind:name,... (replaces --cases/--real); 'held-out': issue 57's eleven ({HELD_OUT})")  # fmt: skip
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--other-length", type=float, default=0.0,
                    help="also run, with the cache the file's runs filled, a copy holding this share of its rows "
                    "(a second file of another length: what it still compiles)")  # fmt: skip
    ap.add_argument("--sr-time", default="0",
                    help="nnphd detect's --sr-time (default 0, as issue 31 measured; 10 is the CLI's own default)")  # fmt: skip
    ap.add_argument("--json", default=None)
    ap.add_argument("--workers", default="", help="nnphd detect's --workers (default: its own, one per core)")
    a = ap.parse_args()
    work = tempfile.mkdtemp(prefix="nnphd-stages-")
    files = []
    if a.records:
        specs = HELD_OUT if a.records == "held-out" else a.records
        files = [record(s, work, a.seed) for s in specs.split(",") if s]
        a.cases = a.real = ""
    for name in [n for n in a.cases.split(",") if n]:
        if name not in NAMES:
            raise SystemExit(f"error: unknown case {name!r}; expected some of {', '.join(NAMES)}")
        rec = make(name, seed=a.seed)
        files.append((name, rec.write_csv(os.path.join(work, f"{name}.csv")), list(rec.angles), rec.n_samples, []))
    for name in [n for n in a.real.split(",") if n]:
        path, angles = _real(name)
        with open(path) as f:
            rows = sum(1 for line in f if line.strip() and not line.startswith("#")) - 1
        files.append((name, path, angles, rows, []))
    head = " | ".join(SHORT[s] for s in STAGES)
    print(f"| file | rows | cache | verdict | total s (process) | compile s | {head} |")
    print("|---" * (6 + len(STAGES)) + "|", flush=True)
    out = []
    for name, path, angles, rows, extra in files:
        cache = os.path.join(work, f"cache-{name}")  # empty: cold; the second run finds what the first compiled
        runs = {}
        kinds = ("cold", "warm", "other length") if a.other_length else ("cold", "warm")
        for kind in kinds:
            src, n_rows = path, rows
            if kind == "other length":
                src, n_rows = shortened(path, a.other_length, os.path.join(work, f"{name}-short.csv"))
            rep, wall = _run(src, angles, a.seed, cache, os.path.join(work, f"out-{name}-{kind.replace(' ', '-')}"),
                             a.workers, extra, a.sr_time)  # fmt: skip
            tm = rep["timings"]
            by = {s["stage"]: s for s in tm["stages"]}
            cells = " | ".join(f"{by[s]['s']:.1f} ({by[s]['compile_s']:.1f})" if s in by else "—" for s in STAGES)
            print(f"| {name} | {n_rows} | {kind} | {rep['status']} | {tm['total_s']:.1f} ({wall:.1f}) | "
                  f"{tm['compile_s']:.1f} | {cells} |", flush=True)  # fmt: skip
            runs[kind] = {
                "status": rep["status"],
                "law": (rep.get("law") or {}).get("status"),
                "total_s": tm["total_s"],
                "process_s": wall,
                "compile_s": tm["compile_s"],
                "compile_parts_s": tm.get("compile_parts_s"),  # of this process (the seeds' workers: in per_seed)
                "workers_compile_s": sum(p.get("compile_s") or 0.0 for p in tm["per_seed"] or []),
                "rows": n_rows,
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

    def median(xs):
        xs = sorted(xs)
        return xs[len(xs) // 2] if len(xs) % 2 else 0.5 * (xs[len(xs) // 2 - 1] + xs[len(xs) // 2])

    for kind in ("cold", "warm", "other length") if a.other_length else ("cold", "warm"):
        tot = sorted(r[kind]["total_s"] for r in out)
        comp = [r[kind]["compile_s"] for r in out]
        wcomp = [r[kind]["workers_compile_s"] for r in out]
        print(f"\n{kind}: median {median(tot):.1f} s, max {tot[-1]:.1f} s per file; compiling {sum(comp):.0f} of "
              f"{sum(tot):.0f} s in all (per file: median {median(comp):.1f} s, max {max(comp):.1f} s; the seeds' "
              f"workers beside it: median {median(wcomp):.1f} s)")  # fmt: skip
    print(f"same verdict and law cold and warm: {sum(r['same_verdict'] for r in out)} of {len(out)}")


if __name__ == "__main__":
    main()
