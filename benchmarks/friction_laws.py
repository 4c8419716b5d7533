"""Issue 29's look-alikes of real friction (tests/fixtures/friction.py: viscous + dry, linear + quadratic drag, offset
rest, a record ending at rest, a 1 kHz quantized encoder, a 20 Hz/1° sensor in one run and in ten, a jittered nominal
clock, heavy damping, a 2-D throw, a conservative control) written as CSV and run through ``nnphd detect`` at its default settings — the
throw with the uniform field its user knows declared (DECLARED; ``--undeclared``: none); prints per case the truth,
the verdict, the winning family and its coefficients, the runner-up, their ΔIC and the law's error.

    .venv/bin/python benchmarks/friction_laws.py [name,name,...] [--seeds 0,1] [--json out.json] [--sindy]
                                                 [--undeclared] [--duration name=seconds,...]

Columns: **truth** (family key and coefficients, nnphd's names and signs: g = −γ q̇ − μ sign(q̇) − c |q̇| q̇ per unit
mass, in the file's units); **verdict** (``detect``'s status); **winner** (the claimed family and its coefficients
with their relative errors; "tie: a or b" when the table cannot tell families apart, "(cand. x)" when the verdict
claims no law, x the best candidate; "none" when no candidate beats zero); **runner-up** (the next family in the
table that is eligible — its terms significant and each needed —, the zero law "none" included; the JSON also has
the next row of any kind, ``next_row``; where no other row is eligible, the next row, marked "not eligible");
**ΔIC** (IC of the runner-up − IC of the winner: > 0 means the winner is
better); **err** = rms over the measured rows (the rows ``detect`` kept after trimming) of (our law's force − the true
non-conservative force) / rms(the true force), over all kept rows and over the moving ones (on a stuck tail the true
force is the static friction −f_c, which no smooth law reproduces), and in brackets the floor: the error of the
true law written in nnphd's form (its sign smoothed over 2 % of the rms speed, the truth's over 0.1 %); with no claimed law our force is 0 (err = 1)
and the candidate's error is shown in brackets; **family** yes/no (the claimed family is the truth's; for the
conservative control: no law claimed); **s** the wall time of the whole ``detect_file`` call.

Our law's force is evaluated on the TRUE states of the kept rows, from the family's own basis
(:func:`nnphd.explain.families.families`, ε of the smooth sign = 2 % of the rms speed, as nnphd) when the key is a
built-in family; otherwise (a family this checkout does not have) from its parameters named gamma*, mu*, c* as
−γ v − μ tanh(|v|/ε) v/|v| − c |v| v; a sparse polynomial from its monomials. ``--sindy`` adds the PySINDy peer
(benchmarks/sindy_baseline.py: the velocity-odd part of a cubic polynomial fit of q̈) and its error on the same rows.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import tempfile
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

import nnphd
from tests.fixtures.friction import _PARAMS, NAMES, make

nnphd.configure()  # float64 and the XLA:CPU setting, as the CLI

from nnphd.user.detect import detect_file

# what the user of such a recording knows and declares: a throw is filmed in a uniform field (gravity), under which a
# learned potential cannot hide a drag (nnphd.user.settings.FIELDS) — with a level camera, y up, the field is vertical
# (one parameter fewer: along a 1.2-s arc a sideways field lets linear drag stand in for quadratic); ``--undeclared``
# runs every case at the defaults, ``--declare throw-2d=uniform`` declares another field
DECLARED = {"throw-2d": {"field": "vertical"}}

COULOMB_EPS = 0.02  # nnphd's smoothing of sign(q̇), relative to the rms speed (explain/families.py)


# ---- our law's force on given states -------------------------------------------------------------------------------
def _builtin_force(row, q, v, t, names, v_rms):
    """The force of a built-in family's row from its basis (None when this checkout has no such family)."""
    from nnphd.explain.families import families

    fam = next((f for f in families(len(names), names, v_rms) if f.key == row["law"]), None)
    if fam is None:
        return None
    p = row["params"]
    beta = np.array([p[c] for c in fam.coef_names], float)
    theta = np.array([p[c] for c in fam.nl_names], float)
    g = np.einsum("snk,k->sn", fam.basis(np, theta, q, v, t), beta)
    if fam.fixed is not None:
        g = g + fam.fixed(np, theta, q, v, t)
    return g


