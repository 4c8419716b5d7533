"""The README's commands are real: every ``nnphd …`` line of its bash blocks (and of docs/guide.md's) is parsed by
the command line itself — the sub-command exists, every option exists and its value is valid — without running it
(the paper-scale ones take minutes; the Python quickstart is run whole by tests/test_api.py). The README stays a
five-minute read."""

from __future__ import annotations

import math
import os
import re
import shlex

import pytest
import typer

from nnphd.cli import app

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _commands(doc: str) -> list[str]:
    text = open(os.path.join(ROOT, doc), encoding="utf-8").read()
    lines = [ln.split("  #")[0].strip() for b in re.findall(r"```bash\n(.*?)```", text, re.S) for ln in b.splitlines()]
    return [ln for ln in lines if ln.startswith("nnphd ")]


def _parse(line: str):
    """(the sub-command's name, its parsed parameters) as the CLI would see ``line``; click's error if it would not."""
    cmd = typer.main.get_command(app)
    ctx = cmd.make_context("nnphd", shlex.split(line)[1:])
    c, rest = cmd, [*ctx._protected_args, *ctx.args]
    while hasattr(c, "resolve_command"):  # a group: descend to the sub-command
        name, c, rest = c.resolve_command(ctx, rest)
        ctx = c.make_context(name, rest, parent=ctx)
        rest = [*getattr(ctx, "_protected_args", []), *ctx.args]
    assert rest == [], f"{line}: left unparsed: {rest}"
    return c.name, ctx.params


@pytest.mark.parametrize("line", _commands("README.md") + _commands("docs/guide.md"))
def test_every_command_in_the_docs_is_one_the_cli_takes(line):
    name, params = _parse(line)
    assert name == shlex.split(line)[1 + (shlex.split(line)[1] in ("study", "demo"))]


def test_the_parse_reads_values_and_fails_on_what_the_cli_would_refuse():
    name, p = _parse("nnphd detect data.csv --steps 300 --n-seeds 1 --law-fit pointwise --field uniform")
    assert name == "detect" and p["steps"] == 300 and p["n_seeds"] == 1 and p["files"] == ["data.csv"]
    assert p["law_fit"].value == "pointwise" and p["field"].value == "uniform"
    assert _parse("nnphd detect data.csv --repeats 3")[1]["n_seeds"] == 3  # the old name of --n-seeds
    for bad in ("nnphd detect data.csv --no-such-option", "nnphd detect data.csv --steps 2", "nnphd sweepp"):
        with pytest.raises(Exception) as e:
            _parse(bad)
        assert type(e.value).__name__ in ("NoSuchOption", "BadParameter", "UsageError"), e.value


def test_the_readme_is_a_five_minute_read():
    lines = open(os.path.join(ROOT, "README.md"), encoding="utf-8").read().splitlines()
    assert len(lines) <= 150
    assert lines[0].startswith("# nnphd")


def _json(name):
    import json

    with open(os.path.join(ROOT, "benchmarks", "results", name)) as f:
        return json.load(f)


# ---- the README's measured numbers, each recomputed from the JSON of benchmarks/results/ ---------------------------
# Each check takes the README's text (whitespace-normalised), finds its sentence, recomputes every number in it from
# the JSON with the README's own rounding, and returns the matches it checked (the last test below asserts that no
# number of "Results at a glance" is left outside them).
WORDS = {w: i for i, w in enumerate("one two three four five six seven eight nine ten eleven twelve".split(), 1)}
MISSING = "the README no longer says: "  # a sentence not found (the edit test tells it from a wrong number)
# Numbers no JSON holds (none now: every number of "Results at a glance" is recomputed by a check below).
NO_JSON: tuple[str, ...] = ()


def _readme() -> str:
    return " ".join(open(os.path.join(ROOT, "README.md"), encoding="utf-8").read().split())


def _find(pattern: str, text: str) -> re.Match:
    m = re.search(pattern, text)
    assert m, MISSING + pattern
    return m


def _n(word: str) -> int:
    return WORDS[word] if word in WORDS else int(word)


def _as(x: float, shown: str) -> str:
    """x with as many decimals as the README's ``shown``: the README's rounding."""
    return f"{x:.{len(shown.partition('.')[2])}f}"


def _within(errors) -> int:
    """The N of "within N %": the largest error in whole per cent, rounded up."""
    return math.ceil(100 * max(errors))


