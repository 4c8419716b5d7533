"""Periodic (angle) coordinates in the LNN: ModelConfig.periodic, embed_periodic and the hand-written pass."""

from functools import partial

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import nnphd  # noqa: F401  (enables float64)
from nnphd.engine import models
from nnphd.engine.data import rk4_trajectory
from nnphd.engine.models import ModelConfig, embed_periodic, init_lnn, lnn_value
from nnphd.engine.train import TrainConfig, make_trainer

TWO_PI = 2 * np.pi

# jitted (cfg static) so the per-op dispatch of the eager jax.hessian reference does not dominate the test time
lnn_accel = jax.jit(models.lnn_accel, static_argnames="cfg")
lnn_accel_reference = jax.jit(models.lnn_accel_reference, static_argnames="cfg")
lnn_derivatives = jax.jit(models.lnn_derivatives, static_argnames="cfg")
lnn_energy = jax.jit(models.lnn_energy, static_argnames="cfg")


def _states(n, periodic, b=11, seed=0, big=100.0):
    """Random states: periodic coordinates of size ~big (whole turns), the others O(1)."""
    rng = np.random.default_rng(seed)
    q = rng.normal(size=(b, n))
    for i in periodic:
        q[:, i] = rng.uniform(-big, big, b)
    return jnp.asarray(q), jnp.asarray(rng.normal(size=(b, n)) * 2.0)


@partial(jax.jit, static_argnames="cfg")
def _autodiff_derivatives(lnn, q, qd, cfg):
    """(∇_q L, ∂²L/∂q̇², (∂²L/∂q̇∂q) q̇) per sample by jax.grad / jax.hessian of lnn_value."""
    n = q.shape[-1]

    def one(qi, qdi):
        lz = lambda z: lnn_value(lnn, z[None, :n], z[None, n:], cfg)[0]  # noqa: E731
        z = jnp.concatenate([qi, qdi])
        g, h = jax.grad(lz)(z), jax.hessian(lz)(z)
        return g[:n], h[n:, n:], h[n:, :n] @ qdi

    return jax.vmap(one)(q, qd)


# ---- the embedding and the config ------------------------------------------------------------------------------------


def test_embed_periodic_order_and_identity():
    q = jnp.asarray(np.random.default_rng(0).normal(size=(5, 3)) * 50)
    np.testing.assert_array_equal(embed_periodic(q, ()), q)
    e = embed_periodic(q, (2, 0))  # sorted: [q1, sin q0, sin q2, cos q0, cos q2]
    expected = jnp.stack([q[:, 1], jnp.sin(q[:, 0]), jnp.sin(q[:, 2]), jnp.cos(q[:, 0]), jnp.cos(q[:, 2])], axis=-1)
    np.testing.assert_allclose(e, expected, atol=0, rtol=0)
    assert embed_periodic(q[0], (1,)).shape == (4,)  # single sample (n,) → (n + |P|,)


def test_config_validates_and_sorts_periodic():
    assert ModelConfig(n=3, periodic=[2, 0]).periodic == (0, 2)
    assert ModelConfig(n=3, periodic=(np.int64(1),)).periodic == (1,)
    assert ModelConfig(n=3).periodic == ()
    with pytest.raises(ValueError, match="out of range"):
        ModelConfig(n=2, periodic=(2,))
    with pytest.raises(ValueError, match="out of range"):
        ModelConfig(n=2, periodic=(-1,))
    with pytest.raises(ValueError, match="unique"):
        ModelConfig(n=2, periodic=(1, 1))
    with pytest.raises(ValueError, match="integers"):
        ModelConfig(n=2, periodic=(0.5,))
    with pytest.raises(ValueError, match="integers"):
        ModelConfig(n=2, periodic=(True,))
    with pytest.raises(ValueError, match="sequence"):
        ModelConfig(n=2, periodic=0)
    with pytest.raises(ValueError, match="out of range"):
        embed_periodic(jnp.zeros((3, 2)), (5,))


def test_init_lnn_fan_in_grows_by_the_number_of_angles():
    for per, fan_in in [((), 4), ((0,), 5), ((0, 1), 6)]:
        lnn = init_lnn(jax.random.PRNGKey(0), ModelConfig(n=2, lnn_widths=(7,), periodic=per))
        assert lnn[0]["w"].shape == (fan_in, 7)


