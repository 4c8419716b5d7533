"""Issue 58: the constraints and coordinates nnphd chooses from camera markers, against the truth — the look-alikes
of tests/fixtures/markers.py (pixels, a pixel of jitter, rounded positions, lost frames, the camera turned) over
several seeds, and the real IBM double pendulum's raw tracks (../shared/data/real/ibm_markers, runs 5–8) against the
hand conversion. Prints one row per record; ``--json`` writes them.

    .venv/bin/python benchmarks/markers_constraints.py [--seeds 0,1,2] [--json out.json]

Per record: the constraints found (kinds and markers), the coordinates chosen, whether both are the truth's (the
right rods, pivot, rail, nothing assumed for a spring or a throw), the largest rod-length error and (an untracked
pivot) the pivot's distance from the truth, both against the rod's length, and the largest deviation of each chosen
coordinate from the true one (up to a constant and the image's sense; angles in rad, a rail in metres).
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "src"))

from nnphd.io.results import write_json  # noqa: E402
from nnphd.user.markers import from_columns  # noqa: E402
from tests.fixtures.markers import NAMES, PX_PER_M, make  # noqa: E402

REAL = os.path.join(os.path.dirname(ROOT), "shared", "data", "real")
# what each look-alike must give: the constraints (kind, markers) and the coordinates' kinds
TRUTH = {
    "double-pendulum": ({("fixed", ("pivot",)), ("rod", ("pivot", "joint")), ("rod", ("joint", "tip"))},
                        ["angle", "angle"]),
    "double-pendulum-untracked": ({("pivot", ("pivot", "joint")), ("rod", ("joint", "tip"))}, ["angle", "angle"]),
    "cart-pendulum": ({("rail", ("cart",)), ("rod", ("cart", "bob"))}, ["rail", "angle"]),
    "spring-pendulum": ({("fixed", ("pivot",))}, ["free", "free"]),
    "throw": (set(), ["free", "free"]),
    "rigid-pendulum": ({("fixed", ("pivot",)), ("rod", ("pivot", "mid")), ("rod", ("pivot", "end")),
                        ("rod", ("mid", "end"))}, ["angle"]),
    "damped-pendulum": ({("fixed", ("pivot",)), ("rod", ("pivot", "bob"))}, ["angle"]),
}  # fmt: skip


def _dev(a, b) -> float:
    """The largest deviation of a from ±b + a constant (the image's sense may flip an angle)."""
    return float(min(np.ptp(a - b), np.ptp(a + b)) / 2)


def lookalike(name: str, seed: int) -> dict:
    cam = make(name, seed)
    t0 = time.perf_counter()
    mm = from_columns(cam.columns, fps=cam.fps)
    secs = time.perf_counter() - t0
    found = {(c.kind, c.markers) for c in mm.constraints}
    want, kinds = TRUTH[name]
    rods = {c.markers: c.value[0] for c in mm.constraints if c.kind in ("rod",)}
    rod_err = max((abs(rods[k] - v) / v for k, v in cam.rods.items() if k in rods), default=None)
    pivot_err = None
    for c in mm.constraints:
        if c.kind == "pivot" and cam.pivot is not None:
            length = cam.rods[("pivot", c.markers[1])]
            pivot_err = float(np.linalg.norm(np.asarray(c.value[:2]) - cam.pivot) / length)
            rod_err = max(rod_err or 0.0, abs(c.value[2] - length) / length)
    keep = np.all([np.isfinite(v) for k, v in cam.columns.items() if k != "frame"], axis=0)
    scale = [PX_PER_M if c.kind == "rail" else 1.0 for c in mm.coordinates]
    dev = (
        [_dev(mm.q[:, j] / s, cam.q[keep, j]) for j, s in enumerate(scale)]
        if [c.kind for c in mm.coordinates] == kinds and name != "spring-pendulum" and name != "throw"
        else None
    )
    return {
        "record": f"{name} (seed {seed})",
        "constraints": sorted(f"{k} {'–'.join(m)}" for k, m in found),
        "coordinates": [f"{c.name} ({c.kind})" for c in mm.coordinates],
        "right": found == want and [c.kind for c in mm.coordinates] == kinds,
        "rod_length_error": rod_err,
        "pivot_error": pivot_err,
        "coordinate_deviation": dev,
        "note": mm.note(),
        "seconds": secs,
    }


def ibm(run: int) -> dict | None:
    path = os.path.join(REAL, "ibm_markers", f"run{run}.csv")
    if not os.path.exists(path):
        return None
    d = np.genfromtxt(path, delimiter=",", names=True)
    t0 = time.perf_counter()
    mm = from_columns({k: d[k] for k in d.dtype.names}, fps=400.0)
    secs = time.perf_counter() - t0
    hand = np.genfromtxt(os.path.join(REAL, "ibm_double_pendulum_runs5-20.csv"), delimiter=",", names=True)
    m = hand["traj"] == run
    P = mm.positions
    rod_err = max(
        abs(c.value[0] - np.median(np.linalg.norm(P[c.markers[1]] - P[c.markers[0]], axis=1))) / c.value[0]
        for c in mm.constraints
        if c.kind == "rod"
    )
    found = {(c.kind, c.markers) for c in mm.constraints}
    want = {("fixed", ("red",)), ("rod", ("red", "green")), ("rod", ("green", "blue"))}
    return {
        "record": f"IBM double pendulum run {run} (real, 400 fps)",
        "constraints": sorted(f"{k} {'–'.join(m)}" for k, m in found),
        "coordinates": [f"{c.name} ({c.kind})" for c in mm.coordinates],
        "right": found == want and mm.angles == ("theta_green", "theta_blue"),
        "rod_length_error": rod_err,  # against the median marker distance (issue 58's check)
        "rod_scatter_rel": [c.rel for c in mm.constraints if c.kind == "rod"],
        "pivot_error": None,
        "coordinate_deviation": [
            float(np.max(np.abs(mm.q[:, 0] - hand["theta1"][m]))),
            float(np.max(np.abs(mm.q[:, 1] - hand["theta2"][m]))),
        ],  # fmt: skip
        "note": mm.note(),
        "seconds": secs,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", default="0,1,2")
    ap.add_argument("--json", default=None)
    a = ap.parse_args()
    rows = [lookalike(n, int(s)) for n in NAMES for s in a.seeds.split(",")]
    rows += [r for r in (ibm(k) for k in (5, 6, 7, 8)) if r is not None]
    print("| record | constraints | coordinates | right | rod length error | pivot error | coordinate deviation |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        f = lambda x: "—" if x is None else f"{100 * x:.2f} %"  # noqa: E731
        dev = "—" if r["coordinate_deviation"] is None else ", ".join(f"{x:.2g}" for x in r["coordinate_deviation"])
        print(f"| {r['record']} | {'; '.join(r['constraints']) or 'none'} | {', '.join(r['coordinates'])} | "
              f"{'yes' if r['right'] else '**no**'} | {f(r['rod_length_error'])} | {f(r['pivot_error'])} | {dev} |")  # fmt: skip
    print(f"\nright: {sum(r['right'] for r in rows)} of {len(rows)}")
    if a.json:
        write_json(a.json, rows)


if __name__ == "__main__":
    main()
