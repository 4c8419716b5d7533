"""Sanity checks of the lab-like recordings in tests/fixtures/recordings.py (numpy/scipy only, fast).

Measured while writing this (seed 0): pendulum-damped r = 0.010946 (γ = 0.011; the prediction γ(1 − A²/24) at the
log-mid amplitude is 0.010929), cart r = 0.0140000, carts-coupled r = 0.0140010, double-pendulum r = 0.0472 with an
energy drop of 65 %; the free double pendulum conserves energy to 7e-10 (relative to E − E_min) on the dense solution.
"""

import math
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from nnphd.user.recording import load_trajectories  # noqa: E402
from tests.fixtures.recordings import (  # noqa: E402
    NAMES,
    Recording,
    double_pendulum_accel,
    energy,
    make,
    true_decay_rate,
)

VERDICTS = {"detected", "none", "inconclusive", "not-detected"}


@pytest.fixture(scope="module")
def recs():
    return {name: make(name) for name in NAMES}


def test_unknown_name_lists_the_cases():
    with pytest.raises(ValueError, match=", ".join(NAMES)):
        make("no-such-case")


@pytest.mark.parametrize("name", NAMES)
def test_shapes_and_fields(recs, name):
    out = recs
    r = out[name]
    assert isinstance(r, Recording) and r.name == name
    N, n = r.q.shape
    assert r.t.shape == (N,) and n == len(r.coords) and N == r.truth["n_samples"]
    assert np.all(np.isfinite(r.t)) and np.all(np.isfinite(r.q))
    assert set(r.angles) <= set(r.coords)
    assert r.expected in VERDICTS
    assert (r.energy_decay_rate is None) == (r.expected != "detected")
    if r.energy_decay_rate is not None:
        assert not r.conservative and r.energy_decay_rate > 0
        assert r.energy_decay_rate == r.truth["rate"]
    # t strictly increasing per trajectory, recorded times rounded to 1 ms
    ids = np.zeros(N, int) if r.traj is None else r.traj
    assert r.traj is None or (r.traj.shape == (N,) and np.issubdtype(r.traj.dtype, np.integer))
    for i in np.unique(ids):
        assert np.all(np.diff(r.t[ids == i]) > 0)
    np.testing.assert_array_equal(r.t, np.round(r.t, 3))
    if "t_true" in r.truth:
        assert np.max(np.abs(r.t - r.truth["t_true"])) <= 5e-4 + 0.05 * np.median(np.diff(r.t))


def test_seeds_reproducible():
    a, b, c = make("pendulum-damped", 1), make("pendulum-damped", 1), make("pendulum-damped", 2)
    np.testing.assert_array_equal(a.q, b.q)
    np.testing.assert_array_equal(a.t, b.t)
    assert a.q.shape != c.q.shape or not np.array_equal(a.q, c.q)
    assert make("pendulum-damped", 2).truth["rate"] == pytest.approx(a.truth["rate"], rel=1e-3)


def test_true_decay_rate_definition():
    t = np.linspace(0, 50, 5001)
    assert true_decay_rate(t, 3.0 + 2.0 * np.exp(-0.02 * t), 3.0) == pytest.approx(0.02, rel=1e-12)
    with pytest.raises(ValueError):
        true_decay_rate(t, np.zeros_like(t), 0.0)


def test_pendulum_rate(recs):
    r = recs["pendulum-damped"]
    g, T = r.truth["gamma"], r.truth["t_dense"][-1] - r.truth["t_dense"][0]
    # dE/dt = −γθ̇² and 2⟨KE⟩/E = 1 − A²/24 for the pendulum at amplitude A: r ≈ γ(1 − A²/24) at the mid amplitude
    a_mid = r.truth["theta0"] * math.exp(-g * T / 4)
    predicted = g * (1 - a_mid**2 / 24)
    assert abs(r.energy_decay_rate / g - 1) < 0.03
    assert abs(r.energy_decay_rate / predicted - 1) < 0.005
    assert r.truth["energy_drop"] == pytest.approx(1 - math.exp(-g * (T - r.truth["period"])), abs=0.02)
    # the free pendulum: no decay
    f = recs["pendulum"]
    assert abs(f.truth["rate"]) < 1e-8 and abs(f.truth["energy_drop"]) < 1e-8
    assert f.conservative and f.expected == "none"