# ---- the hand-written pass against jax.hessian ----------------------------------------------------------------------


# tanh with one angle of two: slow tier (the fast tier has tanh with two angles, softplus+quadratic with both)
@pytest.mark.parametrize(
    "periodic, act",
    [((0,), "softplus+quadratic"), ((0, 1), "softplus+quadratic"), ((0, 1), "tanh"),
     pytest.param((0,), "tanh", marks=pytest.mark.slow)],
)  # fmt: skip
def test_periodic_pass_equals_hessian_reference(periodic, act):
    cfg = ModelConfig(n=2, lnn_widths=(40, 30), lnn_activation=act, lnn_out_scale=1.0, periodic=periodic)
    lnn = init_lnn(jax.random.PRNGKey(5), cfg)
    q, qd = _states(2, periodic)
    assert float(jnp.max(jnp.abs(q))) > 80  # whole turns
    ours = lnn_accel(lnn, q, qd, cfg)
    ref = lnn_accel_reference(lnn, q, qd, cfg)
    assert float(jnp.max(jnp.abs(ref))) > 1e-2
    np.testing.assert_allclose(ours, ref, atol=1e-10, rtol=0)
    for a, b in zip(lnn_derivatives(lnn, q, qd, cfg), _autodiff_derivatives(lnn, q, qd, cfg)):
        assert float(jnp.max(jnp.abs(b))) > 1e-3
        np.testing.assert_allclose(a, b, atol=1e-10, rtol=0)


@pytest.mark.slow  # tens of seconds: run by `python3 dev.py test --slow` (and by CI)
@pytest.mark.parametrize("periodic", [(0, 2)])
def test_periodic_pass_n3_with_standardisation_and_parameter_gradients(periodic):
    # non-contiguous / middle angle indices, standardisation on, three hidden layers; gradients w.r.t. the weights
    cfg = ModelConfig(n=3, lnn_widths=(20, 20, 20), lnn_out_scale=1.0, periodic=periodic)
    q, qd = _states(3, periodic, seed=3)
    rng = np.random.default_rng(9)
    cfg = cfg.standardized(q + rng.normal(size=q.shape), qd * 3 + 1, rng.normal(size=q.shape[0]))
    lnn = init_lnn(jax.random.PRNGKey(2), cfg)
    np.testing.assert_allclose(
        jax.jit(lambda p: lnn_accel(p, q, qd, cfg))(lnn),
        jax.jit(lambda p: lnn_accel_reference(p, q, qd, cfg))(lnn),
        atol=1e-10,
        rtol=0,
    )
    derivs = jax.jit(lambda p: (lnn_derivatives(p, q, qd, cfg), _autodiff_derivatives(p, q, qd, cfg)))(lnn)
    for a, b in zip(*derivs):
        np.testing.assert_allclose(a, b, atol=1e-10, rtol=0)
    g1 = jax.jit(jax.grad(lambda p: jnp.sum(lnn_accel(p, q, qd, cfg) ** 2)))(lnn)
    g2 = jax.jit(jax.grad(lambda p: jnp.sum(lnn_accel_reference(p, q, qd, cfg) ** 2)))(lnn)
    for a, b in zip(jax.tree_util.tree_leaves(g1), jax.tree_util.tree_leaves(g2)):
        np.testing.assert_allclose(a, b, atol=1e-9)


def test_standardisation_ignores_the_shift_and_scale_of_angle_columns():
    # with periodic=(0,), the shift/scale of q_0 must not change L (only q_1, q̇ and t are standardised)
    base = ModelConfig(n=2, lnn_widths=(16,), lnn_out_scale=1.0, periodic=(0,))
    lnn = init_lnn(jax.random.PRNGKey(1), base)
    q, qd = _states(2, (0,))
    c1 = base.replace(input_shift=(0.0, 0.3, -0.2, 0.1, 0.0), input_scale=(1.0, 2.0, 1.5, 0.7, 1.0))
    c2 = base.replace(input_shift=(40.0, 0.3, -0.2, 0.1, 5.0), input_scale=(30.0, 2.0, 1.5, 0.7, 9.0))
    np.testing.assert_allclose(lnn_value(lnn, q, qd, c1), lnn_value(lnn, q, qd, c2), atol=1e-13, rtol=0)
    np.testing.assert_allclose(lnn_accel(lnn, q, qd, c1), lnn_accel(lnn, q, qd, c2), atol=1e-12, rtol=0)
    # ...while that of q_1 does
    c3 = c1.replace(input_shift=(0.0, 1.3, -0.2, 0.1, 0.0))
    assert float(jnp.max(jnp.abs(lnn_value(lnn, q, qd, c1) - lnn_value(lnn, q, qd, c3)))) > 1e-3


