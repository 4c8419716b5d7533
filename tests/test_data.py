"""Data generation: RK4 accuracy, labelling, samplers, argument validation."""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import nnphd  # noqa: F401  (enables float64)
from nnphd.engine.data import (
    Dataset,
    gaussian_dataset,
    imbalanced_dataset,
    label,
    pie_dataset,
    rk4_trajectory,
    train_test,
    trajectory_dataset,
)
from nnphd.engine.systems import SYSTEMS, get_system


def _sho(q, qd, t):
    return -q


def _euler_lagrange(L, q, qd):
    """q̈ = (∂²L/∂q̇²)⁻¹ (∂L/∂q − (∂²L/∂q̇∂q) q̇) by autodiff of L(q, q̇)."""
    H = jax.hessian(L, argnums=(0, 1))(q, qd)
    return jnp.linalg.solve(H[1][1], jax.grad(L, argnums=0)(q, qd) - H[1][0] @ qd)


def test_rk4_matches_cosine():
    t, q, qd = rk4_trajectory(_sho, [1.0, 0.0], 0.01, 1000)
    assert t.shape == (1001,) and q.shape == (1001, 1) and qd.shape == (1001, 1)
    assert q.dtype == jnp.float64 and t.dtype == jnp.float64
    np.testing.assert_allclose(t, 0.01 * np.arange(1001), rtol=0, atol=1e-12)
    np.testing.assert_allclose(q[:, 0], np.cos(np.asarray(t)), rtol=0, atol=1e-8)
    np.testing.assert_allclose(qd[:, 0], -np.sin(np.asarray(t)), rtol=0, atol=1e-8)


def test_rk4_fourth_order_and_time_dependence():
    # q̈ = cos t, q(t0)=0, q̇(t0)=0 with t0 = 1:  q = -cos t + cos t0 - (t - t0) sin t0
    f = lambda q, qd, t: jnp.cos(t) * jnp.ones_like(q)  # noqa: E731
    t0 = 1.0
    errs = []
    for dt, n in [(0.2, 25), (0.1, 50)]:
        t, q, qd = rk4_trajectory(f, [0.0, 0.0], dt, n, t0=t0)
        tt = np.asarray(t)
        assert tt[0] == t0 and tt[-1] == pytest.approx(t0 + 5.0)
        exact = -np.cos(tt) + math.cos(t0) - (tt - t0) * math.sin(t0)
        errs.append(np.max(np.abs(np.asarray(q)[:, 0] - exact)))
    assert errs[1] < 1e-5 and errs[0] / errs[1] > 12.0  # ~2^4


def test_rk4_2d_rotation():
    # ho+mf with k=0, B=1: a cyclotron orbit; from q=(0,0), q̇=(1,0): q = (sin t, cos t - 1)
    s = get_system("ho+mf", k=0.0)
    t, q, qd = rk4_trajectory(s.f, [0.0, 0.0, 1.0, 0.0], 0.01, 700)
    tt = np.asarray(t)
    np.testing.assert_allclose(q, np.stack([np.sin(tt), np.cos(tt) - 1.0], axis=1), atol=1e-9)


def test_rk4_bad_arguments():
    with pytest.raises(ValueError, match="n_steps"):
        rk4_trajectory(_sho, [1.0, 0.0], 0.1, 0)
    with pytest.raises(ValueError, match="dt"):
        rk4_trajectory(_sho, [1.0, 0.0], -0.1, 10)
    with pytest.raises(ValueError, match="x0"):
        rk4_trajectory(_sho, [1.0, 0.0, 0.0], 0.1, 10)


def test_label_matches_system():
    s = SYSTEMS["ho+pf"]
    q = np.array([[0.5], [-1.0], [2.0]])
    qd = np.array([[1.0], [0.0], [-3.0]])
    t = np.array([0.0, 1.0, -2.0])
    d = label(s, q, qd, t)
    np.testing.assert_allclose(d.fc, -q, rtol=1e-15)
    np.testing.assert_allclose(d.fn[:, 0], 0.5 * np.sin(t), rtol=1e-15)
    # the label is the system's equation of motion, q̈ = −k q + a sin t with k = 1, a = 0.5
    np.testing.assert_allclose(d.qdd[:, 0], -q[:, 0] + 0.5 * np.sin(t), rtol=1e-15, atol=1e-15)
    assert isinstance(d.q, np.ndarray) and d.q.dtype == np.float64 and len(d) == 3