def test_pendulum_gaps_and_noise(recs):
    r = recs["pendulum-damped"]
    dt = np.diff(r.t)
    assert dt.max() > 2.5 * np.median(dt)
    assert len(r.truth["gaps"]) == 4 and np.sum(dt > 2.5 * np.median(dt)) == 4
    N = r.t.size
    big = np.flatnonzero(dt > 2.5 * np.median(dt))
    assert big.min() > 0.09 * N and big.max() < 0.91 * N
    resid = r.q - r.truth["q_true"]
    assert np.std(resid) == pytest.approx(0.0025, rel=0.15)
    # not a uniform grid (jitter + ms rounding)
    assert np.ptp(dt[dt < 1.5 * np.median(dt)]) > 1e-3


@pytest.mark.parametrize("name", ["cart", "carts-coupled"])
def test_cart_rates(recs, name):
    r = recs[name]
    assert abs(r.energy_decay_rate / 0.014 - 1) < 0.05
    assert 0.3 < r.truth["energy_drop"] < 0.5


@pytest.mark.parametrize("name", ["cart", "carts-coupled", "carts-coupled-free"])
def test_carts_integer_pixels(recs, name):
    r = recs[name]
    np.testing.assert_array_equal(r.q, np.round(r.q))
    assert np.max(np.abs(r.q - r.truth["q_true"])) <= 0.5


def test_carts_free_conserved_and_beating(recs):
    r = recs["carts-coupled-free"]
    assert abs(r.truth["rate"]) < 1e-8 and r.expected == "none"
    # the energy beats: cart 1 comes (almost) to rest while cart 2 swings
    x1 = r.truth["q_true"][:, 0] - 200.0
    win = int(round(1.6 * 30))
    amp1 = np.array([np.ptp(x1[i : i + win]) for i in range(0, x1.size - win, win)])
    assert amp1.min() < 0.2 * amp1.max()


