"""Systems catalogue: forces against independently written formulas, Lagrangians, energies, conservation laws."""

import math
from dataclasses import replace

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import nnphd  # noqa: F401  (enables float64)
from nnphd.engine.data import rk4_trajectory
from nnphd.engine.systems import SYSTEMS, Goal, get_system, gw_k

NAMES = ["ho+mf", "ho+cg", "ho+ld", "ho+cd", "ho+pf", "double-pendulum", "neptune", "gw"]


def _points(n, seed, count=5, scale=1.0):
    rng = np.random.default_rng(seed)
    return [
        (scale * rng.standard_normal(n), rng.standard_normal(n), float(rng.standard_normal())) for _ in range(count)
    ]


def _kepler_points(seed, count=5):
    # keep |r| away from the singular origin (and from Neptune at r_n = 3)
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(count):
        ang = rng.uniform(0, 2 * np.pi)
        r = rng.uniform(0.8, 2.2)
        out.append((r * np.array([np.cos(ang), np.sin(ang)]), 0.7 * rng.standard_normal(2), float(rng.uniform(0, 30))))
    return out


def points_for(system, seed=0, count=5):
    if system.name in ("neptune", "gw"):
        return _kepler_points(seed, count)
    return _points(system.n, seed, count)


# ---- expected formulas, written independently in plain numpy ------------------------------------------------------
def expected(name, p, q, qd, t):
    """(f_c, f_n) for catalogue system ``name`` with parameters p."""
    if name == "ho+mf":
        return -p["k"] * q + p["B"] * np.array([qd[1], -qd[0]]), np.zeros(2)
    if name == "ho+cg":
        return -p["k"] * q - p["g"], np.zeros(1)
    if name == "ho+ld":
        return -p["k"] * q, -p["gamma"] * qd
    if name == "ho+cd":
        return -p["k"] * q, -p["gamma"] * np.sign(qd)
    if name == "ho+pf":
        return -p["k"] * q, np.array([p["a"] * math.sin(t)])
    if name == "double-pendulum":
        m1, m2, g, l1, l2 = p["m1"], p["m2"], p["g"], p["l1"], p["l2"]
        th1, th2 = q
        w1, w2 = qd
        D = th2 - th1
        num1 = (
            m2 * l1 * w1**2 * math.sin(D) * math.cos(D)
            + m2 * g * math.sin(th2) * math.cos(D)
            + m2 * l2 * w2**2 * math.sin(D)
            - (m1 + m2) * g * math.sin(th1)
        )
        num2 = -m2 * l2 * w2**2 * math.sin(D) * math.cos(D) + (m1 + m2) * (
            g * math.sin(th1) * math.cos(D) - l1 * w1**2 * math.sin(D) - g * math.sin(th2)
        )
        a1 = num1 / ((m1 + m2) * l1 - m2 * l1 * math.cos(D) ** 2)
        a2 = num2 / ((m1 + m2) * l2 - m2 * l2 * math.cos(D) ** 2)
        return np.array([a1, a2]), -p["gamma"] * qd
    if name == "neptune":
        x, y = q
        r3 = (x * x + y * y) ** 1.5
        xn = p["rn"] * math.cos(p["omega_n"] * t + p["phase_n"])
        yn = p["rn"] * math.sin(p["omega_n"] * t + p["phase_n"])
        d3 = ((x - xn) ** 2 + (y - yn) ** 2) ** 1.5
        return (
            np.array([-p["GM"] * x / r3, -p["GM"] * y / r3]),
            np.array([p["GMn"] * (xn - x) / d3, p["GMn"] * (yn - y) / d3]),
        )
    if name == "gw":
        G, M1, M2, c = p["G"], p["M1"], p["M2"], p["c"]
        x, y = q
        r3 = (x * x + y * y) ** 1.5
        k = 32 * M1 * M2 * (M1**2 + M2**2) / (5 * G * c**5 * (M1 + M2) ** 5)
        v2 = qd[0] ** 2 + qd[1] ** 2
        return (np.array([-G * (M1 + M2) * x / r3, -G * (M1 + M2) * y / r3]), -k * v2**4 * qd)
    raise KeyError(name)


