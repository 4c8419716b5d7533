"""Real data (paper §III.A, Neptune): Uranus' motion from JPL DE405, its residual and Le Verrier's perturber fit."""

import numpy as np
import pytest

pytest.importorskip("de405")
pytest.importorskip("jplephem")

from nnphd.astro import ephemeris as E  # noqa: E402

GALLE_JD = 2395562.5  # 1846-09-23, the night Galle found Neptune near Le Verrier's position


@pytest.fixture(scope="module")
def residual():
    return E.uranus_residual(E.epochs(step_days=60.0))  # 1600–2200


@pytest.fixture(scope="module")
def truth():
    return E.neptune_truth()


def test_coverage_and_units():
    lo, hi = E.coverage()
    assert E.jd_to_year(lo) < 1600.0 and E.jd_to_year(hi) > 2200.0
    assert E.gm("sun") == pytest.approx(0.01720209895**2, rel=1e-6)  # Gauss' constant squared, AU³/day²
    assert E.gm("neptune") / E.gm("sun") == pytest.approx(5.15e-5, rel=0.01)
    jd = E.epochs(step_days=20.0)
    assert jd[0] == lo and jd[-1] <= hi and np.allclose(np.diff(jd), 20.0)


def test_state_matches_jplephem_and_velocity_derivative():
    e = E.load_ephemeris()
    jd = np.array([e.jalpha, e.jalpha + 0.3, E.J2000_JD, e.jomega - 1e-3, e.jomega])
    p, v = e.position_and_velocity("uranus", jd)
    r, vv, _ = E.state("uranus", jd, frame="icrf")
    np.testing.assert_allclose(r, p.T / e.AU, rtol=0, atol=1e-13)
    np.testing.assert_allclose(vv, v.T / e.AU, rtol=0, atol=1e-16)
    # The ecliptic frame is a rotation: distances unchanged, Uranus stays within 1° of the ecliptic.
    re = E.state("uranus", jd)[0]
    np.testing.assert_allclose(np.linalg.norm(re, axis=1), np.linalg.norm(r, axis=1), rtol=1e-14)
    assert np.all(np.abs(re[:, 2]) / np.linalg.norm(re, axis=1) < np.sin(np.deg2rad(1.0)))
    # Acceleration = derivative of the velocity (central difference, h = 0.25 day: truncation ~1e-9).
    jd = E.epochs(1601, 2199, 97.3)
    for body in ("uranus", "jupiter"):
        _, _, a = E.state(body, jd)
        dv = (E.state(body, jd + 0.25)[1] - E.state(body, jd - 0.25)[1]) / 0.5
        assert np.max(np.linalg.norm(dv - a, axis=1) / np.linalg.norm(a, axis=1)) < 1e-7


def test_residual_is_neptunes_pull(residual):
    mis = residual.mismatch
    # Measured: median 6e-5, max 1.1e-3 (Pluto ~1e-4, Chebyshev interpolation error of the acceleration).
    assert np.median(mis) < 1e-3 and mis.max() < 5e-3
    # The residual points at Neptune.
    cos = np.sum(residual.a_res * residual.a_neptune, axis=1) / (
        np.linalg.norm(residual.a_res, axis=1) * np.linalg.norm(residual.a_neptune, axis=1)
    )
    assert cos.min() > 0.999
    # New physics is faint: 8e-6 … 1.9e-4 of the Sun's pull.
    size = residual.relative_size
    assert 3e-6 < size.min() < 2e-5 and 1e-4 < size.max() < 3e-4
    # Without Saturn in the known physics the residual is no longer Neptune.
    no_saturn = E.uranus_residual(residual.jd[::10], known=("sun", "mercury", "venus", "earthmoon", "mars", "jupiter"))
    assert np.median(no_saturn.mismatch) > 1.0


