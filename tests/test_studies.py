"""λ/p study (Fig. 5) and data-quality study (Fig. 6) at reduced settings: numbers that can fail, cache, CLI."""

import json
import math
import re

import pytest

from nnphd.cli import main
from nnphd.paper.data_quality import DataQualitySettings, data_quality_study
from nnphd.paper.lambda_p import LambdaPSettings, lambda_p_study, transition_sharpness
from nnphd.paper.study_results import DataQualityResult, LambdaPResult
from nnphd.paper.sweep import SweepSettings, run_sweep

LP = dict(steps=200, seed=0, lambdas=(0.1, 0.5, 2.0, 10.0, 50.0), ps=(1, "mse"), systems=("ho+ld", "ho+mf"))
DQ = dict(steps=300, seed=1, alphas=(0.25, 1.0), betas=(0.5, 1.0))


# ---- the jump/smooth criterion on known curves ------------------------------------------------------------------
GRID = (0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0)


def test_sharpness_of_ideal_mse_curve_is_smooth():
    # MSE minimiser: L_e = (λ/(1+λ))² ‖f_n‖² — steepest at small λ, slope 1 at λ=1
    t = transition_sharpness(GRID, [(x / (1 + x)) ** 2 * 0.25 for x in GRID])
    assert t["kind"] == "smooth" and t["sharpness"] == pytest.approx(0.5, abs=0.03)
    assert t["rise_fraction"] == pytest.approx(0.36, abs=0.02)
    assert (t["lam_below"], t["lam_above"]) == (0.5, 2.0)
    # a fitting floor at small λ does not make it a jump
    t = transition_sharpness(GRID, [max((x / (1 + x)) ** 2 * 0.25, 1e-4) for x in GRID])
    assert t["kind"] == "smooth" and t["sharpness"] < 1


def test_sharpness_of_step_and_flat_curves():
    noise = [1.0, 1.3, 0.8, 1.1, 0.9, 1.2, 5.0, 1.0, 0.9, 1.1, 1.0, 0.95, 1.05]
    step = [n * (1e-3 if x < 1 else 0.3) for x, n in zip(GRID, noise)]
    t = transition_sharpness(GRID, step)
    assert t["kind"] == "jump" and t["sharpness"] > 5 and t["rise_fraction"] == pytest.approx(1.0, abs=0.15)
    # flat with noise: it falls across λ = 1 (from 1.2e-3 at λ = 0.5 to 1.0e-3 at λ = 2), so no transition; the
    # steepest other step is 0.02 → 0.05 (1.3e-3 → 0.8e-3)
    flat = [n * 1e-3 for n in noise]
    t = transition_sharpness(GRID, flat)
    steepest = math.log(1.3 / 0.8) / math.log(0.05 / 0.02)
    assert t["slope_across"] == pytest.approx(math.log(1.0 / 1.2) / math.log(2.0 / 0.5), rel=1e-12)
    assert t["slope_max_other"] == pytest.approx(steepest, rel=1e-12) and t["kind"] == "none"
    # the same noise mirrored rises across λ = 1, but less steeply than elsewhere: smooth, not a jump
    t = transition_sharpness(GRID, flat[::-1])
    assert t["sharpness"] == pytest.approx(math.log(1.2 / 1.0) / math.log(4.0) / steepest, rel=1e-12)
    assert t["kind"] == "smooth"
    falling = [1e-2 if x < 1 else 1e-3 for x in GRID]
    assert transition_sharpness(GRID, falling)["kind"] == "none"
    with pytest.raises(ValueError):
        transition_sharpness((0.1, 0.5), (1.0, 2.0))


# ---- λ/p study ----------------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def lp(tmp_path_factory):
    out = tmp_path_factory.mktemp("lp")
    calls = []
    res = lambda_p_study(LambdaPSettings(**LP), out=out, progress=lambda d, t, s: calls.append((d, t)))
    return out, res, calls


