"""A stuck phase as evidence about the law (:mod:`nnphd.explain.stuck`): the rule on hand-made law tables."""

from __future__ import annotations

import math

import numpy as np
import pytest

from nnphd.explain.families import families
from nnphd.explain.stuck import OFFSET_MIN, Z_STUCK, bar_stuck, holds_at_rest, stuck_contradictions
from nnphd.explain.table import LawTable, law_row, zero_row

A = 50.0  # a pendulum −A sin θ about θ = 0 ("short" library: f_c = α₀ cos θ − α₁ sin θ)


def _row(key, beta, ic, cons=(0.0, A), se_cons=0.01):
    fam = next(f for f in families(1, ["th"], np.ones(1)) if f.key == key)
    beta = np.asarray(beta, float)
    r = law_row(fam, beta, np.zeros(len(fam.nl_names)), 0.01 * np.ones(len(beta) + len(fam.nl_names)), ["th"], 1.0,
                 "trajectory")  # fmt: skip
    r.ic = r.delta_ic = ic
    r.conservative = np.asarray(cons, float)
    r.conservative_cov = se_cons**2 * np.eye(2)
    return r


def _table(rows):
    zero = zero_row(["th"], 1.0, 10, "trajectory")
    zero.ic = zero.delta_ic = 0.0
    settings = {"method": "trajectory", "names": ["th"], "library": "short"}
    best = min(rows, key=lambda r: r.ic)
    return LawTable([best, zero, *(r for r in rows if r is not best)], best, "r", 10.0, 1.0, "f", settings)


def _at(q, tol=1e-3, seconds=1.5):
    return [{"q": [q], "seconds": seconds, "tolerance": [tol]}]


def test_only_a_law_with_a_dry_term_holds_a_body_at_rest():
    assert holds_at_rest(_row("coulomb", [1.0], -10.0))
    assert holds_at_rest(_row("linear+coulomb", [0.3, 1.0], -10.0))
    for key, beta in (("linear", [0.3]), ("quadratic", [0.1]), ("rayleigh", [0.1, 0.01]), ("vanderpol", [-0.1, 1.0])):
        assert not holds_at_rest(_row(key, beta, -10.0))


def test_a_rest_off_the_equilibrium_contradicts_the_laws_without_a_dry_term():
    lin, dry = _row("linear", [3.0], -20.0), _row("linear+coulomb", [2.9, 0.9], -18.0)
    table = _table([lin, dry])
    # at rest 0.02 rad off: f_c = −50 sin 0.02 = −1.0 ± 0.01 · |(cos, −sin)| — 100 se, 20 tolerances off
    out = stuck_contradictions(table, _at(0.02), angles=(True,))
    assert set(out) == {"linear"}
    c = out["linear"]
    assert c["force"] == pytest.approx(-A * math.sin(0.02), rel=1e-9)
    assert c["offset"] == pytest.approx(math.tan(0.02), rel=1e-3)  # |f_c| / |∂f_c/∂θ| = tan θ
    assert c["se"] == pytest.approx(0.01 * math.hypot(math.cos(0.02), math.sin(0.02)), rel=1e-9)
    # the equilibrium itself, or within OFFSET_MIN tolerances of it: no contradiction
    assert stuck_contradictions(table, _at(0.0), angles=(True,)) == {}
    assert stuck_contradictions(table, _at(0.9 * OFFSET_MIN * 1e-3), angles=(True,)) == {}
    assert "linear" in stuck_contradictions(table, _at(1.1 * OFFSET_MIN * 1e-3), angles=(True,))
    # the equilibrium poorly known (the force at the rest within Z_STUCK se of zero): no contradiction
    vague = _table([_row("linear", [3.0], -20.0, se_cons=A * 0.02 / (0.9 * Z_STUCK)), dry])
    assert stuck_contradictions(vague, _at(0.02), angles=(True,)) == {}
    # a shifted equilibrium (α₀ cos θ − α₁ sin θ = 0 at θ = atan(α₀/α₁)): resting there is fine
    eq = 0.02
    shifted = _table([_row("linear", [3.0], -20.0, cons=(A * math.sin(eq), A * math.cos(eq))), dry])
    assert stuck_contradictions(shifted, _at(eq), angles=(True,)) == {}
    # a pointwise table or no stuck stretch: nothing to judge
    assert stuck_contradictions(table, [], angles=(True,)) == {}
    pointwise = _table([lin, dry])
    pointwise.settings["method"] = "pointwise"
    assert stuck_contradictions(pointwise, _at(0.02), angles=(True,)) == {}


