"""Does the law search's funnel drop a family that could have won? (issue 57.) Each record is run through
``detect_file`` twice in one process at its default settings (no genetic symbolic regression), with the same seed:
once with the funnel at its default and once off (``nnphd.explain.trajectory.FUNNEL_REACH = inf``: every shortlisted
family fitted by shooting, as before the funnel) — where the funnel cut nothing the second run would fit the same
families from the same starts, and is not run; prints per record the verdict, the claimed law (or the best candidate)
with its coefficients, the ties, how many families each trajectory-level table fitted, and whether the two runs agree:
the same verdict, the same claimed law and ties, each coefficient within the larger of the two stated standard errors.

    .venv/bin/python benchmarks/funnel_audit.py [--records kind:name,...] [--seeds 0] [--json out.json]

``--records``: as benchmarks/stage_times.py (friction:, laws:, recordings:, real:, ibm:RUN; ``all``: every look-alike
of tests/fixtures with two or more coordinates and the real IBM double-pendulum runs 6 and 13 at 100 Hz; ``all1d``:
every look-alike of one coordinate and the real 1-D recordings of results/friction_reference.json — the funnel does
not run on one coordinate; results/funnel_audit_1d.json is the run of a one-coordinate funnel that was not kept, as
it changed a claim). Results: results/funnel_audit.json. Each base's table of a combined one is read from the law
table's ``settings.bases``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "benchmarks"))

from stage_times import record  # noqa: E402

import nnphd  # noqa: E402
from tests.fixtures import recordings  # noqa: E402

TWO_D_LAWS = ("quadratic-drag-2d", "anisotropic-damping", "henon-heiles", "gyroscopic")


def _all() -> list[str]:
    """The records with two or more coordinates (the funnel's; on one coordinate every family is fitted, as the
    amplitude envelope ranks after the windows): the 2-D look-alikes of tests/fixtures and two real IBM runs."""
    return [
        "friction:throw-2d",
        *(f"laws:{n}" for n in TWO_D_LAWS),
        *(f"recordings:{n}" for n in recordings.NAMES if recordings.make(n, 0).q.shape[1] > 1),
        "ibm:6",
        "ibm:13",
    ]


def _all1d() -> list[str]:
    """The records of one coordinate (where the funnel does not run: a funnel tried there is audited on them): every
    1-D look-alike of tests/fixtures and the real 1-D recordings of results/friction_reference.json."""
    from tests.fixtures import friction, laws

    with open(os.path.join(ROOT, "benchmarks", "results", "friction_reference.json")) as f:
        real = [os.path.splitext(os.path.basename(r["file"]))[0] for r in json.load(f)["recordings"]]
    return [
        *(f"friction:{n}" for n in friction.NAMES if n != "throw-2d"),
        *(f"laws:{n}" for n in laws.NAMES if n not in TWO_D_LAWS),
        *(f"recordings:{n}" for n in recordings.NAMES if recordings.make(n, 0).q.shape[1] == 1),
        *(f"real:{n}" for n in real),
    ]


def _tables(rep: dict) -> list[dict]:
    """The law tables of a report that a trajectory-level ranking made (the claimed one; the library base's; each
    base's of a combined table, as {"settings": {"funnel": …}})."""
    out = []

    def walk(d):
        if isinstance(d, dict):
            if "funnel" in d.get("settings", {}) and "candidates" in d:
                out.append(d)
            for base in d.get("settings", {}).get("bases", []) if "candidates" in d else []:
                if isinstance(base, dict) and "funnel" in base:
                    out.append({"settings": {"funnel": base["funnel"]}})
            for v in d.values():
                walk(v)
        elif isinstance(d, list):
            for v in d:
                walk(v)

    walk(rep)
    return out


def _summary(rep: dict) -> dict:
    law = rep.get("law") or {}
    win = law.get("law")
    best = win or next((c for c in law.get("candidates", []) if c.get("law") != "none"), None)
    fits = [
        {
            "pointwise": t["settings"]["funnel"]["pointwise"],
            "trajectory": t["settings"]["funnel"]["trajectory"],
            "cut": bool(t["settings"]["funnel"].get("cut")),
        }
        for t in _tables(rep)
    ]
    stages = {s["stage"]: s["s"] for s in rep.get("timings", {}).get("stages", [])}
    return {
        "status": rep.get("status"),
        "law_status": law.get("status"),
        "law": win.get("law") if win else None,
        "params": dict(win.get("params", {})) if win else {},
        "stderr": dict(win.get("stderr", {})) if win else {},
        "best_candidate": best.get("law") if best else None,
        "ties": sorted(t.get("law") for t in (law.get("ties") or [])),
        "fits": fits,
        "trajectory_s": stages.get("law table: trajectory-level fits"),
        "total_s": rep.get("timings", {}).get("total_s"),
    }


def _agree(a: dict, b: dict) -> tuple[bool, str]:
    for k in ("status", "law_status", "law", "ties"):
        if a[k] != b[k]:
            return False, f"{k}: {a[k]} vs {b[k]}"
    for p, v in a["params"].items():
        w = b["params"].get(p)
        se = max(a["stderr"].get(p, 0.0) or 0.0, b["stderr"].get(p, 0.0) or 0.0)
        if w is None or not abs(v - w) <= se:
            return False, f"{p}: {v:.4g} vs {w} (se {se:.2g})"
    return True, ""


def _write(path: str, rows: list) -> None:
    tmp = path + ".tmp"
    with open(tmp, "w") as f:
        json.dump(rows, f, indent=1)
    os.replace(tmp, path)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--records", default="all")
    ap.add_argument("--seeds", default="0")
    ap.add_argument("--json", default=None)
    a = ap.parse_args()
    nnphd.configure()  # float64 and the XLA:CPU setting, as the CLI
    specs = {"all": _all, "all1d": _all1d}.get(a.records, lambda: [s for s in a.records.split(",") if s])()
    import nnphd.explain.trajectory as trajectory
    from nnphd.user.detect import detect_file

    default = trajectory.FUNNEL_REACH
    rows = []
    with tempfile.TemporaryDirectory() as work:
        for seed in [int(s) for s in a.seeds.split(",")]:
            for spec in specs:
                name, path, angles, _, extra = record(spec, work, seed)
                settings = {"field": extra[1]} if extra else {}
                got = {}
                for label, reach in (("funnel", default), ("all", math.inf)):
                    if label == "all" and not any(x["cut"] for x in got["funnel"]["fits"]):
                        # the funnel fitted the whole shortlist: the same fits as without it (each candidate's fit
                        # starts from the zero law's and its own pointwise one, whatever the order)
                        got[label] = {**got["funnel"], "not_run": "the funnel cut nothing: the same fits"}
                        continue
                    trajectory.FUNNEL_REACH = reach
                    t0 = time.perf_counter()
                    rep = detect_file(path, out=None, angles=angles, seed=seed, sr_time=0, **settings)
                    got[label] = {**_summary(rep), "wall_s": time.perf_counter() - t0}
                trajectory.FUNNEL_REACH = default
                same, why = _agree(got["all"], got["funnel"])
                row = {"record": spec, "seed": seed, "same": same, "differs": why, **got}
                rows.append(row)
                f = got["funnel"]
                fitted = "; ".join(f"{x['trajectory']}/{x['pointwise']}" for x in f["fits"]) or "-"
                fitted_all = "; ".join(str(x["trajectory"]) for x in got["all"]["fits"]) or "-"
                print(
                    f"{spec:42s} seed {seed}  {str(f['status']):14s} law {f['law'] or '-':24s} "
                    f"(best {f['best_candidate']}) ties {','.join(f['ties']) or '-':20s} fitted "
                    f"{fitted:12s} vs all {fitted_all:8s} "
                    f"{'same' if same else 'DIFFERS: ' + why}",
                    flush=True,
                )
                if a.json:  # after every record: a long run stopped part way keeps what it measured
                    _write(a.json, rows)
    n_same = sum(r["same"] for r in rows)
    print(f"{n_same} of {len(rows)} records: the same verdict, law, ties and coefficients with the funnel")


if __name__ == "__main__":
    main()