# ---- periodicity ---------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("periodic", [(0,), (0, 1)])
def test_accel_and_energy_are_2pi_periodic_in_the_angles(periodic):
    cfg = ModelConfig(n=2, lnn_widths=(32, 32), lnn_out_scale=1.0, periodic=periodic)
    lnn = init_lnn(jax.random.PRNGKey(4), cfg)
    q, qd = _states(2, periodic, big=10.0)
    a0, e0 = lnn_accel(lnn, q, qd, cfg), lnn_energy(lnn, q, qd, cfg)
    for i in range(2):
        for k in (1, -1, 17, -17):
            qs = q.at[:, i].add(TWO_PI * k)
            a1, e1 = lnn_accel(lnn, qs, qd, cfg), lnn_energy(lnn, qs, qd, cfg)
            if i in periodic:
                np.testing.assert_allclose(a1, a0, atol=1e-9, rtol=0)
                np.testing.assert_allclose(e1, e0, atol=1e-9, rtol=0)
            else:  # sanity: a plain coordinate is not periodic
                assert float(jnp.max(jnp.abs(a1 - a0))) > 1e-3
                assert float(jnp.max(jnp.abs(e1 - e0))) > 1e-3


# ---- known Lagrangians -----------------------------------------------------------------------------------------------


def test_exact_pendulum_in_the_network():
    # L = ½θ̇² (split trick) + cos θ + ½ with z = (sin θ, cos θ, θ̇) and quadratic units σ(a) = a²/2:
    # σ(cos θ + 1) − σ(cos θ) = cos θ + ½  →  θ̈ = −sin θ, H = ½θ̇² − cos θ − ½, for θ of any size.
    cfg = ModelConfig(n=1, lnn_widths=(2,), lnn_activation="quadratic", periodic=(0,))
    w1 = jnp.array([[0.0, 0.0], [1.0, 1.0], [0.0, 0.0]])
    lnn = [{"w": w1, "b": jnp.array([1.0, 0.0])}, {"w": jnp.array([[1.0], [-1.0]]), "b": jnp.zeros(1)}]
    q, qd = _states(1, (0,), b=25)
    np.testing.assert_allclose(lnn_accel(lnn, q, qd, cfg), -jnp.sin(q), atol=1e-10, rtol=0)
    np.testing.assert_allclose(lnn_accel_reference(lnn, q, qd, cfg), -jnp.sin(q), atol=1e-10, rtol=0)
    h = 0.5 * qd[:, 0] ** 2 - jnp.cos(q[:, 0]) - 0.5
    np.testing.assert_allclose(lnn_energy(lnn, q, qd, cfg), h, atol=1e-12, rtol=0)


@pytest.mark.parametrize("periodic", [(0,), (0, 1)])
def test_velocity_independent_network_gives_minus_grad_potential(periodic):
    # first-layer rows of q̇ zeroed: L = ½|q̇|² − V(q) with −V = L_NN(φ(q)), so q̈ = −∇V = ∇_q L_NN (autodiff).
    cfg = ModelConfig(n=2, lnn_widths=(24, 24), lnn_out_scale=1.0, periodic=periodic)
    lnn = init_lnn(jax.random.PRNGKey(8), cfg)
    lnn[0] = {"w": lnn[0]["w"].at[-2:].set(0.0), "b": lnn[0]["b"]}
    q, qd = _states(2, periodic)
    minus_dv = jax.jit(jax.grad(lambda qq: jnp.sum(lnn_value(lnn, qq, qd, cfg))))(q)
    assert float(jnp.max(jnp.abs(minus_dv))) > 1e-2
    np.testing.assert_allclose(lnn_accel(lnn, q, qd, cfg), minus_dv, atol=1e-10, rtol=0)


def _pendulum(q, qd, t):
    return -jnp.sin(q)