def test_double_pendulum_closed_form():
    """The closed form agrees with the textbook (myphysicslab) equations for unequal masses and lengths."""
    rng = np.random.default_rng(0)
    m1, m2, l1, l2, g = 1.3, 0.7, 0.9, 1.4, 9.81
    th1, th2, w1, w2 = rng.uniform(-4, 4, (4, 50))
    a1, a2 = double_pendulum_accel(th1, th2, w1, w2, 0.0, m1, m2, l1, l2, g)
    den = 2 * m1 + m2 - m2 * np.cos(2 * th1 - 2 * th2)
    ref1 = (
        -g * (2 * m1 + m2) * np.sin(th1)
        - m2 * g * np.sin(th1 - 2 * th2)
        - 2 * np.sin(th1 - th2) * m2 * (w2**2 * l2 + w1**2 * l1 * np.cos(th1 - th2))
    ) / (l1 * den)
    ref2 = (
        2
        * np.sin(th1 - th2)
        * (w1**2 * l1 * (m1 + m2) + g * (m1 + m2) * np.cos(th1) + w2**2 * l2 * m2 * np.cos(th1 - th2))
    ) / (l2 * den)
    np.testing.assert_allclose(a1, ref1, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(a2, ref2, rtol=1e-12, atol=1e-12)


def test_double_pendulum_energy(recs):
    free, damped = recs["double-pendulum-free"], recs["double-pendulum"]
    E, E_min = free.truth["E_dense"], free.truth["E_min"]
    assert np.max(np.abs(E - E[0])) / (E[0] - E_min) < 1e-8
    # the energy at the true sample times agrees with the dense one
    Es = energy("double-pendulum-free", free.truth["q_true"], free.truth["qd_true"])
    assert np.max(np.abs(Es - E[0])) / (E[0] - E_min) < 1e-8
    # damped: dE/dt = −γ|θ̇|² ≤ 0, a clear decay
    Ed = damped.truth["E_dense"]
    assert np.all(np.diff(Ed) <= 1e-9 * (Ed[0] - E_min))
    assert damped.truth["energy_drop"] > 0.3
    assert 0.02 < damped.energy_decay_rate < 0.2
    assert free.expected == "not-detected" and damped.expected == "detected"


@pytest.mark.parametrize("name", ["double-pendulum", "double-pendulum-free"])
def test_double_pendulum_whole_turns(recs, name):
    r = recs[name]
    assert np.max(np.abs(r.truth["q_true"])) > 4 * np.pi
    assert np.max(np.abs(r.q)) > 4 * np.pi  # recorded unwrapped
    assert np.max(np.abs(np.diff(r.q, axis=0))) < np.pi  # continuous, no 2π jumps
    assert r.angles == ("theta1", "theta2")


def test_disjoint_clock(recs):
    r = recs["disjoint-clock"]
    assert r.traj is not None and set(np.unique(r.traj)) == {0, 1}
    t0, t1 = r.t[r.traj == 0], r.t[r.traj == 1]
    assert (t0.min(), t0.max(), t1.min(), t1.max()) == (0.0, 30.0, 100.0, 130.0)
    assert max(abs(x) for x in r.truth["rate_per_traj"]) < 1e-8
    assert r.conservative and r.expected == "not-detected"


def test_undersampled_and_noise(recs):
    u = recs["undersampled"]
    assert u.t.size == 101 and u.t[-1] == 290.0
    np.testing.assert_allclose(u.q[:, 0], np.cos(2.9 * np.arange(101)), atol=1e-15)
    for name, n in (("white-noise", 1), ("undersampled-2d", 2)):
        w = recs[name]
        assert w.q.shape == (1001, n) and w.expected == "inconclusive"
        assert abs(np.std(w.q) - 1) < 0.1


@pytest.mark.parametrize("name", NAMES)
def test_csv_round_trip(recs, tmp_path, name):
    r = recs[name]
    path = r.write_csv(tmp_path / f"{name}.csv")
    header = path.read_text().splitlines()[0]
    assert header == ",".join(["t", *r.coords] + (["traj"] if r.traj is not None else []))
    data = load_trajectories(path, angles=r.angles)
    assert data.coords == r.coords and data.n_samples == r.n_samples
    assert data.n_traj == (1 if r.traj is None else len(np.unique(r.traj)))
    t = np.concatenate([tr.t for tr in data.trajectories])
    q = np.concatenate([tr.q for tr in data.trajectories])
    np.testing.assert_array_equal(t, r.t)  # full precision
    np.testing.assert_array_equal(q, r.q)
    if name in ("cart", "carts-coupled"):
        row = path.read_text().splitlines()[1].split(",")
        assert all(c.lstrip("-").isdigit() for c in row[1:])  # integer pixels written as integers


@pytest.mark.parametrize("name", ["double-pendulum-camera", "double-pendulum-camera-free"])
def test_double_pendulum_camera_takes(recs, name):
    """Two takes at 200 fps from rest, whole turns of the lower rod, dropped frames, angles of pixel-tracked bobs."""
    r = recs[name]
    assert r.traj is not None and set(np.unique(r.traj)) == {0, 1}
    for j in (0, 1):
        t = r.t[r.traj == j]
        assert t[0] == 0.0 and t[-1] == 10.0 and np.all(np.diff(t) > 0)
        assert np.isclose(np.median(np.diff(t)), 0.005) and np.sum(np.diff(t) > 0.0075) == 3  # 3 runs dropped
        q = r.q[r.traj == j]
        assert np.ptp(q[:, 1]) > 3 * np.pi  # the lower rod sweeps more than one and a half turns in each take
        assert np.max(np.abs(np.diff(q, axis=0))) < np.pi  # unwrapped: no 2π jumps
    err = r.q - r.truth["q_true"]  # the tracker's error: ~0.4 px of 150 px (upper rod), both bobs' (lower)
    assert 0.002 < err[:, 0].std() < 0.0035 and 0.003 < err[:, 1].std() < 0.005
    assert np.abs(err).max() < 0.02
    E = energy("double-pendulum", r.truth["q_true"], r.truth["qd_true"])
    for j in (0, 1):
        Ej = E[r.traj == j]
        if r.conservative:
            assert np.ptp(Ej) / (Ej[0] - r.truth["E_min"]) < 1e-8
        else:
            assert Ej[-1] < Ej[0] - 0.3 * (Ej[0] - r.truth["E_min"])  # loses over 30 % of its energy per take
    assert r.expected == ("not-detected" if r.conservative else "detected")
    if not r.conservative:
        assert 0.03 < r.energy_decay_rate < 0.07
