"""Shape classes: rows, windows and steps padded so that one compiled program serves records of many lengths, with
the padding inert — the same numbers as unpadded (to 1e-10), against references that pad nothing."""

import jax
import jax.numpy as jnp
import numpy as np
import optax
import pytest
from test_alongside import _rk4_written_out

from nnphd.engine.batching import bucket, by_rows, pad_rows
from nnphd.engine.shooting import (
    Integrator,
    ShootingWindows,
    model_jac,
    model_residuals,
    model_residuals_and_jac,
    pad_windows,
    shooting_windows,
    window_shape_class,
)
from nnphd.engine.train import TrainConfig, make_trainer, pnorm


def test_the_classes_of_rows_windows_and_steps():
    assert [bucket(n) for n in (1, 44, 1024, 1025, 4565, 16384)] == [1024, 1024, 1024, 2048, 8192, 16384]
    assert bucket(5, minimum=1) == 8 and bucket(1, minimum=1) == 1
    assert window_shape_class(7, 10) == ((8,), 10)
    assert window_shape_class(1, 58) == ((1,), 128)  # a whole record: one window
    assert window_shape_class(33, 80) == ((40,), 80)
    assert window_shape_class(300, 80) == ((128, 128, 48), 80)  # beyond 128 windows: 128 at a time, the rest its own
    assert window_shape_class(1, 300) == ((1,), 384) and window_shape_class(2, 400) == ((8,), 512)
    # files of one kind and other lengths share a class: a few windows fewer, the same steps
    assert window_shape_class(40, 21) == window_shape_class(34, 21)


def test_rows_padded_by_repeating_the_last_one():
    a = np.arange(6.0).reshape(3, 2)
    (p,) = pad_rows((a,), 5)
    assert p.shape == (5, 2) and np.array_equal(p[:3], a) and np.array_equal(p[3:], [[4.0, 5.0], [4.0, 5.0]])
    with pytest.raises(ValueError, match="cannot pad 3 rows to 2"):
        pad_rows((a,), 2)


def test_a_row_function_on_padded_rows_gives_the_unpadded_numbers():
    @jax.jit
    def f(w, a):
        return jnp.tanh(a @ w) ** 3

    rng = np.random.default_rng(4)
    w = rng.normal(size=(3, 4))
    for n in (1, 37, 1100):  # padded to 1024, 1024, 2048
        a = rng.normal(size=(n, 3))
        np.testing.assert_allclose(by_rows(f, w, a), np.tanh(a @ w) ** 3, rtol=1e-12, atol=1e-14)


def _reference_train(params, arrays, lam, key, tcfg, loss):
    """The trainer written plainly, on the unpadded rows (the row count a Python int)."""
    opt = optax.adam(tcfg.schedule())
    n = arrays[0].shape[0]

    def obj(p, batch):
        le, lb = loss(p, *batch)
        return le + lam * lb

    state = opt.init(params)
    for k in jax.random.split(key, tcfg.steps):
        idx = jax.random.randint(k, (tcfg.batch_size,), 0, n)
        g = jax.grad(obj)(params, tuple(a[idx] for a in arrays))
        up, state = opt.update(g, state, params)
        params = optax.apply_updates(params, up)
    return params


def test_training_on_rows_padded_to_their_class_is_training_on_the_rows():
    tcfg = TrainConfig(steps=40, batch_size=8)

    def loss(p, q, qd, t, qdd):  # a small nonlinear model: q̈ = a·tanh(b q) + c q̇
        r = p["a"] * jnp.tanh(p["b"] * q) + p["c"] * qd - qdd
        return pnorm(r, 1.0), pnorm(p["c"] * qd, 1.0)

    rng = np.random.default_rng(5)
    n = 44  # padded to 1024 by the trainer
    q, qd, t = rng.normal(size=(n, 1)), rng.normal(size=(n, 1)), rng.normal(size=(n, 1))
    qdd = -2.0 * np.tanh(0.7 * q) - 0.1 * qd
    arrays = tuple(jnp.asarray(a) for a in (q, qd, t, qdd))
    p0 = {"a": jnp.asarray(-1.0), "b": jnp.asarray(1.0), "c": jnp.asarray(0.0)}
    key, lam = jax.random.PRNGKey(7), jnp.asarray(0.5)
    got, _ = make_trainer(None, tcfg, loss)(p0, arrays, lam, key)
    want = _reference_train(p0, arrays, lam, key, tcfg, loss)
    for k in p0:
        np.testing.assert_allclose(float(got[k]), float(want[k]), rtol=1e-10, atol=1e-12)
    assert abs(float(got["a"]) - float(p0["a"])) > 1e-3  # it trained: a comparison that can fail