@pytest.mark.slow  # an end-to-end run of tens of seconds: slow tier (`python3 dev.py test --slow`, and CI)
def test_lambda_p_verdicts_and_files(lp):
    out, res, calls = lp
    assert isinstance(res, LambdaPResult)
    v = {(r.system, r.p): r for r in res.verdicts}
    assert set(v) == {("ho+ld", "1"), ("ho+ld", "mse"), ("ho+mf", "1"), ("ho+mf", "mse")}
    for p in ("1", "mse"):
        assert v[("ho+ld", p)].new_physics and v[("ho+ld", p)].ratio > 3
        assert not v[("ho+mf", p)].new_physics and v[("ho+mf", p)].ratio < 1.5
    assert all(r.correct for r in res.verdicts) and res.verdict("ho+ld", 1) is v[("ho+ld", "1")]
    # curves: one row per λ, L_e from the test set
    for s in ("ho+ld", "ho+mf"):
        for p in ("1", "mse"):
            rows = res.curves[s][p]
            assert [r.lam for r in rows] == list(LP["lambdas"])
            assert all(r.L_e > 0 and math.isfinite(r.m_c) for r in rows)
    # HO+LD: above λ=1 the UAN is switched off
    for r in res.alignment.by_p["1"]:
        if r.lam > 1:
            assert r.fn_rms < 0.05 * res.alignment.fn_true_rms
    f = res.alignment.forces["1"]
    assert [a.lam for a in f.by_lambda] == [0.1, 0.5, 2.0, 10.0] and len(f.q) == len(f.by_lambda[2].fn) == 400
    assert sorted(f.to_dict()["by_lambda"]) == ["0.1", "0.5", "10", "2"]
    for c in res.claims:
        assert set(c.to_dict()) == {"claim", "ours", "met"} and isinstance(c.met, bool)
    assert any("MSE" in c.claim for c in res.claims) and any("no jump" in c.claim for c in res.claims)
    # each claim's verdict, from the numbers asserted above or recomputed from the curves and verdicts it quotes
    curves, by_p1 = res.curves["ho+ld"], res.alignment.by_p["1"]

    def aligned(p):  # m_c, m_n ≤ 0.05 at every λ of 0.05 ≤ λ < 1
        return max(max(r.m_c, r.m_n) for r in curves[p] if 0.05 <= r.lam < 1) <= 0.05

    expected = [
        True,  # HO+LD, p = 1: new physics (asserted above)
        v[("ho+ld", "1")].transition == "jump",
        True,  # HO+MF, p = 1: no new physics (asserted above)
        v[("ho+mf", "1")].ratio < 1,
        v[("ho+ld", "mse")].transition == "smooth",
        aligned("1"),
        aligned("mse"),
        True,  # HO+LD, p = 1, λ > 1: f_n rms ≤ 0.1 × the truth's (asserted above with 0.05 ×)
        all(r.m_c <= 0.05 for r in by_p1 if r.lam > 1),
    ]
    assert [c.met for c in res.claims] == expected, res.claims
    assert not res.cached
    assert calls[-1] == (20, 20) and [d for d, _ in calls] == sorted(d for d, _ in calls)
    for name in ("results.json", "fig5.png", "fig5_forces.png"):
        assert (out / name).stat().st_size > 1000
    assert (out / "runs" / "ho+ld_pmse" / "results.json").exists()
    saved = json.loads((out / "results.json").read_text())
    assert saved == res.to_dict() and saved["settings"]["steps_per_lambda"] == 200
    assert LambdaPResult.from_dict(saved) == res  # results.json reads back as the result returned


@pytest.mark.slow  # needs the λ/p study run (~40 s): slow tier (`python3 dev.py test --slow`, and CI)
def test_lambda_p_subrun_is_nnphd_sweep(lp):
    """Same seed → same numbers: a sub-run reproduces `nnphd sweep` (run_sweep) exactly."""
    _, res, _ = lp
    ref = run_sweep("ho+ld", SweepSettings(p=1, steps=LP["steps"], seed=LP["seed"], lambdas=LP["lambdas"]))
    assert [r.L_e for r in res.curves["ho+ld"]["1"]] == [r.L_e for r in ref.table]
    assert [r.m_c for r in res.curves["ho+ld"]["1"]] == [r.m_c for r in ref.table]


@pytest.mark.slow  # an end-to-end run of tens of seconds: slow tier (`python3 dev.py test --slow`, and CI)
def test_lambda_p_cached_rerun_and_cli(lp, capsys):
    out, res, _ = lp
    again = lambda_p_study(LambdaPSettings(**LP), out=out)
    assert sorted(again.cached) == ["ho+ld/p=1", "ho+ld/p=mse", "ho+mf/p=1", "ho+mf/p=mse"]
    assert again.curves == res.curves and again.claims == res.claims
    assert [v.ratio for v in again.verdicts] == [v.ratio for v in res.verdicts]
    (out / "results.json").unlink()
    rc = main(
        [
            "study",
            "lambda-p",
            "--steps",
            "200",
            "--seed",
            "0",
            "--lambdas",
            "0.1,0.5,2,10,50",
            "--ps",
            "1,mse",
            "--systems",
            "ho+ld,ho+mf",
            "--out",
            str(out),
        ]
    )
    assert rc == 0
    text = capsys.readouterr().out
    assert "loaded 4 of 4 sweeps from the cache" in text and "verdicts" in text
    saved = json.loads((out / "results.json").read_text())
    assert saved["curves"] == res.to_dict()["curves"]
    _assert_claims_printed(text, saved["claims"])