# non-default parameters, to check that every parameter enters the formulas correctly
OVERRIDES = {
    "ho+mf": dict(k=1.7, B=0.6),
    "ho+cg": dict(k=0.8, g=2.5),
    "ho+ld": dict(k=2.0, gamma=0.3),
    "ho+cd": dict(k=2.0, gamma=0.3),
    "ho+pf": dict(k=0.5, a=1.3),
    "double-pendulum": dict(m1=1.3, m2=0.7, g=9.81, l1=0.9, l2=1.4, gamma=0.1),
    "neptune": dict(GM=1.2, GMn=0.01, rn=3.5, omega_n=0.2, phase_n=0.4),
    "gw": dict(G=1.1, M1=0.8, M2=1.5, c=2.5),
}


def el_acceleration(L, q, qd):
    """Euler–Lagrange q̈ = H_vv⁻¹ (∇_q L − (∂²L/∂q̇∂q) q̇) by autodiff of a Lagrangian L(q, q̇)."""
    H = jax.hessian(L, argnums=(0, 1))(q, qd)
    H_vv, H_vq = H[1][1], H[1][0]  # ∂²L/∂q̇², ∂²L/∂q̇∂q (row: q̇ index, column: q index)
    g_q = jax.grad(L, argnums=0)(q, qd)
    return jnp.linalg.solve(H_vv, g_q - H_vq @ qd)


# ---- catalogue ------------------------------------------------------------------------------------------------------
def test_catalogue_names_and_metadata():
    assert list(SYSTEMS) == NAMES
    for name, s in SYSTEMS.items():
        assert s.name == name and len(s.coords) == s.n and len(s.x0) == 2 * s.n
        assert s.description
    assert [n for n, s in SYSTEMS.items() if s.conservative] == ["ho+mf", "ho+cg"]
    assert {n for n, s in SYSTEMS.items() if s.data == "trajectory"} == {"double-pendulum", "neptune", "gw"}
    assert SYSTEMS["double-pendulum"].coords == ("theta1", "theta2")
    # paper's simulation settings: N_step 300/1000/300, dt 0.1/0.1/0.05
    assert [(SYSTEMS[n].n_steps, SYSTEMS[n].dt) for n in ("double-pendulum", "neptune", "gw")] == [
        (300, 0.1),
        (1000, 0.1),
        (300, 0.05),
    ]
    assert SYSTEMS["neptune"].x0 == pytest.approx((2.0, 0.0, 0.0, 1 / math.sqrt(2)))
    assert SYSTEMS["gw"].x0 == (0.0, 2.0, -1.0, 0.0)
    assert SYSTEMS["double-pendulum"].params["gamma"] == 0.02


def test_get_system_and_overrides():
    assert get_system("ho+ld") is SYSTEMS["ho+ld"]
    s = get_system("ho+ld", gamma=0.1)
    assert s.params["gamma"] == 0.1 and s.params["k"] == 1.0
    assert SYSTEMS["ho+ld"].params["gamma"] == 0.5  # the catalogue entry is untouched
    assert (
        s != SYSTEMS["ho+ld"]
        and s == get_system("ho+ld", gamma=0.1)
        and hash(s) == hash(get_system("ho+ld", gamma=0.1))
    )
    np.testing.assert_allclose(s.f_n(np.array([0.3]), np.array([2.0]), 0.0), [-0.2], rtol=0, atol=1e-15)
    with pytest.raises(ValueError, match="unknown system 'nope'; expected one of: ho\\+mf"):
        get_system("nope")
    with pytest.raises(ValueError, match="'zeta'.*allowed keys: k, gamma"):
        get_system("ho+ld", zeta=1.0)
    with pytest.raises(ValueError, match="zeta"):
        SYSTEMS["gw"].with_params(zeta=1.0)


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("use_overrides", [False, True])
def test_forces_match_formulas(name, use_overrides):
    s = get_system(name, **OVERRIDES[name]) if use_overrides else get_system(name)
    p = dict(s.params)
    for q, qd, t in points_for(s, seed=1):
        fc_exp, fn_exp = expected(name, p, q, qd, t)
        fc, fn, f = s.f_c(q, qd), s.f_n(q, qd, t), s.f(q, qd, t)
        assert fc.shape == fn.shape == f.shape == (s.n,)
        np.testing.assert_allclose(fc, fc_exp, rtol=1e-12, atol=1e-14)
        np.testing.assert_allclose(fn, fn_exp, rtol=1e-12, atol=1e-14)
        np.testing.assert_allclose(f, fc_exp + fn_exp, rtol=1e-12, atol=1e-14)
        if s.conservative:
            assert np.all(np.asarray(fn) == 0.0)


