"""The realistic stress set (tests/fixtures/recordings.py: one noisy, jittered, gappy, quantized recording per case)
written as CSV and run through the whole ``nnphd detect`` pipeline at its default settings; prints the table of docs/RESULTS.md.

    .venv/bin/python benchmarks/detect_recordings.py [name,name,...] [--seeds 0,1] [--json out.json]
    .venv/bin/python benchmarks/detect_recordings.py double-pendulum,cart --duration double-pendulum=100,cart=333
        (longer recordings of the same kind: 10⁴ samples, for the time per file)

Per case: the expected verdict, ours (status and confidence), the energy-decay rate estimated from the learned
Lagrangian's energy trend against the truth (the same definition, ``true_decay_rate``, applied to the exact energy),
the shooting fit's damping z, and the wall time of the whole ``detect_file`` call (derivatives, training, checks).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

import nnphd
from tests.fixtures import recordings
from tests.fixtures.recordings import NAMES, make

nnphd.configure()  # float64 and the XLA:CPU setting, as the CLI

from nnphd.user.detect import detect_file


def right(expected: str, status: str) -> bool:
    return status == expected or (expected == "not-detected" and status in ("none", "inconclusive"))


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("names", nargs="?", default=",".join(NAMES))
    ap.add_argument("--seeds", default="0")
    ap.add_argument("--json", default=None)
    ap.add_argument("--duration", default="", help="name=seconds,... : record these cases for longer")
    a = ap.parse_args()
    for item in filter(None, a.duration.split(",")):
        name, sec = item.split("=")
        recordings._PARAMS[name]["duration"] = float(sec)
    rows = []
    print(
        "| case | samples | truth | expected | ours (confidence) | energy-decay rate: ours / truth | shooting z "
        "| law (or best candidate, not claimed) | s |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for seed in [int(s) for s in a.seeds.split(",")]:
        for name in a.names.split(","):
            rec = make(name, seed=seed)
            path = rec.write_csv(os.path.join(tempfile.mkdtemp(), f"{name}.csv"))
            t0 = time.perf_counter()
            rep = detect_file(path, out=None, angles=rec.angles, seed=seed, sr_time=0)
            wall = time.perf_counter() - t0
            tr, sh = rep["evidence"]["energy_trend"], rep["evidence"]["shooting"]
            rate = tr.get("rate") if tr.get("valid") else None
            truth = rec.energy_decay_rate
            if rate is None:
                rate_s = "—"
            elif truth:
                rate_s = f"{rate:.4g} / {truth:.4g} ({100 * (rate / truth - 1):+.1f}%)"
            else:
                rate_s = f"{rate:.2g} ± {tr['se']:.1g} / 0"
            z = f"{sh['z']:.1f}" if sh.get("valid") else "—"
            ok = right(rec.expected, rep["status"])
            lw = rep.get("law") or {}
            best = lw.get("law") or lw.get("candidate_law")
            law_s = (
                "—"
                if best is None
                else (
                    ("" if lw.get("law") else "(")
                    + "; ".join(f"{k} = {v}" for k, v in best["formula"].items())
                    + f", ΔIC {best['delta_ic']:.0f}"
                    + ("" if lw.get("law") else ")")
                )
            )
            print(
                f"| {name}{'' if seed == 0 else f' (seed {seed})'} | {rec.n_samples} | "
                f"{'conservative' if rec.conservative else 'non-conservative'} | {rec.expected} | "
                f"{'' if ok else '**'}{rep['status']}{'' if ok else '**'} ({rep['confidence']:.2f}) | {rate_s} | {z} "
                f"| {law_s} | {wall:.0f} |",
                flush=True,
            )
            rows.append(
                {
                    "name": name,
                    "seed": seed,
                    "expected": rec.expected,
                    "status": rep["status"],
                    "confidence": rep["confidence"],
                    "right": ok,
                    "rate": rate,
                    "rate_truth": truth,
                    "shooting_z": sh.get("z"),
                    "energy_z": tr.get("z"),
                    "wall_s": wall,
                    "law": law_s,
                    "law_status": lw.get("status"),  # "claimed", "tie" (law_s is then the tie's first) or "none"
                    "ties": [x.get("title") for x in lw.get("ties") or []],
                    "reasons": rep["reasons"],
                }
            )
    print(f"\n{sum(r['right'] for r in rows)} of {len(rows)} verdicts right")
    if a.json:
        with open(a.json, "w") as fh:
            json.dump(rows, fh, indent=1)


if __name__ == "__main__":
    main()