def _assert_claims_printed(text: str, claims: list[dict]) -> None:
    """Each claim of results.json printed once, as "met: …" or "not met: …" with our numbers, as judged there."""
    flat = " ".join(text.split())  # the console wraps long lines
    assert len(re.findall(r"\b(?:not )?met: ", flat)) == len(claims) > 0, text
    for c in claims:
        line = f"met: {c['claim']} — {c['ours']}"
        assert (f"not {line}" in flat) is not c["met"] and line in flat, (c, text)


# ---- data-quality study ---------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def dq(tmp_path_factory):
    out = tmp_path_factory.mktemp("dq")
    return out, data_quality_study(DataQualitySettings(**DQ), out=out)


@pytest.mark.slow  # needs the data-quality study run: slow tier (`python3 dev.py test --slow`, and CI)
def test_data_quality_coverage_and_imbalance(dq):
    out, res = dq
    assert isinstance(res, DataQualityResult)
    a = {r.alpha: r for r in res.alpha.table}
    # q̇ ≥ 0 only (α = 0.25): constant damping looks conservative → L_e ≈ 0; full plane: L_e ≈ ‖f_n‖₁ = 0.5
    assert a[0.25].L_e < 0.05 and a[1.0].L_e > 0.25
    assert a[1.0].L_e > 10 * a[0.25].L_e
    # …but only on the data's own distribution: on the full plane the half-plane model is wrong
    assert a[0.25].L_e_full > 5 * a[0.25].L_e
    b = {r.beta: r for r in res.beta.table}
    assert b[0.5].frac_qd_pos == 0.5 and b[1.0].frac_qd_pos == 1.0
    assert all(
        math.isfinite(getattr(r, k)) and getattr(r, k) >= 0
        for r in b.values()
        for k in ("m_c", "m_n", "m_c_full", "m_n_full")
    )
    # λ = 10 > 1 switches the UAN off (Theorem 1): f_n^NN ≈ 0, so m_n = rms(f_n^PHY) = ½ exactly for HO+CD, whose
    # f_n = −½ sgn q̇ has size ½ at every sample (measured 0.50004, 0.49985; the UAN's output L_b is ~1e-3)
    assert all(r.m_n == pytest.approx(0.5, abs=0.01) for r in a.values())
    # imbalance: with every q̇ > 0 (β = 1) the split is not pinned down (a Lagrangian can absorb part of the damping
    # on one side of q̇ = 0), balanced data (β = 0.5) pins it (paper Fig. 6b; measured m_c, m_n 0.055 at β = 0.5,
    # 0.33 at β = 1)
    assert all(3 * getattr(b[0.5], k) < getattr(b[1.0], k) for k in ("m_c", "m_n"))
    # …and the one-sided model's f_n is wrong on the half it never saw: worse on the full plane than on its own data
    # (measured 0.62 vs 0.33), while β = 0.5 draws from the full plane's own distribution (measured 0.0548 vs 0.0547)
    assert b[1.0].m_n_full > 1.5 * b[1.0].m_n
    assert all(getattr(b[0.5], f"{k}_full") == pytest.approx(getattr(b[0.5], k), rel=0.2) for k in ("m_c", "m_n"))
    for c in res.claims:
        assert set(c.to_dict()) == {"claim", "ours", "met"} and isinstance(c.met, bool)
    assert len(res.claims) == 5  # α: nearly zero, median jump, strict jump; β: minimum at 0.5, nearly zero there
    # the first four follow from the assertions above (L_e(0.25) < 0.05 = 0.1 × ‖f_n‖₁; L_e(1) > 10 × L_e(0.25) ≥ 3 ×,
    # median and strict; m_c, m_n smallest at β = 0.5); the fifth is m_c, m_n ≤ 0.05 at β = 0.5, read off the table
    near_zero = max(b[0.5].m_c, b[0.5].m_n) <= 0.05
    assert [c.met for c in res.claims] == [True, True, True, True, near_zero], res.claims
    for name in ("results.json", "fig6.png", "alpha.json", "beta.json"):
        assert (out / name).stat().st_size > 500
    assert not res.cached
    saved = json.loads((out / "results.json").read_text())
    assert saved == res.to_dict() and DataQualityResult.from_dict(saved) == res