@pytest.mark.parametrize("ndim", [2, 3])
def test_fit_recovers_neptune(residual, truth, ndim):
    fit = E.fit_neptune(residual, ndim=ndim)
    err = E.compare(fit, truth)
    # Measured (2-D / 3-D): GM −1.7 % / −1.6 %, R +0.08 % / +0.04 %, P +0.01 %, longitude +0.20° / +0.19°.
    assert abs(err["gm_rel"]) < 0.05
    assert abs(err["radius_rel"]) < 0.01
    assert abs(err["period_rel"]) < 0.01
    assert abs(err["longitude_deg"]) < 1.0
    assert abs(err["mean_longitude_deg"]) < 1.0
    assert fit.rel_rms < 0.03
    if ndim == 3:  # measured: i 1.78° vs 1.77°, node 131.6° vs 131.8°
        assert abs(err["inclination_deg"]) < 0.1
        assert abs(err["node_deg"]) < 1.0
    else:
        assert fit.inclination_deg is None


def test_le_verrier_1846():
    """Only data up to mid-1846 (Uranus observed since 1690): where is Neptune on the night Galle looked?"""
    fit = E.fit_neptune(E.uranus_residual(E.epochs(1690.0, 1846.7, 30.0)))
    r = E.state("neptune", [GALLE_JD])[0][0]
    true_lon = np.rad2deg(np.arctan2(r[1], r[0])) % 360.0
    d = (fit.longitude(GALLE_JD)[0] - true_lon + 180.0) % 360.0 - 180.0
    assert abs(d) < 0.5  # measured 0.07°
    assert fit.gm_ratio == pytest.approx(E.gm("neptune") / E.gm("sun"), rel=0.05)


def test_uranus_dataset():
    data = E.uranus_dataset(step_days=60.0)
    N = data.t.shape[0]
    for a in (data.q, data.qd, data.qdd, data.a_kepler, data.a_res, data.a_neptune, data.a_true):
        assert a.shape == (N, 2) and a.dtype == np.float64
    assert data.t.dtype == np.float64 and data.time_unit_days == pytest.approx(4895.4, rel=1e-3)
    # Order-one units: GM_sun = 1, |q| ≈ 1, |q̇| ≈ 1, t = 0 at J2000, ~7 Uranus orbits.
    rq = np.linalg.norm(data.q, axis=1)
    assert 0.94 < rq.min() and rq.max() < 1.06
    assert 0.9 < np.linalg.norm(data.qd, axis=1).mean() < 1.1
    assert data.t[0] < -29 and data.t[-1] > 14
    np.testing.assert_allclose(data.qdd, data.a_kepler + data.a_res, rtol=0, atol=1e-15)
    np.testing.assert_allclose(data.a_kepler, -data.q / rq[:, None] ** 3, rtol=1e-14)
    # f_n is Neptune's (in-plane) pull; the real acceleration is Kepler to ~1e-2 (the known planets + wobble).
    assert np.max(np.linalg.norm(data.a_res - data.a_neptune, axis=1) / np.linalg.norm(data.a_neptune, axis=1)) < 5e-3
    assert np.max(np.linalg.norm(data.a_true - data.qdd, axis=1)) < 0.02
    ds = data.dataset()
    assert ds.n == 2 and len(ds) == N and np.array_equal(ds.fn, data.a_res)
    d3 = E.uranus_dataset(1800, 1900, step_days=100.0, ndim=3, kepler=False)
    assert d3.q.shape[1] == 3 and np.all(d3.a_kepler == 0) and np.array_equal(d3.qdd, d3.a_res)


def test_bad_input():
    with pytest.raises(ValueError, match="coverage"):
        E.state("uranus", [2000000.0])
    with pytest.raises(ValueError, match="coverage"):
        E.epochs(1500, 1700)
    with pytest.raises(ValueError, match="unknown body"):
        E.state("vulcan", [E.J2000_JD])
    with pytest.raises(ValueError, match="frame"):
        E.state("uranus", [E.J2000_JD], frame="galactic")
    with pytest.raises(ValueError, match="step_days"):
        E.epochs(step_days=0)
    with pytest.raises(ValueError, match="ndim"):
        E.uranus_dataset(ndim=4)
    with pytest.raises(ValueError, match="uranus"):
        E.uranus_residual([E.J2000_JD], known=("sun", "uranus"))
    assert issubclass(E.EphemerisUnavailable, ImportError) and E.available()