def _check_machine(text):
    m = _find(r"are in \[docs/RESULTS\.md\]\(docs/RESULTS\.md\) \((\d+) cores, CPU\)", text)
    machines = [_json(f)["machine"] for f in ("time_to_verdict.json", "flops.json", "speed.json")]
    assert all(x["nproc"] == int(m[1]) and x["jax_backend"] == "cpu" for x in machines), machines
    return [m]


def _check_paper(text):
    from nnphd.engine.systems import SYSTEMS

    # the paper protocol (13 λ × 2000 steps, seed 0) on every system: the "paper" half of time_to_verdict.json
    m = _find(r"on its (\w+) toy and (\w+) Table I systems: every verdict right", text)
    rows = _json("time_to_verdict.json")["rows"]
    kinds = [SYSTEMS[r["system"]].data for r in rows]  # the toys are iid samples, Table I's systems trajectories
    assert [_n(m[1]), _n(m[2])] == [kinds.count("gaussian"), kinds.count("trajectory")]
    assert all(r["paper"]["new_physics"] == (not SYSTEMS[r["system"]].conservative) for r in rows)
    # Table II: the float64 joint fit of benchmarks/float32_accuracy.py --table2 (`discover` of the three systems;
    # the same digits as docs/RESULTS.md's Table II of `nnphd discover --all`)
    t = _find(r"\*\*Table II\*\* within every goal: (.+?)\. ", text)
    shown = dict(re.findall(r"(\S+) = (\d+\.\d+)", t[1]))
    json_names = {"Γ": ("Gamma_11", "Gamma_22"), "GM": ("GM",), "R": ("R",), "ω": ("omega",), "k": ("k",), "m": ("m",)}
    fits = {r["quantity"]: r["float64"] for r in _json("float32_table2.json")["rows"]}
    assert set(shown) == set(json_names), shown
    for name, value in shown.items():
        assert all(_as(fits[q]["ours"], value) == value for q in json_names[name]), (name, value)
    assert all(f["goal_met"] for f in fits.values())
    return [m, t]


def _check_recordings(text):
    # the recording look-alikes (tests/fixtures/recordings.py) at nnphd detect's defaults, seed 0: the "recordings"
    # of seed_robustness.json (benchmarks/seed_robustness.py, seeds 0, 1, 2; its seed 0 is the run of the README)
    m = _find(
        r"(\d+) of (\d+) verdicts right on seeds (\d), (\d), (\d), damping rates within ([\d.]+) % \(pendulum, carts\); "
        r"noise → \"inconclusive\" in ~(\d+) s",
        text,
    )
    rows = [r for r in _json("seed_robustness.json")["rows"] if r["set"] == "recordings"]
    assert all(sorted(x["seed"] for x in r["runs"]) == [int(m[3]), int(m[4]), int(m[5])] for r in rows)

    def right(status, expected):  # as benchmarks/seed_robustness.py
        return status in ("none", "inconclusive") if expected == "not-detected" else status == expected

    every = [all(right(x["status"], r["expected"]) for x in r["runs"]) for r in rows]
    assert [int(m[1]), int(m[2])] == [sum(every), len(rows)]
    noise = [x["seconds"] for r in rows if r["expected"] == "inconclusive" for x in r["runs"]]  # refused at once
    assert noise and all(
        x["status"] == "inconclusive" for r in rows if r["expected"] == "inconclusive" for x in r["runs"]
    )
    assert math.ceil(max(noise)) == int(m[7]), noise
    # the energy-decay rates against their truth: detect_recordings.json (benchmarks/detect_recordings.py, seed 0,
    # the damped pendulum and the two cart recordings), the largest error rounded up to the README's decimals
    rates = {
        r["name"]: abs(r["rate"] / r["rate_truth"] - 1) for r in _json("detect_recordings.json") if r["rate_truth"]
    }
    assert set(rates) == {"pendulum-damped", "cart", "carts-coupled"}, rates
    assert f"{math.ceil(1000 * max(rates.values())) / 10:.1f}" == m[6], rates
    # the real double pendulum's whole runs: runs 6–20 in real_double_pendulum.json; run 5 was measured by hand with
    # the command line, and docs/RESULTS.md documents it ("Run 5 is not in the JSON …: detected (1.00)")
    d = _find(r"A real chaotic double pendulum: (\d+) of (\d+) whole runs \"detected\"", text)
    runs = [r for r in _json("real_double_pendulum.json") if r["seconds"] == 0]  # --seconds 0: whole runs
    results = " ".join(open(os.path.join(ROOT, "docs", "RESULTS.md"), encoding="utf-8").read().split())
    run5 = re.search(r"Run 5 is not in the JSON \(measured by hand with the command line[^)]*\): (\w+) \(", results)
    assert run5 and 5 not in {r["run"] for r in runs}
    detected = sum(r["status"] == "detected" for r in runs) + (run5[1] == "detected")
    assert [int(d[1]), int(d[2])] == [detected, len(runs) + 1]
    return [m, d]