@pytest.mark.slow  # needs the data-quality study run: slow tier (`python3 dev.py test --slow`, and CI)
def test_data_quality_cached_rerun(dq):
    out, res = dq
    again = data_quality_study(DataQualitySettings(**DQ), out=out)
    assert again.cached == ("alpha", "beta")
    assert again.alpha.table == res.alpha.table and again.beta.table == res.beta.table
    assert again.claims == res.claims


@pytest.mark.slow  # tens of seconds: run by `python3 dev.py test --slow` (and by CI)
def test_data_quality_cli_same_seed_same_numbers(dq, tmp_path, capsys):
    _, res = dq
    out = tmp_path / "cli"
    rc = main(
        [
            "study",
            "data-quality",
            "--steps",
            "300",
            "--seed",
            "1",
            "--alphas",
            "0.25,1",
            "--betas",
            "0.5,1",
            "--out",
            str(out),
        ]
    )
    assert rc == 0
    text = capsys.readouterr().out
    assert "pie coverage" in text and "imbalance" in text and "wrote" in text
    got = json.loads((out / "results.json").read_text())
    d = res.to_dict()
    assert got["alpha"]["table"] == d["alpha"]["table"] and got["beta"]["table"] == d["beta"]["table"]
    assert (out / "fig6.png").stat().st_size > 1000


# ---- bad input ----------------------------------------------------------------------------------------------------
BAD = [
    (["study", "lambda-p", "--steps", "0"], "Invalid value for '--steps': Input should be greater than or equal to 4"),
    (["study", "lambda-p", "--seed", "-1"], "Invalid value for '--seed': Input should be greater than or equal to 0"),
    (["study", "lambda-p", "--systems", "ho+xx"], "--systems must be among"),
    (["study", "lambda-p", "--systems", "gw"], "--systems must be among"),
    (["study", "lambda-p", "--systems", "ho+ld,,ho+mf"], "--systems must be a comma-separated list"),
    (["study", "lambda-p", "--systems", "ho+ld,ho+ld"], "must not repeat"),
    (["study", "lambda-p", "--ps", "0.5"], "p must be a number ≥ 1 or 'mse'"),
    (["study", "lambda-p", "--lambdas", "0.2,0.5"], "both below and above 1"),
    (["study", "data-quality", "--steps", "abc"], "Invalid value for '--steps': Input should be a valid integer"),
    (["study", "data-quality", "--alphas", "0.5,1.5"], "--alphas must be comma-separated numbers in [0, 1]"),
    (["study", "data-quality", "--betas", "x"], "--betas must be comma-separated numbers in [0, 1]"),
    (["study", "data-quality", "--wat"], "No such option"),
]


@pytest.mark.parametrize("argv,msg", BAD)
def test_study_bad_input_exit_2(argv, msg, tmp_path, capsys):
    out = tmp_path / "never"
    assert main(argv + ["--out", str(out)]) == 2
    lines = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: ") and msg in lines[0], lines
    assert not out.exists()


def test_api_rejects_bad_settings():
    with pytest.raises(ValueError, match="toy systems"):
        lambda_p_study(LambdaPSettings(systems=("gw",)))
    with pytest.raises(ValueError, match="below and above 1"):
        lambda_p_study(LambdaPSettings(lambdas=(2.0, 5.0)))
    with pytest.raises(ValueError, match="alphas"):
        data_quality_study(DataQualitySettings(alphas=(1.2,)))


def test_the_forces_figure_says_so_when_no_forces_were_stored():
    """A λ grid without any of force_lambdas stores no learned forces (None): the figure says so instead of raising
    (it raised TypeError before)."""
    from nnphd.paper.figures import plot_fig5_forces

    fig = plot_fig5_forces({"settings": {"ps": [1, 2]}, "alignment": {"forces": {1: None, 2: None}}})
    texts = [t.get_text() for ax in fig.axes for t in ax.texts]
    assert len(texts) == 4 and all("no learned forces" in t for t in texts)
    assert all(not ax.axison for ax in fig.axes)
