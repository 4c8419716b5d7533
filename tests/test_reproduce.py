"""nnphd reproduce: every experiment section in the report, every referenced figure present, the cache resumes."""

import base64
import json
import re

import pytest

from nnphd.cli import main
from nnphd.paper.reproduce import EXPERIMENTS, FIGURES, plan, reproduce

# the same code paths as the full run, at toy sizes
TINY = {
    "discover": {
        "systems": ["double-pendulum"],
        "steps": 30,
        "sweep_steps": 8,
        "sr_time": 0.0,
        "sweep_lambdas": [0.5, 2.0],
        "n_steps": 100,
    },
    "predict": {"steps": 8, "widths": [16, 16], "n_traj": 400},
    "lambda-p": {
        "steps": 8,
        "systems": ["ho+ld"],
        "ps": [1],
        "lambdas": [0.5, 2.0],
        "force_lambdas": [0.5, 2.0],
        "n_train": 200,
        "n_test": 200,
    },
    "data-quality": {"steps": 8, "alphas": [0.25, 1.0], "betas": [0.5, 1.0], "n_train": 200, "n_test": 200},
}


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    out = tmp_path_factory.mktemp("rep")
    msgs = []
    summary = reproduce(
        out=out, quick=True, seed=0, overrides=TINY, progress=lambda done, total, m: msgs.append((done, total, m))
    )
    return out, summary, msgs


@pytest.mark.slow  # tens of seconds: run by `python3 dev.py test --slow` (and by CI)
def test_report_has_every_section_and_figure(run):
    out, summary, _ = run
    page = (out / "report.html").read_text()
    assert page.startswith("<!DOCTYPE html>") and page.rstrip().endswith("</html>")
    for exp in EXPERIMENTS:
        assert f'<section id="{exp}">' in page
    # every linked file exists, and every linked figure is also embedded as a valid PNG
    links = re.findall(r'<a href="([^"#]+)"', page)
    figures = [f for figs in FIGURES.values() for f in figs]
    assert sorted(set(links)) == sorted(figures)
    for rel in links:
        assert (out / rel).is_file(), rel
    imgs = re.findall(r'src="data:image/png;base64,([^"]+)"', page)
    assert len(imgs) == len(figures)
    for data in imgs:
        assert base64.b64decode(data)[:8] == b"\x89PNG\r\n\x1a\n"
    assert "figure not produced" not in page
    assert "Quick mode" in page
    # each Table II number of ours is in the page, as the summary's claims state it
    ours = [c["ours"] for c in summary["claims"] if c["experiment"] == "discover" and "±" in c["ours"]]
    assert len(ours) == 4
    for v in ours:
        assert f"<td>{v}</td>" in page, v


@pytest.mark.slow  # tens of seconds: run by `python3 dev.py test --slow` (and by CI)
def test_summary_claims_and_settings(run):
    out, summary, msgs = run
    saved = json.loads((out / "summary.json").read_text())
    assert saved["claims_total"] == summary["claims_total"] == len(summary["claims"])
    assert saved["claims_met"] == sum(c["met"] for c in summary["claims"])
    assert {c["experiment"] for c in summary["claims"]} == set(EXPERIMENTS)
    # discover contributes the verdict and four Table II rows of the pendulum
    assert sum(c["experiment"] == "discover" for c in summary["claims"]) == 5
    assert summary["settings"]["predict"]["steps"] == 8
    assert set(summary["runs"]) == {"discover/double-pendulum", "predict", "lambda-p", "data-quality"}
    assert not any(r["cached"] for r in summary["runs"].values())
    assert any("discover double-pendulum" in m for *_, m in msgs)
    assert {t for _, t, _ in msgs} == {4} and {d for d, _, _ in msgs} <= {0, 1, 2, 3}  # units of the whole run
    for rel in (
        "discover/double-pendulum/results.json",
        "discover/table2.json",
        "predict/results.json",
        "lambda-p/results.json",
        "data-quality/results.json",
    ):
        assert (out / rel).is_file()


@pytest.mark.slow  # tens of seconds: run by `python3 dev.py test --slow` (and by CI)
def test_rerun_loads_every_unit_from_the_cache(run):
    out, summary, _ = run
    again = reproduce(out=out, quick=True, seed=0, overrides=TINY)
    assert all(r["cached"] for r in again["runs"].values())
    assert again["claims"] == summary["claims"]
    # other settings for one unit recompute that unit only
    changed = {**TINY, "data-quality": {**TINY["data-quality"], "steps": 9}}
    third = reproduce(out=out, quick=True, seed=0, overrides=changed)
    assert [k for k, r in third["runs"].items() if not r["cached"]] == ["data-quality"]


def test_plan_quick_is_full_with_fewer_steps():
    full, quick = plan(False), plan(True)
    assert set(full) == set(quick) == set(EXPERIMENTS)
    for exp in EXPERIMENTS:
        assert set(full[exp]) == set(quick[exp])
        assert quick[exp]["steps"] < full[exp]["steps"]
    assert full["discover"]["systems"] == quick["discover"]["systems"] == ["double-pendulum", "neptune", "gw"]
    with pytest.raises(ValueError, match="unknown experiment"):
        plan(True, {"fig7": {}})


def test_cli_bad_input(tmp_path, capsys):
    assert main(["reproduce", "--seed", "-1", "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err
    assert "--seed" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "r").exists()


@pytest.mark.slow  # tens of seconds: run by `python3 dev.py test --slow` (and by CI)
def test_two_workers_same_claims(run, tmp_path):
    """On 2 local worker processes (the λ/p study's sweeps as units of their own) the claims — every number in
    them — are those of the run in this process."""
    _, summary, _ = run
    two = reproduce(out=tmp_path, quick=True, seed=0, overrides=TINY, workers=2)
    assert two["failed"] == {} and two["workers"] == 2
    assert two["claims"] == summary["claims"]
    assert set(two["runs"]) == set(summary["runs"])
    assert (tmp_path / "lambda-p" / "runs" / "ho+ld_p1" / "results.json").is_file()  # the sweep ran as a unit
    assert {r["where"] for k, r in two["runs"].items() if k != "lambda-p"} != {"in-process"}


@pytest.mark.slow  # tens of seconds: run by `python3 dev.py test --slow` (and by CI)
def test_a_failing_unit_is_reported_the_others_finish(run, tmp_path):
    import shutil

    out, summary, _ = run
    shutil.copytree(out, tmp_path / "r")
    bad = {**TINY, "data-quality": {**TINY["data-quality"], "alphas": [2.0]}}  # α outside [0, 1]: the unit raises
    s = reproduce(out=tmp_path / "r", quick=True, seed=0, overrides=bad)
    assert list(s["failed"]) == ["data-quality"] and "alphas" in s["failed"]["data-quality"]
    assert all(s["runs"][k]["cached"] for k in s["runs"] if k != "data-quality")
    assert {c["experiment"] for c in s["claims"]} == set(EXPERIMENTS) - {"data-quality"}
    page = (tmp_path / "r" / "report.html").read_text()
    assert "Failed units" in page and "Not run to the end" in page
