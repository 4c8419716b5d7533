"""Checks of the friction look-alikes themselves (tests/fixtures/friction.py): the truth is what it says (numpy/scipy
only, fast). Whether ``nnphd detect`` finds the laws is benchmarks/friction_laws.py's business."""

import math
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from nnphd.user.recording import load_trajectories  # noqa: E402
from tests.fixtures.friction import FAMILIES, NAMES, law_force, make  # noqa: E402
from tests.fixtures.recordings import Recording  # noqa: E402

STICKY = ["viscous-dry", "offset-rest", "ends-at-rest", "sensor-20hz"]


@pytest.fixture(scope="module")
def recs():
    return {name: make(name) for name in NAMES}


def _rms(x):
    return float(np.sqrt(np.mean(np.square(x))))


def _ranges(rec):
    """Row ranges (start, stop) of each trajectory."""
    if rec.traj is None:
        return [(0, rec.n_samples)]
    cuts = [0, *(np.flatnonzero(np.diff(rec.traj) != 0) + 1), rec.n_samples]
    return list(zip(cuts[:-1], cuts[1:]))


def test_cases_and_unknown_name():
    assert len(NAMES) == 11 and len(set(NAMES)) == 11
    with pytest.raises(ValueError, match="unknown case 'nope'; expected one of viscous-dry"):
        make("nope")


def test_complete(recs):  # (build times are a benchmark's business: a wall-time assertion fails under load)
    out = recs
    for name, r in out.items():
        assert isinstance(r, Recording)
        tr = r.truth
        N, n = r.q.shape
        assert r.t.shape == (N,) and N == tr["n_samples"] and n == len(r.coords)
        assert tr["law"] in FAMILIES
        assert set(tr["coefficients"]) <= {"gamma", "mu", "c"}
        assert all(v > 0 for v in tr["coefficients"].values())
        for k in ("q_true", "qd_true", "qdd_true", "fc_true", "fn_true"):
            assert tr[k].shape == (N, n), (name, k)
        assert tr["t_true"].shape == tr["moving"].shape == (N,)
        assert (tr["law"] == "none") == r.conservative == (r.expected == "none")
        assert np.all(np.isfinite(r.q)) and np.all(np.isfinite(r.t))


def test_truth_force_is_qdd_minus_fc(recs):
    """f_n = q̈ − f_c on every row; on the moving rows it is the law (and q̈ matches a finite difference of the exact
    velocity); on the stuck rows q̈ = 0 and f_n is the static friction −f_c."""
    out = recs
    h = 1e-5
    for name, r in out.items():
        tr = r.truth
        np.testing.assert_allclose(tr["fn_true"], tr["qdd_true"] - tr["fc_true"], atol=1e-12)
        np.testing.assert_allclose(tr["fc_true"], tr["fc_fn"](tr["q_true"]), atol=1e-12)
        mv = tr["moving"]
        law = tr["law_fn"](tr["q_true"], tr["qd_true"])
        np.testing.assert_allclose(tr["fn_true"][mv], law[mv], atol=1e-12)
        assert np.all(tr["qdd_true"][~mv] == 0) and np.all(tr["qd_true"][~mv] == 0)
        scale = _rms(tr["qdd_true"])
        for i, (a, b) in enumerate(_ranges(r)):
            t = tr["t_true"][a:b]
            ts = tr["t_stick"][i]
            keep = (t > 2 * h) if ts is None else (t > 2 * h) & (np.abs(t - ts) > 2 * h)
            t = t[keep]
            _, vp = tr["state"](i, t + h)
            _, vm = tr["state"](i, t - h)
            fd = ((np.asarray(vp) - np.asarray(vm)) / (2 * h)).reshape(t.size, -1)
            err = np.abs(fd - tr["qdd_true"][a:b][keep]).max() / scale
            assert err < 1e-4, (name, i, err)