@pytest.mark.parametrize(
    "name,N,n",
    [
        pytest.param("double-pendulum", 301, 2, marks=pytest.mark.slow),
        pytest.param("neptune", 1001, 2, marks=pytest.mark.slow),
        ("gw", 301, 2),
    ],
)
def test_trajectory_dataset_defaults(name, N, n):
    s = SYSTEMS[name]
    d = trajectory_dataset(s)
    assert d.q.shape == (N, n) and d.qd.shape == (N, n) and d.t.shape == (N,) and d.qdd.shape == (N, n)
    assert d.fc.shape == d.fn.shape == (N, n)
    np.testing.assert_allclose(d.t, s.dt * np.arange(N), atol=1e-12)
    np.testing.assert_allclose(np.concatenate([d.q[0], d.qd[0]]), s.x0, rtol=0, atol=0)
    # f_c is the Euler–Lagrange acceleration of the system's Lagrangian (autodiff, independent of the closed-form
    # f_c), and q̈ is that plus f_n, at every state of the trajectory
    el = np.asarray(jax.jit(jax.vmap(lambda q, qd: _euler_lagrange(s.lagrangian, q, qd)))(d.q, d.qd))  # op by op: 4 s
    np.testing.assert_allclose(d.fc, el, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(d.qdd - d.fn, el, rtol=1e-10, atol=1e-12)
    # labels agree with the system at a sample row
    i = N // 3
    np.testing.assert_allclose(d.fn[i], s.f_n(d.q[i], d.qd[i], d.t[i]), rtol=1e-13)
    # the trajectory is consistent with its labels: q̇(t+dt) - q̇(t-dt) = ∫q̈ dt, Simpson's rule on the labels
    dv = d.qd[2:] - d.qd[:-2]
    simpson = s.dt / 3 * (d.qdd[:-2] + 4 * d.qdd[1:-1] + d.qdd[2:])
    tol = {"double-pendulum": 5e-3, "neptune": 1e-6, "gw": 1e-8}[name]  # Simpson error O(dt^5 f'''') per step
    assert np.max(np.abs(dv - simpson)) < tol


def test_trajectory_dataset_overrides_and_names():
    d = trajectory_dataset("ho+ld", x0=(1.0, 0.0), dt=0.01, n_steps=100)
    assert len(d) == 101
    g, w = 0.5, math.sqrt(1 - 0.0625)
    x = np.exp(-g * d.t / 2) * (np.cos(w * d.t) + g / (2 * w) * np.sin(w * d.t))
    np.testing.assert_allclose(d.q[:, 0], x, atol=1e-10)
    with pytest.raises(ValueError, match="x0"):
        trajectory_dataset("ho+ld", x0=(1.0, 0.0, 0.0, 0.0))


def test_gaussian_dataset_shapes_seeds_statistics():
    s = SYSTEMS["ho+mf"]
    d = gaussian_dataset(s, 4000, seed=0)
    assert d.q.shape == (4000, 2) and d.qd.shape == (4000, 2) and d.t.shape == (4000,) and d.qdd.shape == (4000, 2)
    for a in (d.q, d.qd, d.t):
        assert abs(a.mean()) < 0.06 and abs(a.std() - 1.0) < 0.05
    np.testing.assert_allclose(d.qdd, -d.q + np.stack([d.qd[:, 1], -d.qd[:, 0]], axis=1), rtol=1e-14, atol=1e-15)
    np.testing.assert_array_equal(d.fn, 0.0)
    d2 = gaussian_dataset(s, 4000, seed=0)
    np.testing.assert_array_equal(d.q, d2.q)
    np.testing.assert_array_equal(d.t, d2.t)
    d3 = gaussian_dataset(s, 4000, seed=1)
    assert not np.allclose(d.q, d3.q)


def test_dataset_subset_and_validation():
    d = gaussian_dataset("ho+cd", 10, seed=3)
    sub = d.subset(np.array([1, 3, 5]))
    assert len(sub) == 3 and sub.q.shape == (3, 1)
    np.testing.assert_array_equal(sub.qdd, d.qdd[[1, 3, 5]])
    np.testing.assert_array_equal(sub.fn, d.fn[[1, 3, 5]])
    np.testing.assert_allclose(d.fn[:, 0], -0.5 * np.sign(d.qd[:, 0]), rtol=0)
    assert len(d.subset(slice(0, 4))) == 4 and len(d.subset(d.qd[:, 0] > 0)) == int(np.sum(d.qd[:, 0] > 0))
    bare = Dataset(q=np.zeros((2, 1)), qd=np.zeros((2, 1)), t=np.zeros(2), qdd=np.zeros((2, 1)))
    assert bare.subset([0]).fc is None
    with pytest.raises(ValueError, match="qdd"):
        Dataset(q=np.zeros((2, 1)), qd=np.zeros((2, 1)), t=np.zeros(2), qdd=np.zeros((3, 1)))


def test_pie_dataset_sectors():
    s = SYSTEMS["ho+ld"]
    half = pie_dataset(s, 3000, alpha=0.5, seed=0)
    assert half.q.shape == (3000, 1) and half.t.shape == (3000,)
    assert np.all(half.qd >= 0.0) and np.mean(half.q < 0) == pytest.approx(0.5, abs=0.04)
    quarter = pie_dataset(s, 3000, alpha=0.25, seed=0)
    assert np.all(quarter.q >= 0.0) and np.all(quarter.qd >= 0.0)
    full = pie_dataset(s, 20000, alpha=1.0, seed=0)
    assert np.mean(full.qd < 0) == pytest.approx(0.5, abs=0.02)
    # radius of an isotropic standard Gaussian: Rayleigh(1), E r² = 2, P(r < 1) = 1 - e^{-1/2}
    r2 = full.q[:, 0] ** 2 + full.qd[:, 0] ** 2
    assert r2.mean() == pytest.approx(2.0, rel=0.04)
    assert np.mean(r2 < 1.0) == pytest.approx(1 - math.exp(-0.5), abs=0.01)
    # angles fill the sector: three-quarter pie has ~1/3 of its points in the third quadrant
    tq = pie_dataset(s, 6000, alpha=0.75, seed=1)
    assert np.mean((tq.q < 0) & (tq.qd < 0)) == pytest.approx(1 / 3, abs=0.03)
    assert not np.any((tq.q > 0) & (tq.qd < 0))
    np.testing.assert_allclose(half.qdd, -half.q - 0.5 * half.qd, rtol=1e-14, atol=1e-15)
    np.testing.assert_array_equal(pie_dataset(s, 50, 0.3, seed=7).q, pie_dataset(s, 50, 0.3, seed=7).q)


def test_imbalanced_dataset():
    s = SYSTEMS["ho+cd"]
    d = imbalanced_dataset(s, 1000, beta=0.8, seed=0)
    assert d.q.shape == (1000, 1)
    assert int(np.sum(d.qd > 0)) == 800 and int(np.sum(d.qd < 0)) == 200
    assert imbalanced_dataset(s, 7, beta=0.5, seed=0).qd.__gt__(0).sum() in (3, 4)  # round(3.5)
    assert np.all(imbalanced_dataset(s, 100, beta=1.0, seed=0).qd > 0)
    assert np.all(imbalanced_dataset(s, 100, beta=0.0, seed=0).qd < 0)
    # |q̇| is half-normal, q ~ N(0,1)
    big = imbalanced_dataset(s, 20000, beta=0.3, seed=2)
    assert np.mean(np.abs(big.qd)) == pytest.approx(math.sqrt(2 / math.pi), rel=0.03)
    assert abs(big.q.mean()) < 0.03 and big.q.std() == pytest.approx(1.0, rel=0.03)
    np.testing.assert_allclose(d.fn[:, 0], -0.5 * np.sign(d.qd[:, 0]), rtol=0)
    np.testing.assert_array_equal(d.qd, imbalanced_dataset(s, 1000, beta=0.8, seed=0).qd)


def test_train_test():
    tr, te = train_test("ho+pf", seed=0, n_train=200, n_test=100)
    assert len(tr) == 200 and len(te) == 100
    assert not np.isin(tr.q, te.q).any()  # independent draws
    tr2, te2 = train_test(SYSTEMS["ho+pf"], seed=0, n_train=200, n_test=100)
    np.testing.assert_array_equal(tr.q, tr2.q)
    np.testing.assert_array_equal(te.t, te2.t)
    tr3, _ = train_test("ho+pf", seed=1, n_train=200, n_test=100)
    assert not np.allclose(tr.q, tr3.q)
    traj, none = train_test("gw", seed=0)
    assert none is None and len(traj) == 301 and traj.t[-1] == pytest.approx(15.0)


def test_bad_arguments():
    s1, s2 = SYSTEMS["ho+ld"], SYSTEMS["ho+mf"]
    with pytest.raises(ValueError, match="alpha"):
        pie_dataset(s1, 10, alpha=1.5, seed=0)
    with pytest.raises(ValueError, match="alpha"):
        pie_dataset(s1, 10, alpha=-0.1, seed=0)
    with pytest.raises(ValueError, match="beta"):
        imbalanced_dataset(s1, 10, beta=2.0, seed=0)
    with pytest.raises(ValueError, match="n_samples"):
        gaussian_dataset(s1, 0, seed=0)
    with pytest.raises(ValueError, match="n_samples"):
        pie_dataset(s1, 2.5, alpha=0.5, seed=0)
    with pytest.raises(ValueError, match="n == 1"):
        pie_dataset(s2, 10, alpha=0.5, seed=0)
    with pytest.raises(ValueError, match="n == 1"):
        imbalanced_dataset(s2, 10, beta=0.5, seed=0)
    with pytest.raises(ValueError, match="n_train"):
        train_test(s1, seed=0, n_train=0)
    with pytest.raises(ValueError, match="unknown system"):
        gaussian_dataset("nope", 10, seed=0)
