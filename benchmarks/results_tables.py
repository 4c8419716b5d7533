"""The tables of docs/RESULTS.md that are generated from ``benchmarks/results/*.json``, so they cannot drift from
what was measured. Each sits between ``<!-- generated: NAME -->`` and ``<!-- end generated -->``; this script
re-renders them from the JSON. The prose around them is written by hand.

    python benchmarks/results_tables.py           # rewrite docs/RESULTS.md in place
    python benchmarks/results_tables.py --check   # exit 1 (and say which) when a table differs from its JSON

tests/test_results_tables.py runs ``--check``'s comparison.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import statistics
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
RESULTS = os.path.join(ROOT, "benchmarks", "results")
DOC = os.path.join(ROOT, "docs", "RESULTS.md")
BLOCK = re.compile(r"(<!-- generated: (?P<name>[a-z_]+) -->\n)(?P<body>.*?)(<!-- end generated -->)", re.S)


def _load(name: str):
    with open(os.path.join(RESULTS, name)) as f:
        return json.load(f)


def _median(xs):
    return statistics.median(xs) if xs else float("nan")


# ---- the tables ---------------------------------------------------------------------------------------------------
STAGE_COLUMNS = (
    ("training", "training and trust checks"),
    ("law, pointwise", "law table: pointwise fits"),
    ("law, trajectory level", "law table: trajectory-level fits"),
    ("rests, stops, envelope", "law table: rests, stops and envelope"),
)
REAL_FILES = ("servo_sts3250_drop", "seismometer_blow")


def stage_times() -> str:
    """results/stage_times.json (benchmarks/stage_times.py): per file, cold and warm totals and the warm stages."""
    rows = sorted(_load("stage_times.json"), key=lambda r: r["warm"]["total_s"])
    head = " | ".join(f"warm: {c}" for c, _ in STAGE_COLUMNS)
    out = [
        f"| file | rows | verdict | cold total | warm total | {head} | warm compiling |",
        "|---" * (6 + len(STAGE_COLUMNS)) + "|",
    ]
    for r in rows:
        by = {s["stage"]: s for s in r["warm"]["stages"]}
        cells = " | ".join(f"{by[s]['s']:.1f} ({by[s]['compile_s']:.1f})" if s in by else "—" for _, s in STAGE_COLUMNS)
        name = r["file"] + (" (real)" if r["file"] in REAL_FILES else "")
        out.append(
            f"| {name} | {r['rows']} | {r['warm']['status']} | {r['cold']['total_s']:.1f} | {r['warm']['total_s']:.1f} "
            f"| {cells} | {r['warm']['compile_s']:.1f} |"
        )
    for kind in ("cold", "warm"):
        tot = [r[kind]["total_s"] for r in rows]
        out.append("")
        out.append(f"{kind}: median {_median(tot):.1f} s, max {max(tot):.1f} s per file")
    same = sum(r["same_verdict"] for r in rows)
    out.append("")
    out.append(
        f"Same verdict and law cold and warm on {same} of {len(rows)}. (Seconds; in brackets, of them compiling.)"
    )
    return "\n".join(out) + "\n"


def cluster_scaling() -> str:
    """results/cluster_scaling.json (benchmarks/cluster_scaling.py): simulated makespan and efficiency."""
    d = _load("cluster_scaling.json")
    shown = [w for w in d["workers"] if w > 1]
    out = [
        "| batch (unit times measured here) | units | work s | " + " | ".join(f"{w} workers" for w in shown) + " |",
        "|---" * (3 + len(shown)) + "|",
    ]
    for name, s in d["sets"].items():
        by = {r["workers"]: r for r in s["rows"]}
        cells = " | ".join(f"{by[w]['makespan_s']:.0f} s ({by[w]['efficiency']:.2f})" for w in shown)
        out.append(f"| {name} | {s['n_units']} | {s['work_s']:.0f} | {cells} |")
    o = d["overhead"]
    out.append("")
    out.append(
        f"(makespan, efficiency = work / (workers × makespan); Dask measured here: {o['startup_s']:.1f} s to start "
        f"and stop a cluster, {1000 * o['per_unit_s']:.0f} ms per unit.)"
    )
    return "\n".join(out) + "\n"


def declared_field_guard() -> str:
    """results/declared_field_guard.json (benchmarks/declared_field_guard.py): a wrong declaration."""
    d = _load("declared_field_guard.json")
    seeds = sorted({r["seed"] for r in d["rows"]})
    out = [
        "| case | truth | " + " | ".join(f"seed {s}" for s in seeds) + " | share of the law's force opposing v | s |",
        "|---" * (4 + len(seeds)) + "|",
    ]
    for case, spec in d["cases"].items():
        rows = {r["seed"]: r for r in d["rows"] if r["case"] == case}
        truth = "none or inconclusive" if spec["truth"] == "not-detected" else spec["truth"]
        sts = " | ".join(rows[s]["status"] + ("" if rows[s]["right"] else " ✗") for s in seeds)
        along = ", ".join(
            "—" if rows[s]["against_velocity"] is None else f"{100 * rows[s]['against_velocity']:.0f} %" for s in seeds
        )
        secs = ", ".join(f"{rows[s]['seconds']:.0f}" for s in seeds)
        label = case if spec["R"] is None else f"{case} (1/r² field, R = {spec['R']:g} m)"
        label += f", drag c = {spec['c']:g}" if spec["c"] else ", no drag"
        out.append(f"| {label} | {truth} | {sts} | {along} | {secs} |")
    wrong = sum(r["status"] == "detected" and not r["right"] for r in d["rows"])
    out.append("")
    out.append(f'{d["right"]} of {d["n"]} right; {wrong} wrong "detected".')
    return "\n".join(out) + "\n"


def seed_robustness() -> str:
    """results/seed_robustness.json (benchmarks/seed_robustness.py): one verdict whatever the seed."""
    d = _load("seed_robustness.json")
    seeds = d["seeds"]
    out = [
        "| set | file | truth | " + " | ".join(f"seed {s}" for s in seeds) + " | agree | right | s per seed |",
        "|---" * (6 + len(seeds)) + "|",
    ]
    for r in d["rows"]:
        runs = {x["seed"]: x for x in r["runs"]}
        sts = " | ".join(runs[s]["status"] for s in seeds)
        secs = ", ".join(f"{runs[s]['seconds']:.0f}" for s in seeds)
        truth = "none or inconclusive" if r["expected"] == "not-detected" else r["expected"]
        out.append(
            f"| {r['set']} | {r['file']} | {truth} | {sts} | {'yes' if r['agree'] else '**no**'} | "
            f"{'yes' if r['right_all'] else '**no**'} | {secs} |"
        )
    s = d["summary"]
    out.append("")
    out.append(
        f"Statuses agree on {s['agree']} of {s['files']} files ({100 * s['agree'] / s['files']:.0f} %); right on every "
        f'seed on {s["right_all_seeds"]} of {s["files"]}; runs with a wrong "detected": {s["wrong_detected_runs"]}; '
        f'"none" on new physics: {s["missed_runs"]}; seconds per run: median {s["median_s"]:.0f}, max '
        f"{s['max_s']:.0f}."
    )
    drives = [r for r in d["rows"] if "drive_within_5pct" in r]
    for r in drives:
        got = "; ".join(
            "no drive" if x["drive"] is None else f"A = {x['drive']['A']:.4g}, ω = {x['drive']['omega']:.4g}"
            for x in r["runs"]
        )
        t = r["drive_truth"]
        out.append(
            f"The drive of {r['file']} (truth A = {t['A']:g}, ω = {t['omega']:g}): {got} — within 5 % on "
            f"{sum(r['drive_within_5pct'])} of {len(r['runs'])} seeds."
        )
    return "\n".join(out) + "\n"


TABLES = {
    "stage_times": stage_times,
    "cluster_scaling": cluster_scaling,
    "declared_field_guard": declared_field_guard,
    "seed_robustness": seed_robustness,
}


def render(text: str) -> tuple[str, list[str]]:
    """``text`` with every generated block re-rendered, and the names of the blocks that changed."""
    changed = []

    def one(m):
        name = m.group("name")
        if name not in TABLES:
            raise SystemExit(f"error: {DOC}: unknown generated table {name!r}; expected one of {', '.join(TABLES)}")
        body = TABLES[name]()
        if body != m.group("body"):
            changed.append(name)
        return m.group(1) + body + m.group(4)

    return BLOCK.sub(one, text), changed


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--check", action="store_true", help="change nothing; exit 1 when a table differs")
    a = ap.parse_args()
    with open(DOC, encoding="utf-8") as f:
        text = f.read()
    new, changed = render(text)
    if a.check:
        if changed:
            print(f"docs/RESULTS.md differs from the JSON in: {', '.join(changed)}", file=sys.stderr)
            raise SystemExit(1)
        print("docs/RESULTS.md: every generated table matches its JSON")
        return
    tmp = DOC + ".tmp"
    with open(tmp, "w", encoding="utf-8") as f:
        f.write(new)
    os.replace(tmp, DOC)
    print(f"rewrote: {', '.join(changed) or 'nothing (all up to date)'}")


if __name__ == "__main__":
    main()