def _check_laws(text):
    # the law table of the constructed cases: laws_table.json (benchmarks/laws_table.py, seed 0)
    m = _find(
        r"on (\w+) constructed cases: right on (\d+) of (\d+) \(the drive ([\d.]+) cos ([\d.]+)t found as ([\d.]+) "
        r"cos ([\d.]+)t\), the PySINDy peer on (\d+) of (\d+); no law on the conservative controls \(Hénon–Heiles, "
        r"a gyroscopic force\)",
        text,
    )
    rows = _json("laws_table.json")
    assert _n(m[1]) == int(m[3]) == int(m[9]) == len(rows)
    assert [int(m[2]), int(m[8])] == [sum(r["right"] for r in rows), sum(r["baseline_right"] for r in rows)]
    drive = next(r for r in rows if r["case"] == "drive")
    assert f"{m[4]} cos({m[5]} t)" in drive["truth"] and drive["law_status"] == "claimed"
    p = drive["law"]["params"]
    assert [_as(p["A_cos"], m[6]), _as(p["omega"], m[7])] == [m[6], m[7]]
    controls = [r for r in rows if "control" in r["truth"]]
    assert [r["case"] for r in controls] == ["henon-heiles", "gyroscopic"]
    assert all(r["law"] is None and r["right"] for r in controls)
    return [m]


def _check_real_friction(text):
    m = _find(
        r"\*\*Real friction\*\* \(seed (\d+)\): (\w+) look-alikes, (\d+) right \(laws within (\d+) %\), (\d+) ties "
        r"holding the truth \(one the throw, its field declared vertical; (\w+) that an independent "
        r"whole-trajectory fit "
        r"cannot decide either\), no wrong family; (\w+) real recordings "
        r"\((\w+) sources\): laws within (\d+) % of the reference's force, one string-pendulum run's tie led by a "
        r"family without the reference's quadratic term",
        text,
    )
    # the look-alikes: friction_laws.json (benchmarks/friction_laws.py), counted as benchmarks/results_tables.py does
    looks = _json("friction_laws.json")
    assert {r["seed"] for r in looks} == {int(m[1])} and _n(m[2]) == len(looks)
    right = [r for r in looks if r["family_right"]]
    ties = [
        r
        for r in looks
        if not r["family_right"] and r["law_status"] == "tie" and r["truth_law"] in (r["winner"], *r["ties"])
    ]
    assert [int(m[3]), int(m[5])] == [len(right), len(ties)]
    assert _within(r["err_moving"] for r in right if r["truth_law"] != "none") == int(m[4])
    declared = [r["name"] for r in ties if (r.get("declared") or {}).get("field") == "vertical"]
    assert len(declared) == 1 and declared[0].startswith("throw")
    # the ties the reference cannot decide either (benchmarks/friction_reference.py --lookalikes): by its IC (its
    # residuals weighed by their number, `information`) the best fit lacking a true term within ΔIC 6 of the truth's
    ref = {e["file"].removeprefix("lookalike:"): e for e in _json("friction_reference_lookalikes.json")["recordings"]}

    def undecided(e):
        truth = {k for k, v in e["truth"].items() if v}
        ic = e["information"]["ic"]
        lacking = [v for k, v in ic.items() if not truth <= set(k.strip("{}").split(","))]
        return min(lacking) - ic["{" + ",".join(sorted(truth)) + "}"] < 6

    undecided_ties = [r["name"] for r in ties if r["name"] in ref and undecided(ref[r["name"]])]
    assert _n(m[6]) == len(undecided_ties) and undecided_ties == ["sensor-20hz"]
    assert not [r for r in looks if r["law_status"] == "claimed" and not r["family_right"]]  # no wrong family
    # the real recordings: real_friction.json (benchmarks/real_friction.py, seed 0) against the reference's fit
    real = _json("real_friction.json")
    sources = {r["file"].split("_")[0] for r in real}  # a file's name starts with its source: servo, encoder, …
    assert [_n(m[7]), _n(m[8])] == [len(real), len(sources)]
    assert all(r["laws"] for r in real) and _within(r["laws"][0]["err"] for r in real) == int(m[9])
    lacking = [r for r in real if not r["laws"][0]["necessary_in"]]  # a law led by a family without a needed term
    assert [(r["law_status"], "string_pendulum" in r["file"], "e" in r["reference"]["necessary"]) for r in lacking] == [
        ("tie", True, True)  # e: the reference's quadratic term
    ]
    return [m]