def test_a_contradicted_law_loses_to_the_best_law_that_can_hold_the_body():
    lin, dry = _row("linear", [3.0], -20.0), _row("linear+coulomb", [2.9, 0.9], -18.0)
    ray = _row("rayleigh", [3.0, 0.01], -17.0)
    table = _table([lin, dry, ray])
    assert table.law is lin
    out = bar_stuck(table, stuck_contradictions(table, _at(0.02), angles=(True,)))
    assert out.law.key == "linear+coulomb" and out.ties == []
    barred = {r.key: r for r in out.rows}
    assert not barred["linear"].significant and not barred["rayleigh"].significant
    assert barred["linear"].stuck["seconds"] == 1.5 and "stuck" in barred["linear"].to_dict()
    assert "nothing in them acts at zero speed: linear, rayleigh" in out.reason
    assert bar_stuck(table, {}) is table


def test_no_stable_equilibrium_at_the_rest_means_nothing_to_judge():
    # a uniform field (slope 0) or a hilltop (slope > 0): a rest there says nothing about the friction law
    hill = _table([_row("linear", [3.0], -20.0, cons=(0.0, -A)), _row("linear+coulomb", [2.9, 0.9], -18.0)])
    assert stuck_contradictions(hill, _at(0.02), angles=(True,)) == {}


def test_only_a_rest_that_ends_its_trajectory_is_evidence():
    """A pendulum held at 0.3 rad for a second before its release, then swinging down with dry friction to rest at
    0.02 rad: only the final rest is the body's own (the first was a hand)."""
    from types import SimpleNamespace

    from nnphd.explain.search import moving_rows

    dt, w2, mu, gam = 0.01, 40.0, 0.8, 0.3
    q, v, qs = 0.3, 0.0, [0.3] * 100
    for _ in range(900):
        f = -w2 * q - gam * v - mu * np.sign(v) if abs(v) > 1e-9 or abs(w2 * q) > mu else 0.0
        v_new = v + f * dt
        v = 0.0 if v != 0 and np.sign(v_new) != np.sign(v) and abs(w2 * q) <= mu else v_new
        q += v * dt
        qs.append(q)
    q = np.asarray(qs)[:, None]
    t = dt * np.arange(len(q))
    data = SimpleNamespace(q=q, qd=np.gradient(q, dt, axis=0), qdd=np.zeros_like(q), t=t)
    info = {"per_coordinate": {"th": {"noise": 1e-4, "quantization_step": 0.0, "qdd": {"windows": [4]}}}}
    traj = np.zeros(len(q), int)
    *_, rest = moving_rows(data, traj, ["th"], info, None, None, 2 * np.pi / np.sqrt(w2), margin=False)
    assert rest is not None and len(rest["stretches"]) == 2  # the hold and the final rest
    assert rest["stretches"][0][0] == 0.0
    (final,) = rest["final"]
    assert abs(final["q"][0] - q[-1, 0]) <= final["tolerance"][0] and abs(final["q"][0]) <= mu / w2 + 1e-9
    assert final["seconds"] > 1.0


def _swing(gam, mu, *, q0=0.3, w2=A, dt=0.01, seconds=9.0, step=0.0):
    """A pendulum θ̈ = −w2 sin θ − γ θ̇ − μ sign(θ̇) from rest at q0, sticking when |w2 sin θ| ≤ μ at a stop; positions
    rounded to ``step`` (an encoder). Returns (data, traj, info, period)."""
    from types import SimpleNamespace

    from tests.fixtures.friction import stick_slip_euler

    q, t = stick_slip_euler(q0, gam, mu, w2, dt, seconds)
    if step:
        q = step * np.round(q / step)
    data = SimpleNamespace(q=q, qd=np.gradient(q, dt, axis=0), qdd=np.zeros_like(q), t=t)
    info = {"per_coordinate": {"th": {"noise": 1e-4, "quantization_step": step, "qdd": {"windows": [4]}}}}
    return data, np.zeros(len(q), int), info, 2 * np.pi / math.sqrt(w2)


def _final_rest(data, traj, info, period):
    from nnphd.explain.search import moving_rows

    *_, rest = moving_rows(data, traj, ["th"], info, None, None, period, margin=False)
    assert rest is not None and rest["final"]
    return rest["final"]


def _stop(table, data, traj, final, period):
    from nnphd.explain.stuck import stop_contradictions
    from nnphd.explain.trajectory import Motion

    return stop_contradictions(table, final, Motion(data.q, data.qd, data.t, traj), period, angles=(True,))