def _named_force(params, v, names, v_rms):
    """−γ v − μ tanh(|v|/ε) v/|v| − c |v| v from parameters gamma / mu / c (one coordinate, or isotropic in 2-D) or
    gamma_<x> / mu_<x> / c_<x> (per coordinate); None if a parameter is none of these."""
    n = v.shape[1]
    g = np.zeros_like(v)
    speed = np.sqrt(np.sum(v * v, axis=1))
    eps_i = np.where(v_rms > 0, COULOMB_EPS * v_rms, 1.0)
    eps_all = COULOMB_EPS * float(np.sqrt(np.sum(v_rms**2))) or 1.0
    for name, x in params.items():
        base, _, coord = name.partition("_")
        if base not in ("gamma", "mu", "c"):
            return None
        if coord:
            if coord not in names:
                return None
            cols = [names.index(coord)]
            w = v[:, cols]
            sp_, eps = np.abs(w), eps_i[cols]
        else:
            cols = list(range(n))
            w = v
            sp_, eps = speed[:, None], np.full(n, eps_all) if n > 1 else eps_i
        if base == "gamma":
            g[:, cols] -= x * w
        elif base == "c":
            g[:, cols] -= x * sp_ * w
        else:
            g[:, cols] -= x * w * np.where(sp_ > 0, np.tanh(sp_ / eps) / np.where(sp_ > 0, sp_, 1.0), 1.0 / eps)
    return g


def _sparse_force(params, q, v, names):
    """A sparse polynomial's force from parameters named '<c>_ddot:<monomial>' (None if not all are)."""
    import sympy as sp

    syms = [sp.Symbol(c) for c in names] + [sp.Symbol(f"{c}_dot") for c in names]
    cols = np.concatenate([q, v], axis=1)
    g = np.zeros_like(v)
    for name, x in params.items():
        comp, sep, mono = name.partition(":")
        comp = comp.removesuffix("_ddot")
        if not sep or comp not in names:
            return None
        f = sp.lambdify(syms, sp.sympify(mono, locals={s.name: s for s in syms}), "numpy")
        g[:, names.index(comp)] += x * np.broadcast_to(f(*cols.T), (len(v),))
    return g


def law_force(row, q, v, t, names):
    """Our law (a candidate row of the report) on the states q, v (N, n); None if it cannot be evaluated here."""
    if row is None or row["law"] == "none":
        return np.zeros_like(v)
    v_rms = np.sqrt(np.mean(v**2, axis=0))
    try:
        g = _builtin_force(row, q, v, t, names, v_rms)
    except Exception:  # noqa: BLE001 — a family whose parameters this checkout names differently
        g = None
    if g is None and row["law"] == "sparse":
        g = _sparse_force(row["params"], q, v, names)
    if g is None:
        g = _named_force(row["params"], v, names, v_rms)
    return g


def rel_err(g, truth, rows):
    if g is None or not rows.any():
        return None
    d = g[rows] - truth[rows]
    return float(np.sqrt(np.mean(d**2)) / np.sqrt(np.mean(truth[rows] ** 2)))


# ---- one case ------------------------------------------------------------------------------------------------------
def kept_rows(rep, rec) -> np.ndarray:
    """The rows ``detect`` used (its trim of each trajectory's ends), as a mask over the record's rows."""
    N = rec.n_samples
    trs = (rep.get("data") or {}).get("trajectories")
    if not trs:
        return np.ones(N, bool)
    starts = [0] if rec.traj is None else [0, *(np.flatnonzero(np.diff(rec.traj) != 0) + 1)]
    mask = np.zeros(N, bool)
    for s, tr in zip(starts, trs):
        a, b = tr["kept"]
        mask[s + a : s + b] = True
    return mask