@pytest.mark.parametrize("name", NAMES)
def test_jit_vmap(name):
    s = get_system(name)
    pts = points_for(s, seed=2, count=4)
    q = jnp.stack([a for a, _, _ in pts])
    qd = jnp.stack([b for _, b, _ in pts])
    t = jnp.array([c for *_, c in pts])
    f = jax.jit(jax.vmap(s.f))(q, qd, t)
    L = jax.jit(jax.vmap(s.lagrangian))(q, qd)
    E = jax.jit(jax.vmap(s.energy))(q, qd)
    assert f.shape == (4, s.n) and L.shape == (4,) and E.shape == (4,)
    for i in range(4):
        np.testing.assert_allclose(f[i], sum(expected(name, dict(s.params), *pts[i])), rtol=1e-12, atol=1e-14)


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("use_overrides", [False, True])
def test_euler_lagrange_of_lagrangian_gives_fc(name, use_overrides):
    s = get_system(name, **OVERRIDES[name]) if use_overrides else get_system(name)
    pts = points_for(s, seed=3)
    q = jnp.stack([a for a, _, _ in pts])
    qd = jnp.stack([b for _, b, _ in pts])
    acc = jax.jit(jax.vmap(lambda a, b: el_acceleration(s.lagrangian, a, b)))(q, qd)
    np.testing.assert_allclose(acc, jax.vmap(s.f_c)(q, qd), rtol=1e-10, atol=1e-10)


@pytest.mark.parametrize("name", NAMES)
def test_energy_is_legendre_transform(name):
    s = get_system(name, **OVERRIDES[name])
    pts = points_for(s, seed=4)
    q = jnp.stack([a for a, _, _ in pts])
    qd = jnp.stack([b for _, b, _ in pts])
    legendre = lambda a, b: b @ jax.grad(s.lagrangian, argnums=1)(a, b) - s.lagrangian(a, b)  # noqa: E731
    np.testing.assert_allclose(jax.vmap(s.energy)(q, qd), jax.jit(jax.vmap(legendre))(q, qd), rtol=1e-12, atol=1e-12)


def test_closed_form_energies():
    q2, v2 = np.array([0.3, -1.2]), np.array([0.7, 0.4])
    assert float(SYSTEMS["ho+mf"].energy(q2, v2)) == pytest.approx(0.5 * (0.49 + 0.16) + 0.5 * (0.09 + 1.44), rel=1e-14)
    assert float(SYSTEMS["ho+cg"].energy(np.array([0.3]), np.array([0.7]))) == pytest.approx(
        0.5 * 0.49 + 0.5 * 0.09 + 0.3
    )
    # double pendulum hanging at rest: E = -(m1+m2) g l1 - m2 g l2 = -3 at the defaults
    assert float(SYSTEMS["double-pendulum"].energy(np.zeros(2), np.zeros(2))) == pytest.approx(-3.0, abs=1e-15)
    # circular Kepler orbits: E = -GM / (2r)
    nep = SYSTEMS["neptune"]
    assert float(nep.energy(np.array(nep.x0[:2]), np.array(nep.x0[2:]))) == pytest.approx(-0.25, rel=1e-14)
    gw = SYSTEMS["gw"]
    assert float(gw.energy(np.array(gw.x0[:2]), np.array(gw.x0[2:]))) == pytest.approx(-0.5, rel=1e-14)


# ---- conservation laws along RK4 trajectories ----------------------------------------------------------------------
def _energy_drift(s, f, x0, dt, T):
    t, q, qd = rk4_trajectory(f, x0, dt, int(round(T / dt)))
    E = np.asarray(jax.vmap(s.energy)(q, qd))
    return np.max(np.abs(E - E[0])), E


