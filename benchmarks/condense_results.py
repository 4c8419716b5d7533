"""Condense the output folders of the paper's commands into the small JSON of ``benchmarks/results/`` that
``benchmarks/results_tables.py`` renders into docs/RESULTS.md (no per-step losses, no force samples).

    python benchmarks/condense_results.py reproduce OUT [--discover-300 DIR] [--sweep-8000 DIR]
        # OUT: `nnphd reproduce --seed 0 --out OUT`; DIR: `nnphd discover --system double-pendulum --n-steps 300
        # --out DIR` and `nnphd sweep --system ho+ld --steps 8000 --out DIR` -> results/reproduce.json
    python benchmarks/condense_results.py neptune OUT     # `nnphd demo neptune --seed S --out OUT` (repeatable)
        -> results/demo_neptune.json (one entry per seed)
    python benchmarks/condense_results.py recordings FILE...  # benchmarks/detect_recordings.py --json FILE
        -> results/detect_recordings_all.json (with each case's samples and truth from tests/fixtures/recordings.py)
"""

from __future__ import annotations

import argparse
import json
import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
RESULTS = os.path.join(ROOT, "benchmarks", "results")


def _read(path: str):
    with open(path) as f:
        return json.load(f)


def _write(name: str, data) -> None:
    path = os.path.join(RESULTS, name)
    with open(path, "w") as f:
        json.dump(data, f, indent=1, ensure_ascii=False)
        f.write("\n")
    print(f"wrote {os.path.relpath(path, ROOT)} ({os.path.getsize(path)} bytes)")


def _pick(d: dict, keys) -> dict:
    return {k: d[k] for k in keys if k in d}


VERDICT = ("new_physics", "ratio", "L_below", "L_above", "relative_size", "min_ratio", "min_relative_size", "reason")
CURVE = ("lam", "L_e", "L_b", "m_c", "m_n", "fn_rms")


def _discover(r: dict) -> dict:
    return {
        "system": r["system"],
        "new_physics": r["new_physics"],
        "verdict": _pick(r["verdict"], VERDICT),
        "table2": r["table2"],
        "law_winner": r.get("law_winner"),
        "law": {  # the law ranking: its status and the best candidates (ΔIC against no law)
            "status": r["law"]["status"],
            "candidates": [
                {"law": c["law"], "title": c["title"], "delta_ic": c["delta_ic"]} for c in r["law"]["candidates"][:6]
            ],
        },
        "constrained_lagrangian": r["constrained_lagrangian"].get("formula"),
        "trajectory": r["settings"]["trajectory"],
        "settings": {k: v for k, v in r["settings"].items() if k != "trajectory"},
        "wall_time_s": r["wall_time_s"],
    }


def _sweep(r: dict) -> dict:
    return {
        "system": r["system"],
        "p": r.get("p", r["settings"].get("p")),
        "verdict": _pick(r["verdict"], VERDICT),
        "table": [_pick(x, CURVE) for x in r["table"]],
        "steps_per_lambda": r["settings"]["steps_per_lambda"],
        "train_wall_time_s": r.get("train_wall_time_s", r.get("wall_time_s")),  # `nnphd sweep` writes the wall only
        "wall_time_s": r.get("wall_time_s"),
    }