def _fmt_params(row, truth_coef=None):
    if row is None:
        return ""
    out = []
    for k, x in row["params"].items():
        s = f"{k}={x:.3g}"
        tv = (truth_coef or {}).get(k)
        if tv:
            s += f" ({100 * (x / tv - 1):+.0f}%)"
        out.append(s)
    return ", ".join(out)


def run_case(name, seed, sindy=False, declared=True):
    rec = make(name, seed=seed)
    tr = rec.truth
    path = rec.write_csv(os.path.join(tempfile.mkdtemp(), f"{name}.csv"))
    settings = DECLARED.get(name, {}) if declared else {}
    t0 = time.perf_counter()
    rep = detect_file(path, out=None, angles=rec.angles, seed=seed, sr_time=0, **settings)
    wall = time.perf_counter() - t0
    lw = rep.get("law") or {}
    cands = lw.get("candidates") or []
    claimed = lw.get("law")
    cand = claimed or lw.get("candidate_law")
    ties = lw.get("ties") or []
    law_status = lw.get("status") or ("claimed" if claimed else "none")
    # the winner's row in the table and the runner-up: the next row of another family (the zero law included)
    win_key = cand["law"] if cand else (cands[0]["law"] if cands else "none")
    win_row = next((r for r in cands if r["law"] == win_key), cand)
    # (eligible: every term significant and needed; the zero law always is) — and the next row of any kind
    others = [r for r in cands if r["law"] != win_key]
    runner = next((r for r in others if r.get("significant", True) or r["law"] == "none"), None)
    nxt = others[0] if others else None
    runner_eligible = runner is not None
    runner = runner or nxt  # none eligible: the next row, marked
    d_ic = None if (runner is None or win_row is None) else float(runner["ic"] - win_row["ic"])

    keep = kept_rows(rep, rec)
    moving = keep & tr["moving"]
    q, v, t = tr["q_true"], tr["qd_true"], tr["t_true"]
    names = list(rec.coords)
    fn = tr["fn_true"]
    g_claim = law_force(claimed, q, v, t, names) if claimed else np.zeros_like(fn)
    g_cand = law_force(cand, q, v, t, names) if cand and not claimed else None
    truth_none = tr["law"] == "none"
    if truth_none:
        err_all = err_mov = None  # no force to compare with: the right answer is no law
        err_cand = None
    else:
        err_all, err_mov = rel_err(g_claim, fn, keep), rel_err(g_claim, fn, moving)
        err_cand = rel_err(g_cand, fn, moving) if g_cand is not None else None
    if truth_none:
        right = claimed is None
    else:
        right = claimed is not None and law_status != "tie" and claimed["law"] == tr["law"]
    floor = None  # the error of the true law in nnphd's own form (its smoother sign): the best err can be
    if not truth_none:
        g_true = law_force({"law": tr["law"], "params": dict(tr["coefficients"])}, q, v, t, names)
        floor = rel_err(g_true, fn, moving)
    coef_err = {}
    if claimed:
        for k, x in tr["coefficients"].items():
            if k in claimed["params"]:
                coef_err[k] = float(claimed["params"][k] / x - 1)
    row = {
        "name": name,
        "seed": seed,
        "n_samples": rec.n_samples,
        "truth_law": tr["law"],
        "truth_coefficients": tr["coefficients"],
        "declared": settings,
        "whole_record": (lw.get("settings") or {}).get("whole_record"),  # a tie re-judged over the whole record
        "status": rep["status"],
        "confidence": rep.get("confidence"),
        "law_status": law_status,
        "winner": claimed["law"] if claimed else None,
        "winner_params": claimed["params"] if claimed else None,
        "winner_stderr": claimed.get("stderr") if claimed else None,
        "candidate": None if claimed or not cand else cand["law"],
        "candidate_params": None if claimed or not cand else cand["params"],
        "ties": [r["law"] for r in ties],
        "runner_up": runner["law"] if runner else None,
        "runner_up_params": runner["params"] if runner else None,
        "runner_up_eligible": runner_eligible,
        "delta_ic": d_ic,
        "next_row": nxt["law"] if nxt else None,
        "next_row_eligible": bool(nxt.get("significant", True)) if nxt else None,
        "next_row_delta_ic": None if (nxt is None or win_row is None) else float(nxt["ic"] - win_row["ic"]),
        "winner_delta_ic_vs_none": win_row.get("delta_ic") if win_row else None,
        "err_kept": err_all,
        "err_moving": err_mov,
        "err_candidate_moving": err_cand,
        "err_floor_moving": floor,
        "coef_rel_err": coef_err,
        "family_right": bool(right),
        # the law right to ≤ 10 %: the family right and every true coefficient within 10 % (the force error has a
        # floor from the smoothing of sign(q̇): err_floor_moving)
        "law_within_10pct": bool(
            right
            and (
                truth_none
                or (len(coef_err) == len(tr["coefficients"]) and all(abs(x) <= 0.10 for x in coef_err.values()))
            )
        ),
        "wall_s": wall,
        "law_reason": lw.get("reason"),
        "reasons": rep.get("reasons"),
        "kept_rows": int(keep.sum()),
        "stuck_rows_kept": int((keep & ~tr["moving"]).sum()),
        "candidates": [
            {k: r.get(k) for k in ("law", "params", "delta_ic", "ic", "heldout_ratio", "significant", "method")}
            for r in cands
        ],
    }
    wr = row["whole_record"] or {}
    if wr.get("dropped") and win_key in wr.get("delta_ic", {}):  # the whole record decided: its runner-up and ΔIC
        rivals = {k: d for k, d in wr["delta_ic"].items() if k != win_key}
        k = min(rivals, key=rivals.get)
        row.update(runner_up=k, runner_up_params=wr["params"].get(k), runner_up_eligible=True,
                   delta_ic=float(rivals[k]), delta_ic_from="the whole record")  # fmt: skip
    if sindy:
        row.update(_sindy(rec, keep))
    return row