CONSERVATIVE_CASES = [  # (system, dt, total time)
    ("ho+mf", 0.1, 30.0),
    ("ho+cg", 0.1, 30.0),
    ("double-pendulum", 0.1, 30.0),
    ("neptune", 0.1, 100.0),
    ("gw", 0.2, 15.0),
]


@pytest.mark.parametrize("name,dt,T", CONSERVATIVE_CASES)
def test_rk4_of_fc_conserves_energy_with_dt4_drift(name, dt, T):
    s = get_system(name)
    fc = lambda q, qd, t: s.f_c(q, qd)  # noqa: E731  (undamped / Sun-only / no radiation)
    d1, E = _energy_drift(s, fc, s.x0, dt, T)
    d2, _ = _energy_drift(s, fc, s.x0, dt / 2, T)
    assert d1 < 1e-3 * max(1.0, abs(E[0]))
    # global RK4 error is O(dt^4): halving dt must shrink the drift by ~16 (at least 10)
    assert d1 / d2 > 10.0, (d1, d2)


def test_conservative_systems_conserve_energy_with_full_f():
    for name in ("ho+mf", "ho+cg"):
        s = get_system(name)
        d, _ = _energy_drift(s, s.f, s.x0, 0.05, 30.0)
        assert d < 1e-6


def test_damped_systems_lose_energy():
    dp = get_system("double-pendulum")
    t, q, qd = rk4_trajectory(dp.f, dp.x0, dp.dt, dp.n_steps)
    E = np.asarray(jax.vmap(dp.energy)(q, qd))
    assert np.all(np.diff(E) < 0.0)  # dE/dt = -γ q̇ᵀ M(q) q̇ < 0
    assert E[0] == pytest.approx(-2.0 * math.cos(1.0) - 1.0, abs=1e-14)  # -(m1+m2) g l1 cos θ1 - m2 g l2
    assert E[-1] < E[0] - 0.1

    ld = get_system("ho+ld")
    t, q, qd = rk4_trajectory(ld.f, ld.x0, 0.01, 1000)
    E = np.asarray(jax.vmap(ld.energy)(q, qd))
    assert np.all(np.diff(E) <= 1e-15)
    # analytic underdamped solution: x = e^{-γt/2}(cos ωt + γ/(2ω) sin ωt), ω = sqrt(k - γ²/4)
    g, w = 0.5, math.sqrt(1 - 0.0625)
    tt = np.asarray(t)
    x = np.exp(-g * tt / 2) * (np.cos(w * tt) + g / (2 * w) * np.sin(w * tt))
    np.testing.assert_allclose(np.asarray(q)[:, 0], x, atol=1e-9)

    cd = get_system("ho+cd")
    t, q, qd = rk4_trajectory(cd.f, cd.x0, 0.01, 300)
    E = np.asarray(jax.vmap(cd.energy)(q, qd))
    assert E[-1] < E[0] - 0.1