def _check_time_and_scale_out(text):
    import statistics

    m = _find(r"takes (\d+)–(\d+) s a file warm \(median (\d+);", text)
    warm = [r["warm"]["total_s"] for r in _json("stage_times.json")]
    assert [int(x) for x in m.groups()] == [round(min(warm)), round(max(warm)), round(statistics.median(warm))]
    h = _find(r"\(median (\d+) s, max (\d+\.\d) s on (\w+) held-out ones of other kinds", text)
    held = [r["warm"]["total_s"] for r in _json("stage_times_held_out.json")["records"]]  # stage_times.py --records
    assert (f"{statistics.median(held):.0f}", f"{max(held):.1f}") == (h[1], h[2])
    assert (h[3], len(held)) == ("eleven", 11)
    w = _find(r"on Dask the same numbers with (\d+) or (\d+) workers", text)
    workers = _json("workers_detect.json")  # benchmarks/bench_workers.py detect: the same files, 1 and 2 workers
    assert workers["identical_numbers"] and sorted(map(int, workers["wall_s"])) == [int(w[1]), int(w[2])]
    c = _find(r"a batch of (\d+) files simulated on (\d+) workers at efficiency (\d\.\d+)", text)
    sets = _json("cluster_scaling.json")["sets"]
    batch = next(s for k, s in sets.items() if k.endswith(f"= {c[1]} files"))
    row = next(r for r in batch["rows"] if r["workers"] == int(c[2]))
    assert f"{row['efficiency']:.2f}" == c[3]
    return [m, h, w, c]


def _check_speed(text):
    m = _find(r"a training step's FLOPs are (\d+\.\d)× a plain MLP's, (half) the per-sample-Hessian reference's", text)
    ratios = _json("flops.json")["ratios"]  # benchmarks/bench_flops.py: XLA's FLOPs at batch 1000
    assert _as(ratios["ours_over_plain_flops_b1000"], m[1]) == m[1]
    assert round(1 / ratios["reference_over_ours_flops_b1000"], 1) == 0.5  # "half"
    f = _find(
        r"gives the paper protocol's verdict on all (\w+) systems in (\d\.\d+) of its time \((\d\.\d+) on the "
        r"(\w+) clear ones\)",
        text,
    )
    ttv = _json("time_to_verdict.json")  # benchmarks/time_to_verdict.py
    rows = ttv["rows"]
    assert _n(f[1]) == len(rows) and all(r["same_verdict"] for r in rows) and ttv["summary"]["all_same_verdict"]
    total = sum(r["fast"]["wall_s"] for r in rows) / sum(r["paper"]["wall_s"] for r in rows)
    assert _as(total, f[2]) == _as(ttv["summary"]["fast_over_paper"], f[2]) == f[2]
    clear = [r for r in rows if not r["fast"]["ran_paper_protocol"]]  # fast did not fall back to the paper protocol
    assert _n(f[4]) == len(clear)
    assert _as(sum(r["fast"]["wall_s"] for r in clear) / sum(r["paper"]["wall_s"] for r in clear), f[3]) == f[3]
    return [m, f]


def _check_energy_example(text):
    # "Reading a verdict" quotes a report's energy trend: the damped pendulum recording (damping ~1 % of the force)
    # at nnphd detect's defaults, seed 0 — its reason in seed_robustness.json
    m = _find(r"\(\"decays (\d+\.\d) %/period, z = ([\d.]+)\"\)", text)
    row = next(r for r in _json("seed_robustness.json")["rows"] if r["file"] == "pendulum-damped")
    reason = next(x["reason"] for x in row["runs"] if x["seed"] == 0)
    j = re.search(r"energy decays ([\d.]+)%/period \(rate [^,]+, z = ([\d.]+)", reason)
    assert j and [m[1], m[2]] == [j[1], j[2]], reason
    return [m]


