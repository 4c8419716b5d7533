"""The tables of docs/RESULTS.md, docs/paper.md and docs/scaling.md that are generated from
``benchmarks/results/*.json``, so they cannot drift from what was measured. Each sits between
``<!-- generated: NAME -->`` and ``<!-- end generated -->`` (every table in one of the pages, once); this script
re-renders them from the JSON. The prose around them is written by hand.

    python benchmarks/results_tables.py           # rewrite the three pages in place
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
DOCS = tuple(os.path.join(ROOT, "docs", name) for name in ("RESULTS.md", "paper.md", "scaling.md"))
DOC = DOCS[0]  # nnphd detect's results; the paper's experiments are in paper.md, time and speed in scaling.md
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
    ("library base ∥ (beside the training)", "law table: library base (alongside training)"),
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
        f"Same verdict and law cold and warm on {same} of {len(rows)}. (Seconds; in brackets, of them compiling; ∥: "
        "on another thread, beside the others — its seconds overlap theirs.)"
    )
    return "\n".join(out) + "\n"


def stage_times_held_out() -> str:
    """results/stage_times_held_out.json (benchmarks/stage_times.py --records …, issue 57's held-out set): per record,
    cold and warm totals, the warm stages that dominate, a second file of another length (the first F of its rows,
    with the first's cache), and the warm totals of the baseline it replaced."""
    d = _load("stage_times_held_out.json")
    rows = sorted(d["records"], key=lambda r: r["warm"]["total_s"])
    base = d.get("baseline", {}).get("warm_s", {})
    base_other = d.get("baseline", {}).get("other_compile_s", {})
    out = [
        "| record | rows | verdict | law | cold total | warm total (before) | warm: training | warm: law, trajectory "
        "level | warm compiling | other length: rows, total, compiling (before) |",
        "|---" * 10 + "|",
    ]
    for r in rows:
        by = {s["stage"]: s for s in r["warm"]["stages"]}

        def cell(stage, by=by):
            return f"{by[stage]['s']:.1f} ({by[stage]['compile_s']:.1f})" if stage in by else "—"

        o = r.get("other length")
        was = f" ({base_other[r['file']]:.1f})" if r["file"] in base_other else ""
        other = f"{o['rows']}, {o['total_s']:.1f}, {o['compile_s']:.1f}{was}" if o else "—"
        before = f" ({base[r['file']]:.1f})" if r["file"] in base else ""
        at = f" [{r['measured_at']}]" if "measured_at" in r else ""  # a table measured in parts: which part
        out.append(
            f"| {r['file']}{at} | {r['rows']} | {r['warm']['status']} | {r['warm']['law']} | {r['cold']['total_s']:.1f} "
            f"| {r['warm']['total_s']:.1f}{before} | {cell('training and trust checks')} "
            f"| {cell('law table: trajectory-level fits')} | {r['warm']['compile_s']:.1f} | {other} |"
        )
    out.append("")
    for kind in ("cold", "warm", "other length"):
        got = [r[kind] for r in rows if kind in r]
        tot, comp = [x["total_s"] for x in got], [x["compile_s"] for x in got]
        out.append(
            f"{kind}: median {_median(tot):.1f} s, max {max(tot):.1f} s per record; compiling median "
            f"{_median(comp):.1f} s, max {max(comp):.1f} s ({len(got)} records)"
        )
        out.append("")
    if base:
        when = d["baseline"].get("when", "another day")
        line = (f"before ({d['baseline']['commit']}, {when}), warm: median {_median(list(base.values())):.1f} s,"
                f" max {max(base.values()):.1f} s")  # fmt: skip
        if base_other:
            line += (f"; other length, compiling: median {_median(list(base_other.values())):.1f} s, max "
                     f"{max(base_other.values()):.1f} s")  # fmt: skip
        out += [line, ""]
    for ab in d.get("ab") or []:  # same-day runs of the code before and after
        b, a = ab["before"], ab["after"]
        other = ""
        if "other_s" in b and "other_s" in a:
            other = (f", other length {b['other_s']:.1f} → {a['other_s']:.1f} s (compiling {b['other_compile_s']:.1f} → "
                     f"{a['other_compile_s']:.1f} s)")  # fmt: skip
        out.append(
            f"{ab['record']}, before ({b['commit']}) and after ({a['commit']}) one after the other on the same day: "
            f"cold {b['cold_s']:.1f} → {a['cold_s']:.1f} s, warm {b['warm_s']:.1f} → {a['warm_s']:.1f} s{other}"
        )
        out.append("")
    same = sum(r["same_verdict"] for r in rows)
    out.append(
        f"Same verdict and law cold and warm on {same} of {len(rows)}. ({d['what']} Seconds; in brackets, of them "
        "compiling.)"
    )
    return "\n".join(out) + "\n"


def markers_constraints() -> str:
    """results/markers_constraints.json (benchmarks/markers_constraints.py, issue 58): per camera record, the
    constraints and coordinates chosen from its markers against the truth."""
    rows = _load("markers_constraints.json")
    out = [
        "| record | constraints found | coordinates chosen | right | rod length error | untracked pivot error "
        "| coordinate deviation |",
        "|---" * 7 + "|",
    ]
    for r in rows:

        def pct(x):
            return "—" if x is None else f"{100 * x:.2f} %"

        dev = "—" if r["coordinate_deviation"] is None else ", ".join(f"{x:.2g}" for x in r["coordinate_deviation"])
        out.append(
            f"| {r['record']} | {'; '.join(r['constraints']) or 'none'} | {', '.join(r['coordinates'])} | "
            f"{'yes' if r['right'] else '**no**'} | {pct(r['rod_length_error'])} | {pct(r['pivot_error'])} | {dev} |"
        )
    out += ["", f"Right constraints and coordinates: {sum(r['right'] for r in rows)} of {len(rows)}."]
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


# ---- shared formatting ---------------------------------------------------------------------------------------------
def _neg(s: str) -> str:
    """A formatted number with the typographic minus the hand-written tables use (exponents keep '-')."""
    return "−" + s[1:] if s.startswith("-") else s


def _compact(s: str) -> str:
    """A formatted number with its exponent unpadded ('5e-9', not '5e-09') and a typographic leading minus."""
    return _neg(re.sub(r"e([+-])0*(\d)", lambda m: "e" + m[1].replace("+", "") + m[2], s))


def _g(x: float, digits: int, zeros: bool = False) -> str:
    """``x`` to ``digits`` significant digits; with ``zeros`` trailing zeros kept (0.620, not 0.62)."""
    return _compact(f"{x:#.{digits}g}".rstrip(".") if zeros else f"{x:.{digits}g}")


def _f(x: float, decimals: int) -> str:
    return _neg(f"{x:.{decimals}f}")


def _signed(x: float, fmt: str) -> str:
    """' + 3' / ' − 3': a term after the first."""
    return (" − " if x < 0 else " + ") + format(abs(x), fmt)


# ---- the real chaotic double pendulum ------------------------------------------------------------------------------
DP_FAMILIES = {
    "linear": "linear",
    "linear-diag": "linear per joint",
    "quadratic": "quadratic",
    "quadratic-diag": "quadratic per joint",
    "coulomb": "Coulomb",
    "coulomb-diag": "Coulomb per joint",
    "power": "power",
}


def _dp_best(title: str) -> str:
    """'linear friction −γ q̇ (isotropic)' -> 'linear'; a per-coordinate family ('−c_i …') -> '… per joint'."""
    return title.split()[0] + (" per joint" if "_i" in title else "")


def _dp_law(r) -> str:
    """The law column, from the report's law_status and law_reason: a tie's families in its order, or why no law."""
    why = r.get("law_reason") or ""
    if r["law_status"] == "tie":
        fams = re.findall(r"(?:— |; )([a-z+-]+): \w+ =", why)
        return "tie: " + " / ".join(DP_FAMILIES.get(f, f) for f in fams)
    if r["law_status"] != "none":
        return r["law_status"]
    m = re.search(r"the best, (.+?) \(ΔIC = ([-+\d.]+)\), is not eligible", why)
    if m:
        return f"none ({_dp_best(m[1])} ΔIC {_neg(m[2])}, not eligible)"
    m = re.search(r"the best, (.+?), changes the held-out error by ([-+\d.]+)%.*\(ΔIC = ([-+\d.]+)\)", why)
    if m:
        return f"none ({_dp_best(m[1])} {_f(float(m[2]), 1)} %, ΔIC {_neg(m[3])})"
    return "none"


def _dp_mark(r) -> str:
    """'*': a run its JSON says ran beside the test suite ('beside': 'runs 11 and 12 beside …'); '†': a run of the
    round after (its JSON names no older code), measured beside that round's development; '' : ran alone."""
    named = re.match(r"runs? ([\d, and]+?) beside", r.get("beside", ""))
    if named and r["run"] in {int(n) for n in re.findall(r"\d+", named[1])}:
        return "*"
    return "" if "code" in r else "†"


def _dp_probe(s, i: int) -> str:
    if not s["valid"][i]:
        return "invalid"
    return f"{_f(s['d_mean'][i], 3)} ± {s['se_d_mean'][i]:.3f} ({_f(s['z'][i], 1)})"


def real_double_pendulum() -> str:
    """results/real_double_pendulum.json (benchmarks/real_double_pendulum.py --seconds 0): whole runs, the rounds
    in the order they were measured (runs with an older 'code' first)."""
    rows = sorted(_load("real_double_pendulum.json"), key=lambda r: ("code" not in r, r["run"]))
    out = [
        "| run | verdict (confidence) | energy z (seeds 0, 1) | shooting probe d ± se (z), seeds 0, 1 | law | s |",
        "|---" * 6 + "|",
    ]
    for r in rows:
        z = ", ".join(_f(x, 1) for x in r["energy_trend"]["z"])
        probe = "; ".join(_dp_probe(r["shooting"], i) for i in range(len(r["shooting"]["z"])))
        out.append(
            f"| {r['run']} | {r['status']} ({r['confidence']:.2f}) | {z} | {probe} | {_dp_law(r)} | "
            f"{r['wall_s']:.0f}{_dp_mark(r)} |"
        )
    return "\n".join(out) + "\n"


# ---- time to a verdict, float32 ------------------------------------------------------------------------------------
def _verdict(new_physics: bool) -> str:
    return "new physics" if new_physics else "none"


def time_to_verdict() -> str:
    """results/time_to_verdict.json (benchmarks/time_to_verdict.py): the paper protocol against --mode fast."""
    out = [
        "| system | paper: verdict | ratio | s | fast: verdict | ratio | s | steps | what fast ran |",
        "|---" * 9 + "|",
    ]
    for r in _load("time_to_verdict.json")["rows"]:
        p, f = r["paper"], r["fast"]
        ran = f"{len(f['lambdas'])} λ"
        if f["ran_paper_protocol"]:
            ran = "the paper protocol (" + "; ".join(f["doubts"]) + ")"
        out.append(
            f"| {r['system']} | {_verdict(p['new_physics'])} | {_g(p['ratio'], 3, True)} | {p['wall_s']:.1f} | "
            f"{_verdict(f['new_physics'])} | {_g(f['ratio'], 3, True)} | {f['wall_s']:.1f} | {f['steps']} | {ran} |"
        )
    return "\n".join(out) + "\n"


def single_precision() -> str:
    """results/float32.json (benchmarks/float32_accuracy.py): the 13-λ sweeps in float64 and float32."""
    out = [
        "| system | float64: verdict, ratio | float32: verdict, ratio | largest relative difference of L_e over the "
        "13 λ | s (float64 / float32, one-thread worker) |",
        "|---" * 5 + "|",
    ]
    for r in _load("float32.json")["rows"]:
        runs = (r["float64"], r["float32"])
        cells = " | ".join(f"{'new' if x['new_physics'] else 'none'} ×{_g(x['ratio'], 3, True)}" for x in runs)
        out.append(
            f"| {r['system']} | {cells} | {_g(r['max_rel_diff_L_e'], 3, True)} | "
            f"{r['wall_s']['float64']:.1f} / {r['wall_s']['float32']:.1f} |"
        )
    return "\n".join(out) + "\n"


# label, then the formats of the joint fits and of the post-hoc fits (as the table had them by hand)
TABLE2_ROWS = {
    "Gamma_11": ("Γ11", "d7", "d6"),
    "Gamma_12": ("Γ12", "e1", "e2"),
    "Gamma_21": ("Γ21", "e2", "e2"),
    "Gamma_22": ("Γ22", "d7", "d6"),
    "GM": ("GM", "d8", "d6"),
    "R": ("R", "d7", "d4"),
    "omega": ("ω", "d8", "d6"),
    "k": ("k", "d8", "d7"),
    "m": ("m", "d6", "d3"),
}


def _num(spec: str, x: float) -> str:
    """``spec``: 'dN' N decimals; 'eN' N significant digits in scientific notation (5e-9, 6.5e-6)."""
    n = int(spec[1:])
    return _f(x, n) if spec[0] == "d" else _compact(f"{x:.{n - 1}e}")


def single_precision_laws() -> str:
    """results/float32_table2.json (benchmarks/float32_accuracy.py --table2): Table II in float64 and float32."""
    out = [
        "| system | quantity | truth | float64 (joint) | float32 (joint) | goal | met 64 / 32 | post hoc, of the UAN's "
        "output: float64 / float32 |",
        "|---" * 8 + "|",
    ]
    for r in _load("float32_table2.json")["rows"]:
        label, ours, post = TABLE2_ROWS.get(r["quantity"], (r["quantity"], "e4", "e4"))
        a, b = r["float64"], r["float32"]
        goal = re.sub(r"(\d)%", r"\1 %", r["goal"].replace("|·| ", ""))
        met = " / ".join("yes" if x["goal_met"] else "no" for x in (a, b))
        out.append(
            f"| {r['system']} | {label} | {_g(r['truth'], 5)} | {_num(ours, a['ours'])} | {_num(ours, b['ours'])} | "
            f"{goal} | {met} | {_num(post, a['posthoc'])} / {_num(post, b['posthoc'])} |"
        )
    return "\n".join(out) + "\n"


# ---- a throw with its field declared -------------------------------------------------------------------------------
LAW_NAMES = {"power": "power law"}
GREEK = {"gamma": "γ", "mu": "μ", "omega": "ω"}


def _throw_law(r) -> str:
    """The law column: the tie's members, the true family in bold, the first one's coefficient when it is not the
    true family (it is the one used for predictions); or the claimed law."""
    truth = r["truth_law"]
    bold = lambda f: f"**{f}**" if f == truth else f
    if r["law_status"] != "tie":
        return f"{bold(r['winner'])}, {r['law_status']}"
    first = bold(r["winner"])
    if r["winner"] != truth:
        first += "".join(f" {GREEK.get(k, k)} = {_g(v, 3)}" for k, v in r["winner_params"].items())
    return "tie: " + " / ".join([first, *(bold(f) for f in r["ties"])])


def throw_declared() -> str:
    """results/throw_declared.json (benchmarks/friction_laws.py throw-2d --seeds 0,1,2, field declared uniform)."""
    rows = _load("throw_declared.json")
    truth = rows[0]["truth_coefficients"]["c"]
    out = [f"| seed | verdict | law | ΔIC to runner-up | c (truth {truth:g}) | err |", "|---" * 6 + "|"]
    for r in rows:
        fit = next(c for c in r["candidates"] if c["law"] == r["truth_law"])["params"]["c"]
        dic = f"{r['delta_ic']:.1f}"
        if r["runner_up"] not in r["ties"]:
            dic += f" ({LAW_NAMES.get(r['runner_up'], r['runner_up'])})"
        err = f"{_g(100 * r['err_moving'], 2)} %"
        if r["winner"] != r["truth_law"]:
            err += f" ({r['winner']}, the tie's first)" if r["law_status"] == "tie" else f" ({r['winner']})"
        out.append(
            f"| {r['seed']} | {r['status']} ({r['confidence']:.2f}) | {_throw_law(r)} | {dic} | "
            f"{_g(fit, 3)} ({_neg(f'{100 * (fit / truth - 1):+.0f}')} %) | {err} |"
        )
    return "\n".join(out) + "\n"


# ---- the law of real friction --------------------------------------------------------------------------------------
FRICTION_NAMES = {  # nnphd's family keys as the friction tables name them
    "linear": "viscous",
    "coulomb": "dry",
    "quadratic": "quadratic",
    "linear+coulomb": "viscous + dry",
    "linear+quadratic": "viscous + quadratic",
    "coulomb+quadratic": "dry + quadratic",
    "linear+coulomb+quadratic": "viscous + dry + quadratic",
    "power": "power law",
    "rayleigh": "Rayleigh",
    "vanderpol": "van der Pol",
    "drive": "drive",
}
REF_TERMS = {"c": "viscous", "d": "dry", "e": "quadratic"}  # benchmarks/friction_reference.py's friction terms
FAMILY_TERMS = {"linear": "c", "coulomb": "d", "quadratic": "e"}  # the reference's term each family part is
SEEDS = (0, 1, 2)
REAL_SEED_FILES = {0: "real_friction.json", 1: "real_friction_seed1.json", 2: "real_friction_seed2.json"}
LOOK_SEED_FILES = {0: "friction_laws.json", 1: "friction_laws_seed1.json", 2: "friction_laws_seed2.json"}
REAL_SOURCES = {  # the recording column's source, as data/real/README.md describes it
    "servo_sts3250_drop": "Rhoban/bam, 66 Hz, one drop, ends stuck",
    "encoder_pendulum_free_swing": "1 kHz, 0.09°, 3 runs from up to 157°",
    "seismometer_blow": "PASCO, 10 Hz, magnet",
    "video_string_pendulum_lab1": "phone video, 20 Hz",
    "video_string_pendulum_lab2": "29.6 Hz",
}
LOOK_CASES = {  # the case column: what each look-alike of tests/fixtures/friction.py is
    "viscous-dry": "servo-like, 3 drops ending stuck",
    "ends-at-rest": "dry, last 30 % stuck",
    "linear-quadratic": "string pendulum, 20 Hz, 120 s",
    "jitter-clock": "k/100 s written, 2 ms jitter",
    "heavy-damping": "ratio 0.13, 4 s",
    "sensor-20hz": "torsion, whole degrees",
    "sensor-20hz-runs": "the same, 10 runs, each to rest",
    "offset-rest": "θ₀ = 0.05, stuck in the dead band",
    "throw-2d": "60 fps, 1.2 s",
    "pendulum-free": "control",
    "encoder-1khz": "1 kHz, 0.09° steps, 3 runs of 5 s",
}


def _fam(key: str) -> str:
    return FRICTION_NAMES.get(key, key)


def _params(p: dict, digits: int, zeros: bool = True) -> str:
    return ", ".join(f"{GREEK.get(k, k)} = {_g(v, digits, zeros)}" for k, v in p.items())


def _pct(x: float) -> str:
    return f"{100 * x:.0f} %"


def _lacks(law: dict, necessary: list[str]) -> str:
    """', lacks dry': the reference's necessary terms a law without them (``necessary_in`` false) does not have."""
    if law["necessary_in"]:
        return ""
    has = {FAMILY_TERMS[p] for p in law["law"].split("+") if p in FAMILY_TERMS}
    return ", lacks " + " and ".join(REF_TERMS[t] for t in necessary if t not in has)


def _real_law(r: dict, necessary: list[str], params: str = "all") -> str:
    """A real recording's law: claimed, a tie (each member), a candidate the verdict does not claim, or why none;
    each with its error against the reference's force, in bold where it is within 25 % and has every necessary
    term. ``params``: 'all' members' coefficients, or 'first' (the claimed law's, or a tie's first)."""

    def one(i, law):
        txt = _fam(law["law"])
        if params == "all" or i == 0:
            txt += " " + _params(law["params"], 3)
        txt += f" ({_pct(law['err'])}{_lacks(law, necessary)})"
        return f"**{txt}**" if law["err"] <= 0.25 and law["necessary_in"] else txt

    laws = [one(i, x) for i, x in enumerate(r["laws"])]
    if r["law_status"] == "tie":
        return "tie: " + " / ".join(laws)
    if r["law_status"].startswith("candidate"):
        return "candidate " + laws[0]
    if laws:
        return laws[0]
    why = r.get("reason") or ""
    blocked = re.findall(r"(?:library|LNN): ([\w+]+) \(blocked\)", why)
    dist = re.search(r"distance² ([\d.]+)", why)
    if blocked and dist and len(set(blocked)) == 1:
        bases = "both bases" if len(blocked) == 2 else "its base"
        return (
            f"no law: {_fam(blocked[0])}, the envelope's choice, bars the weaker candidates, but its windows and "
            f"envelope disagree on its coefficients (distance² {dist[1]}), with {bases}"
        )
    return "no law"


def _signed_pct(x: float) -> str:
    """+4 %, −3 %, ±0 % (a relative error, rounded to whole per cent)."""
    v = round(100 * x)
    return "±0 %" if v == 0 else f"{'+' if v > 0 else '−'}{abs(v)} %"


def lookalike_reference() -> str:
    """results/friction_reference_lookalikes.json (``benchmarks/friction_reference.py --lookalikes``): per
    look-alike the truth, the reference's best model, the rms of its fit with the truth's terms against the best
    fit that lacks one of them, and nnphd's law status (results/friction_laws.json, seed 0)."""
    look = {r["name"]: r for r in _load("friction_laws.json")}
    out = [
        "| look-alike | truth | the reference's best model | rms: the truth's terms | rms: the best lacking a "
        "true term | ratio | IC: best, its rival (ΔIC; n_eff) | nnphd, seed 0 |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for e in _load("friction_reference_lookalikes.json")["recordings"]:
        name = e["file"].removeprefix("lookalike:")
        truth = {k: v for k, v in e["truth"].items() if v}
        true_set = "{" + ",".join(sorted(truth)) + "}"
        lacking = {k: v for k, v in e["rms"].items() if not set(truth) <= set(k.strip("{}").split(","))}
        # the fewest terms among the fits within 1e-6 of the lowest rms (a term fitted to ~0 is no other model)
        low = min(lacking.values())
        lk, lv = min(
            ((k, v) for k, v in lacking.items() if v <= low * (1 + 1e-6)), key=lambda kv: (kv[0].count(","), kv[1])
        )
        best = e["best_params"]
        terms = " + ".join(REF_TERMS[t] for t in e["best_subset"]) or "none"
        coef = ", ".join(f"{t} = {_g(best[t], 3)} ({_signed_pct(best[t] / truth[t] - 1)})" if t in truth
                         else f"{t} = {_g(best[t], 3)}" for t in e["best_subset"])  # fmt: skip
        tw = " + ".join(f"{REF_TERMS[t]} {t} = {_g(v, 3)}" for t, v in truth.items())
        r = look.get(name)
        said = "not run" if r is None else (
            "tie: " + " / ".join(_fam(k) for k in [r["winner"] or r["candidate"] or "", *r["ties"]] if k)
            if r["law_status"] == "tie" else f"{r['law_status']}: {_fam(r['winner'] or 'none')}"
        )  # fmt: skip
        lacks = _ref_terms(lk).replace("none", "no friction")
        out.append(
            f"| {name} | {tw} | {terms}: {coef} | {_g(e['rms'][true_set], 3)} | {_g(lv, 3)} ({lacks}) | "
            f"{_g(lv / e['rms'][true_set], 4)} | {_ref_ic(e)} | {said} |"
        )
    return "\n".join(out) + "\n"


def _ref_terms(subset: str) -> str:
    return " + ".join(REF_TERMS[t] for t in subset.strip("{}").split(",") if t) or "none"


def _ref_ic(e: dict) -> str:
    """The reference's information criterion (benchmarks/friction_reference.py ``information``): its best subset,
    the best rival that is neither a subset nor a superset of it, their ΔIC and the effective number of residuals."""
    inf = e.get("information")
    if not inf:
        return "—"
    rival = (
        "none" if inf["runner_up"] is None else f"{_ref_terms(inf['runner_up'])} ({_g(inf['delta_ic_runner_up'], 3)}"
    )
    return f"{_ref_terms(inf['best'])}, {rival}; {_g(inf['n_eff'], 4)})"


def _real_seed_rows() -> dict[int, dict[str, dict]]:
    return {s: {r["file"].removesuffix(".csv"): r for r in _load(f)} for s, f in REAL_SEED_FILES.items()}


def _verdict_prefix(r: dict) -> str:
    return "" if r["status"] == "detected" else f"{r['status']}: "


def real_friction() -> str:
    """results/real_friction.json (benchmarks/real_friction.py, seed 0) against results/friction_reference.json
    (benchmarks/friction_reference.py): per recording the reference's necessary terms and best model, the verdict,
    the law with its error against the reference's force, the seconds of the whole detect."""
    refs = {os.path.basename(x["file"]).removesuffix(".csv"): x for x in _load("friction_reference.json")["recordings"]}
    out = [
        "| recording (source) | reference: necessary; best model | verdict | nnphd's law (error vs the reference's "
        "force) | s |",
        "|---" * 5 + "|",
    ]
    for r in _load("real_friction.json"):
        name = r["file"].removesuffix(".csv")
        ref = refs[name]
        nec = [REF_TERMS[t] for t in ref["necessary"]]
        best = " + ".join(REF_TERMS[t] for t in ref["best_subset"])
        coefs = ", ".join(f"{t} = {_g(ref['best_params'][t], 3)}" for t in ref["best_subset"])
        if ref["necessary"] == ref["best_subset"]:
            cell = f"{best}; {coefs}"
        else:
            cell = f"{' + '.join(nec) or 'none'}{'' if nec else ' necessary'}; best {best} {coefs}"
        src = REAL_SOURCES.get(name)
        label = f"{name} ({src})" if src else name
        out.append(f"| {label} | {cell} | {r['status']} | {_real_law(r, ref['necessary'])} | {r['wall_s']:.0f} |")
    return "\n".join(out) + "\n"


def _families_of(r: dict) -> tuple[str, frozenset]:
    """What seeds are compared on (as benchmarks/seed_agreement.py): a claimed family, or a tie's set of families."""
    if r["law_status"] in ("claimed", "tie"):
        return r["law_status"], frozenset(x["law"] for x in r["laws"])
    return "none", frozenset()


def real_friction_seeds() -> str:
    """results/real_friction.json, real_friction_seed1.json, real_friction_seed2.json (benchmarks/real_friction.py
    --seed 0/1/2): each seed's verdict (when not "detected") and law, with its error against the reference's force."""
    runs = _real_seed_rows()
    refs = {n: r["reference"]["necessary"] for n, r in runs[0].items()}
    out = ["| recording | " + " | ".join(f"seed {s}" for s in SEEDS) + " |", "|---" * (1 + len(SEEDS)) + "|"]
    same_verdict = same_law = wrong = 0
    for name in runs[0]:
        rs = [runs[s][name] for s in SEEDS]
        cells = [_verdict_prefix(r) + _real_law(r, refs[name], params="first") for r in rs]
        shown = [cells[0], *("the same" if c == cells[0] else c for c in cells[1:])]
        out.append(f"| {name} | {' | '.join(shown)} |")
        same_verdict += len({r["status"] for r in rs}) == 1
        same_law += len({_families_of(r) for r in rs}) == 1
        wrong += any(r["law_status"] == "claimed" and not r["right"] for r in rs)
    n = len(runs[0])
    out.append("")
    out.append(
        f"The same verdict on every seed: {same_verdict} of {n} recordings; the same law (a claimed family, or a tie's "
        f"set of families): {same_law} of {n}; a claimed law more than 25 % from the reference's force or lacking a "
        f"term it needs, on any seed: {wrong} of {n}. Seconds for the {n}: "
        + ", ".join(f"{sum(r['wall_s'] for r in runs[s].values()):.0f}" for s in SEEDS)
        + f" on seeds {', '.join(map(str, SEEDS[:-1]))} and {SEEDS[-1]}. (In brackets each law's error against the "
        "reference's force; in bold within 25 % with every term the reference needs.)"
    )
    return "\n".join(out) + "\n"


def _look_law(r: dict, first: bool = True) -> str:
    """A look-alike's law: claimed, a tie (the true family in bold), a candidate the verdict does not claim, or none;
    with the coefficients of the claimed law, the candidate, the tie's true family and (``first``) its first."""
    truth = r["truth_law"]
    cands = {c["law"]: c["params"] for c in r["candidates"]}

    def one(fam, p, show):
        txt = _fam(fam) + (" " + _params(p, 4) if show and p else "")
        return f"**{txt}**" if fam == truth and r["law_status"] == "tie" else txt

    if r["law_status"] == "claimed":
        return one(r["winner"], r["winner_params"], True)
    if r["law_status"] == "tie":
        head = one(r["winner"], r["winner_params"], first or r["winner"] == truth)
        return "tie: " + " / ".join([head, *(one(f, cands.get(f), f == truth) for f in r["ties"])])
    if r["candidate"]:
        return "candidate " + one(r["candidate"], r["candidate_params"], True)
    return "no law" if truth == "none" else "no candidate beats no law"


def _look_err(r: dict) -> str | None:
    """The error of the law (a tie: its first member) or of the candidate on the true moving states."""
    if r["truth_law"] == "none":
        return None
    if r["law_status"] in ("claimed", "tie"):
        return f"{100 * r['err_moving']:.1f} %"
    if r["err_candidate_moving"] is not None:
        return f"{100 * r['err_candidate_moving']:.1f} %"
    return None


def _look_seed(r: dict) -> str:
    err = _look_err(r)
    return f"{r['status']}: {_look_law(r, first=False)}" + (f" (err {err})" if err else "")


def _look_family(r: dict) -> str:
    if r["family_right"]:
        return "yes"
    if r["law_status"] == "tie" and r["truth_law"] in (r["winner"], *r["ties"]):
        return "tie holds it"
    return "**no**" if r["law_status"] == "claimed" else "—"


def friction_lookalikes() -> str:
    """results/friction_laws.json (benchmarks/friction_laws.py, seed 0; DECLARED fields declared) and
    friction_laws_seed1.json, friction_laws_seed2.json (--seeds 1, 2): the look-alikes of real friction."""
    runs = {s: {r["name"]: r for r in _load(f)} for s, f in LOOK_SEED_FILES.items()}
    out = [
        "| case | truth | seed 0: verdict (confidence) | law | ΔIC to runner-up | err (floor) | family | s | "
        "seed 1: verdict: law (err) | seed 2: verdict: law (err) |",
        "|---" * 10 + "|",
    ]
    right = ties = inconclusive = wrong = 0
    for name, r in runs[0].items():
        desc = LOOK_CASES.get(name, "")
        field = (r.get("declared") or {}).get("field")
        if field:
            desc += ("; " if desc else "") + f"**field declared {field}**"
        truth = _params(r["truth_coefficients"], 4, zeros=False) if r["truth_coefficients"] else r["truth_law"]
        dic = f"{r['delta_ic']:.1f}"
        if r["runner_up"] not in (r["ties"] or []):
            dic += f" ({'no law' if r['runner_up'] == 'none' else _fam(r['runner_up'])})"
        err = _look_err(r) or "—"
        floor = r["err_floor_moving"]
        if floor and floor >= 0.001 and r["law_status"] in ("claimed", "tie"):
            err += f" ({100 * floor:.1f} %)"
        if r["law_status"] == "tie" and r["winner"] != r["truth_law"]:
            err += f" ({_fam(r['winner'])}, the tie's first)"
        elif r["law_status"] not in ("claimed", "tie") and r["candidate"]:
            err += " (the candidate)"
        seeds = " | ".join(_look_seed(runs[s][name]) if name in runs[s] else "not run" for s in SEEDS[1:])
        out.append(
            f"| {name} ({desc}) | {truth} | {r['status']} ({r['confidence']:.2f}) | {_look_law(r)} | {dic} | {err} | "
            f"{_look_family(r)} | {r['wall_s']:.0f} | {seeds} |"
        )
        fam = _look_family(r)
        right += fam == "yes"
        ties += fam == "tie holds it"
        inconclusive += r["status"] == "inconclusive"
        wrong += fam == "**no**"
    n = len(runs[0])
    every = [x for x in runs[0] if all(x in runs[s] for s in SEEDS)]  # the cases run on every seed
    same = sum(len({runs[s][x]["status"] for s in SEEDS}) == 1 for x in every)
    out.append("")
    out.append(
        f"Seed 0: {right} of {n} right with the family, {ties} ties holding the truth, {inconclusive} "
        f'"inconclusive", {wrong} wrong family. The same verdict on seeds 0, 1 and 2: {same} of {len(every)}. Seconds for '
        f"the {len(every)}: "
        + ", ".join(f"{sum(runs[s][x]['wall_s'] for x in every):.0f}" for s in SEEDS)
        + " on seeds 0, 1 and 2. (err: the law's, or the tie's first member's, on the true moving states; in "
        "brackets the floor, the true law in nnphd's smoothed form.)"
    )
    return "\n".join(out) + "\n"


# ---- the law table of the constructed cases ------------------------------------------------------------------------
LAW_CASES = {  # the case column: what each case of tests/fixtures/laws.py is (its truth is in the JSON too)
    "dry-friction": "dry friction −0.02 sign(ẋ)",
    "rayleigh": "Rayleigh (0.05 − 0.05ẋ²)ẋ",
    "van-der-pol": "van der Pol 0.1(1 − x²)ẋ",
    "quadratic-drag-2d": "quadratic drag −0.05 \\|q̇\\|q̇, 2-D",
    "anisotropic-damping": "anisotropic damping −0.04ẋ, −0.01ẏ (coupled springs)",
    "drive": "drive 0.2 cos(0.7t) (Duffing)",
    "linear-noisy": "damped pendulum −0.03θ̇, 0.5 % noise",
    "damped-double-well": "damped double well −0.05ẋ",
    "henon-heiles": "Hénon–Heiles (control)",
    "gyroscopic": "gyroscopic 0.8 ẑ×q̇ (control)",
}
SYMBOLS = (("theta_dot", "θ̇"), ("x_dot", "ẋ"), ("y_dot", "ẏ"), ("theta", "θ"), ("**2", "²"), ("**3", "³"), ("*", ""))


def _sym(name: str) -> str:
    for a, b in SYMBOLS:
        name = name.replace(a, b)
    return name


def _law_text(law) -> str:
    """nnphd's law in the table's notation, from its family and coefficients (4 significant digits, ω 5)."""
    p, name = law["params"], law["law"]
    x = _sym(next(iter(law["formula"])).removesuffix("_ddot"))
    v = _sym(next(iter(law["formula"])).replace("_ddot", "_dot"))
    c = lambda k: f"{abs(p[k]):.4g}"
    if name == "coulomb":
        return f"−{c('mu')} sign({v})"
    if name == "linear":
        return f"−{c('gamma')}{v}"
    if name == "quadratic":
        return f"−{c('c')} \\|q̇\\|q̇"
    if name == "rayleigh":
        return f"({_g(p['a'], 4)}{_signed(p['c'], '.4g')}{v}²){v}"
    if name == "vanderpol":
        return f"({_g(p['a'], 4)}{_signed(p['b'], '.4g')}{x}²){v}"
    if name == "linear-diag":
        return ", ".join(f"−{c(k)}{_sym(k.split('_')[1] + '_dot')}" for k in p)
    if name == "drive":
        w = f"{p['omega']:.5g}"
        return f"{_g(p['A_cos'], 4)} cos({w}t){_signed(p['A_sin'], '.4g')} sin({w}t)"
    return "; ".join(_peer_component(e) for e in law["formula"].values())


def _law_se(law) -> str:
    """'(± se, se)', '(± se each)', and the drive's '; ω ± se'."""
    se = {k: _g(s, 2) for k, s in law["stderr"].items()}
    w = se.pop("omega", None)
    out = "± " + (
        f"{next(iter(se.values()))} each" if len(se) > 1 and len(set(se.values())) == 1 else ", ".join(se.values())
    )
    return f"({out}" + (f"; ω ± {w})" if w else ")")


def _peer_terms(expr: str) -> list[tuple[float, str, int]]:
    """'0.003466*x_dot**3 - 0.02333*x_dot' -> [(0.003466, 'x_dot**3', 3), (-0.02333, 'x_dot', 1)]."""
    parts = re.split(r" ([+-]) ", expr.strip())
    signs, terms = ["+", *parts[1::2]], parts[0::2]
    out = []
    for sign, t in zip(signs, terms):
        neg = (sign == "-") != t.startswith("-")
        m = re.match(r"-?([\d.]+(?:e-?\d+)?)?\*?(.*)", t)
        coef = float(m[1]) if m[1] else 1.0
        deg = sum(int(f.split("^")[1]) if "^" in f else 1 for f in m[2].replace("**", "^").split("*"))
        out.append((-coef if neg else coef, m[2], deg))
    return out


def _peer_component(expr: str) -> str:
    """One component of the peer's law, lowest degree first, 3 significant digits: '−0.0233ẋ + 0.00347ẋ³'."""
    terms = sorted(_peer_terms(expr), key=lambda t: t[2])
    c = lambda x: "" if abs(x) == 1 else f"{abs(x):.3g}"
    head = ("−" if terms[0][0] < 0 else "") + c(terms[0][0]) + _sym(terms[0][1])
    return head + "".join((" − " if x < 0 else " + ") + c(x) + _sym(s) for x, s, _ in terms[1:])


def _peer_law(r) -> str:
    """The PySINDy peer's law ('x_ddot = …; y_ddot = …'): its components, or how many terms when they are many."""
    if r["baseline"] == "—":
        return "no law" if r["baseline_right"] else "—"
    comps = [c.split(" = ", 1)[1] for c in r["baseline"].split("; ")]
    terms = [_peer_terms(e) for e in comps]
    if max(map(len, terms)) > 4:
        degs = {d for ts in terms for _, _, d in ts}
        word = {1: "linear ", 2: "quadratic ", 3: "cubic "}.get(next(iter(degs)), "") if len(degs) == 1 else ""
        n = sorted({len(ts) for ts in terms})
        return f"{'/'.join(map(str, n))} {word}terms per component"
    return ", ".join(_peer_component(e) for e in comps)


def _law_err(err: float, has_law: bool) -> str:
    if not has_law and err == 0:
        return "—"
    return f"{err:.3f}" if err < 1 else f"{err:.1f}"


def laws_table() -> str:
    """results/laws_table.json (benchmarks/laws_table.py): nnphd's law beside the PySINDy peer's, on the true states."""
    out = [
        "| case | nnphd law (± 1 se) | err | right | s | PySINDy peer | err | right | s |",
        "|---" * 9 + "|",
    ]
    yes = lambda b: "yes" if b else "no"
    for r in _load("laws_table.json"):
        law = r["law"]
        ours = f"{_law_text(law)} {_law_se(law)}" if law else "no law"
        peer_has = r["baseline"] != "—"
        out.append(
            f"| {LAW_CASES.get(r['case'], r['truth'])} | {ours} | {_law_err(r['error'], law is not None)} | "
            f"{yes(r['right'])} | {r['seconds']:.0f} | {_peer_law(r)} | {_law_err(r['baseline_error'], peer_has)} | "
            f"{yes(r['baseline_right'])} | {r['baseline_seconds']:.1f} |"
        )
    return "\n".join(out) + "\n"


def detect_recordings() -> str:
    """The energy-decay rate of the damped recording look-alikes against its truth (results/detect_recordings.json)."""
    rows = _load("detect_recordings.json")
    out = [
        "| case | seed | verdict (confidence) | energy-decay rate: ours / truth | energy z | shooting z "
        "| law (or best candidate, not claimed) | s |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        rate = (
            f"{r['rate']:.4g} / {r['rate_truth']:.4g} ({100 * (r['rate'] / r['rate_truth'] - 1):+.1f} %)"
            if r["rate"] is not None and r["rate_truth"]
            else "—"
        )
        z = [f"{x:.1f}" if x is not None else "—" for x in (r["energy_z"], r["shooting_z"])]
        law = r["law"].replace("|", "\\|")
        out.append(
            f"| {r['name']} | {r['seed']} | {r['status']} ({r['confidence']:.2f}) | {rate} | {z[0]} | {z[1]} | "
            f"{law} | {r['wall_s']:.0f} |"
        )
    worst = max(abs(r["rate"] / r["rate_truth"] - 1) for r in rows if r["rate"] is not None and r["rate_truth"])
    out.append("")
    out.append(f"Largest error of the decay rate: {100 * worst:.2f} %.")
    return "\n".join(out) + "\n"


# ---- scale-out, FLOPs, speed ---------------------------------------------------------------------------------------
WORKER_RUNS = (  # results/workers_<what>.json (benchmarks/bench_workers.py <what>): the work each row is
    ("workers_reproduce_quick.json", "`reproduce --quick`"),
    ("workers_lambda-p.json", "λ/p study, 20 sweeps at {steps} steps per λ (`lambda-p --steps {steps}`)"),
    ("workers_reproduce.json", "`reproduce` (full: paper settings)"),
    ("workers_detect.json", "the 8 noisy constructed cases as one batch, {detect_steps} steps, 2 seeds (`detect`)"),
)


def _claims_met(run: dict) -> int:
    return sum(bool(v[1]) for v in run.values())


def workers() -> str:
    """results/workers_*.json (benchmarks/bench_workers.py): the latest run of each work on 1 and on 2 workers."""
    out = ["| work | 1 worker | 2 workers | speed-up | numbers |", "|---" * 5 + "|"]
    for name, label in WORKER_RUNS:
        d = _load(name)
        w = str(d["settings"]["workers"])
        same = "identical" if d["identical_numbers"] else "**differ**"
        if d["what"] == "reproduce":
            met = {_claims_met(d["numbers"][k]) for k in ("1", w)}
            n = len(d["numbers"]["1"])
            same += f" ({met.pop()} of {n} claims met both ways)" if len(met) == 1 else ""
        out.append(
            f"| {label.format(**d['settings'])} | {d['wall_s']['1']:.1f} s | {d['wall_s'][w]:.1f} s | "
            f"{d['speedup']:.2f}× | {same} |"
        )
    return "\n".join(out) + "\n"


def workers_detect() -> str:
    """results/workers_detect.json (benchmarks/bench_workers.py detect): each file's seconds one by one and in the
    batch (its report's wall_time_s), and the walls."""
    d = _load("workers_detect.json")
    w = str(d["settings"]["workers"])
    out = [
        f"| file ({d['settings']['detect_steps']} steps, 2 seeds) | verdict | one by one, in this process (s) | "
        f"in the batch, on a 1-thread worker (s) |",
        "|---" * 4 + "|",
    ]
    for name, s1 in d["file_s"]["1"].items():
        status, conf = d["numbers"]["1"][name][:2]
        out.append(f"| {name} | {status}, {conf:.2f} | {s1:.1f} | {d['file_s'][w][name]:.1f} |")
    same = "identical reports" if d["identical_numbers"] else "**reports differ**"
    out.append(
        f"| **all {len(d['file_s']['1'])}** | {same} | **{d['wall_s']['1']:.1f} wall** | "
        f"**{d['wall_s'][w]:.1f} wall ({d['speedup']:.2f}×)** |"
    )
    return "\n".join(out) + "\n"


FLOP_STEPS = {  # bench_flops.py's step labels as the table names them
    "reference": "reference (per-sample `jax.hessian`)",
    "plain": "plain MLP",
    "ours, 13 λ vmapped": "ours, 13 λ vmapped into one program (shared batch)",
    "ours, 32 seeds vmapped": "ours, 32 seeds vmapped (own weights and batches)",
    "breakdown: ours with SGD": "breakdown: ours with plain SGD instead of Adam",
    "breakdown: Adam alone": "breakdown: Adam's update alone",
}


def _ms(x: float) -> str:
    return f"{x:.3f}" if x < 10 else f"{x:.1f}"


def flops() -> str:
    """results/flops.json (benchmarks/bench_flops.py): FLOPs of a training step from XLA's cost analysis, its time,
    and the share of a one-thread float64 GEMM's rate; the breakdown rows last."""
    d = _load("flops.json")
    out = ["| step | batch | MFLOP (XLA) | ms per step | GFLOP/s | % of the GEMM peak |", "|---" * 6 + "|"]
    for r in sorted(d["rows"], key=lambda r: r["step"].startswith("breakdown")):
        batch = "—" if r["batch"] == 0 else f"{r['batch']}" + (f" × {r['copies']}" if r["copies"] > 1 else "")
        out.append(
            f"| {FLOP_STEPS.get(r['step'], r['step'])} | {batch} | {r['mflop']:.1f} | {_ms(r['ms'])} | "
            f"{r['gflops']:.1f} | {100 * r['fraction_of_peak']:.1f} |"
        )
    g, ra, a = d["gemm"], d["ratios"], d["args"]
    goal = d["goal_batch32_fraction"]
    ref_reps = next(r["reps_per_block"] for r in d["rows"] if r["step"] == "reference" and r["batch"] == 1000)
    out.append("")
    out.append(
        f"One run, {d['timestamp'][:10]} (load {d['machine']['loadavg_1min']:.2f}); ms: the median of {a['blocks']} "
        f"blocks of {a['reps']} steps (the reference at batch 1000: {ref_reps}). The peak: a {g['n']}³ float64 matrix "
        f"product, {1000 * g['s']:.0f} ms = {g['gflops']:.1f} GFLOP/s. FLOPs at batch 1000: ours / plain MLP "
        f"{ra['ours_over_plain_flops_b1000']:.2f}, reference / ours {ra['reference_over_ours_flops_b1000']:.2f}. "
        f"The best batch-32 work of ours: {100 * ra['best_batch32_fraction']:.1f} % of the peak (goal ≥ "
        f"{100 * goal:.0f} %: {'met' if ra['best_batch32_fraction'] >= goal else '**not met**'})."
    )
    return "\n".join(out) + "\n"


SWEEP_NAMES = {
    "ho+ld warm": "HO+LD, warm start",
    "ho+ld vmap": "HO+LD, 13 λ vmapped",
    "ho+mf warm": "HO+MF, warm start",
}


def _met(ok: bool) -> str:
    return "met" if ok else "**not met**"


def speed() -> str:
    """results/speed.json (benchmarks/bench_speed.py): ms per training step of ours, the reference and a plain MLP,
    and the full 13-λ sweeps."""
    d = _load("speed.json")
    g = d["goals"]
    out = [
        f"| batch | ours ms | reference ms | plain MLP ms | reference / ours (goal ≥ {g['reference_over_ours_min']:g}) "
        f"| ours / plain (goal ≤ {g['ours_over_plain_max']:g}) |",
        "|---" * 6 + "|",
    ]
    for b, r in d["steps"].items():
        out.append(
            f"| {b} | {_g(r['ours_ms'], 3, True)} | {_g(r['reference_ms'], 3, True)} | {_g(r['plain_ms'], 3, True)} | "
            f"{r['reference_over_ours']:.2f} — {_met(r['goal_reference_met'])} | "
            f"{r['ours_over_plain']:.2f} — {_met(r['goal_plain_met'])} |"
        )
    reps = ", ".join(f"{r['reps_per_block']['reference']} at batch {b}" for b, r in d["steps"].items())
    out.append("")
    out.append(
        f"One run, {d['timestamp'][:10]} (load {d['machine']['loadavg_1min']:.2f}); the median of "
        f"{d['args']['blocks']} blocks of {d['args']['reps']} steps (the reference: {reps})."
    )
    if d.get("sweeps"):
        out.append("")
        out.append(
            f"| full 13-λ sweep, 2000 steps per λ | s in all | s, the sweep's own wall time | goal (in all) ≤ "
            f"{g['sweep_s_max']:g} s |"
        )
        out.append("|---" * 4 + "|")
        for k, r in d["sweeps"].items():
            out.append(
                f"| {SWEEP_NAMES.get(k, k)} | {r['total_s']:.1f} | {r['sweep_only_s']:.1f} | {_met(r['goal_met'])} |"
            )
    return "\n".join(out) + "\n"


# ---- the paper's experiments: `nnphd reproduce` (results/reproduce.json, benchmarks/condense_results.py) ----------
SYSTEM_NAMES = {"ho+ld": "HO+LD", "ho+cd": "HO+CD", "ho+pf": "HO+PF", "ho+mf": "HO+MF", "ho+cg": "HO+CG"}


def _repro() -> dict:
    return _load("reproduce.json")


def _lp_verdict(system: str, p: str) -> dict:
    return next(v for v in _repro()["lambda_p"]["verdicts"] if v["system"] == system and str(v["p"]) == p)


def _at(curve: list[dict], lam: float) -> dict:
    return next(x for x in curve if abs(x["lam"] - lam) < 1e-12)


def phase_transition() -> str:
    """The five toy systems at the paper's settings, p = 1: the λ/p study's p = 1 sweeps of `nnphd reproduce`
    (each is `nnphd sweep --system <name>`: 13 λ, 2000 steps per λ, warm start)."""
    d = _repro()
    lp = d["lambda_p"]
    out = [
        "| system | truth | L_e below λ=1 | L_e above λ=1 | statistic | verdict | m_c / m_n at λ=0.2 | sweep s |",
        "|---" * 8 + "|",
    ]
    for v in sorted(lp["verdicts"], key=lambda v: list(SYSTEM_NAMES).index(v["system"])):
        if str(v["p"]) != "1":
            continue
        at = _at(lp["curves"][v["system"]]["1"], 0.2)
        out.append(
            f"| {v['system']} | {'conservative' if v['truth_conservative'] else 'non-conservative'} | "
            f"{v['L_below']:.5f} | {v['L_above']:.5f} | {_g(v['ratio'], 3)} | {_verdict(v['new_physics'])} | "
            f"{at['m_c']:.4f} / {at['m_n']:.4f} | {v['train_wall_time_s']:.1f} |"
        )
    right = sum(v["correct"] for v in lp["verdicts"] if str(v["p"]) == "1")
    out.append("")
    out.append(
        f"{right} of 5 verdicts right (seed {d['summary']['seed']}, {lp['settings']['steps_per_lambda']} steps per λ; "
        f"sweep s: the training time of each sweep inside `nnphd reproduce`, {d['summary']['workers']} workers)."
    )
    return "\n".join(out) + "\n"


def _disc_row(r: dict) -> str:
    t, v = r["trajectory"], r["verdict"]
    steps = f"{t['n_steps']}" + (" (paper)" if t["n_steps"] == t["paper_n_steps"] else "")
    return (
        f"| {r['system']} | {steps} | {v['L_below']:.5f} | {v['L_above']:.5f} | {v['ratio']:.1f} | "
        f"{_verdict(r['new_physics'])} | {100 * v['relative_size']:.1f} % | {r['wall_time_s']:.0f} |"
    )


def discover() -> str:
    """`nnphd discover` of the three Table I systems inside `nnphd reproduce`, and the pendulum on the paper's
    300 steps (`nnphd discover --system double-pendulum --n-steps 300`, results/reproduce.json's "extra")."""
    d = _repro()
    out = [
        "| system | steps | L_e below λ=1 | L_e above λ=1 | statistic | verdict | f_n / f (L1) | s |",
        "|---" * 8 + "|",
    ]
    rows = list(d["discover"])
    short = d["extra"].get("discover_paper_length")
    if short:
        rows.insert(1, short)
    out += [_disc_row(r) for r in rows]
    return "\n".join(out) + "\n"


# the label of each Table II quantity, then the formats of the joint fit and of the post-hoc fit ('dN': N decimals,
# 'eN': N significant digits in scientific notation); a post-hoc stderr has its value's decimals
PAPER_TABLE2 = {
    "Gamma_11": ("friction Γ₁₁", "d7", "d5"),
    "Gamma_12": ("friction Γ₁₂", "e1", "d6"),
    "Gamma_21": ("friction Γ₂₁", "e2", "d5"),
    "Gamma_22": ("friction Γ₂₂", "d7", "d5"),
    "GM": ("Neptune GM", "d10", "d6"),
    "R": ("Neptune r_n", "d7", "d4"),
    "omega": ("Neptune ω_n", "d7", "d5"),
    "k": ("GW k", "d9", "d6"),
    "m": ("GW m (of v²)", "d6", "d3"),
}


def table_ii() -> str:
    """Table II: the joint law fit and the post-hoc fit of each discovery in `nnphd reproduce`."""
    out = [
        "| quantity | truth | paper | ours, joint fit (± stderr) | goal | met | post hoc (± stderr) |",
        "|---" * 7 + "|",
    ]
    for r in _repro()["discover"]:
        for q in r["table2"]:
            label, ours, post = PAPER_TABLE2.get(q["quantity"], (q["quantity"], "e4", "e4"))
            goal = re.sub(r"(\d)%", r"\1 %", q["goal"].replace("|·| ", ""))
            n = int(post[1:])
            out.append(
                f"| {label} | {_g(q['truth'], 5)} | {_g(q['paper'], 4)} | {_num(ours, q['ours'])} ± "
                f"{_g(q['stderr'], 1)} | {goal} | {'yes' if q['goal_met'] else '**no**'} | "
                f"{_num(post, q['posthoc'])} ± {_f(q['posthoc_stderr'], n)} |"
            )
    s = _repro()["summary"]
    secs = " / ".join(f"{s['runs']['discover/' + r['system']]['compute_time_s']:.0f}" for r in _repro()["discover"])
    out.append("")
    out.append(f"(seed {s['seed']}; {secs} s for the three systems inside `nnphd reproduce`)")
    return "\n".join(out) + "\n"


def _align_cells(curve: list[dict], tol: float) -> tuple[str, str]:
    cells = " | ".join(f"{_at(curve, lam)['m_c']:.3f} / {_at(curve, lam)['m_n']:.3f}" for lam in (0.05, 0.1, 0.2, 0.5))
    on = [x for x in curve if 0.1 - 1e-12 <= x["lam"] <= 0.5 + 1e-12]
    worst = max(on, key=lambda x: max(x["m_c"], x["m_n"]))
    m = max(worst["m_c"], worst["m_n"])
    goal = "yes" if m <= tol else f"no (λ = {worst['lam']:g} is {m / tol:.1f}× over)"
    return cells, goal


def alignment() -> str:
    """HO+LD's misalignment m_c / m_n: the p = 1 sweep of the λ/p study (`nnphd reproduce`) and the same sweep at
    8000 steps per λ (`nnphd sweep --system ho+ld --steps 8000`, results/reproduce.json's "extra")."""
    d = _repro()
    lp = d["lambda_p"]
    tol = lp["settings"].get("align_tol", 0.05)
    out = [
        "| steps per λ | m_c / m_n at λ=0.05 | λ=0.1 | λ=0.2 | λ=0.5 | goal met on [0.1, 0.5]? | sweep s |",
        "|---" * 7 + "|",
    ]
    cells, goal = _align_cells(lp["curves"]["ho+ld"]["1"], tol)
    v = _lp_verdict("ho+ld", "1")
    out.append(f"| {lp['settings']['steps_per_lambda']} (paper) | {cells} | {goal} | {v['train_wall_time_s']:.1f} |")
    long = d["extra"].get("sweep_8000")
    if long:
        cells, goal = _align_cells(long["table"], tol)
        out.append(
            f"| {long['steps_per_lambda']} (`--steps {long['steps_per_lambda']}`) | {cells} | {goal} | "
            f"{long['train_wall_time_s']:.1f} |"
        )
    return "\n".join(out) + "\n"


PREDICT_MODELS = {"nnphd": "NNPhD", "lnn": "LNN", "blackbox": "black box"}


def predict() -> str:
    """Fig. 4: the rollout errors of `nnphd predict` inside `nnphd reproduce`, and its judged claims."""
    d = _repro()
    p = d["predict"]
    out = [
        "| model | θ₁ RMSE [30, 40] | θ₁ RMSE [30, 200] | E RMSE [30, 200] | \\|Δθ₁\\| > 0.1 first at t |",
        "|---" * 5 + "|",
    ]
    for k, label in PREDICT_MODELS.items():
        m = p["metrics"][k]
        t = m.get("t_error_exceeds_0.1")
        out.append(
            f"| {label} | {m['theta1_rmse_30_40']:.3f} | {m['theta1_rmse_30_200']:.3f} | "
            f"{m['energy_rmse_30_200']:.3f} | {'never' if t is None else f'{t:.1f}'} |"
        )
    out.append("")
    out.append(
        f"(seed {d['summary']['seed']}, {p['steps']} steps per model, {p['wall_time_s']:.0f} s inside "
        f"`nnphd reproduce`.) Claims:"
    )
    out.append("")
    for c in p["claims"]:
        out.append(f"- {c['claim']}: {c['ours']} — {_met(c['met'])}")
    b, f = p["energy_balance"], p["decomposition"]
    out.append("")
    out.append(
        f"Energy balance along the NNPhD rollout: dH/dt of the learned energy against the learned dissipated power "
        f"q̇ᵀ(∂²L/∂q̇²)f_n, {100 * b['dHdt_vs_power_rel_rms']:.1f} % rms apart (correlation "
        f"{b['dHdt_vs_power_corr']:.4f}); the learned dissipated power against the true one: correlation "
        f"{b['learned_vs_true_power_corr']:.3f}; the learned f_n against the true friction on the test states: "
        f"{f['fn_rel_error_test']:.0f}× its rms; dH/dt against the plain f_n·q̇: {b['dHdt_vs_naive_fn_dot_qd_rel_rms']:.0f}× "
        "off."
    )
    return "\n".join(out) + "\n"


def _lp_cell(v: dict) -> str:
    """'187, jump (3.36)' for a right jump; '0.21, none'; a wrong verdict in bold with '(wrong)'."""
    if not v["correct"]:
        return f"**{v['ratio']:.2f}, {_verdict(v['new_physics'])} (wrong)**"
    if not v["new_physics"]:
        return f"{v['ratio']:.2f}, none"
    sharp = f" ({_g(v['sharpness'], 3)})" if v.get("sharpness") is not None else ""
    return f"{_g(v['ratio'], 3)}, {v['transition']}{sharp}"


def lambda_p() -> str:
    """Fig. 5: the λ/p study of `nnphd reproduce` (`nnphd study lambda-p`): the statistic (median L_e above λ = 1
    over below), and for a jump the transition's kind and sharpness."""
    d = _repro()
    lp = d["lambda_p"]
    ps = [str(p) for p in lp["settings"]["ps"]]
    head = " | ".join("MSE" if p == "mse" else f"p = {p}" for p in ps)
    out = [f"| system | {head} |", "|---" * (1 + len(ps)) + "|"]
    for s in sorted(lp["settings"]["systems"], key=list(SYSTEM_NAMES).index):
        out.append(f"| {SYSTEM_NAMES.get(s, s)} | " + " | ".join(_lp_cell(_lp_verdict(s, p)) for p in ps) + " |")
    sm = d["summary"]
    out.append("")
    out.append(
        f"(seed {sm['seed']}, {lp['settings']['steps_per_lambda']} steps per λ; the 20 sweeps took "
        f"{lp['train_wall_time_s']:.0f} s of training in all, inside `nnphd reproduce` on {sm['workers']} workers.) "
        "Claims:"
    )
    out.append("")
    for c in lp["claims"]:
        out.append(f"- {c['claim']}: {_met(c['met'])}")
    return "\n".join(out) + "\n"


def data_quality() -> str:
    """Fig. 6: `nnphd study data-quality` inside `nnphd reproduce`: L_e against the pie coverage α, m_c against the
    imbalance β."""
    d = _repro()
    q = d["data_quality"]
    st = q["settings"]
    a, b = q["alpha"], q["beta"]
    out = [
        f"| α (pie coverage, {SYSTEM_NAMES.get(st['alpha_system'])}, λ = {st['lam_alpha']:g}) | "
        + " | ".join(f"{r['alpha']:g}" for r in a)
        + " |",
        "|---" * (1 + len(a)) + "|",
        "| L_e (test set of the same α) | " + " | ".join(_g(r["L_e"], 2, True) for r in a) + " |",
        "",
        f"| β (imbalance, {SYSTEM_NAMES.get(st['beta_system'])}, λ = {st['lam_beta']:g}) | "
        + " | ".join(f"{r['beta']:g}" for r in b)
        + " |",
        "|---" * (1 + len(b)) + "|",
        "| m_c | " + " | ".join(f"{r['m_c']:.3f}" for r in b) + " |",
        "",
        f"(seed {st['seed']}, {st['steps']} steps, {q['wall_time_s']:.0f} s inside `nnphd reproduce`.) Claims:",
        "",
    ]
    for c in q["claims"]:
        out.append(f"- {c['claim']}: {c['ours']} — {_met(c['met'])}")
    return "\n".join(out) + "\n"


def reproduce_claims() -> str:
    """The summary of the full `nnphd reproduce` (results/reproduce.json): wall time, units, claims met."""
    s = _repro()["summary"]
    out = ["| unit | s of compute | of them compiling | where |", "|---" * 4 + "|"]
    for k, r in s["runs"].items():
        out.append(
            f"| {k} | {r['compute_time_s']:.1f} | {r.get('compile_time_s', 0.0):.1f} | "
            f"{r.get('where', '—').split(' pid')[0]} |"
        )
    out.append(f"| **wall** | **{s['wall_time_s']:.1f}** | {s['compile_time_s']:.1f} | {s['workers']} workers |")
    missed = [c for c in s["claims"] if not c["met"]]
    out.append("")
    out.append(
        f"{s['claims_met']} of {s['claims_total']} judged claims met (mode {s['mode']}, seed {s['seed']}); "
        f"not met: " + "; ".join(f"{c['experiment']}: {c['claim']}" for c in missed) + "."
    )
    if s.get("failed"):
        out.append("")
        out.append("Failed units: " + "; ".join(f"{k}: {v}" for k, v in s["failed"].items()))
    return "\n".join(out) + "\n"


# ---- Neptune from Uranus' real orbit (results/demo_neptune.json) ---------------------------------------------------
def _sg(x: float, decimals: int) -> str:
    """A signed number ('+0.86', '−1.7')."""
    return _neg(f"{x:+.{decimals}f}")


def demo_neptune() -> str:
    """`nnphd demo neptune` (benchmarks/condense_results.py neptune): seed 0's fit against DE405, the other seeds'
    errors below."""
    runs = _load("demo_neptune.json")["runs"]
    r = next(x for x in runs if x["seed"] == 0)
    f, t, e, g, se = r["fit"], r["truth"], r["errors"], r["goals"], r["fit"]["stderr"]
    met = lambda k, unit: f"± {g[k]['goal'] * (100 if unit == ' %' else 1):g}{unit} {_met(g[k]['met'])}"
    out = [
        "| | NNPhD (fit of the learned f_n) | DE405 Neptune | error | goal |",
        "|---" * 5 + "|",
        f"| verdict | L_e jumps {r['verdict']['ratio']:.0f}× across λ = 1 | | | "
        f"{'new physics' if r['verdict']['new_physics'] else '**no new physics**'} |",
        f"| GM / GM_sun | {_g(f['gm_ratio'], 5)} ± {_g(se['gm_ratio'], 2)} | {_g(t['gm_ratio'], 5)} | "
        f"{_sg(100 * e['gm_rel'], 2)} % | {met('gm_rel', ' %')} |",
        f"| orbit radius | {f['radius_au']:.3f} ± {se['radius_au']:.3f} AU | {t['radius_au']:.3f} AU | "
        f"{_sg(100 * e['radius_rel'], 3)} % | {met('radius_rel', ' %')} |",
        f"| period | {f['period_yr']:.2f} ± {se['period_yr']:.2f} yr | {t['period_yr']:.2f} yr | "
        f"{_sg(100 * e['period_rel'], 3)} % | {met('period_rel', ' %')} |",
        f"| longitude at J2000 | {f['longitude_j2000_deg']:.2f}° | {t['longitude_j2000_deg']:.2f}° | "
        f"{_sg(e['longitude_deg'], 2)}° | {met('longitude_deg', '°')} |",
    ]
    out.append("")
    out.append(
        f"(seed 0, {r['wall_time_s']:.0f} s.) On 1846-09-23, the night Galle found Neptune, the fit puts it at "
        f"{f['longitude_1846_09_23_deg']:.2f}° (true {t['longitude_1846_09_23_deg']:.2f}°). The learned Lagrangian: "
        f"{r['learned_lagrangian']['formula']}."
    )
    direct = (r.get("diagnostics") or {}).get("direct_fit_of_a_res")
    if direct:
        de = direct["errors"]
        out.append(
            f"A direct fit to the ephemeris residual (no networks, `nnphd.astro.ephemeris.fit_neptune`): GM "
            f"{_sg(100 * de['gm_rel'], 1)} %, radius {_sg(100 * de['radius_rel'], 2)} %, longitude {_sg(de['longitude_deg'], 2)}°."
        )
    for x in runs:
        if x["seed"] == 0:
            continue
        ex = x["errors"]
        out.append(
            f"Seed {x['seed']}: GM {_sg(100 * ex['gm_rel'], 2)} %, radius {_sg(100 * ex['radius_rel'], 3)} %, longitude "
            f"{_sg(ex['longitude_deg'], 2)}° ({'all goals met' if x['all_goals_met'] else '**a goal missed**'}, "
            f"{x['wall_time_s']:.0f} s)."
        )
    return "\n".join(out) + "\n"


# ---- the recording look-alikes, all cases (results/detect_recordings_all.json) -------------------------------------
def _rec_rate(r: dict) -> str:
    if r["rate"] is None:
        return "—"
    if r["rate_truth"]:
        err = 100 * (r["rate"] / r["rate_truth"] - 1)
        e = f"{_sg(err, 1)} %"
        return f"{r['rate']:.4g} / {r['rate_truth']:.4g} ({'**' + e + '**' if abs(err) > 10 else e})"
    se = abs(r["rate"] / r["energy_z"]) if r.get("energy_z") else None
    return f"{_g(r['rate'], 2)}" + (f" ± {_g(se, 1)}" if se else "") + " / 0"


def recordings_stress() -> str:
    """results/detect_recordings_all.json (benchmarks/detect_recordings.py, one case a run, seed 0, condensed):
    every recording look-alike through `nnphd detect` at its default settings."""
    rows = _load("detect_recordings_all.json")
    out = [
        "| case | samples | truth | expected | ours (confidence) | energy-decay rate: ours / truth | energy z "
        "| shooting z | law (or best candidate, not claimed) | s |",
        "|---" * 10 + "|",
    ]
    for r in rows:
        z = [_f(x, 1) if x is not None else "—" for x in (r["energy_z"], r["shooting_z"])]
        st = f"{r['status']} ({r['confidence']:.2f})"
        seed = "" if r["seed"] == 0 else f" (seed {r['seed']})"
        law = r["law"].replace("|", "\\|")
        if r.get("law_status") == "tie":  # the script's law is the tie's first; "ties" names the others
            law = "tie: " + " / ".join([law, *r.get("ties", [])])
        exp = "none or inconclusive" if r["expected"] == "not-detected" else r["expected"]
        out.append(
            f"| {r['name']}{seed} | "
            f"{r['samples']} | {r['truth']} | {exp} | "
            f"{st if r['right'] else '**' + st + '**'} | {_rec_rate(r)} | {z[0]} | {z[1]} | "
            f"{law} | {r['wall_s']:.0f} |"
        )
    out.append("")
    out.append(f"{sum(r['right'] for r in rows)} of {len(rows)} verdicts right.")
    return "\n".join(out) + "\n"


TRUST_CASES = {
    "anharmonic": "anharmonic q⁴",
    "morse": "Morse",
    "pendulum": "pendulum, large amplitude",
    "kepler2d": "Kepler 2-D",
    "kepler2d-eccentric": "Kepler 2-D, eccentric",
    "double-well": "double well",
    "magnetic2d": "magnetic 2-D (velocity-dependent)",
    "anharmonic+drag": "anharmonic + drag",
    "pendulum+drag": "pendulum + drag",
    "kepler2d+drag": "Kepler + drag",
    "anharmonic+drive": "anharmonic + drive cos ωt",
    "vanderpol": "van der Pol (self-excitation)",
}


def _trust_naive(r) -> str:
    nv = r["naive_paper"]
    if nv["new_physics"] is None:
        return "not run"
    said = "new" if nv["new_physics"] else "none"
    if nv["new_physics"] == r["conservative"]:
        said = "**false**" if r["conservative"] else "**missed**"
    return f"{said} ({_g(nv['ratio'], 3)})"


def _trust_ours(r) -> str:
    st = f"{r['status']}, {r['confidence']:.2f}"
    return st if r["correct"] and r["status"] != "inconclusive" else f"**{st}**"


def trust_table() -> str:
    """results/trust_table.json (benchmarks/trust_table.py --single): the naive ratio and nnphd's assess, per case
    on 8 trajectories and on one; a wrong or undecided answer in bold."""
    doc = _load("trust_table.json")
    rows = {(r["case"], r["n_traj"]): r for r in doc["rows"]}
    k = doc["config"]["ntraj"]
    out = [
        f"| case | truth | f_n / f | naive ({k} traj.) | ours ({k} traj.) | naive (1 traj.) | ours (1 traj.) | s ({k} / 1) |",
        "|---" * 8 + "|",
    ]
    for name, label in TRUST_CASES.items():
        many, one = rows.get((name, k)), rows.get((name, 1))
        ref = many or one
        if ref is None:
            continue
        cells = []
        for r in (many, one):
            cells += ["not run", "not run"] if r is None else [_trust_naive(r), _trust_ours(r)]
        secs = " / ".join("—" if r is None else f"{r['time_s']:.0f}" for r in (many, one))
        truth = "conservative" if ref["conservative"] else "non-cons."
        frac = "0" if ref["conservative"] else f"{100 * ref['fn_fraction']:.1f}%"
        out.append(f"| {label} | {truth} | {frac} | {cells[0]} | {cells[1]} | {cells[2]} | {cells[3]} | {secs} |")
    done = doc["rows"]
    right = sum(r["correct"] and r["status"] != "inconclusive" for r in done)
    undecided = sum(r["status"] == "inconclusive" for r in done)
    wrong = sum(r["status"] == ("detected" if r["conservative"] else "none") for r in done)
    out.append("")
    out.append(
        f"Ours: {right} of {len(done)} runs right, {undecided} inconclusive, {wrong} wrong (a conservative case "
        f'"detected" or a non-conservative one "none"). The naive ratio: '
        f"{sum(_trust_naive(r).startswith('**') for r in done)} of {len(done)} wrong."
    )
    return "\n".join(out) + "\n"


def uan_settled() -> str:
    """results/uan_settled.json (benchmarks/uan_settled.py): --mode fast's first chain, max/min of L_b below λ = 1."""
    doc = _load("uan_settled.json")
    out = ["| case | truth | chain: verdict, ratio | L_b below λ = 1: max / min | then |", "|---" * 5 + "|"]
    for r in doc["rows"]:
        cv = r["chain_verdict"]
        said = f"{_verdict(cv['new_physics'])}, ×{_g(cv['ratio'], 3)}"
        if cv["new_physics"] != r["truth_new_physics"]:
            said = f"**{said}**"
        then = (
            "kept"
            if not r["ran_paper_protocol"]
            else "paper protocol (" + "; ".join(d.split(":")[0] for d in r["doubts"]) + ")"
        )
        fin = r["final"]
        if r["ran_paper_protocol"]:
            then += f" → {_verdict(fin['new_physics'])}, ×{_g(fin['ratio'], 3)}"
        truth = "new physics" if r["truth_new_physics"] else "none"
        out.append(
            f"| {r['system']} seed {r['seed']}, {r['steps']} steps, {r['samples']} samples | {truth} | {said} | "
            f"{r['lb_ratio']:.2f} | {then} |"
        )
    return "\n".join(out) + "\n"


def conservative_controls() -> str:
    """results/conservative_controls.json (benchmarks/conservative_controls.py): conservative records, seeds 0–2."""
    d = _load("conservative_controls.json")
    seeds = sorted({r["seed"] for r in d["runs"]})
    by = {(r["record"], r["seed"]): r for r in d["runs"]}
    records = list(dict.fromkeys(r["record"] for r in d["runs"]))

    def cell(r) -> str:
        st = r["status"] + ("" if r["confidence"] == 1.0 else f" ({r['confidence']:.2f})")
        if r["candidate"] == "drive" and r["candidate_omega"] is not None:
            st += f", drive ω = {r['candidate_omega']:.4f}" + ("" if r["status"] != "none" else " not claimed")
        return st

    out = ["| record | frame | " + " | ".join(f"seed {s}" for s in seeds) + " | s |", "|---" * (3 + len(seeds)) + "|"]
    for name in records:
        runs = [by[name, s] for s in seeds]
        drive = runs[0]["known_drive_omega"]
        label = name + (f" (the Sun's tide: ω = {drive:.4f})" if drive else "")
        secs = ", ".join(f"{r['wall_s']:.0f}" for r in runs)
        out.append(f"| {label} | {runs[0]['frame']} | " + " | ".join(cell(r) for r in runs) + f" | {secs} |")
    out.append("")
    out.append(
        "; ".join(
            f"seed {s}: {x['detected']} detected, {x['none']} none of {x['runs']} ({100 * x['none_share']:.0f} %; "
            f"{x['autonomous']['none']} of the {x['autonomous']['runs']} autonomous records)"
            for s, x in sorted(d["summary"].items())
        )
        + "."
    )
    return "\n".join(out) + "\n"


TABLES = {
    "conservative_controls": conservative_controls,
    "stage_times": stage_times,
    "stage_times_held_out": stage_times_held_out,
    "markers_constraints": markers_constraints,
    "cluster_scaling": cluster_scaling,
    "declared_field_guard": declared_field_guard,
    "seed_robustness": seed_robustness,
    "real_double_pendulum": real_double_pendulum,
    "time_to_verdict": time_to_verdict,
    "single_precision": single_precision,
    "single_precision_laws": single_precision_laws,
    "throw_declared": throw_declared,
    "laws_table": laws_table,
    "friction_lookalikes": friction_lookalikes,
    "lookalike_reference": lookalike_reference,
    "real_friction": real_friction,
    "real_friction_seeds": real_friction_seeds,
    "detect_recordings": detect_recordings,
    "workers": workers,
    "workers_detect": workers_detect,
    "flops": flops,
    "speed": speed,
    "phase_transition": phase_transition,
    "discover": discover,
    "table_ii": table_ii,
    "alignment": alignment,
    "predict": predict,
    "lambda_p": lambda_p,
    "data_quality": data_quality,
    "reproduce_claims": reproduce_claims,
    "demo_neptune": demo_neptune,
    "recordings_stress": recordings_stress,
    "trust_table": trust_table,
    "uan_settled": uan_settled,
}


def render(text: str) -> tuple[str, list[str]]:
    """``text`` with every generated block re-rendered, and the names of the blocks that changed."""
    changed = []

    def one(m):
        name = m.group("name")
        if name not in TABLES:
            raise SystemExit(f"error: unknown generated table {name!r}; expected one of {', '.join(TABLES)}")
        body = TABLES[name]()
        if body != m.group("body"):
            changed.append(name)
        return m.group(1) + body + m.group(4)

    return BLOCK.sub(one, text), changed


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--check", action="store_true", help="change nothing; exit 1 when a table differs")
    a = ap.parse_args()
    differ = []
    for doc in DOCS:
        with open(doc, encoding="utf-8") as f:
            text = f.read()
        new, changed = render(text)
        name = os.path.relpath(doc, ROOT)
        if a.check:
            differ += [f"{name}: {c}" for c in changed]
            continue
        tmp = doc + ".tmp"
        with open(tmp, "w", encoding="utf-8") as f:
            f.write(new)
        os.replace(tmp, doc)
        print(f"{name}: rewrote {', '.join(changed) or 'nothing (all up to date)'}")
    if differ:
        print(f"differs from the JSON: {', '.join(differ)}", file=sys.stderr)
        raise SystemExit(1)
    if a.check:
        print("every generated table matches its JSON")


if __name__ == "__main__":
    main()
