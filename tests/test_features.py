"""Constrained-form Lagrangians: exact at the true coefficients; friction rediscovered end to end (Table II row 1)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import nnphd  # noqa: F401
from nnphd.engine.data import trajectory_dataset
from nnphd.engine.features import FEATURE_SETS, feature_lagrangian, train_constrained
from nnphd.engine.systems import SYSTEMS, get_system
from nnphd.explain.parametric import fit_linear_friction


def _points(n=20, seed=0):
    rng = np.random.default_rng(seed)
    return jnp.asarray(rng.uniform(-1.5, 1.5, (n, 2)) + np.array([2.5, 0.0])), jnp.asarray(rng.normal(size=(n, 2)))


@pytest.mark.slow  # tens of seconds: run by `python3 dev.py test --slow` (and by CI)
def test_double_pendulum_features_at_true_coefficients_give_f_c():
    s = get_system("double-pendulum")
    assert s.feature_set == "double-pendulum"
    q, qd = _points()
    c = jnp.array([2.0, 1.0, 1.0, 0.5, 1.0])  # (m1+m2)gl1, m2gl2, ½(m1+m2)l1², ½m2l2², m2l1l2
    expected = np.asarray(jax.jit(jax.vmap(s.f_c))(q, qd))
    np.testing.assert_allclose(jax.jit(FEATURE_SETS[s.feature_set].accel)(c, q, qd), expected, atol=1e-10)


@pytest.mark.parametrize("name", [pytest.param("neptune", marks=pytest.mark.slow), "gw"])  # neptune: ~20 s, slow tier
def test_kepler_features_at_true_coefficients_give_f_c(name):
    s = get_system(name)
    gm = s.params["GM"] if name == "neptune" else s.params["G"] * (s.params["M1"] + s.params["M2"])
    q, qd = _points()
    expected = np.asarray(jax.jit(jax.vmap(s.f_c))(q, qd))  # compiled: point by point, op by op, it took 18 s
    assert s.feature_set == "kepler"
    accel = jax.jit(FEATURE_SETS[s.feature_set].accel)  # compiled too: op by op the features' Hessians took 6–18 s
    np.testing.assert_allclose(accel(jnp.array([0.5, 0.5, gm]), q, qd), expected, atol=1e-10)


def test_every_named_feature_set_exists():
    named = {s.feature_set for s in SYSTEMS.values() if s.feature_set is not None}
    assert named == {"double-pendulum", "kepler"} and named <= set(FEATURE_SETS)


def test_features_given_as_functions_and_formula():
    fl = feature_lagrangian({"q̇²": lambda q, qd: qd[0] ** 2, "q²": lambda q, qd: q[0] ** 2}, reference="q̇²")
    a = fl.accel(jnp.array([0.5, -2.0]), jnp.array([[0.3]]), jnp.array([[1.0]]))
    assert float(a[0, 0]) == pytest.approx(-4 * 0.3, abs=1e-10)  # L = ½q̇² − 2q² → q̈ = −4q
    assert fl.formula([0.5, -2.0]) == "L ∝ 1·q̇² + -4·q²"
    with pytest.raises(ValueError):
        feature_lagrangian({})


# float32 (what a GPU user may choose) must meet the same Table II goals: measured Γ11, Γ22 = 0.01972, 0.01987
# (float64: 0.01973, 0.01981), Γ12, Γ21 = 7e-5, 1.7e-4 (1.1e-4, 2.5e-4)
@pytest.mark.parametrize("dtype", ["float64", pytest.param("float32", marks=pytest.mark.slow)])
def test_friction_rediscovered_from_the_damped_double_pendulum(dtype):
    from nnphd.engine.models import ModelConfig

    d = trajectory_dataset("double-pendulum")  # paper: 300 RK4 steps of 0.1 from (1, 0, 0, 0)
    cfg = ModelConfig(n=2, dtype=dtype)
    fit = train_constrained(d, FEATURE_SETS["double-pendulum"], lam=0.2, steps=2000, seed=0, cfg=cfg)
    assert fit.fn.dtype == np.dtype(dtype) and fit.coefs.dtype == np.dtype(dtype)  # trained in that precision
    c = FEATURE_SETS["double-pendulum"].normalized(fit.coefs)
    np.testing.assert_allclose(c, [4.0, 2.0, 2.0, 1.0, 2.0], rtol=0.01)  # truth ÷ ½m2l2²
    g = fit_linear_friction(d.qd, np.asarray(fit.fn, np.float64)).params
    assert abs(g["Gamma_11"] - 0.02) <= 0.0005 and abs(g["Gamma_22"] - 0.02) <= 0.0005, g
    assert abs(g["Gamma_12"]) <= 0.0005 and abs(g["Gamma_21"]) <= 0.0005, g