def _spinning_pendulum_data(seed, k=8):
    """k rotating-pendulum trajectories (θ̇₀ = ±2.2…4, above the separatrix): θ runs through whole turns."""
    rng = np.random.default_rng(seed)
    qs, vs = [], []
    for _ in range(k):
        x0 = [rng.uniform(-np.pi, np.pi), rng.choice([-1, 1]) * rng.uniform(2.2, 4.0)]
        _, q, qd = rk4_trajectory(_pendulum, x0, 0.05, 400)
        qs.append(q)
        vs.append(qd)
    q, qd = jnp.concatenate(qs), jnp.concatenate(vs)
    return q, qd, jnp.zeros(q.shape[0]), -jnp.sin(q)


def _rel_l1(lnn, data, cfg):
    q, qd, _, qdd = data
    return float(jnp.mean(jnp.abs(lnn_accel(lnn, q, qd, cfg) - qdd)) / jnp.mean(jnp.abs(qdd)))


@pytest.mark.slow  # two training runs: slow tier (`python3 dev.py test --slow`, and CI)
def test_training_on_a_spinning_pendulum_needs_the_embedding():
    train_data, test_data = _spinning_pendulum_data(0), _spinning_pendulum_data(1)
    assert float(jnp.max(jnp.abs(train_data[0]))) > 50 and float(jnp.max(jnp.abs(train_data[1]))) > 3
    errors = {}
    for periodic in [(0,), ()]:
        cfg = ModelConfig(n=1, lnn_widths=(32, 32), periodic=periodic).standardized(*train_data[:3])

        def loss(params, q, qd, t, qdd, cfg=cfg):
            r = models.lnn_accel(params["lnn"], q, qd, cfg) - qdd
            return jnp.mean(jnp.abs(r)), jnp.zeros((), r.dtype)

        train = make_trainer(cfg, TrainConfig(steps=1500, lrs=(3e-3, 1e-3, 3e-4), batch_size=64), loss)
        params, _ = train({"lnn": init_lnn(jax.random.PRNGKey(0), cfg)}, train_data, 0.0, jax.random.PRNGKey(1))
        errors[periodic] = _rel_l1(params["lnn"], test_data, cfg)
        if periodic:  # the learned force is periodic: angles 100 turns away are just as good
            far = (test_data[0] + TWO_PI * 100, *test_data[1:])
            assert _rel_l1(params["lnn"], far, cfg) < 0.05
    # measured: 0.0014 with the embedding, 1.0004 without (the plain net only learns ≈ 0)
    assert errors[(0,)] < 0.05, errors
    assert errors[()] > 0.5, errors
    assert errors[()] / errors[(0,)] > 20, errors


# ---- the default path ----------------------------------------------------------------------------------------------


def test_default_path_unchanged_and_periodic_equals_manual_embedding():
    # periodic=() is the plain network (same weights shape, matches the reference) ...
    cfg = ModelConfig(n=2, lnn_widths=(16, 16), lnn_out_scale=1.0)
    lnn = init_lnn(jax.random.PRNGKey(6), cfg)
    q, qd = _states(2, (), big=1.0)
    assert lnn[0]["w"].shape == (4, 16)
    np.testing.assert_allclose(lnn_accel(lnn, q, qd, cfg), lnn_accel_reference(lnn, q, qd, cfg), atol=1e-10, rtol=0)
    # ... and periodic=(0,) is exactly that plain network applied to (q_1, sin q_0, cos q_0, q̇)
    cfg_p = ModelConfig(n=2, lnn_widths=(16, 16), lnn_out_scale=1.0, periodic=(0,))
    lnn_p = init_lnn(jax.random.PRNGKey(6), cfg_p)
    qp, qdp = _states(2, (0,))
    z = jnp.concatenate([embed_periodic(qp, (0,)), qdp], axis=-1)
    h = z
    for layer in lnn_p[:-1]:
        a = h @ layer["w"] + layer["b"]
        half = (a.shape[-1] + 1) // 2
        h = jnp.concatenate([jax.nn.softplus(a[:, :half]), 0.5 * a[:, half:] ** 2], axis=-1)
    manual = (h @ lnn_p[-1]["w"] + lnn_p[-1]["b"])[:, 0] + 0.5 * jnp.sum(qdp**2, axis=-1)
    np.testing.assert_allclose(lnn_value(lnn_p, qp, qdp, cfg_p), manual, atol=1e-12, rtol=0)