def test_stuck_tails_are_at_rest_in_the_dead_band(recs):
    out = recs
    for name in STICKY:
        r = out[name]
        tr = r.truth
        db, th0 = tr["dead_band"], tr["theta0"]
        assert db == pytest.approx(
            math.asin(tr["mu"] / tr["omega0"] ** 2) if tr["potential"] == "pendulum" else tr["mu"] / tr["omega0"] ** 2
        )
        for i, (a, b) in enumerate(_ranges(r)):
            ts, qs = tr["t_stick"][i], tr["q_stick"][i]
            assert ts is not None, (name, i)
            t = tr["t_true"][a:b]
            tail = t >= ts
            assert tail.sum() >= 10, (name, i)  # a real stuck tail
            assert np.all(tr["q_true"][a:b][tail, 0] == qs)
            assert np.all(~tr["moving"][a:b][tail]) and np.all(tr["moving"][a:b][~tail])
            # in the dead band (static friction holds), and not at the conservative rest
            assert abs(qs - th0) <= db, (name, qs, th0, db)
            assert abs(tr["fc_fn"](qs)) <= tr["mu"]
            assert abs(qs - th0) > 0.05 * db, (name, qs, th0, db)
            # the recorded tail is flat up to its noise: constant when quantized without noise
            qr = r.q[a:b][tail, 0]
            if not tr["noise"]:
                assert np.ptp(qr) == 0
                assert abs(qr[0] - qs) <= tr["step"] / 2 + 1e-12
            else:
                assert np.std(qr) == pytest.approx(tr["noise"], rel=0.5)
    vd = out["viscous-dry"].truth
    assert all(abs(q) > 10 * vd["step"] for q in vd["q_stick"])  # stuck off zero
    ends = out["ends-at-rest"]
    share = 1 - ends.truth["moving"].mean()
    assert 0.28 <= share <= 0.31
    assert out["offset-rest"].truth["theta0"] == 0.05


def test_dry_friction_turning_points(recs):
    """Pure Coulomb on a pendulum: between turning points A_k, A_{k+1} (opposite sides) the work of friction is
    μ(|A_k| + |A_{k+1}|) = ω0²(cos A_{k+1} − cos A_k) (energy balance); the body stops at the first turning point
    inside the dead band."""
    tr = make("ends-at-rest").truth
    w2, mu = tr["omega0"] ** 2, tr["mu"]
    ts = tr["t_stick"][0]
    t = np.linspace(0.0, ts - 1e-9, 200_000)
    q, v = tr["state"](0, t)
    k = np.flatnonzero(np.sign(v[1:]) != np.sign(v[:-1]))
    A = np.concatenate([[q[0]], q[k], [tr["q_stick"][0]]])
    A = A[np.concatenate([[True], np.abs(np.diff(A)) > 1e-6])]
    assert len(A) >= 8
    lhs = mu * (np.abs(A[:-1]) + np.abs(A[1:]))
    rhs = w2 * (np.cos(A[1:]) - np.cos(A[:-1]))
    np.testing.assert_allclose(lhs, rhs, rtol=2e-3)
    assert np.all(np.abs(A[:-1]) > tr["dead_band"]) and abs(A[-1]) <= tr["dead_band"]


def test_energy_decreases(recs):
    out = recs
    for name, r in out.items():
        tr = r.truth
        for i, (a, b) in enumerate(_ranges(r)):
            E = tr["energy_fn"](tr["q_true"][a:b], tr["qd_true"][a:b])
            scale = float(E[0] - E.min()) or 1.0
            if r.conservative:
                assert np.ptp(E) / E[0] < 1e-8, name
                continue
            assert np.all(np.diff(E) <= 1e-9 * scale), name
            assert tr["energy_drop"][i] > 0.1, (name, i, tr["energy_drop"][i])


def test_quantization_seen_in_positions(recs):
    out = recs
    for name in ("viscous-dry", "encoder-1khz", "sensor-20hz", "sensor-20hz-runs"):
        r = out[name]
        step = r.truth["step"]
        k = r.q[:, 0] / step
        assert np.abs(k - np.round(k)).max() < 1e-6, name
        d = np.abs(np.diff(r.q[:, 0]))
        assert np.min(d[d > 0]) == pytest.approx(step, rel=1e-6), name
        err = r.q[:, 0] - r.truth["q_true"][:, 0]
        assert np.abs(err).max() <= step / 2 + 1e-9, name
    assert out["encoder-1khz"].truth["step"] == pytest.approx(0.00157, rel=2e-3)
    assert out["sensor-20hz"].q.dtype.kind == "f" and np.all(out["sensor-20hz"].q == np.round(out["sensor-20hz"].q))


def test_noise_and_clocks(recs):
    out = recs
    for name, r in out.items():
        tr = r.truth
        if tr["noise"] and not tr["step"]:
            err = r.q - tr["q_true"]
            assert np.std(err) == pytest.approx(tr["noise"], rel=0.2), name
        dt = r.t - tr["t_true"]
        if tr["clock"] == "nominal":
            assert np.std(dt) == pytest.approx(tr["jitter"], rel=0.2), name
            k = r.t * tr["fs"]
            assert np.abs(k - np.round(k)).max() < 1e-6, name  # written at exactly k/fs
        else:
            assert np.abs(dt).max() <= 5e-4 + 1e-12, name  # rounded to 1 ms
    jc = out["jitter-clock"]
    assert np.all(np.diff(jc.truth["t_true"]) > 0)


