"""The law of the new force on constructed cases (tests/fixtures/laws.py): ``nnphd detect`` (whole pipeline, default
settings, positions only) beside the PySINDy peer baseline (benchmarks/sindy_baseline.py); prints the table of docs/RESULTS.md.

    .venv/bin/python benchmarks/laws_table.py [name,name,...] [--json out.json] [--seed 0]

Per case: the law nnphd reports (the winner of the ranked candidates; "—" when none is claimed) and the baseline's
(its terms odd in velocity), each scored on the TRUE states as rms(law − true f_n)/rms(true f_n) (for the conservative
controls: rms(law)/rms(q̈), where any law is wrong); "right" = within 20 % and, for nnphd, the form (family) right /
for a control, no law. Times: the whole ``detect_file`` call (derivatives, λ-sweep, checks, laws) and the baseline's
derivatives + fit.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time

import numpy as np
import sympy as sp

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "benchmarks"))

from sindy_baseline import sindy_law

import nnphd

nnphd.configure()  # float64 and the XLA:CPU setting, as the CLI

from nnphd.user.detect import detect_file
from tests.fixtures import laws as cases

TOL = 0.2


def formula_fn(formula: dict, coords):
    """Evaluate a reported formula {"<c>_ddot": "sympy string"} at states (q, qd, t)."""
    syms = [sp.Symbol(c) for c in coords] + [sp.Symbol(f"{c}_dot") for c in coords] + [sp.Symbol("t")]
    loc = {s.name: s for s in syms}
    fs = [sp.lambdify(syms, sp.sympify(formula[f"{c}_ddot"], locals=loc), "numpy") for c in coords]

    def f(q, qd, t):
        args = [q[:, j] for j in range(q.shape[1])] + [qd[:, j] for j in range(q.shape[1])] + [t]
        return np.stack([np.broadcast_to(np.asarray(g(*args), float), t.shape) for g in fs], axis=1)

    return f


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("names", nargs="?", default=",".join(cases.NAMES))
    ap.add_argument("--json", default=None)
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args()
    rows = []
    print("| case | truth | nnphd: law (± 1 se) | err | right | s | PySINDy baseline: law | err | right | s |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for name in a.names.split(","):
        c = cases.make(name, seed=a.seed)
        coords = list(c.spec.coords)
        path = c.write_csv(os.path.join(tempfile.mkdtemp(), f"{name}.csv"))
        t0 = time.perf_counter()
        rep = detect_file(path, out=None, angles=c.spec.angles, seed=a.seed, sr_time=0)
        wall = time.perf_counter() - t0
        law = (rep.get("law") or {}).get("law")
        pred = formula_fn(law["formula"], coords) if law else None
        err = cases.score(c, pred)
        ok = cases.form_right(c, law["law"] if law else None) and (err <= TOL or not c.spec.forms)
        if not c.spec.forms:
            ok = law is None
        b = sindy_law(c.t, c.q, c.traj, coords)
        berr = cases.score(c, b["predict"])
        bok = (berr <= TOL) if c.spec.forms else not b["terms"]
        if law:
            txt = (
                "; ".join(f"{k} = {v}" for k, v in law["formula"].items())
                + " ("
                + ", ".join(f"{p} = {v:.4g} ± {law['stderr'][p]:.2g}" for p, v in law["params"].items())
                + ")"
            )
        else:
            txt = "— (" + rep["status"] + ")"
        btxt = "; ".join(f"{k} = {v}" for k, v in b["formula"].items() if v != "0") or "—"
        print(
            f"| {name} | {c.spec.description} | {txt} | {err:.3f} | {'yes' if ok else 'NO'} | {wall:.0f} | "
            f"{btxt} | {berr:.3f} | {'yes' if bok else 'NO'} | {b['seconds']:.2f} |",
            flush=True,
        )
        rows.append(
            {
                "case": name,
                "truth": c.spec.description,
                "status": rep["status"],
                "law": law,
                "law_status": (rep.get("law") or {}).get("status"),
                "error": err,
                "right": bool(ok),
                "seconds": wall,
                "baseline": btxt,
                "baseline_error": berr,
                "baseline_right": bool(bok),
                "baseline_seconds": b["seconds"],
                "law_reason": (rep.get("law") or {}).get("reason"),
            }
        )
    n, nb = sum(r["right"] for r in rows), sum(r["baseline_right"] for r in rows)
    print(f"\nnnphd right: {n}/{len(rows)}; baseline right: {nb}/{len(rows)}")
    if a.json:
        with open(a.json, "w") as fh:
            json.dump(rows, fh, indent=1, default=str)


if __name__ == "__main__":
    main()