def _pendulum_windows(n_rows, periods=0.75):
    rng = np.random.default_rng(3)
    t = np.cumsum(rng.uniform(0.05, 0.12, n_rows))  # an uneven clock
    q = (0.6 * np.exp(-0.05 * t) * np.cos(2.0 * t))[:, None]
    qd = np.gradient(q[:, 0], t)[:, None]
    wins = [np.arange(t.size)] if periods is None else shooting_windows([np.arange(t.size)], t, np.pi, periods=periods)
    tw, qw, mask, s0 = pad_windows(wins, t, q, (q, qd))
    t0w, tw = tw[:, 0].copy(), tw - tw[:, :1]
    windows = ShootingWindows(jnp.asarray(tw), jnp.asarray(t0w), jnp.asarray(qw), jnp.asarray(mask), jnp.asarray([1.0]))
    return windows, tw, qw, mask, s0


def _rhs(theta, q_, v_, tt, aux):
    return -aux * jnp.sin(q_) - theta[0] * v_


@pytest.mark.parametrize("n_rows, periods", [(120, 0.75), (5000, 0.75), (120, None)])
def test_shooting_residuals_on_padded_windows_are_those_written_out(n_rows, periods):
    """7 windows (padded to 8); 130+ (128 at a time, the rest padded); one whole record of 120 steps (to 128)."""
    windows, tw, qw, mask, s0 = _pendulum_windows(n_rows, periods)
    W, L = tw.shape
    assert window_shape_class(W, L) != ((W,), L) and (n_rows < 1000 or W > 128)
    r = model_residuals(s0, jnp.asarray([0.07]), jnp.asarray(4.0), windows, Integrator(_rhs, 2))
    assert np.shape(r) == (W, L, 1)
    want = _rk4_written_out(s0, tw, qw, 0.07, 4.0, 2) * mask[..., None]
    np.testing.assert_allclose(np.asarray(r), want, rtol=0, atol=1e-12)
    assert np.max(np.abs(want)) > 1e-3


def test_shooting_derivatives_do_not_depend_on_the_padding_or_the_chunks():
    """The derivatives of 130+ windows (128 at a time, the rest padded) are, window for window, those of the same
    windows fitted in other classes (the first 8 alone; windows 3–5: padded windows),
    and match finite differences."""
    windows, tw, qw, mask, s0 = _pendulum_windows(5000)
    model, th, aux = Integrator(_rhs, 2), jnp.asarray([0.07]), jnp.asarray(4.0)
    r, jac = model_residuals_and_jac(s0, th, aux, windows, model)
    assert np.array_equal(np.asarray(model_jac(s0, th, aux, windows, model)), np.asarray(jac))
    assert np.array_equal(np.asarray(model_residuals(s0, th, aux, windows, model)), np.asarray(r))
    for sl in (slice(0, 8), slice(3, 6), slice(126, 131)):
        sub = ShootingWindows(*(a[sl] for a in windows[:4]), windows.inv_sigma)
        r_s, j_s = model_residuals_and_jac(s0[sl], th, aux, sub, model)
        np.testing.assert_allclose(np.asarray(r_s), np.asarray(r)[sl], rtol=0, atol=1e-10)
        np.testing.assert_allclose(np.asarray(j_s), np.asarray(jac)[:, sl], rtol=0, atol=1e-10)
    h = 1e-6
    fd = (np.asarray(model_residuals(s0, th.at[0].add(h), aux, windows, model)) - np.asarray(r)) / h
    np.testing.assert_allclose(np.asarray(jac)[-1], fd, rtol=0, atol=1e-4 * np.max(np.abs(fd)))
    assert np.max(np.abs(fd)) > 1e-3