def test_seed_moves_noise_only():
    for name in ("viscous-dry", "jitter-clock", "throw-2d"):
        a, b = make(name, 0), make(name, 1)
        assert a.truth["coefficients"] == b.truth["coefficients"]
        assert a.truth["t_stick"] == b.truth["t_stick"]
        if a.truth["clock"] == "nominal":
            assert np.array_equal(a.t, b.t) and not np.array_equal(a.truth["t_true"], b.truth["t_true"])
        else:
            assert np.array_equal(a.truth["q_true"], b.truth["q_true"])
        if a.truth["noise"] or a.truth["clock"] == "nominal":
            assert not np.array_equal(a.q, b.q)
    x, y = make("offset-rest", 3), make("offset-rest", 3)
    assert np.array_equal(x.q, y.q) and np.array_equal(x.t, y.t)


def test_case_physics(recs):
    out = recs
    # string pendulum: quadratic drag dominates the linear term, amplitude 0.7 → ~0.2 over 2 minutes
    lq = out["linear-quadratic"].truth
    v = lq["qd_true"]
    assert _rms(lq["c"] * np.abs(v) * v) > 2 * _rms(lq["gamma"] * v)
    assert np.abs(lq["q_true"][-80:]).max() == pytest.approx(0.2, abs=0.03)
    # both terms of the servo's friction matter
    vd = out["viscous-dry"].truth
    mv = vd["moving"]
    assert 0.2 < _rms(vd["mu"] * np.tanh(vd["qd_true"][mv] / vd["eps"])) / _rms(vd["gamma"] * vd["qd_true"][mv]) < 5
    # heavy damping: damping ratio 0.13
    hd = out["heavy-damping"].truth
    assert hd["gamma"] / (2 * hd["omega0"]) == pytest.approx(0.13)
    # encoder: released from 2.7 rad (155°), three runs of 5 s at 1 kHz
    enc = out["encoder-1khz"]
    assert (
        enc.truth["q_true"][0, 0] == pytest.approx(2.7, abs=1e-6)
        and len(_ranges(enc)) == 3
        and enc.n_samples == 3 * 5001
    )
    # throw: drag 5–10 % of gravity at the release, in metres
    th = out["throw-2d"].truth
    f0 = np.linalg.norm(th["fn_true"][0])
    assert 0.05 <= f0 / th["g"] <= 0.10
    assert th["q_true"][:, 1].max() > th["q_true"][0, 1] + 1.0  # it flies up first
    # the truth law is the family's formula (tanh sign in the truth)
    np.testing.assert_allclose(
        law_force({"gamma": 1.0, "mu": 2.0, "c": 3.0}, np.array([[0.5], [-2.0]]), eps=1e-9),
        [[-0.5 - 2.0 - 0.75], [2.0 + 2.0 + 12.0]],
    )


def test_csv_round_trip(tmp_path, recs):
    out = recs
    for name, r in out.items():
        path = r.write_csv(tmp_path / f"{name}.csv")
        ud = load_trajectories(path, r.angles)
        assert ud.coords == r.coords
        assert ud.n_traj == (1 if r.traj is None else int(r.traj.max()) + 1)
        assert sum(len(tr) for tr in ud.trajectories) == r.n_samples
        q = np.concatenate([tr.q for tr in ud.trajectories])
        np.testing.assert_array_equal(q, r.q)
    head = (tmp_path / "sensor-20hz.csv").read_text().splitlines()[1]
    assert head.split(",")[1] == "30"  # whole degrees, written as integers


def test_the_sensor_in_runs_is_ten_releases_of_the_same_oscillator(recs):
    """The 20 Hz/1° sensor as the measured record was: 10 runs, released from 20–40° on either side, each stopping;
    the same oscillator and friction as the one-run case."""
    one, runs = recs["sensor-20hz"], recs["sensor-20hz-runs"]
    for k in ("omega0", "theta0", "gamma", "mu", "c", "fs", "step"):
        assert runs.truth[k] == one.truth[k], k
    spans = _ranges(runs)
    assert len(spans) == 10
    first = np.array([runs.truth["q_true"][a, 0] for a, _ in spans])
    assert sorted(np.abs(first)) == [20, 20, 25, 25, 30, 30, 35, 35, 40, 40]
    assert (first > 0).sum() == 5
    tr, db = runs.truth, runs.truth["dead_band"]
    for i, (a, b) in enumerate(spans):  # each run sticks in the dead band (one of them next to the spring's rest)
        assert tr["t_stick"][i] is not None and abs(tr["q_stick"][i]) <= db
        assert (tr["t_true"][a:b] >= tr["t_stick"][i]).sum() >= 10
    assert runs.n_samples > 9 * one.n_samples
