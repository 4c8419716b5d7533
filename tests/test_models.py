"""LNN / UAN against analytic truths: known Lagrangians, the jax.hessian reference, energy conservation."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import nnphd  # noqa: F401  (enables float64)
from nnphd.engine.data import rk4_trajectory
from nnphd.engine.models import (
    ModelConfig,
    accel_from_lagrangian,
    euler_lagrange_solve,
    init_lnn,
    init_nnphd,
    lnn_accel,
    lnn_accel_reference,
    lnn_energy,
    lnn_value,
    nnphd_forces,
    uan_force,
)
from nnphd.engine.systems import get_system


def _batch(n, b=9, seed=0):
    rng = np.random.default_rng(seed)
    return jnp.asarray(rng.normal(size=(b, n))), jnp.asarray(rng.normal(size=(b, n))), jnp.asarray(rng.normal(size=b))


# every size with the default activation and every activation with two coordinates in the fast tier; the other
# activations with one and three coordinates in the slow tier (each a compilation of the Hessian reference, 2–3 s)
@pytest.mark.parametrize(
    "n, act",
    [(n, a) if a == "softplus+quadratic" or n == 2 else pytest.param(n, a, marks=pytest.mark.slow)
     for a in ("softplus+quadratic", "softplus", "tanh", "quadratic") for n in (1, 2, 3)],
)  # fmt: skip
def test_handwritten_pass_equals_hessian_reference(n, act):
    cfg = ModelConfig(n=n, lnn_widths=(40, 30), lnn_activation=act, lnn_out_scale=1.0)
    lnn = init_lnn(jax.random.PRNGKey(n), cfg)
    q, qd, _ = _batch(n)
    ours = jax.jit(lambda p, a, b: lnn_accel(p, a, b, cfg))(lnn, q, qd)  # compiled, as in training
    ref = jax.jit(lambda p, a, b: lnn_accel_reference(p, a, b, cfg))(lnn, q, qd)
    assert float(jnp.max(jnp.abs(ref))) > 1e-2  # a non-trivial acceleration
    np.testing.assert_allclose(ours, ref, atol=1e-10, rtol=0)


@pytest.mark.slow  # compiles the reference's gradients (~17 s): slow tier (`python3 dev.py test --slow`, and CI)
def test_handwritten_pass_three_layers_and_gradients_match_reference():
    cfg = ModelConfig(n=2, lnn_widths=(20, 20, 20), lnn_out_scale=1.0)
    lnn = init_lnn(jax.random.PRNGKey(3), cfg)
    q, qd, _ = _batch(2)
    ours = jax.jit(lambda p: lnn_accel(p, q, qd, cfg))(lnn)
    np.testing.assert_allclose(ours, jax.jit(lambda p: lnn_accel_reference(p, q, qd, cfg))(lnn), atol=1e-10)
    g1 = jax.jit(jax.grad(lambda p: jnp.sum(lnn_accel(p, q, qd, cfg) ** 2)))(lnn)
    g2 = jax.jit(jax.grad(lambda p: jnp.sum(lnn_accel_reference(p, q, qd, cfg) ** 2)))(lnn)
    for a, b in zip(jax.tree_util.tree_leaves(g1), jax.tree_util.tree_leaves(g2)):
        np.testing.assert_allclose(a, b, atol=1e-9)


# ---- known Lagrangians through the same Euler–Lagrange solve ------------------------------------------------------


def test_harmonic_oscillator_lagrangian():
    lag = lambda q, qd: 0.5 * qd[0] ** 2 - 0.5 * q[0] ** 2  # noqa: E731
    for x, v in [(0.3, -1.2), (-2.0, 0.7)]:
        a = accel_from_lagrangian(lag, jnp.array([x]), jnp.array([v]))
        assert abs(float(a[0]) - (-x)) < 1e-10


def test_table3_magnetic_lagrangian():
    # Table III: L = (q̇1 − q2)²/2 + (q̇2 + q1)²/2. Euler–Lagrange by hand: q̈1 − q̇2 = q̇2 + q1, q̈2 + q̇1 = −q̇1 + q2.
    lag = lambda q, qd: 0.5 * (qd[0] - q[1]) ** 2 + 0.5 * (qd[1] + q[0]) ** 2  # noqa: E731
    rng = np.random.default_rng(1)
    for _ in range(5):
        q, qd = rng.normal(size=2), rng.normal(size=2)
        a = accel_from_lagrangian(lag, jnp.asarray(q), jnp.asarray(qd))
        np.testing.assert_allclose(a, [2 * qd[1] + q[0], -2 * qd[0] + q[1]], atol=1e-10)


def test_double_pendulum_lagrangian_gives_closed_form():
    s = get_system("double-pendulum")
    rng = np.random.default_rng(2)
    for _ in range(5):
        q, qd = jnp.asarray(rng.uniform(-2, 2, 2)), jnp.asarray(rng.normal(size=2))
        np.testing.assert_allclose(accel_from_lagrangian(s.lagrangian, q, qd), s.f_c(q, qd), atol=1e-10)


def _exact_quadratic_lnn(w1, w_out, n):
    """One hidden layer of quadratic units σ(a) = a²/2, zero biases: L_NN = Σ_k w_out[k] (w1[:,k]·z)²/2."""
    w1 = jnp.asarray(w1, jnp.float64)
    return [{"w": w1, "b": jnp.zeros(w1.shape[1])}, {"w": jnp.asarray(w_out, jnp.float64)[:, None], "b": jnp.zeros(1)}]


def test_exact_harmonic_oscillator_in_the_network():
    # L = ½q̇² (split trick) − ½q²: one quadratic unit a = q with output weight −1.
    cfg = ModelConfig(n=1, lnn_widths=(1,), lnn_activation="quadratic")
    lnn = _exact_quadratic_lnn([[1.0], [0.0]], [-1.0], 1)
    q, qd, _ = _batch(1)
    np.testing.assert_allclose(lnn_accel(lnn, q, qd, cfg), -q, atol=1e-10)


@pytest.mark.slow  # compiles a reference pass (~9 s): slow tier (`python3 dev.py test --slow`, and CI)
def test_exact_magnetic_lagrangian_in_the_network():
    # L = ½|q̇|² + (B/2)(q1 q̇2 − q2 q̇1) − ½k|q|², with xy = ½[σ(x+y) − σ(x−y)] for σ(a)=a²/2 → q̈ = −kq + B(q̇2, −q̇1)
    k, b = 1.3, 0.7
    # z = (q1, q2, q̇1, q̇2); units: q1+q̇2, q1−q̇2, q2+q̇1, q2−q̇1, q1, q2
    w1 = np.array([[1, 1, 0, 0, 1, 0], [0, 0, 1, 1, 0, 1], [0, 0, 1, -1, 0, 0], [1, -1, 0, 0, 0, 0]], float)
    w_out = [b / 4, -b / 4, -b / 4, b / 4, -k, -k]
    cfg = ModelConfig(n=2, lnn_widths=(6,), lnn_activation="quadratic")
    lnn = _exact_quadratic_lnn(w1, w_out, 2)
    q, qd, _ = _batch(2)
    expected = -k * q + b * jnp.stack([qd[:, 1], -qd[:, 0]], axis=1)
    np.testing.assert_allclose(lnn_accel(lnn, q, qd, cfg), expected, atol=1e-10)
    # and it conserves H = ½|q̇|² + ½k|q|²
    np.testing.assert_allclose(
        lnn_energy(lnn, q, qd, cfg), 0.5 * jnp.sum(qd**2, 1) + 0.5 * k * jnp.sum(q**2, 1), atol=1e-12
    )


# ---- energy of a learned Lagrangian ------------------------------------------------------------------------------


def test_random_lnn_conserves_its_energy_with_rk4_order_4():
    cfg = ModelConfig(n=2, lnn_widths=(32, 32), lnn_out_scale=0.3)
    lnn = init_lnn(jax.random.PRNGKey(7), cfg)

    def f(q, qd, t):
        return lnn_accel(lnn, q[None], qd[None], cfg)[0]

    x0 = jnp.array([0.3, -0.2, 0.1, 0.4])
    drifts = []
    for dt in (0.1, 0.05):
        _, q, qd = rk4_trajectory(f, x0, dt, int(round(4.0 / dt)))
        e = jax.jit(lambda a, b: lnn_energy(lnn, a, b, cfg))(q, qd)
        drifts.append(float(jnp.max(jnp.abs(e - e[0]))))
    assert drifts[0] < 1e-4
    ratio = drifts[0] / drifts[1]
    assert 8 < ratio < 40, (drifts, ratio)  # 2⁴ = 16 for a 4th-order integrator


# ---- the guarded solve -----------------------------------------------------------------------------------------------


@pytest.mark.slow  # a training run: slow tier (`python3 dev.py test --slow`, and CI)
def test_guard_singular_mass_matrix_gives_finite_output():
    # H = 0 (no split trick, L_NN without q̇ dependence) must not produce inf/NaN, nor NaN gradients
    cfg = ModelConfig(n=2, lnn_widths=(8,), split_mass=0.0, lnn_activation="quadratic")
    lnn = _exact_quadratic_lnn(np.array([[1.0], [0.5], [0.0], [0.0]]), [-1.0], 2)
    q, qd, _ = _batch(2)
    a = lnn_accel(lnn, q, qd, cfg)
    assert bool(jnp.all(jnp.isfinite(a)))
    g = jax.grad(lambda p: jnp.sum(lnn_accel(p, q, qd, cfg)))(lnn)
    assert all(bool(jnp.all(jnp.isfinite(x))) for x in jax.tree_util.tree_leaves(g))


@pytest.mark.parametrize("n", [1, 2, 3])
def test_guarded_solve_matches_exact_solve_when_well_conditioned(n):
    rng = np.random.default_rng(n)
    m = rng.normal(size=(5, n, n))
    h = m @ np.swapaxes(m, 1, 2) + np.eye(n)  # SPD, eigenvalues ≥ 1
    r = rng.normal(size=(5, n))
    x = euler_lagrange_solve(jnp.asarray(r), jnp.asarray(h), jnp.zeros((5, n)), eps=1e-6)
    np.testing.assert_allclose(x, np.linalg.solve(h, r[..., None])[..., 0], atol=1e-10)
    # a singular H gives a bounded answer |x| ≤ |H r| / ε²-regularised, never inf
    x0 = euler_lagrange_solve(jnp.asarray(r), jnp.zeros((5, n, n)), jnp.zeros((5, n)), eps=1e-6)
    assert bool(jnp.all(x0 == 0))


def test_float32_model_runs_and_matches_float64():
    cfg64 = ModelConfig(n=2, lnn_widths=(30, 30))
    cfg32 = cfg64.replace(dtype="float32")
    p64 = init_nnphd(jax.random.PRNGKey(0), cfg64)
    p32 = jax.tree_util.tree_map(lambda a: a.astype(jnp.float32), p64)
    q, qd, t = _batch(2)
    fc64, fn64 = jax.jit(lambda *a: nnphd_forces(*a, cfg64))(p64, q, qd, t)
    fc32, fn32 = jax.jit(lambda *a: nnphd_forces(*a, cfg32))(
        p32, q.astype(jnp.float32), qd.astype(jnp.float32), t.astype(jnp.float32)
    )
    assert fc32.dtype == jnp.float32
    np.testing.assert_allclose(fc32, fc64, atol=1e-4)
    np.testing.assert_allclose(fn32, fn64, atol=1e-4)


@pytest.mark.slow  # a training run: slow tier (`python3 dev.py test --slow`, and CI)
def test_float32_config_trains_in_float32():
    """ModelConfig(dtype="float32") means float32 weights (a NumPy float64 scale once made them float64, so the
    "float32" runs were float64 but for their biases and data), and they stay float32 through Adam."""
    from nnphd.engine.train import TrainConfig, make_trainer

    cfg = ModelConfig(n=2, lnn_widths=(16, 16), uan_widths=(16, 16), dtype="float32")
    p0 = init_nnphd(jax.random.PRNGKey(0), cfg)
    assert {str(x.dtype) for x in jax.tree_util.tree_leaves(p0)} == {"float32"}
    q, qd, t = _batch(2)
    arrays = tuple(a.astype(jnp.float32) for a in (q, qd, t, q))  # (q, q̇, t, q̈)
    p1, (le, lb) = make_trainer(cfg, TrainConfig(steps=8))(p0, arrays, jnp.asarray(0.5, jnp.float32), jax.random.key(1))
    assert {str(x.dtype) for x in jax.tree_util.tree_leaves(p1)} == {"float32"} and le.dtype == jnp.float32
    assert not all(np.array_equal(a, b) for a, b in zip(jax.tree_util.tree_leaves(p0), jax.tree_util.tree_leaves(p1)))


def test_uan_is_leaky_relu_mlp_of_q_qd_t():
    cfg = ModelConfig(n=1, uan_widths=(2,))
    uan = [
        {"w": jnp.array([[1.0, -1.0], [0.0, 0.0], [0.0, 0.0]]), "b": jnp.zeros(2)},
        {"w": jnp.array([[1.0], [1.0]]), "b": jnp.array([0.5])},
    ]
    q = jnp.array([[2.0], [-3.0]])
    out = uan_force(uan, q, jnp.zeros_like(q), jnp.zeros(2), cfg)
    # q=2: relu(2) + leaky(−2) = 2 − 0.4; q=−3: leaky(−3) + 3 = −0.6 + 3
    np.testing.assert_allclose(out[:, 0], [2 - 0.4 + 0.5, -0.6 + 3 + 0.5], atol=1e-12)


def test_split_trick_makes_initial_mass_matrix_near_identity():
    cfg = ModelConfig(n=2)
    lnn = init_lnn(jax.random.PRNGKey(0), cfg)
    q, qd, _ = _batch(2, b=64)
    lag = lnn_value(lnn, q, qd, cfg)
    assert lag.shape == (64,)
    from nnphd.engine.models import lnn_derivatives

    _, h, _ = lnn_derivatives(lnn, q, qd, cfg)
    eig = np.linalg.eigvalsh(np.asarray(h))
    assert eig.min() > 0.5 and eig.max() < 1.5


@pytest.mark.slow  # a training run: slow tier (`python3 dev.py test --slow`, and CI)
def test_input_standardisation_is_folded_into_the_first_layer():
    rng = np.random.default_rng(5)
    q, qd, t = rng.normal(3, 2, (50, 2)), rng.normal(-1, 0.5, (50, 2)), rng.uniform(0, 100, 50)
    cfg = ModelConfig(n=2, lnn_widths=(16, 16), uan_widths=(16, 16), lnn_out_scale=1.0).standardized(q, qd, t)
    assert cfg.input_shift[4] == pytest.approx(t.mean()) and cfg.input_scale[4] == pytest.approx(t.std())
    params = init_nnphd(jax.random.PRNGKey(2), cfg)
    q, qd, t = jnp.asarray(q), jnp.asarray(qd), jnp.asarray(t)
    # the hand-written pass still equals jax.hessian of the same (standardised) Lagrangian
    np.testing.assert_allclose(
        jax.jit(lambda p: lnn_accel(p, q, qd, cfg))(params["lnn"]),
        jax.jit(lambda p: lnn_accel_reference(p, q, qd, cfg))(params["lnn"]),
        atol=1e-10,
    )
    # and the networks see (x − μ)/σ: same outputs as an unstandardised config on transformed inputs
    mu, sd = np.asarray(cfg.input_shift), np.asarray(cfg.input_scale)
    raw = cfg.replace(input_shift=None, input_scale=None)
    zs = (np.concatenate([q, qd, t[:, None]], 1) - mu) / sd
    np.testing.assert_allclose(
        uan_force(params["uan"], q, qd, t, cfg),
        uan_force(params["uan"], zs[:, :2], zs[:, 2:4], zs[:, 4], raw),
        atol=1e-12,
    )
    lag_std = lnn_value(params["lnn"], q, qd, cfg) - 0.5 * jnp.sum(qd**2, 1)
    lag_raw = lnn_value(params["lnn"], zs[:, :2], zs[:, 2:4], raw) - 0.5 * jnp.sum(zs[:, 2:4] ** 2, 1)
    np.testing.assert_allclose(lag_std, lag_raw, atol=1e-12)


@pytest.mark.parametrize("time", ["none", "one", "features"])
def test_free_mlp_with_angles_and_standardisation(time):
    """The one free MLP: angles as (sin, cos), standardisation folded into the first layer on the non-angle q, q̇ and
    a single time column (not on time features), any number of time columns."""
    from nnphd.engine.models import free_force, init_free

    rng = np.random.default_rng(6)
    q, qd, t = rng.normal(3, 2, (40, 2)), rng.normal(-1, 0.5, (40, 2)), rng.uniform(0, 50, 40)
    cfg = ModelConfig(n=2, uan_widths=(8, 8), periodic=(1,)).standardized(q, qd, t)
    raw = cfg.replace(input_shift=None, input_scale=None)
    mu, sd = np.asarray(cfg.input_shift), np.asarray(cfg.input_scale)
    tin = {"none": None, "one": t, "features": np.stack([np.sin(t), np.cos(t), t], 1)}[time]
    n_time = {"none": 0, "one": 1, "features": 3}[time]
    layers = init_free(jax.random.PRNGKey(1), cfg, n_time=n_time)
    assert layers[0]["w"].shape == (5 + n_time, 8)  # x, sin θ, cos θ, ẋ, θ̇, time
    q_s = q.copy()
    q_s[:, 0] = (q[:, 0] - mu[0]) / sd[0]  # the angle keeps its radians (sin/cos of the raw value)
    qd_s = (qd - mu[2:4]) / sd[2:4]
    t_s = None if tin is None else ((t - mu[4]) / sd[4] if time == "one" else tin)
    got = free_force(layers, jnp.asarray(q), jnp.asarray(qd), None if tin is None else jnp.asarray(tin), cfg)
    want = free_force(layers, jnp.asarray(q_s), jnp.asarray(qd_s), None if t_s is None else jnp.asarray(t_s), raw)
    np.testing.assert_allclose(got, want, atol=1e-12)
    x = np.concatenate(
        [q_s[:, :1], np.sin(q[:, 1:]), np.cos(q[:, 1:]), qd_s] + ([] if t_s is None else [np.reshape(t_s, (40, -1))]), 1
    )
    h = x
    for layer in layers[:-1]:
        h = np.where(h @ layer["w"] + layer["b"] > 0, 1.0, 0.2) * (h @ layer["w"] + layer["b"])
    np.testing.assert_allclose(got, h @ layers[-1]["w"] + layers[-1]["b"], atol=1e-12)  # leaky ReLU 0.2, by hand