# ---- neptune ----------------------------------------------------------------------------------------------------------
def test_neptune_kepler_frequency_and_unperturbed_orbit_closes():
    s = SYSTEMS["neptune"]
    p = s.params
    assert p["omega_n"] == pytest.approx(math.sqrt(p["GM"] / p["rn"] ** 3), rel=1e-14)
    assert p["omega_n"] == pytest.approx(0.19245, abs=1e-5)
    # x0 is on the circular orbit of radius 2: |v|² = GM / r, v ⟂ r
    x0 = np.array(s.x0)
    assert np.dot(x0[:2], x0[2:]) == 0.0 and np.dot(x0[2:], x0[2:]) == pytest.approx(p["GM"] / 2.0, rel=1e-15)
    # Uranus does not start on Neptune (the paper's (3, 0, 0, 1/√3) would)
    assert np.linalg.norm(x0[:2] - np.asarray(jnp.array([p["rn"], 0.0]))) == pytest.approx(1.0)
    period = 2 * math.pi * 2**1.5
    n = 2000
    t, q, qd = rk4_trajectory(lambda q, qd, t: s.f_c(q, qd), x0, period / n, n)
    assert float(t[-1]) == pytest.approx(period, rel=1e-14)
    assert np.linalg.norm(np.asarray(q[-1]) - x0[:2]) < 1e-6
    assert np.linalg.norm(np.asarray(qd[-1]) - x0[2:]) < 1e-6
    # halfway round: (-2, 0)
    assert np.linalg.norm(np.asarray(q[n // 2]) - np.array([-2.0, 0.0])) < 1e-6
    # with Neptune the orbit no longer closes
    t, q, qd = rk4_trajectory(s.f, x0, period / n, n)
    assert np.linalg.norm(np.asarray(q[-1]) - x0[:2]) > 1e-3


# ---- gravitational waves ----------------------------------------------------------------------------------------------
def test_gw_coefficient():
    assert gw_k(SYSTEMS["gw"].params) == pytest.approx(0.0016460905349794, rel=1e-12)
    assert gw_k(SYSTEMS["gw"].params) == pytest.approx(64 / 38880, rel=1e-14)
    # f_n = -k |v|^8 v: at |v| = 1 along -x it is +k along x
    np.testing.assert_allclose(
        SYSTEMS["gw"].f_n(np.array([0.0, 2.0]), np.array([-1.0, 0.0]), 0.0), [64 / 38880, 0.0], rtol=1e-14
    )


def test_gw_inspiral_follows_adiabatic_decay():
    s = SYSTEMS["gw"]
    t, q, qd = rk4_trajectory(s.f, s.x0, s.dt, s.n_steps)
    r = np.linalg.norm(np.asarray(q), axis=1)
    E = np.asarray(jax.vmap(s.energy)(q, qd))
    assert r[0] == 2.0 and r[-1] < r[0] - 0.05
    assert np.all(np.diff(E) < 0)  # dE/dt = -k |v|^10
    # quasi-circular orbit: v² = GM/r, dE/dt = d(-v²/2)/dt = -k v^10  =>  r(t) = r0 (1 - 8 k t v0^8)^{1/4}
    k = gw_k(s.params)
    r_adiabatic = 2.0 * (1.0 - 8.0 * k * np.asarray(t)) ** 0.25
    np.testing.assert_allclose(r, r_adiabatic, rtol=0.02)
    # initial energy loss rate equals -k |v0|^10 = -k
    dEdt0 = (E[1] - E[0]) / s.dt
    assert dEdt0 == pytest.approx(-k, rel=0.01)


# ---- what the rediscovery (Table II) needs --------------------------------------------------------------------------
TABLE2 = ["double-pendulum", "neptune", "gw"]


def test_table2_metadata():
    assert [n for n, s in SYSTEMS.items() if s.law_family is not None] == TABLE2
    for n, s in SYSTEMS.items():
        assert len(s.angles) == s.n
        if n not in TABLE2:
            assert s.angles == (False,) * s.n and s.truth is None
            assert s.feature_set is s.law_family is s.law_params is s.goals is s.discover_n_steps is None
    assert SYSTEMS["double-pendulum"].angles == (True, True)
    assert SYSTEMS["neptune"].angles == SYSTEMS["gw"].angles == (False, False)
    assert {n: (SYSTEMS[n].law_family, SYSTEMS[n].feature_set, SYSTEMS[n].discover_n_steps) for n in TABLE2} == {
        "double-pendulum": ("linear-full", "double-pendulum", 600),
        "neptune": ("perturber", "kepler", 1000),
        "gw": ("power", "kepler", 1000),
    }
    assert dict(SYSTEMS["double-pendulum"].law_params) == {
        "Gamma_theta1theta1": "Gamma_11",
        "Gamma_theta1theta2": "Gamma_12",
        "Gamma_theta2theta1": "Gamma_21",
        "Gamma_theta2theta2": "Gamma_22",
    }
    for n in TABLE2:
        s = SYSTEMS[n]
        assert list(s.truth) == list(s.goals) and set(s.truth) == set(s.law_params.values())
    with pytest.raises(ValueError, match="angles must have length"):
        replace(SYSTEMS["gw"], angles=(True,))


def test_law_params_are_parameters_of_the_hypothesis_family():
    from nnphd.explain.families import families, perturber_family

    for n in TABLE2:
        s = SYSTEMS[n]
        fams = {f.key: f for f in families(s.n, s.coords, np.ones(s.n))}
        fams["perturber"] = perturber_family(s.coords)
        f = fams[s.law_family]
        assert set(s.law_params) <= set(f.coef_names + f.nl_names)


def test_truth_follows_from_the_parameters():
    assert SYSTEMS["double-pendulum"].truth == {"Gamma_11": 0.02, "Gamma_12": 0.0, "Gamma_21": 0.0, "Gamma_22": 0.02}
    assert SYSTEMS["double-pendulum"].truth["Gamma_11"] == SYSTEMS["double-pendulum"].params["gamma"]
    assert get_system("double-pendulum", gamma=0.05).truth["Gamma_22"] == 0.05
    assert SYSTEMS["neptune"].truth == {"GM": 0.005, "R": 3.0, "omega": 3.0**-1.5}
    assert get_system("neptune", GMn=0.01, rn=4.0).truth == {"GM": 0.01, "R": 4.0, "omega": 3.0**-1.5}
    gw = SYSTEMS["gw"]
    assert gw.truth == {"k": gw_k(gw.params), "m": 4.0}
    assert gw.truth["k"] == pytest.approx(64 / 38880, rel=1e-14)
    assert get_system("gw", c=2.0).truth["k"] == pytest.approx(64 / 5120, rel=1e-14)  # 32·2 / (5·2⁵·2⁵)


@pytest.mark.parametrize("name", TABLE2)
@pytest.mark.parametrize(
    "overrides",
    [
        {},
        {
            "double-pendulum": {"gamma": 0.07},
            "neptune": {"GMn": 0.02, "rn": 3.5, "omega_n": 0.3},
            "gw": {"M1": 2.0, "c": 2.5},
        },
    ],
)
def test_truth_is_the_law_of_f_n(name, overrides):
    """The hypothesis family's formula at the true parameters is the system's f_n."""
    s = get_system(name, **overrides.get(name, {}))
    tr = s.truth
    for q, qd, t in points_for(s, seed=3):
        if name == "double-pendulum":
            law = -np.array([[tr["Gamma_11"], tr["Gamma_12"]], [tr["Gamma_21"], tr["Gamma_22"]]]) @ qd
        elif name == "neptune":
            ang = tr["omega"] * t + s.params["phase_n"]
            d = tr["R"] * np.array([math.cos(ang), math.sin(ang)]) - q
            law = tr["GM"] * d / np.sum(d**2) ** 1.5
        else:
            law = -tr["k"] * np.sum(qd**2) ** tr["m"] * qd
        np.testing.assert_allclose(s.f_n(q, qd, t), law, rtol=1e-12, atol=1e-15)


def test_goal_labels():
    assert {n: {k: g.label for k, g in SYSTEMS[n].goals.items()} for n in TABLE2} == {
        "double-pendulum": {
            "Gamma_11": "± 0.0005",
            "Gamma_12": "|·| ≤ 0.0005",
            "Gamma_21": "|·| ≤ 0.0005",
            "Gamma_22": "± 0.0005",
        },
        "neptune": {"GM": "± 2%", "R": "± 0.3%", "omega": "± 0.5%"},
        "gw": {"k": "± 2%", "m": "± 0.03"},
    }
    with pytest.raises(ValueError, match="kind"):
        Goal("within", 0.1)
    with pytest.raises(ValueError, match="positive"):
        Goal("abs", 0.0)


@pytest.mark.parametrize("name", TABLE2)
def test_goals_accept_the_truth_and_reject_just_outside(name):
    s = SYSTEMS[name]
    for key, tv in s.truth.items():
        g = s.goals[key]
        assert g.met(tv, tv)
        width = g.tol * abs(tv) if g.kind == "rel" else g.tol
        centre = 0.0 if g.kind == "zero" else tv
        assert width > 0
        for sign in (1, -1):
            assert g.met(centre + sign * 0.99 * width, tv), (key, sign)
            assert not g.met(centre + sign * 1.01 * width, tv), (key, sign)
