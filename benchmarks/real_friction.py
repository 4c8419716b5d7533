"""Issue 29 on real recordings: the law ``nnphd detect`` reports on each measured damped oscillator (data/real/ and
../shared/data/real/servo_sts3250_drop.csv) against the independent reference of benchmarks/friction_reference.py
(a whole-trajectory ODE fit of the positions; results/friction_reference.json — run that first).

    .venv/bin/python benchmarks/friction_reference.py      # the references
    .venv/bin/python benchmarks/real_friction.py [--json out.json] [file,file,...]

Per recording: the verdict; the law (claimed, a tie — each tied family —, or the best candidate when the verdict
claims none); its error = rms over the rows detect kept (their estimated q̇) of (our law's force − the reference's
best model's friction force) / rms(the reference's); whether every term the reference finds necessary (dropping it
costs ≥ 1.2× the rms) is in it (viscous c ↔ q̇, dry d ↔ sign(q̇), quadratic e ↔ |q̇|q̇); "right" = error ≤ 25 % and
the necessary terms present. The reference's dry term is d·tanh(q̇/ε) with its own ε (1.5 % of the rms speed), ours
smooths sign(q̇) over 2 %: a floor of a few % on dry-friction records.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "benchmarks"))

import nnphd

nnphd.configure()  # float64 and the XLA:CPU setting, as the CLI

from friction_laws import _builtin_force

from nnphd.user.detect import detect_data
from nnphd.user.recording import load_trajectories

TERMS = {"c": "q̇", "d": "sign(q̇)", "e": "|q̇|q̇"}  # reference term → our structural label
TOL = 0.25


def _path(ref_file: str) -> str:
    return ref_file if os.path.isabs(ref_file) else os.path.join(ROOT, ref_file)


def _ref_force(ref: dict, v: np.ndarray) -> np.ndarray:
    p = ref["best_params"]
    return -p.get("c", 0.0) * v - p.get("d", 0.0) * np.tanh(v / ref["eps"]) - p.get("e", 0.0) * np.abs(v) * v


def _score(row: dict, data, names, ref: dict) -> tuple[float, bool]:
    v_rms = np.sqrt(np.mean(data.qd**2, axis=0))
    g = _builtin_force(row, data.q, data.qd, data.t, names, v_rms)
    f = _ref_force(ref, data.qd[:, 0])
    err = float(np.sqrt(np.mean((g[:, 0] - f) ** 2)) / np.sqrt(np.mean(f**2))) if g is not None else float("nan")
    has = all(TERMS[k] in row.get("terms", []) for k in ref["necessary"])
    return err, has


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("files", nargs="?", default="")
    ap.add_argument("--json", default=None)
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args()
    refs = json.load(open(os.path.join(ROOT, "benchmarks", "results", "friction_reference.json")))["recordings"]
    if a.files:
        refs = [r for r in refs if os.path.basename(r["file"]) in a.files.split(",")]
    print("| recording | reference (necessary; best) | verdict | law (err vs reference, necessary terms in it) | s |")
    print("|---|---|---|---|---|")
    out = []
    for ref in refs:
        path = _path(ref["file"])
        ud = load_trajectories(path, (ref["coordinate"],) if ref["model"] == "pendulum" else ())
        t0 = time.perf_counter()
        result, model = detect_data(ud, None, seed=a.seed, sr_time=0)
        rep = result.report
        wall = time.perf_counter() - t0
        law = rep["law"]
        rows = [law["law"], *law.get("ties", [])] if law.get("law") else []
        kind = law.get("status", "none")
        if not rows and law.get("candidate_law"):
            rows, kind = [law["candidate_law"]], "candidate (not claimed)"
        scored = []
        for r in rows:
            err, has = _score(r, model.data, list(model.coords), ref)
            scored.append({"law": r["law"], "params": r["params"], "err": err, "necessary_in": has})
        p = ref["best_params"]
        refs_txt = (
            f"{{{', '.join(ref['necessary'])}}}; "
            + ", ".join(f"{k} = {p[k]:.3g}" for k in ref["best_subset"])
            + f" ({', '.join(TERMS[k] for k in ref['best_subset'])})"
        )
        law_txt = (
            "; ".join(
                f"{s['law']} "
                + ", ".join(f"{k} = {v:.3g}" for k, v in s["params"].items())
                + f" (err {s['err']:.2f}, {'has' if s['necessary_in'] else 'LACKS'} the necessary terms)"
                for s in scored
            )
            or "none"
        )
        print(
            f"| {os.path.basename(path)} | {refs_txt} | {rep['status']} | {kind}: {law_txt} | {wall:.0f} |",
            flush=True,
        )
        out.append(
            {
                "file": os.path.basename(path),
                "status": rep["status"],
                "law_status": kind,
                "laws": scored,
                "right": bool(scored) and scored[0]["err"] <= TOL and scored[0]["necessary_in"],
                "reference": {"necessary": ref["necessary"], "best": ref["best_subset"], "params": p},
                "reason": law.get("reason"),
                "whole_record": (law.get("settings") or {}).get("whole_record"),  # a tie re-judged whole
                "wall_s": wall,
            }
        )
        if a.json:
            with open(a.json, "w") as f:
                json.dump(out, f, indent=1)


if __name__ == "__main__":
    main()
