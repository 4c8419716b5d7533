"""Does a refactor change any verdict, law or number? The same seed must give the same report.json, byte for byte.

    .venv/bin/python benchmarks/report_identity.py --json before.json [--steps 400] [--cases a,b]
    .venv/bin/python benchmarks/report_identity.py --json after.json --against before.json

Runs ``detect_file`` (seed 0, no genetic symbolic regression) on twelve records of other kinds — 1-D and 2-D,
constructed (tests/fixtures/recordings.py and friction.py, written as CSV) and real (../shared/data/real: the servo
drop, two runs of the IBM double pendulum at 100 Hz over 8 s) — and stores, per record, the SHA-256 of its
report.json with the fields that cannot repeat removed (``timings``, ``wall_time_s``: seconds; ``file``: the
temporary path; and the checks' ``wall_time_s``), its status and its claimed law. The digest keeps the keys in the
order report.json writes them: a reordering is a difference. ``--against`` compares with a stored run and exits 1 on any
difference, naming the first top-level keys that differ. ``--steps`` (default 400, below the CLI's 1000 so that
the twelve take minutes) is recorded in the JSON; compare runs made with the same steps.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import sys
import tempfile
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

import nnphd  # noqa: E402
from tests.fixtures import friction, recordings  # noqa: E402

nnphd.configure()  # float64 and the XLA:CPU setting, as the CLI

from nnphd.user.detect import detect_file  # noqa: E402

REAL = os.path.join(os.path.dirname(ROOT), "shared", "data", "real")
VOLATILE = ("timings", "wall_time_s", "file")
# name -> (maker, record name, detect settings beyond the seed)
CASES = {
    "pendulum-damped": (recordings.make, "pendulum-damped", {}),
    "cart": (recordings.make, "cart", {}),
    "carts-coupled": (recordings.make, "carts-coupled", {}),
    "double-pendulum-camera": (recordings.make, "double-pendulum-camera", {}),
    "disjoint-clock": (recordings.make, "disjoint-clock", {}),
    "viscous-dry": (friction.make, "viscous-dry", {}),
    "linear-quadratic": (friction.make, "linear-quadratic", {}),
    "sensor-20hz-runs": (friction.make, "sensor-20hz-runs", {}),
    "throw-2d": (friction.make, "throw-2d", {"field": "vertical"}),
    "servo-drop": (None, "servo_sts3250_drop.csv", {}),
    "ibm-run6": (None, 6, {}),
    "ibm-run12": (None, 12, {}),
}


def _ibm_run(run: int, path: str) -> tuple[str, tuple[str, ...]]:
    d = np.genfromtxt(os.path.join(REAL, "ibm_double_pendulum_runs5-20.csv"), delimiter=",", names=True)
    m = d["traj"] == run
    t, a1, a2 = d["t"][m][::4], d["theta1"][m][::4], d["theta2"][m][::4]
    t = t - t[0]
    keep = t <= 8.0
    np.savetxt(path, np.c_[t[keep], a1[keep], a2[keep]], delimiter=",", header="t,theta1,theta2", comments="",
               fmt="%.6f")  # fmt: skip
    return path, ("theta1", "theta2")


def record(name: str, tmp: str) -> tuple[str, tuple[str, ...], dict]:
    """(the CSV path, its angle columns, the detect settings) of case ``name``."""
    maker, what, settings = CASES[name]
    path = os.path.join(tmp, f"{name}.csv")
    if maker is not None:
        rec = maker(what, 0)
        rec.write_csv(path)
        return path, tuple(rec.angles), settings
    if isinstance(what, int):
        return (*_ibm_run(what, path), settings)
    return os.path.join(REAL, what), (), settings


def stable(report: dict) -> dict:
    """The report without the fields that cannot repeat (:data:`VOLATILE`, and the checks' ``wall_time_s``)."""
    kept = {k: v for k, v in report.items() if k not in VOLATILE}
    if isinstance(kept.get("checks"), dict):
        kept["checks"] = {k: v for k, v in kept["checks"].items() if k != "wall_time_s"}
    return kept


def digest(report: dict) -> str:
    """SHA-256 of the stable report as report.json writes it (keys in their order, :func:`stable`)."""
    return hashlib.sha256(json.dumps(stable(report), default=str).encode()).hexdigest()


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--cases", default=",".join(CASES))
    ap.add_argument("--steps", type=int, default=400)
    ap.add_argument("--json", required=True)
    ap.add_argument("--against", default=None)
    a = ap.parse_args()
    old = json.load(open(a.against)) if a.against else None
    out = {"steps": a.steps, "records": {}}
    bad = 0
    with tempfile.TemporaryDirectory() as tmp:
        for name in a.cases.split(","):
            path, angles, settings = record(name, tmp)
            t0 = time.perf_counter()
            rep = detect_file(path, None, angles=angles, seed=0, sr_time=0, steps=a.steps, **settings)
            law = ((rep.get("law") or {}).get("law") or {}).get("law")  # the claimed family's key
            row = {"sha256": digest(rep), "status": rep["status"], "law": law, "report": stable(rep)}
            out["records"][name] = row
            same = ""
            if old is not None:
                ref = old["records"].get(name)
                if ref is not None:  # a stored run: its digest again (the same rule as this run's)
                    ref = {**ref, "sha256": digest(ref["report"])}
                if ref is None or ref["sha256"] != row["sha256"]:
                    bad += 1
                    keys = [k for k in row["report"] if ref is None or row["report"][k] != ref["report"].get(k)]
                    same = f"  DIFFERENT ({', '.join(keys[:6])})"
                else:
                    same = "  identical"
            print(f"{name:24s} {rep['status']:13s} {law!s:22s} {row['sha256'][:12]} "
                  f"{time.perf_counter() - t0:6.0f} s{same}", flush=True)  # fmt: skip
            with open(a.json + ".tmp", "w") as f:
                json.dump(out, f, indent=1, default=str)
            os.replace(a.json + ".tmp", a.json)
    if old is not None:
        print(f"\n{len(out['records']) - bad} of {len(out['records'])} reports identical")
        sys.exit(1 if bad else 0)


if __name__ == "__main__":
    main()