def _check_reproduce_time(text):
    # the full `nnphd reproduce`, as the README names it below its command-line block
    f = _find(r"`reproduce` \(all of them, one HTML report, (\d+)–(\d+) min, resumable\)", text)
    full = _json("workers_reproduce.json")["wall_s"].values()  # bench_workers.py reproduce: 1 and 2 workers
    assert [int(f[1]), int(f[2])] == [round(min(full) / 60), round(max(full) / 60)], list(full)
    return [f]


def _check_controls(text):
    # the conservative negative controls: conservative_controls.json (benchmarks/conservative_controls.py, seeds 0-2)
    m = _find(
        r"\*\*Negative controls\*\*: (\w+) conservative orbits \(DE405, a J2 satellite; rotating frames too\): (\d+) of "
        r"(\d+) runs \"detected\", (\d+) \"none\"",
        text,
    )
    runs = _json("conservative_controls.json")["runs"]
    assert _n(m[1]) == len({r["record"] for r in runs}) and int(m[3]) == len(runs)
    assert [int(m[2]), int(m[4])] == [sum(r["status"] == s for r in runs) for s in ("detected", "none")]
    return [m]


CHECKS = (
    _check_machine,
    _check_controls,
    _check_paper,
    _check_recordings,
    _check_laws,
    _check_real_friction,
    _check_time_and_scale_out,
    _check_speed,
    _check_energy_example,
    _check_reproduce_time,
)


def test_the_readmes_paper_verdicts_and_table2_are_those_of_the_json():
    _check_machine(_readme())
    _check_paper(_readme())


def test_the_readmes_recording_and_double_pendulum_counts_are_those_of_the_json():
    _check_recordings(_readme())


def test_the_readmes_negative_control_counts_are_those_of_the_json():
    _check_controls(_readme())


def test_the_readmes_law_table_numbers_are_those_of_the_json():
    _check_laws(_readme())


def test_the_readmes_real_friction_numbers_are_those_of_the_json():
    _check_real_friction(_readme())


def test_the_readmes_time_and_scale_out_numbers_are_those_of_the_json():
    _check_time_and_scale_out(_readme())


def test_the_readmes_speed_numbers_are_those_of_the_json():
    _check_speed(_readme())


def test_the_readmes_quoted_energy_trend_and_reproduce_times_are_those_of_the_json():
    _check_energy_example(_readme())
    _check_reproduce_time(_readme())


def test_every_number_at_a_glance_is_one_a_test_checks():
    """Each number of "Results at a glance" lies in a sentence a check above recomputes (or is named in NO_JSON):
    a number added there without its check fails here."""
    text = _readme()
    start = text.index("## Results at a glance")
    section = text[start : text.index(" ## ", start)]
    spans = [m.span() for check in CHECKS for m in check(text)]
    spans += [(text.index(p), text.index(p) + len(p)) for p in NO_JSON]
    unchecked = [
        section[max(0, x.start() - 30) : x.end() + 10]
        for x in re.finditer(r"\d+(?:\.\d+)?", section)
        if not any(a <= start + x.start() and start + x.end() <= b for a, b in spans)
    ]
    assert unchecked == []


@pytest.mark.parametrize(
    "old, new",
    [
        ("its five toy", "its four toy"),
        ("Γ = 0.0200000", "Γ = 0.0200001"),
        ("ω = 0.1924501", "ω = 0.1924502"),
        ("(2 cores, CPU)", "(4 cores, CPU)"),
        ("13 of 13 verdicts", "12 of 13 verdicts"),
        ('"inconclusive" in ~1 s', '"inconclusive" in ~2 s'),
        ("16 of 16 whole runs", "15 of 16 whole runs"),
        ("right on 10 of 10", "right on 9 of 10"),
        ("0.2001 cos 0.69996t", "0.2001 cos 0.69997t"),
        ("peer on 6 of 10", "peer on 7 of 10"),
        ("9 right (laws within 11 %)", "8 right (laws within 11 %)"),
        ("(laws within 11 %)", "(laws within 10 %)"),
        ("2 ties holding", "3 ties holding"),
        ("declared vertical; one that", "declared vertical; two that"),
        ("(four sources)", "(five sources)"),
        ("laws within 9 %", "laws within 5 %"),
        ("(median 27;", "(median 26;"),
        ("max 67.8 s on eleven", "max 68.8 s on eleven"),
        ("(median 19 s,", "(median 18 s,"),
        ("efficiency 0.98", "efficiency 0.97"),
        ("6.0× a plain", "5.0× a plain"),
        ("all eight systems", "all seven systems"),
        ("in 0.53 of its time", "in 0.35 of its time"),
        ("(0.26 on the six", "(0.25 on the six"),
        ("decays 6.2 %/period", "decays 6.1 %/period"),
        ("report, 19–22 min", "report, 22–33 min"),
    ],
)
def test_a_wrong_number_in_the_readme_is_found(old, new):
    text = _readme()
    edited = text.replace(old, new, 1)
    assert edited != text, old
    with pytest.raises(AssertionError) as e:
        for check in CHECKS:
            check(edited)
    assert MISSING not in str(e.value)  # the sentence was still found: the number itself failed