def _sindy(rec, keep):
    try:
        from benchmarks.sindy_baseline import sindy_law
    except Exception as e:  # noqa: BLE001 — pysindy is optional
        return {"sindy": f"unavailable: {e}"}
    tr = rec.truth
    try:
        res = sindy_law(rec.t, rec.q, rec.traj, list(rec.coords))
    except Exception as e:  # noqa: BLE001
        return {"sindy": f"failed: {type(e).__name__}: {e}"}
    g = np.asarray(res["predict"](tr["q_true"], tr["qd_true"]))
    rows = keep & tr["moving"]
    err = None if tr["law"] == "none" else rel_err(g, tr["fn_true"], rows)
    return {"sindy": "; ".join(f"{k} = {f}" for k, f in res["formula"].items()), "sindy_err_moving": err}


# ---- table ---------------------------------------------------------------------------------------------------------
def _pct(x):
    return "—" if x is None else f"{100 * x:.1f}%"


def line(r) -> str:
    truth = r["truth_law"] + (
        " (" + ", ".join(f"{k}={x:.3g}" for k, x in r["truth_coefficients"].items()) + ")"
        if r["truth_coefficients"]
        else ""
    )
    tc = r["truth_coefficients"]
    if r["winner"]:
        fam = ("tie: " + " or ".join([r["winner"], *r["ties"]])) if r["law_status"] == "tie" else r["winner"]
        win = f"{fam} ({_fmt_params({'params': r['winner_params']}, tc)})"
    elif r["candidate"]:
        win = f"none (cand. {r['candidate']}: {_fmt_params({'params': r['candidate_params']}, tc)})"
    else:
        win = "none"
    err = (
        "—"
        if r["truth_law"] == "none"
        else f"{_pct(r['err_kept'])} / {_pct(r['err_moving'])} ({_pct(r['err_floor_moving'])})"
    )
    if r.get("err_candidate_moving") is not None:
        err += f" [cand. {_pct(r['err_candidate_moving'])}]"
    dic = "—" if r["delta_ic"] is None else f"{r['delta_ic']:.1f}"
    seed = "" if r["seed"] == 0 else f" (seed {r['seed']})"
    out = (
        f"| {r['name']}{seed} | {r['n_samples']} | {truth} | {r['status']} | {win} | {(r['runner_up'] or '—') + ('' if r.get('runner_up_eligible', True) else ' (not eligible)')} | {dic} "
        f"| {err} | {'yes' if r['family_right'] else '**no**'} | {r['wall_s']:.0f} |"
    )
    if "sindy" in r:
        out += f" {r['sindy']} ({_pct(r.get('sindy_err_moving'))}) |"
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("names", nargs="?", default=",".join(NAMES), help="comma-separated cases (default: all)")
    ap.add_argument("--seeds", default="0")
    ap.add_argument("--json", default=None, help="write the rows to this JSON file")
    ap.add_argument("--sindy", action="store_true", help="add the PySINDy peer's law and error")
    ap.add_argument("--undeclared", action="store_true", help="no declared field (DECLARED): every case at defaults")
    ap.add_argument("--duration", default="", help="name=seconds,... : record these cases for longer (or shorter)")
    ap.add_argument("--declare", default="", help="name=field,... : declare this field for these cases instead")
    a = ap.parse_args()
    for item in filter(None, a.declare.split(",")):
        name, _, fld = item.partition("=")
        if name not in NAMES:
            ap.error(f"--declare: unknown case {name!r}")
        DECLARED[name] = {"field": fld}
    names = [n for n in a.names.split(",") if n]
    bad = [n for n in names if n not in NAMES]
    if bad:
        ap.error(f"unknown case(s) {', '.join(bad)}; expected some of {', '.join(NAMES)}")
    durations = {}
    for item in filter(None, a.duration.split(",")):
        name, _, sec = item.partition("=")
        if name not in _PARAMS or "duration" not in _PARAMS[name]:
            ap.error(f"--duration: {name!r} is not a case recorded for a set duration")
        durations[name] = _PARAMS[name]["duration"] = float(sec)
    head = "| case | rows | truth | verdict | winner (coefficients, error) | runner-up | ΔIC | err kept / moving (floor) | family | s |"
    sep = "|---|---|---|---|---|---|---|---|---|---|"
    if a.sindy:
        head += " SINDy peer (err moving) |"
        sep += "---|"
    print(head)
    print(sep, flush=True)
    rows = []
    for seed in [int(s) for s in a.seeds.split(",")]:
        for name in names:
            try:
                r = run_case(name, seed, a.sindy, declared=not a.undeclared)
            except Exception as e:  # noqa: BLE001 — one broken case must not hide the others
                r = {"name": name, "seed": seed, "error": f"{type(e).__name__}: {e}"}
                print(f"| {name} | **failed**: {r['error']} |", flush=True)
            else:
                print(line(r), flush=True)
            if name in durations:
                r["duration_s"] = durations[name]
            rows.append(r)
            if a.json:  # after every case: a long run keeps what it has
                with open(a.json, "w") as fh:
                    json.dump(rows, fh, indent=1, default=_json_default)
    ok = [r for r in rows if "error" not in r]
    print(
        f"\nfamily right: {sum(r['family_right'] for r in ok)} of {len(rows)}; "
        f"family right and every coefficient within 10 %: {sum(r['law_within_10pct'] for r in ok)} of {len(rows)}; "
        f"total {sum(r['wall_s'] for r in ok):.0f} s"
    )


def _json_default(x):
    if isinstance(x, (np.floating, np.integer)):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return str(x)


if __name__ == "__main__":
    main()
