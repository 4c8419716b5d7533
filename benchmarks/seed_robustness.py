"""One verdict whatever the seed: ``nnphd detect`` at its defaults with seeds 0, 1 and 2 on the constructed cases.

Per file: the truth, the status of each seed, whether the three agree and are right, the law (the drive's A and ω on
a driven case), and the seconds per seed. At the end: the share of files whose statuses agree, the share right on
every seed, and the median / max seconds per run. The seed is the model seed only: the file is the same (its
noise drawn once), so a disagreement is the model's, not the data's.

Sets (``--sets``):

- ``cases``: the trust cases of ``tests/fixtures/cases.py`` as 8 noisy position-only trajectories (0.1 % noise, as
  ``benchmarks/detect_noisy_cases.py``): conservative potentials and a gyroscopic force (``magnetic2d``: "none"),
  drag, a drive ``0.1 cos(1.3 t)`` on 8 trajectories overlapping in time, van der Pol ("detected");
- ``recordings``: the look-alikes of ``tests/fixtures/recordings.py`` (gaps, jitter, rounding; a chaotic damped
  double pendulum filmed at 1 kHz; carts; white noise; undersampled records).

The real recordings and the friction look-alikes are compared across seeds by ``benchmarks/seed_agreement.py``
from their own JSON.

    python benchmarks/seed_robustness.py [--sets cases,recordings] [--only a,b] [--seeds 0,1,2] [--json F]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

import nnphd  # noqa: E402
from nnphd.user.detect import detect_file  # noqa: E402

DRIVE = {"anharmonic+drive": {"A": 0.1, "omega": 1.3}}  # the true drive of the driven case


def _case_file(name: str, folder: str) -> tuple[str, tuple[str, ...], str]:
    from tests.fixtures.cases import CASES, make_case

    d, traj = make_case(name, n_traj=8, seed=3)
    q = d.q + 1e-3 * d.q.std(axis=0) * np.random.default_rng(1).standard_normal(d.q.shape)
    cols = [f"q{i + 1}" for i in range(d.n)]
    path = os.path.join(folder, f"case_{name}.csv")
    with open(path, "w") as fh:
        fh.write("traj,t," + ",".join(cols) + "\n")
        fh.writelines(f"{k},{ti:.6f}," + ",".join(f"{v:.10g}" for v in row) + "\n" for k, ti, row in zip(traj, d.t, q))
    return path, (), "none" if CASES[name].conservative else "detected"


def _recording_file(name: str, folder: str) -> tuple[str, tuple[str, ...], str]:
    from tests.fixtures.recordings import make

    rec = make(name, seed=0)
    return str(rec.write_csv(os.path.join(folder, f"rec_{name}.csv"))), rec.angles, rec.expected


def _right(status: str, expected: str) -> bool:
    return status in ("none", "inconclusive") if expected == "not-detected" else status == expected


def _drive(rep: dict) -> dict | None:
    law = (rep.get("law") or {}).get("law") or {}
    if law.get("law") != "drive":
        return None
    p = law.get("params") or {}
    # A cos(ωt + φ) = A_cos cos(ωt) + A_sin sin(ωt) per coordinate: A = hypot(A_cos, A_sin), the largest coordinate's
    amp = [float(np.hypot(v, p.get("A_sin" + k[len("A_cos") :], 0.0))) for k, v in p.items() if k.startswith("A_cos")]
    return {"A": max(amp) if amp else None, "omega": p.get("omega"), "params": p}


def _candidate(lw: dict) -> dict | None:
    """The law table's best law, claimed or withheld, with the numbers the verdict's rules weigh it by."""
    c = lw.get("law") or lw.get("candidate_law")
    if not c:
        return None
    keys = ("by_position", "by_state", "work_per_trajectory")
    return {"law": c.get("law"), "delta_ic": c.get("delta_ic"), "heldout_ratio": c.get("heldout_ratio"),
            "fn_rel": c.get("fn_rel"), "against_velocity": lw.get("against_velocity"),
            **{k: lw.get(k) for k in keys}}  # fmt: skip


def _release_compiled() -> None:
    """Drop JAX's in-memory compiled programs between runs (the persistent cache keeps them on disk): one process
    running many files otherwise keeps every executable mapped, and after ~15 runs of ``detect`` XLA:CPU failed
    with "LLVM compilation error: Cannot allocate memory" and the process crashed (vm.max_map_count 65530)."""
    import gc

    import jax

    jax.clear_caches()
    gc.collect()


def run_file(set_name: str, name: str, seeds: list[int], folder: str) -> dict:
    path, angles, expected = (_case_file if set_name == "cases" else _recording_file)(name, folder)
    runs = []
    for s in seeds:
        t0 = time.perf_counter()
        rep = detect_file(path, angles=angles, seed=s, sr_time=0)
        _release_compiled()
        lw = rep.get("law") or {}
        law = lw.get("law") or {}
        runs.append({
            "seed": s,
            "status": rep["status"],
            "confidence": rep["confidence"],
            "law": law.get("law"),
            "law_status": lw.get("status"),
            "drive": _drive(rep),
            "candidate": _candidate(lw),
            "reason": rep["reasons"][0] if rep["reasons"] else "",
            "seconds": round(time.perf_counter() - t0, 1),
        })  # fmt: skip
    statuses = [r["status"] for r in runs]
    out = {
        "set": set_name,
        "file": name,
        "expected": expected,
        "runs": runs,
        "agree": len(set(statuses)) == 1,
        "right_all": all(_right(s, expected) for s in statuses),
        "wrong_detected": sum(s == "detected" and not _right(s, expected) for s in statuses),
        "wrong_none": sum(s == "none" and expected == "detected" for s in statuses),
    }
    if name in DRIVE:
        truth = DRIVE[name]
        out["drive_truth"] = truth
        out["drive_within_5pct"] = [
            r["drive"] is not None
            and r["drive"]["A"] is not None
            and abs(r["drive"]["A"] / truth["A"] - 1) <= 0.05
            and abs(r["drive"]["omega"] / truth["omega"] - 1) <= 0.05
            for r in runs
        ]
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sets", default="cases,recordings")
    ap.add_argument("--only", default=None, help="comma-separated file names (cases or recordings)")
    ap.add_argument("--seeds", default="0,1,2")
    ap.add_argument("--json", default=None)
    ap.add_argument("--append", action="store_true", help="keep the files already in --json, run the others")
    a = ap.parse_args()
    nnphd.configure()
    from tests.fixtures.cases import CASES
    from tests.fixtures.recordings import NAMES

    seeds = [int(x) for x in a.seeds.split(",")]
    names = {"cases": list(CASES), "recordings": list(NAMES)}
    todo = [(s, n) for s in a.sets.split(",") for n in names[s]]
    if a.only:  # in the order given (the most telling first: a long run stopped early keeps them)
        order = a.only.split(",")
        todo = sorted((x for x in todo if x[1] in order), key=lambda x: order.index(x[1]))
    rows = []
    if a.append and a.json and os.path.exists(a.json):
        with open(a.json) as f:
            rows = json.load(f)["rows"]
        done = {(r["set"], r["file"]) for r in rows}
        todo = [x for x in todo if x not in done]
    with tempfile.TemporaryDirectory() as folder:
        for set_name, name in todo:
            r = run_file(set_name, name, seeds, folder)
            rows.append(r)
            st = " ".join(f"{x['status']:12s}" for x in r["runs"])
            secs = "/".join(f"{x['seconds']:.0f}" for x in r["runs"])
            extra = ""
            if "drive_within_5pct" in r:
                extra = " drive " + "; ".join(
                    "—" if x["drive"] is None else f"A {x['drive']['A']:.4g} ω {x['drive']['omega']:.4g}"
                    for x in r["runs"]
                )
            print(f"{set_name:10s} {name:22s} truth {r['expected']:12s} {st} agree {'yes' if r['agree'] else 'NO ':3s} "
                  f"right {'yes' if r['right_all'] else 'NO'}  {secs} s{extra}", flush=True)  # fmt: skip
            if a.json:  # after every file: a long run stopped early keeps what it measured
                _write(a.json, seeds, rows)
    summary = _write(a.json, seeds, rows) if a.json else _summary(rows)
    print(
        f"statuses agree on {summary['agree']}/{summary['files']} files; right on every seed {summary['right_all_seeds']}"
        f"/{summary['files']}; wrong 'detected' runs {summary['wrong_detected_runs']}, 'none' on new physics "
        f"{summary['missed_runs']}; seconds per run median {summary['median_s']}, max {summary['max_s']}"
    )


def _summary(rows: list[dict]) -> dict:
    secs = [x["seconds"] for r in rows for x in r["runs"]]
    return {
        "files": len(rows),
        "agree": sum(r["agree"] for r in rows),
        "right_all_seeds": sum(r["right_all"] for r in rows),
        "wrong_detected_runs": sum(r["wrong_detected"] for r in rows),
        "missed_runs": sum(r["wrong_none"] for r in rows),
        "median_s": statistics.median(secs) if secs else None,
        "max_s": max(secs) if secs else None,
    }


def _write(path: str, seeds: list[int], rows: list[dict]) -> dict:
    summary = _summary(rows)
    tmp = path + ".tmp"
    with open(tmp, "w") as f:
        json.dump({"seeds": seeds, "summary": summary, "rows": rows}, f, indent=1, ensure_ascii=False)
    os.replace(tmp, path)
    return summary


if __name__ == "__main__":
    main()