# ---- the README's commands, run as written ---------------------------------------------------------------------
def test_the_readme_shows_only_commands_a_test_runs():
    """The README's command lines are the six the test below runs (the paper-scale ones live in docs/guide.md, parsed
    above): a README edit that adds or renames one fails here, not silently."""
    assert [shlex.split(ln)[1] for ln in _commands("README.md")] == [
        "systems", "sweep", "sweep", "detect", "detect", "demo"
    ]  # fmt: skip


@pytest.mark.slow  # ~2–3 min: the README's six commands run as written (docs/guide.md's paper-scale ones: parsed)
def test_the_readme_commands_run_as_written(tmp_path):
    """Every command line of the README, run verbatim in an empty folder through the installed console script: the
    catalogue, the fast sweep of HO+LD (a jump), a reduced sweep of the conservative HO+MF (no jump), ``detect`` at
    its defaults and its quick look on a damped oscillator written as data.csv (detected, linear friction γ ≈ 0.1),
    and the Neptune demo (a jump, every goal met)."""
    import json
    import subprocess
    import sys

    import numpy as np

    t = np.arange(0.0, 40.0, 0.05)
    q = np.exp(-0.05 * t) * np.cos(np.sqrt(1 - 0.05**2) * t)  # q̈ = −q − 0.1 q̇
    q += 1e-4 * np.random.default_rng(0).standard_normal(t.size)
    np.savetxt(tmp_path / "data.csv", np.c_[t, q], delimiter=",", header="t,q", comments="", fmt="%.6f")
    exe = os.path.join(os.path.dirname(sys.executable), "nnphd")
    out = tmp_path / "out"
    for line in _commands("README.md"):
        r = subprocess.run([exe, *shlex.split(line)[1:]], cwd=tmp_path, capture_output=True, text=True, timeout=600)
        assert r.returncode == 0, (line, r.stderr[-2000:])
        if line.startswith("nnphd systems"):
            assert all(s in r.stdout for s in ("ho+ld", "ho+mf", "double-pendulum", "neptune", "gw")), r.stdout
        if line.startswith("nnphd detect"):  # the quick look writes out/detect, the other out/mydata
            rep = json.loads((out / ("mydata" if "out/mydata" in line else "detect") / "report.json").read_text())
            law = rep["law"]
            assert rep["status"] == "detected", (line, rep["reasons"])
            assert law["status"] == "claimed" and law["law"]["law"] == "linear", (line, law["law"])
            assert abs(law["law"]["params"]["gamma"] - 0.1) < 0.01, (line, law["law"]["params"])
            if "out/mydata" in line:  # the picture's caption: the same data and defaults (benchmarks/readme_figure.py)
                cap = re.search(r"linear friction, γ = ([\d.]+) \(truth 0\.1\)", _readme())
                assert cap and f"{law['law']['params']['gamma']:.4f}" == cap[1], (cap, law["law"]["params"])
    ld = json.loads((out / "ld" / "results.json").read_text())
    assert ld["verdict"]["new_physics"] is True and ld["verdict"]["ratio"] > 10, ld["verdict"]
    mf = json.loads((out / "mf" / "results.json").read_text())
    assert mf["verdict"]["new_physics"] is False and mf["settings"]["steps_per_lambda"] == 500, mf["verdict"]
    neptune = json.loads((out / "demo-neptune" / "results.json").read_text())
    assert neptune["verdict"]["new_physics"] is True and neptune["all_goals_met"] is True, neptune["errors"]