def reproduce(a) -> None:
    out = a.out
    s = _read(os.path.join(out, "summary.json"))
    data: dict = {"command": f"nnphd reproduce --seed {s['seed']}", "summary": s}
    disc = []
    for name in s["settings"]["discover"]["systems"]:
        p = os.path.join(out, "discover", name, "results.json")
        if os.path.exists(p):
            disc.append(_discover(_read(p)))
    data["discover"] = disc
    p = os.path.join(out, "predict", "results.json")
    if os.path.exists(p):
        r = _read(p)
        data["predict"] = {
            "metrics": r["metrics"],
            "truth": r["truth"],
            "lnn_energy_constancy": r["lnn_energy_constancy"],
            "decomposition": {k: v for k, v in r["decomposition"].items() if k != "what"},
            "energy_balance": {k: v for k, v in r["energy_balance"].items() if k != "what"},
            "claims": r["claims"],
            "steps": r["settings"]["steps"],
            "train_time_s": r["train_time_s"],
            "wall_time_s": r["wall_time_s"],
        }
    p = os.path.join(out, "lambda-p", "results.json")
    if os.path.exists(p):
        r = _read(p)
        data["lambda_p"] = {
            "settings": _pick(r["settings"], ("systems", "ps", "lambdas", "steps_per_lambda", "align_tol")),
            "curves": {
                sys_: {pp: [_pick(x, CURVE) for x in rows] for pp, rows in by_p.items()}
                for sys_, by_p in r["curves"].items()
            },
            "verdicts": r["verdicts"],
            "claims": r["claims"],
            "train_wall_time_s": r.get("train_wall_time_s"),
            "wall_time_s": r.get("wall_time_s"),
        }
    p = os.path.join(out, "data-quality", "results.json")
    if os.path.exists(p):
        r = _read(p)
        keep = ("L_e", "L_b", "L_e_full", "m_c", "m_n")
        data["data_quality"] = {
            "settings": r["settings"],
            "alpha": [_pick(x, ("alpha", *keep)) for x in r["alpha"]["table"]],
            "beta": [_pick(x, ("beta", *keep)) for x in r["beta"]["table"]],
            "claims": r["claims"],
            "wall_time_s": r.get("wall_time_s"),
        }
    extra = {}
    if a.discover_300:
        r = _discover(_read(os.path.join(a.discover_300, "results.json")))
        r["command"] = "nnphd discover --system double-pendulum --n-steps 300 --seed 0"
        extra["discover_paper_length"] = r
    if a.sweep_8000:
        r = _sweep(_read(os.path.join(a.sweep_8000, "results.json")))
        r["command"] = "nnphd sweep --system ho+ld --steps 8000 --seed 0"
        extra["sweep_8000"] = r
    data["extra"] = extra
    _write("reproduce.json", data)


def neptune(a) -> None:
    rows = []
    for out in a.out:
        r = _read(os.path.join(out, "results.json"))
        rows.append(
            {
                "seed": r["settings"]["seed"],
                "verdict": _pick(r["verdict"], VERDICT),
                "learned_lagrangian": _pick(r["learned_lagrangian"], ("terms", "normalized", "formula", "gm_sun")),
                "fit": {k: v for k, v in r["fit"].items() if k != "params_model_units"},
                "truth": r["truth"],
                "errors": r["errors"],
                "goals": r["goals"],
                "all_goals_met": r["all_goals_met"],
                "diagnostics": r.get("diagnostics"),
                "settings": _pick(r["settings"], ("steps_per_lambda", "lambdas", "p", "step_days", "n_samples")),
                "wall_time_s": r["wall_time_s"],
            }
        )
    _write(
        "demo_neptune.json", {"command": "nnphd demo neptune --seed S", "runs": sorted(rows, key=lambda x: x["seed"])}
    )


def recordings(a) -> None:
    sys.path.insert(0, ROOT)
    from tests.fixtures.recordings import NAMES, make

    rows = [r for f in a.files for r in _read(f)]
    for r in rows:
        rec = make(r["name"], seed=r["seed"])
        r["samples"] = rec.n_samples
        r["conservative"] = rec.conservative
        # the truth column: the fixture's own words for noise ("no dynamics"), else conservative or not
        r["truth"] = (
            "no dynamics"
            if "no dynamics" in rec.description
            else ("conservative" if rec.conservative else "non-conservative")
        )
    rows.sort(key=lambda r: (r["seed"], NAMES.index(r["name"])))
    _write("detect_recordings_all.json", rows)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="what", required=True)
    p = sub.add_parser("reproduce")
    p.add_argument("out")
    p.add_argument("--discover-300", default=None, help="the folder of discover's double-pendulum results.json")
    p.add_argument("--sweep-8000", default=None, help="the folder of the sweep's results.json")
    p = sub.add_parser("neptune")
    p.add_argument("out", nargs="+")
    p = sub.add_parser("recordings")
    p.add_argument("files", nargs="+")
    a = ap.parse_args()
    {"reproduce": reproduce, "neptune": neptune, "recordings": recordings}[a.what](a)


if __name__ == "__main__":
    main()
