"""A declared uniform field (``field="uniform"``, ``--field uniform``): the verdict and the law of motion that does
not oscillate (a throw, a fall) rest on a fit of the positions beside a uniform field. The rules on hand-made law
tables (fast); the fitted field against gravity, and the whole pipeline on throws and falls with known drag (slow)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from nnphd.explain.work import against_velocity
from nnphd.io.errors import DataError
from nnphd.user.rules import (
    DRAG_ALONG_MIN,
    FIELD_FIT_MSE,
    LAW_DETECT_CONFIDENCE,
    LAW_DETECT_DIC,
    declared_field_decides,
    declared_field_effect,
    declared_field_verdict,
    reconcile,
)
from nnphd.user.settings import check_field
from tests.test_nonoscillating import G, _csv, _throw


def _row(key, dic, ratio, mse, significant=True):
    title = {"none": "no law", "quadratic": "quadratic drag −c |q̇| q̇"}.get(key, key)
    return {"law": key, "title": title, "delta_ic": dic, "heldout_ratio": ratio, "heldout_mse": mse,
            "significant": significant, "method": "trajectory"}  # fmt: skip


def _table(zero_mse=3.1, win=(-190.0, 0.52, 0.84), claimed=True, significant=True):
    """A law table of a throw with drag beside the uniform field (the numbers of the 2-D throw look-alike)."""
    w = _row("quadratic", *win, significant=significant)
    rows = [w, _row("none", 0.0, 1.0, zero_mse)]
    return {"law": w if claimed else None, "status": "claimed" if claimed else "none", "ties": [], "reason": "",
            "candidates": sorted(rows, key=lambda r: r["delta_ic"])}  # fmt: skip


def test_a_decisive_law_that_fits_to_the_noise_beside_the_field_is_detected():
    status, conf, why = declared_field_verdict(_table())
    assert (status, conf) == ("detected", LAW_DETECT_CONFIDENCE)
    assert "quadratic drag" in why and "ΔIC = -190.0" in why and "χ²/N = 0.84" in why and "χ²/N = 3.10" in why
    assert "rests on the declared uniform field" in why  # the verdict names what it assumes


@pytest.mark.parametrize(
    "table, status, words",
    [
        # the field alone fits to the noise and no law helps: none
        (_table(zero_mse=0.9, win=(2.0, 0.99, 0.88), claimed=False), "none", "alone explains the motion"),
        # a law short of decisive: inconclusive, never a confident "none" or "detected"
        (_table(zero_mse=1.1, win=(LAW_DETECT_DIC + 2, 0.9, 0.95)), "inconclusive", "not decisively"),
        # the best law does not reach the noise: the declaration (or the candidate set) is wrong
        (_table(zero_mse=40.0, win=(-300.0, 0.3, FIELD_FIT_MSE + 1)), "inconclusive", "does not explain the record"),
        # neither does the field alone, and nothing beats it: the field is not uniform
        (
            _table(zero_mse=FIELD_FIT_MSE + 1, win=(3.0, 1.0, FIELD_FIT_MSE + 1), claimed=False),
            "inconclusive",
            "does not explain the record",
        ),  # fmt: skip
        # a strong row with a term that is not significant is no law to claim, and no "none" either
        (_table(claimed=False, significant=False), "inconclusive", "every term significant"),
    ],
)
def test_the_field_alone_explains_or_the_data_cannot_decide(table, status, words):
    s, _, why = declared_field_verdict(table)
    assert s == status and words in why


def test_without_a_fit_of_the_positions_there_is_no_verdict_on_a_declared_field():
    t = _table()
    for r in t["candidates"]:
        r["method"] = "pointwise"
    assert declared_field_verdict(t)[0] == "inconclusive"
    assert declared_field_verdict({"candidates": [], "reason": "too short"})[0] == "inconclusive"


def _report(status="inconclusive", oscillating=False, library_law=None):
    lib = {"base": "the conservative library", "status": "tie", "law": library_law}
    return {
        "status": status,
        "new_physics": False,
        "confidence": 1.0,
        "reasons": ["seed 0: the motion does not oscillate"],
        "quality": {"usable": True, "oscillating": oscillating},
        "checks": {"per_seed": [{"status": status}]},
    }, lib


def test_the_share_of_a_force_that_opposes_the_velocity_is_one_for_a_drag_and_not_for_a_field():
    rng = np.random.default_rng(0)
    v = rng.standard_normal((200, 2))
    speed = np.linalg.norm(v, axis=1, keepdims=True)
    assert against_velocity(-0.3 * v, v) == pytest.approx(1.0)  # linear drag
    assert against_velocity(-0.02 * speed * v, v) == pytest.approx(1.0)  # quadratic drag
    assert against_velocity(0.5 * v / speed, v) == pytest.approx(-1.0)  # a thrust
    assert against_velocity(np.c_[-v[:, 1], v[:, 0]], v) == pytest.approx(0.0, abs=1e-12)  # a lift, across v
    # the remainder of a field that varies over the record, g(q) − g(q0) = −k (q − q0), along straight-line motion
    # from q0: it opposes the displacement, and the velocity only on the way out — half along, half against
    t = np.linspace(-1, 1, 201)[:, None]
    vel = np.tile([[1.0, 0.5]], (201, 1))
    assert against_velocity(-2.0 * t * vel, vel) == pytest.approx(0.0, abs=1e-12)
    assert against_velocity(np.zeros((5, 2)), v[:5]) is None and against_velocity(v[:5], np.zeros((5, 2))) is None
    # rows at rest do not count; a 1-D fall's drag opposes the velocity wherever it moves
    vz = np.r_[np.zeros(10), -np.linspace(0.1, 5, 90)][:, None]
    assert against_velocity(-0.05 * np.abs(vz) * vz + np.r_[np.full(10, 7.0), np.zeros(90)][:, None], vz) == 1.0


def test_a_decisive_law_that_does_not_oppose_the_velocity_is_no_drag_and_decides_nothing():
    """A 1/r² field declared uniform: the arc's remainder fits a law that fits to the noise and beats the field alone
    decisively, yet it does not oppose the velocity — the declaration may be wrong, so the verdict is "inconclusive"
    with the reason; a law that opposes it is "detected" as before."""
    for along, status in (
        (0.3, "inconclusive"),
        (-0.85, "inconclusive"),
        (DRAG_ALONG_MIN, "detected"),
        (1.0, "detected"),
    ):
        t = _table()
        t["against_velocity"] = along
        s, conf, why = declared_field_verdict(t)
        assert s == status, (along, why)
        if status == "inconclusive":
            assert conf == 1.0 and "no drag" in why and f"only {100 * along:.0f}% of it opposes" in why
            assert "check that the field is uniform" in why
    t = _table(zero_mse=0.9, win=(2.0, 0.99, 0.88), claimed=False)  # no decisive law: the share plays no part
    t["against_velocity"] = -1.0
    assert declared_field_verdict(t)[0] == "none"


def test_reconcile_lets_the_declared_field_decide_and_withholds_a_law_it_does_not_detect():
    res, _ = _report()
    law = _table()
    assert declared_field_decides(res, "uniform") and not declared_field_decides(res, "learned")
    effect = declared_field_effect(law)
    status, new, conf, reasons, kept = reconcile(res, law, "uniform")
    assert (status, new, conf) == ("detected", True, LAW_DETECT_CONFIDENCE) and kept["law"]["law"] == "quadratic"
    assert reasons[0].startswith("beside the declared uniform field") and reasons[1] == res["reasons"][0]
    assert effect == (
        "beside the declared uniform field, quadratic drag −c |q̇| q̇ lowers the error of the fit of the positions by "
        "48% (χ²/N 3.10 → 0.84, ΔIC = -190.0)"
    )
    law = _table(zero_mse=0.9, win=(2.0, 0.99, 0.88), claimed=False)
    assert reconcile(res, law, "uniform")[:2] == ("none", False)
    law = _table(zero_mse=1.1, win=(LAW_DETECT_DIC + 2, 0.9, 0.95))
    verdict = reconcile(res, law, "uniform")
    assert verdict.status == "inconclusive" and law["law"]["law"] == "quadratic"  # the table handed in: as it was
    kept = verdict.law
    assert kept["law"] is None and kept["candidate_law"]["law"] == "quadratic"  # no law claimed on "inconclusive"


def test_an_undeclared_arc_says_what_would_decide_without_deciding():
    strong = {"law": "quadratic", "title": "quadratic drag", "delta_ic": -191.3, "heldout_ratio": 0.52}
    for lib_law, hint in ((strong, True), (dict(strong, delta_ic=LAW_DETECT_DIC + 1), False), (None, False)):
        res, lib = _report(library_law=lib_law)
        law = {"law": None, "status": "none", "ties": [], "reason": "", "settings": {"bases": [lib]}}
        status, _, _, reasons, _ = reconcile(res, law)
        assert status == "inconclusive"  # a hint is no evidence: the verdict is unchanged
        assert ("--field uniform" in reasons[-1] and "48%" in reasons[-1]) == hint
    res, lib = _report(oscillating=True, library_law=strong)  # an oscillation has its own evidence: no hint
    law = {"law": None, "status": "none", "ties": [], "reason": "", "settings": {"bases": [lib]}}
    assert "--field" not in " ".join(reconcile(res, law)[3])


def test_bad_field_settings_are_refused_with_what_is_expected():
    check_field("learned")
    check_field("uniform", "trajectory")
    check_field("vertical", "auto")
    with pytest.raises(ValueError, match="field must be one of 'learned', 'uniform', 'vertical', got 'gravity'"):
        check_field("gravity")
    with pytest.raises(ValueError, match="law_fit must be 'auto' or 'trajectory'"):
        check_field("vertical", "pointwise")
    with pytest.raises(ValueError, match="law_fit must be 'auto' or 'trajectory'"):
        check_field("uniform", "pointwise")


def _userdata(tmp_path, t, q, names):
    from nnphd.user.recording import load_trajectories

    return load_trajectories(_csv(tmp_path / "r.csv", t, q, names))


def test_a_throw_does_not_oscillate_and_a_declared_field_refuses_one_that_does(tmp_path):
    from nnphd.user.assess import motion_period
    from nnphd.user.derivatives import Derivatives
    from nnphd.user.settings import check_declared_field

    t, _, _, _, noisy = _throw()
    ud = _userdata(tmp_path, t, noisy, ("x", "y"))
    d = Derivatives().dataset(ud)
    data, info = d.data, d.info
    assert motion_period(data) == np.inf
    check_declared_field("uniform", data, None, ud, info)  # a throw: accepted
    tt = np.arange(600) / 50.0  # a damped oscillation of period 2: refused before any training
    q = (np.exp(-0.05 * tt) * np.cos(np.pi * tt))[:, None] + 1e-3 * np.random.default_rng(0).standard_normal((600, 1))
    ud = _userdata(tmp_path, tt, q, ("x",))
    d = Derivatives().dataset(ud)
    data, info = d.data, d.info
    assert motion_period(data) == pytest.approx(2.0, rel=0.05)
    check_declared_field("learned", data, None, ud, info)
    with pytest.raises(
        DataError, match=r"declared uniform, under which nothing oscillates.*\(period 2 in its time unit\)"
    ):
        check_declared_field("uniform", data, None, ud, info)


def test_a_vertical_field_is_one_column_along_the_last_coordinate():
    """``library="vertical"``: the uniform field along the last coordinate alone — the gradient ∂(u_y)/∂y = 1/s_y of
    the potential monomial u_y = (y − m_y)/s_y (positions standardised: centre m, scale s; its coefficient carries
    the sign) — where "minimal" has one column per coordinate."""
    from nnphd.explain.conservative import conservative_basis

    q = np.array([[0.0, 2.0], [1.0, 3.5], [4.0, -1.0]])
    center = (np.array([1.0, 1.0]), np.array([2.0, 4.0]))
    B = conservative_basis(np, q, np.zeros_like(q), [False, False], None, center, "vertical")
    assert B.shape == (3, 2, 1)
    np.testing.assert_allclose(B[:, :, 0], np.tile([0.0, 0.25], (3, 1)))
    M = conservative_basis(np, q, np.zeros_like(q), [False, False], None, center, "minimal")
    assert M.shape == (3, 2, 2)
    np.testing.assert_allclose(M[:, :, 1], B[:, :, 0])  # minimal's y column is the vertical field


# ------------------------------------------------------------------------------------------------------------------
# the fits and the pipeline (slow: trajectory-level fits and training)


@pytest.mark.slow  # two trajectory-level law tables, ~25 s
def test_the_fitted_field_is_gravity_and_the_drag_is_the_truth(tmp_path):
    from nnphd.explain.search import LawRun, find_law, fitted_field
    from nnphd.user.derivatives import Derivatives

    for c in (0.0, 0.012):
        t, _, _, _, noisy = _throw(c=c)
        ud = _userdata(tmp_path, t, noisy, ("x", "y"))
        d = Derivatives().dataset(ud)
        data, info, row_err = d.data, d.info, d.row_errors
        run = LawRun(np.zeros(len(data.t), int), ("x", "y"), (False, False), info, row_err, field="uniform")
        tab = find_law(data, run)
        assert tab.settings["library"] == "minimal"
        zero = next(r for r in tab.rows if r.key == "none")
        law = tab.law if c else zero
        f = fitted_field(tab, law, ["x", "y"], [False, False], data.q)
        for k, g in (("x", 0.0), ("y", -G)):  # gravity within 4 standard errors and 0.3 % of g
            assert abs(f["g"][k] - g) <= max(4 * f["stderr"][k], 0.003 * G), (c, f)
        if c:
            assert law.key == "quadratic" and law.params["c"] == pytest.approx(c, rel=0.15)
        else:
            assert tab.law is None


@pytest.mark.slow  # one trajectory-level law table per seed, ~10 s each
def test_a_vertical_field_decides_the_throw_look_alike_where_a_free_direction_ties(tmp_path):
    """The 2-D throw look-alike (60 fps, 1.2 s, quadratic drag c = 0.021, 3 mm noise), seed 2: beside a uniform field of
    free direction linear drag is Δχ² 10 behind quadratic in a whole-trajectory fit, with the field vertical 23 (seeds
    0, 1: −1.9 / 8.6 and 5.2 / 6.5). Declared vertical: quadratic drag is claimed within 5 % and the field has no x
    component (it is not fitted)."""
    from nnphd.explain.search import LawRun, find_law, fitted_field
    from nnphd.user.derivatives import Derivatives
    from nnphd.user.recording import load_trajectories
    from tests.fixtures import friction as F

    rec = F.make("throw-2d", seed=2)
    ud = load_trajectories(rec.write_csv(tmp_path / "throw.csv"), rec.angles)
    d = Derivatives().dataset(ud)
    data, info, row_err = d.data, d.info, d.row_errors
    traj = np.zeros(len(data.t), int)
    tab = find_law(data, LawRun(traj, ("x", "y"), (False, False), info, row_err, field="vertical"))
    assert tab.settings["library"] == "vertical" and tab.settings["conservative_columns"] == 1
    assert tab.status == "claimed" and tab.law.key == "quadratic", tab.reason
    assert tab.law.params["c"] == pytest.approx(0.021, rel=0.05)
    f = fitted_field(tab, tab.law, ["x", "y"], [False, False], data.q)
    assert f["g"]["x"] == 0.0 and abs(f["g"]["y"] + 9.81) <= max(4 * f["stderr"]["y"], 0.003 * 9.81), f


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    """NNPhD with a declared uniform field on a throw with drag, one without, and a fall (300 steps, one seed)."""
    import nnphd

    out = {}
    d = tmp_path_factory.mktemp("declared")
    for name, c, v0, cols in (("drag", 0.012, 8.0, (0, 1)), ("no-drag", 0.0, 8.0, (0, 1)), ("fall", 0.05, 0.0, (1,))):
        t, q, v, _, noisy = _throw(c=c, v0=v0)
        names = ("x", "y")[cols[0] :]
        data = nnphd.Trajectories.from_csv(_csv(d / f"{name}.csv", t, noisy[:, list(cols)], names))
        m = nnphd.NNPhD(seed=0, steps=300, n_seeds=1, field="uniform").fit(data)
        out[name] = (m, t, q[:, list(cols)], v[:, list(cols)])
    t, q, noisy = _kepler_arc(20.0)
    data = nnphd.Trajectories.from_csv(_csv(d / "arc.csv", t, noisy, ("x", "y")))
    out["arc"] = (nnphd.NNPhD(seed=0, steps=300, n_seeds=1, field="uniform").fit(data), t, q, None)
    return out


def _kepler_arc(R, seed=0):
    """(t, positions, noisy positions) of the throw of :func:`_throw` without drag in a 1/r² field about a centre R
    below the release (g there): a field that varies over the record, wrongly declared uniform."""
    from scipy.integrate import solve_ivp

    def rhs(_, s):
        d = np.array([s[0], s[1] + R])
        return [s[2], s[3], *(-G * R * R * d / np.linalg.norm(d) ** 3)]

    t, _, _, _, _ = _throw()
    s0 = [0.0, 0.0, 8.0 * np.cos(np.radians(50.0)), 8.0 * np.sin(np.radians(50.0))]
    q = solve_ivp(rhs, (0, t[-1]), s0, t_eval=t, rtol=1e-11, atol=1e-12).y[:2].T
    return t, q, q + 0.002 * np.random.default_rng(seed).standard_normal(q.shape)


@pytest.mark.slow  # four fits of ~15 s
def test_declared_field_verdicts_and_laws_on_throws_and_falls(fitted):
    m, *_ = fitted["drag"]
    assert m.status_ == "detected" and m.report_["field"]["kind"] == "uniform"
    assert m.report_["law"]["status"] in ("claimed", "tie")
    fams = [m.law_.key] + [r["law"] for r in m.report_["law"]["ties"]]
    assert "quadratic" in fams  # the truth is claimed or in the tie (linear drag ties it on some noise draws)
    assert fitted["no-drag"][0].status_ == "none" and fitted["no-drag"][0].law_ is None
    fall = fitted["fall"][0]
    assert fall.status_ == "detected" and fall.law_.params["c"] == pytest.approx(0.05, rel=0.05)
    assert fall.report_["field"]["g"]["y"] == pytest.approx(-G, rel=0.01)
    assert m.report_["field"]["against_velocity"] == pytest.approx(1.0)
    assert fall.report_["field"]["against_velocity"] == pytest.approx(1.0)
    # a 1/r² field declared uniform (R = 20 m): a law fits its remainder decisively, but it is no drag — not believed
    arc = fitted["arc"][0]
    assert arc.status_ == "inconclusive" and arc.law_ is None and "no drag" in arc.report_["reasons"][0]
    assert arc.report_["field"]["against_velocity"] < DRAG_ALONG_MIN


@pytest.mark.slow
def test_the_model_of_a_declared_field_predicts_with_it_and_survives_save_and_load(fitted, tmp_path):
    import nnphd

    m, t, q, v = fitted["fall"]
    fc, fn = m.forces(q, v)
    assert np.allclose(fc, m.report_["field"]["g"]["y"])  # the fitted field, not the LNN (which absorbed the drag)
    qs, _ = m.simulate(q[0], v[0], t)
    assert np.max(np.abs(qs - q)) < 0.02  # 1.2 s of a fall with drag, to 2 cm (the noise is 2 mm)
    path = m.save(tmp_path / "fall.npz")
    back = nnphd.load(path)
    assert back.field == "uniform" and np.allclose(back.forces(q, v)[0], fc) and np.allclose(back.forces(q, v)[1], fn)
    meta = json.loads(str(np.load(path)["meta"]))
    assert meta["field"]["law"] == "quadratic" and meta["settings"]["field"] == "uniform"
    html = (m.report(tmp_path / "rep") / "report.html").read_text()
    back = nnphd.read_report(tmp_path / "rep" / "report.json")  # the report file, typed again
    assert back.status == m.status_ == "detected" and back.law.key == m.law_.key == "quadratic"
    assert back.field["g"] == m.report_["field"]["g"] and back.timings["stages"]
    assert "<b>Conservative force:</b> declared uniform" in html and "fitted beside quadratic" in html
    assert "declared uniform field f_c" in str(m.figures()["forces"].axes[0].get_title())


def test_the_cli_refuses_a_declared_uniform_field_on_an_oscillation_in_one_line(tmp_path, capsys):
    from nnphd.cli import main

    tt = np.arange(600) / 50.0
    q = (np.exp(-0.05 * tt) * np.cos(np.pi * tt))[:, None]
    path = _csv(tmp_path / "osc.csv", tt, q, ("x",))
    assert main(["detect", str(path), "--field", "uniform", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "nothing oscillates" in err and "Traceback" not in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "o").exists()  # nothing half-written
    assert main(["detect", str(path), "--field", "gravity", "--out", str(tmp_path / "o")]) == 2
    assert main(["detect", str(path), "--field", "uniform", "--law-fit", "pointwise"]) == 2
    assert "law_fit must be 'auto' or 'trajectory'" in capsys.readouterr().err