def test_a_swing_that_stops_for_good_contradicts_the_laws_that_cannot_stop_it():
    """Viscous + dry friction (γ 0.3, μ 0.8) ends the swing within its dead band — here near the equilibrium, where the
    offset rule above can say nothing. A viscous law (γ 2, what a viscous fit of the whole decay gives) predicts a
    swing of ~0.6 of the last amplitude after the last turning point, where the record is still."""
    from nnphd.explain.stuck import STOP_MIN

    data, traj, info, period = _swing(0.3, 0.8)
    final = _final_rest(data, traj, info, period)
    assert abs(final[0]["q"][0]) < OFFSET_MIN * 0.02  # close to zero: the offset rule has little to go on
    lin, dry = _row("linear", [2.0], -20.0), _row("linear+coulomb", [0.3, 0.8], -18.0)
    table = _table([lin, dry])
    out = _stop(table, data, traj, final, period)
    assert set(out) == {"linear"}
    c = out["linear"]
    assert c["kind"] == "stop" and c["t_turn"] < c["t_rest"] <= c["t_turn"] + period
    assert c["predicted_std"] - Z_STUCK * c["se"] >= STOP_MIN * c["measured_std"]
    assert c["measured_std"] <= 2 * c["tolerance"]
    barred = bar_stuck(table, out)
    assert barred.law.key == "linear+coulomb" and "nothing in them stops a swing: linear" in barred.reason
    # a viscous law whose coefficient is unknown to within its size: its predicted swing is no contradiction
    vague = _row("linear", [2.0], -20.0)
    vague.cov = np.array([[4.0]])
    assert _stop(_table([vague, dry]), data, traj, final, period) == {}


def test_a_sparse_law_and_a_built_in_one_with_the_same_force_predict_the_same_swing():
    """The stop check integrates each candidate with its numbers as data of one compiled program (the built-in
    families rebuilt from their speeds, a sparse law from its support's indices): a sparse law holding only the
    viscous term, −2 θ̇, predicts the swing of the viscous family with γ = 2 and is contradicted alike."""
    from nnphd.explain.families import odd_monomials, sparse_family

    data, traj, info, period = _swing(0.3, 0.8)
    final = _final_rest(data, traj, info, period)
    support = np.zeros((1, len(odd_monomials(1))), bool)
    support[0, odd_monomials(1).index(((0,), (1,)))] = True  # θ̇ alone
    sparse = law_row(sparse_family(1, ["th"], support), np.array([-2.0]), np.zeros(0), 0.01 * np.ones(1), ["th"],
                     1.0, "trajectory")  # fmt: skip
    sparse.ic = sparse.delta_ic = -20.0
    sparse.conservative, sparse.conservative_cov = np.array([0.0, A]), 0.01**2 * np.eye(2)
    dry = _row("linear+coulomb", [0.3, 0.8], -18.0)
    by_sparse = _stop(_table([sparse, dry]), data, traj, final, period)
    by_linear = _stop(_table([_row("linear", [2.0], -20.0), dry]), data, traj, final, period)
    assert set(by_sparse) == {"sparse"} and set(by_linear) == {"linear"}
    # the same force; the coefficient draws alike but for their sign (β = −2 against γ = 2)
    np.testing.assert_allclose(by_sparse["sparse"]["predicted_std"], by_linear["linear"]["predicted_std"], rtol=0.02)
    assert by_sparse["sparse"]["predicted_std"] > 10 * by_sparse["sparse"]["measured_std"]


def test_a_viscous_swing_fading_below_the_encoder_steps_is_no_stop():
    """The true viscous law of a swing that fades below the encoder's resolution (0.0015 rad) predicts what the record
    shows: no contradiction, though the rest detector calls the tail a rest."""
    data, traj, info, period = _swing(0.5, 0.0, seconds=26.0, step=0.0015)
    final = _final_rest(data, traj, info, period)
    true = _row("linear", [0.5], -20.0)
    assert _stop(_table([true, _row("linear+coulomb", [0.5, 0.01], -18.0)]), data, traj, final, period) == {}
    # nor a law 20× too weak: from the last turning point a few steps off, no swing it predicts could be told
    assert _stop(_table([_row("linear", [0.025], -20.0)]), data, traj, final, period) == {}


def test_a_draw_that_runs_away_gives_nan_and_no_warning():
    """The stop check's std over the rest window: each finite draw's own std; NaN, silently, for a draw that reached
    inf or NaN (before, numpy printed "invalid value encountered in subtract" on the user's console)."""
    import warnings

    from nnphd.explain.stuck import window_std

    grid = np.linspace(0.0, 1.0, 11)
    xs = np.stack([np.sin(3 * grid), np.where(grid > 0.7, np.inf, grid), np.where(grid > 0.8, np.nan, 1.0)], axis=1)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        out = window_std(grid, xs, 0.5)
    assert out[0] == pytest.approx(np.std(np.sin(3 * grid[grid >= 0.5])), rel=1e-15)
    assert np.isnan(out[1]) and np.isnan(out[2])
