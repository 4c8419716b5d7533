"""Real data for the Neptune experiment (paper §III.A): Uranus' motion from the JPL DE405 ephemeris.

Le Verrier (1846) found Neptune in the part of Uranus' acceleration that the Sun and the known planets do not
explain. This module redoes that with the real solar system:

1. :func:`state` — barycentric position, velocity and acceleration of a body from DE405 (1599-12-09 … 2201-02-20).
   The ephemeris is the PyPI package ``de405`` (Chebyshev coefficients as ``.npy`` files, read through
   ``jplephem.ephem.Ephemeris``; no download at run time). The acceleration is the second derivative of the same
   Chebyshev series, so position, velocity and acceleration are mutually consistent.
2. :func:`uranus_residual` — a_res = a_Uranus − a_known, a_known = Σ_j GM_j (r_j − r_U)/|r_j − r_U|³ over the
   Sun, Mercury, Venus, Earth–Moon barycentre, Mars, Jupiter and Saturn (what was known in 1846; GM_j from the
   DE405 constants). Everything is barycentric, so there are no indirect terms: the residual is Neptune's direct
   pull GM_N (r_N − r_U)/|r_N − r_U|³ plus Pluto (~1e-4 of it) and the interpolation error of the ephemeris
   (median 6e-5, max 1e-3 of Neptune's pull). Its size is 8e-6 … 1.8e-4 of the Sun's pull on Uranus.
3. :func:`fit_neptune` — explains the residual with a point mass on a circular orbit about the barycentre,
   f = GM (r_p(t) − r)/|r_p(t) − r|³: ``ndim=2`` projects onto the ecliptic plane and uses
   :func:`nnphd.explain.parametric.fit_perturber` (Kepler-informed starts ω = sqrt(GM_sun/R³)); ``ndim=3`` then
   refines an inclined circular orbit (adds inclination and node) in 3-D. :func:`neptune_truth` gives Neptune's
   values from the same ephemeris to compare with.
4. :func:`uranus_dataset` — Uranus' (q, q̇, t, q̈) for NNPhD in order-one units, see its docstring.

Units: the low-level functions use the ephemeris' own units, AU, days (TDB Julian dates) and AU³/day² for GM.
Frames: ``"ecliptic"`` (default; the mean ecliptic and equinox of J2000, obtained by rotating the ICRF axes of DE405
by the IAU 1976 obliquity 84381.448″) or ``"icrf"`` (DE405's own equatorial axes). Origin: the solar-system
barycentre. Years are Julian years of TDB: year 2000.0 is J2000 = JD 2451545.0.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from nnphd._extras import MissingExtra

__all__ = [
    "BODIES",
    "KNOWN_BODIES",
    "J2000_JD",
    "DAYS_PER_YEAR",
    "UNIT_LENGTH_AU",
    "EphemerisUnavailable",
    "available",
    "load_ephemeris",
    "coverage",
    "year_to_jd",
    "jd_to_year",
    "epochs",
    "gm",
    "state",
    "moon_geocentric",
    "pull",
    "UranusResidual",
    "uranus_residual",
    "NeptuneTruth",
    "neptune_truth",
    "PerturberFit",
    "fit_neptune",
    "compare",
    "UranusData",
    "uranus_dataset",
]

J2000_JD = 2451545.0
DAYS_PER_YEAR = 365.25
OBLIQUITY_J2000_DEG = 84381.448 / 3600.0
#: Length unit of :func:`uranus_dataset` (about Uranus' mean distance from the barycentre, 19.19–19.22 AU).
UNIT_LENGTH_AU = 19.2

#: Bodies of the ephemeris used here (DE405 names; "jupiter" … "pluto" are the system barycentres).
BODIES = ("sun", "mercury", "venus", "earthmoon", "mars", "jupiter", "saturn", "uranus", "neptune", "pluto")
#: The "known physics" of 1846: the Sun and the planets out to Saturn.
KNOWN_BODIES = ("sun", "mercury", "venus", "earthmoon", "mars", "jupiter", "saturn")
_GM_KEY = {
    "sun": "GMS",
    "mercury": "GM1",
    "venus": "GM2",
    "earthmoon": "GMB",
    "mars": "GM4",
    "jupiter": "GM5",
    "saturn": "GM6",
    "uranus": "GM7",
    "neptune": "GM8",
    "pluto": "GM9",
}
_FRAMES = ("ecliptic", "icrf")


class EphemerisUnavailable(MissingExtra):
    """The ephemeris packages (``de405``, ``jplephem``) are not installed (the ``astro`` extra)."""


# ---------------------------------------------------------------------------------------------------- ephemeris
@functools.lru_cache(maxsize=1)
def load_ephemeris():
    """DE405 as a ``jplephem.ephem.Ephemeris`` (cached; coefficient sets load lazily, ~27 MB for BODIES)."""
    try:
        import de405
        from jplephem.ephem import Ephemeris
    except ImportError as e:
        raise EphemerisUnavailable(
            f"the JPL ephemeris is not installed ({e}); install it with: pip install 'nnphd[astro]'"
        ) from None
    return Ephemeris(de405)


def available() -> bool:
    """True when the ephemeris can be loaded."""
    try:
        load_ephemeris()
    except EphemerisUnavailable:
        return False
    return True


def coverage() -> tuple[float, float]:
    """First and last Julian date (TDB) of the ephemeris (DE405: 2305424.5 … 2525008.5, 1599-12-09 … 2201-02-20)."""
    e = load_ephemeris()
    return float(e.jalpha), float(e.jomega)


def year_to_jd(year) -> np.ndarray | float:
    """Julian year (TDB; 2000.0 = J2000) → Julian date."""
    return J2000_JD + (np.asarray(year, dtype=np.float64) - 2000.0) * DAYS_PER_YEAR


def jd_to_year(jd) -> np.ndarray | float:
    """Julian date → Julian year (TDB; J2000 = 2000.0)."""
    return 2000.0 + (np.asarray(jd, dtype=np.float64) - J2000_JD) / DAYS_PER_YEAR


def epochs(start_year: float | None = None, stop_year: float | None = None, step_days: float = 20.0) -> np.ndarray:
    """Julian dates start, start + step, … ≤ stop; the defaults are the whole coverage of the ephemeris."""
    lo, hi = coverage()
    step = _positive(step_days, "step_days")
    start = lo if start_year is None else float(year_to_jd(float(start_year)))
    stop = hi if stop_year is None else float(year_to_jd(float(stop_year)))
    _check_jd(np.array([start, stop]), lo, hi)
    if stop <= start:
        raise ValueError(f"stop_year must be after start_year, got {jd_to_year(start):.3f} … {jd_to_year(stop):.3f}")
    n = int(np.floor((stop - start) / step + 1e-9)) + 1
    return start + step * np.arange(n, dtype=np.float64)


def gm(body: str) -> float:
    """GM of a body (system) from the DE405 constants, AU³/day²."""
    return float(getattr(load_ephemeris(), _GM_KEY[_body(body)]))


def _rotation(frame: str) -> np.ndarray:
    if frame == "icrf":
        return np.eye(3)
    if frame == "ecliptic":
        eps = np.deg2rad(OBLIQUITY_J2000_DEG)
        c, s = np.cos(eps), np.sin(eps)
        return np.array([[1.0, 0.0, 0.0], [0.0, c, s], [0.0, -s, c]])
    raise ValueError(f"frame must be one of {_FRAMES}, got {frame!r}")


def state(body: str, jd, frame: str = "ecliptic") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Barycentric position (AU), velocity (AU/day) and acceleration (AU/day²) of ``body`` at Julian dates ``jd``.

    Each is an (N, 3) float64 array. The three come from the same Chebyshev series of DE405 (value, first and second
    derivative), so the acceleration is that of the ephemeris' interpolant (accurate to ~1e-9 relative for Uranus).
    """
    return _series(_body(body), jd, frame)


def moon_geocentric(jd, frame: str = "ecliptic") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The Moon's position (AU), velocity (AU/day) and acceleration (AU/day²) relative to the Earth's centre at
    Julian dates ``jd`` (DE405 stores the Moon geocentric), each (N, 3), as :func:`state`."""
    return _series("moon", jd, frame)


def _series(body: str, jd, frame: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Value, first and second derivative of DE405's Chebyshev series of ``body`` (a segment name) at ``jd``."""
    e = load_ephemeris()
    rot = _rotation(frame)
    jd = np.atleast_1d(np.asarray(jd, dtype=np.float64))
    if jd.ndim != 1:
        raise ValueError(f"jd must be a scalar or 1-D array, got shape {jd.shape}")
    _check_jd(jd, e.jalpha, e.jomega)
    coef = e.load(body)  # (n_sets, 3, n_coef), km
    n_sets, _, n_coef = coef.shape
    span = (e.jomega - e.jalpha) / n_sets
    idx, off = np.divmod(jd - e.jalpha, span)
    idx = idx.astype(np.int64)
    last = idx >= n_sets  # the final instant belongs to the last set
    idx[last] = n_sets - 1
    off[last] = jd[last] - e.jalpha - span * (n_sets - 1)
    x = 2.0 * off / span - 1.0
    T = np.zeros((n_coef, jd.size))
    dT = np.zeros_like(T)
    ddT = np.zeros_like(T)
    T[0] = 1.0
    if n_coef > 1:
        T[1] = x
        dT[1] = 1.0
    for k in range(2, n_coef):  # T_k = 2x T_{k-1} − T_{k-2}, differentiated twice
        T[k] = 2.0 * x * T[k - 1] - T[k - 2]
        dT[k] = 2.0 * T[k - 1] + 2.0 * x * dT[k - 1] - dT[k - 2]
        ddT[k] = 4.0 * dT[k - 1] + 2.0 * x * ddT[k - 1] - ddT[k - 2]
    c = coef[idx]  # (N, 3, n_coef)
    scale = 2.0 / span
    to_au = 1.0 / e.AU
    pos = np.einsum("nak,kn->na", c, T) * to_au
    vel = np.einsum("nak,kn->na", c, dT) * (scale * to_au)
    acc = np.einsum("nak,kn->na", c, ddT) * (scale * scale * to_au)
    return pos @ rot.T, vel @ rot.T, acc @ rot.T


def pull(gm_source: float, r_source, r_target) -> np.ndarray:
    """Newtonian acceleration GM (r_s − r)/|r_s − r|³ of point masses at ``r_target`` (N, d) due to ``r_source``."""
    d = np.asarray(r_source, dtype=np.float64) - np.asarray(r_target, dtype=np.float64)
    dist = np.linalg.norm(d, axis=-1, keepdims=True)
    return gm_source * d / dist**3


# ---------------------------------------------------------------------------------------------------- residual
@dataclass(frozen=True)
class UranusResidual:
    """Uranus' real acceleration minus the known physics, barycentric, AU and days (all (N, 3) but ``jd``).

    ``a_res = a - a_known``; ``a_neptune`` is Neptune's direct pull computed from its ephemeris position (the truth
    the residual should match); ``a_sun`` is the Sun's pull alone (part of ``a_known``).
    """

    jd: np.ndarray
    r: np.ndarray
    v: np.ndarray
    a: np.ndarray
    a_known: np.ndarray
    a_sun: np.ndarray
    a_res: np.ndarray
    a_neptune: np.ndarray
    r_neptune: np.ndarray
    frame: str
    known: tuple[str, ...]

    @property
    def mismatch(self) -> np.ndarray:
        """|a_res − a_neptune| / |a_neptune| per epoch."""
        return np.linalg.norm(self.a_res - self.a_neptune, axis=1) / np.linalg.norm(self.a_neptune, axis=1)

    @property
    def relative_size(self) -> np.ndarray:
        """|a_res| / |a_sun| per epoch (how faint the new physics is)."""
        return np.linalg.norm(self.a_res, axis=1) / np.linalg.norm(self.a_sun, axis=1)


def uranus_residual(jd=None, known=KNOWN_BODIES, frame: str = "ecliptic") -> UranusResidual:
    """Uranus' acceleration minus the pull of the ``known`` bodies at Julian dates ``jd`` (default :func:`epochs`)."""
    jd = epochs() if jd is None else np.atleast_1d(np.asarray(jd, dtype=np.float64))
    known = tuple(_body(b) for b in known)
    if "uranus" in known:
        raise ValueError("known must not contain 'uranus' (its own pull)")
    r, v, a = state("uranus", jd, frame)
    a_known = np.zeros_like(a)
    a_sun = None
    for b in known:
        ab = pull(gm(b), state(b, jd, frame)[0], r)
        a_known += ab
        if b == "sun":
            a_sun = ab
    if a_sun is None:
        a_sun = pull(gm("sun"), state("sun", jd, frame)[0], r)
    r_nep = state("neptune", jd, frame)[0]
    return UranusResidual(
        jd=jd,
        r=r,
        v=v,
        a=a,
        a_known=a_known,
        a_sun=a_sun,
        a_res=a - a_known,
        a_neptune=pull(gm("neptune"), r_nep, r),
        r_neptune=r_nep,
        frame=frame,
        known=known,
    )


# ---------------------------------------------------------------------------------------------------- truth
@dataclass(frozen=True)
class NeptuneTruth:
    """Neptune from the ephemeris: GM (AU³/day², and over GM_sun), time-mean barycentric distance (AU), sidereal
    period from the mean motion of its longitude (yr), actual and mean longitude at ``epoch_jd`` (deg, [0, 360)),
    inclination and ascending node of its mean orbital plane (deg) in ``frame``."""

    gm: float
    gm_ratio: float
    radius_au: float
    period_yr: float
    longitude_deg: float
    mean_longitude_deg: float
    inclination_deg: float
    node_deg: float
    epoch_jd: float
    frame: str


def neptune_truth(jd=None, epoch_jd: float = J2000_JD, frame: str = "ecliptic") -> NeptuneTruth:
    """Neptune's reference values; averages over ``jd`` (default: the whole coverage every 20 days)."""
    jd = epochs() if jd is None else np.atleast_1d(np.asarray(jd, dtype=np.float64))
    if jd.size < 3:
        raise ValueError("jd must hold at least 3 epochs")
    r, v, _ = state("neptune", jd, frame)
    lon = np.unwrap(np.arctan2(r[:, 1], r[:, 0]))
    rate, lon0 = np.polyfit(jd - epoch_jd, lon, 1)  # mean motion (rad/day) and mean longitude at the epoch
    r0 = state("neptune", [epoch_jd], frame)[0][0]
    h = np.mean(np.cross(r, v), axis=0)
    h = h / np.linalg.norm(h)
    return NeptuneTruth(
        gm=gm("neptune"),
        gm_ratio=gm("neptune") / gm("sun"),
        radius_au=float(np.mean(np.linalg.norm(r, axis=1))),
        period_yr=float(2 * np.pi / abs(rate) / DAYS_PER_YEAR),
        longitude_deg=float(np.rad2deg(np.arctan2(r0[1], r0[0])) % 360.0),
        mean_longitude_deg=float(np.rad2deg(lon0) % 360.0),
        inclination_deg=float(np.rad2deg(np.arccos(np.clip(h[2], -1.0, 1.0)))),
        node_deg=float(np.rad2deg(np.arctan2(h[0], -h[1])) % 360.0),
        epoch_jd=float(epoch_jd),
        frame=frame,
    )


# ---------------------------------------------------------------------------------------------------- fit
@dataclass(frozen=True)
class PerturberFit:
    """A circular-orbit point mass fitted to the residual, in physical units.

    ``gm`` in AU³/day² (``gm_ratio`` = gm / GM_sun), ``radius_au``, ``period_yr`` (from |ω|), ``longitude_deg`` of the
    perturber at ``epoch_jd`` (in the residual's frame, [0, 360)), ``inclination_deg``/``node_deg`` (3-D fit only;
    None for ``ndim=2``), ``rel_rms`` = rms(residual − model)/rms(residual). ``params`` are the raw parameters in the
    fit's units (time unit ``time_unit_days``, length unit ``length_unit_au``, GM_sun = 1).
    """

    gm: float
    gm_ratio: float
    radius_au: float
    period_yr: float
    longitude_deg: float
    inclination_deg: float | None
    node_deg: float | None
    rel_rms: float
    ndim: int
    epoch_jd: float
    length_unit_au: float
    time_unit_days: float
    params: dict[str, float]

    def position(self, jd) -> np.ndarray:
        """The fitted perturber's barycentric position (AU) at Julian dates ``jd``, (N, 3) (z = 0 for ``ndim=2``)."""
        t = (np.atleast_1d(np.asarray(jd, dtype=np.float64)) - self.epoch_jd) / self.time_unit_days
        p = self.params
        x = [p["GM"], p["R"], p["omega"], p["phi"], p.get("inc", 0.0), p.get("node", 0.0)]
        return _orbit3(x, t) * self.length_unit_au

    def longitude(self, jd) -> np.ndarray:
        """Longitude (deg, [0, 360)) of the fitted perturber at ``jd``."""
        r = self.position(jd)
        return np.rad2deg(np.arctan2(r[:, 1], r[:, 0])) % 360.0


def _time_unit_days(length_unit_au: float) -> float:
    """Time unit (days) in which GM_sun = 1 for the given length unit: sqrt(L³/GM_sun)."""
    return float(np.sqrt(length_unit_au**3 / gm("sun")))


def _orbit3(x, t) -> np.ndarray:
    """Circular orbit of radius R, argument of latitude u = ωt + φ, inclination ``inc``, ascending node ``node``."""
    _, R, w, ph, inc, node = x
    u = w * t + ph
    cu, su = np.cos(u), np.sin(u)
    ci, si = np.cos(inc), np.sin(inc)
    cn, sn = np.cos(node), np.sin(node)
    return R * np.column_stack([cn * cu - sn * su * ci, sn * cu + cn * su * ci, su * si])


def fit_neptune(
    res: UranusResidual,
    ndim: int = 2,
    epoch_jd: float = J2000_JD,
    length_unit_au: float = UNIT_LENGTH_AU,
    r_grid_au=None,
) -> PerturberFit:
    """Fit f = GM (r_p(t) − r)/|r_p(t) − r|³, r_p on a circular orbit about the barycentre, to ``res.a_res``.

    ``ndim=2``: the ecliptic (x, y) components of Uranus' position and of the residual, fitted with
    :func:`nnphd.explain.parametric.fit_perturber` (GM, R, ω, φ; starts on a grid of radii ``r_grid_au``, default
    0.5…4 × Uranus' median distance, with ω = ±(0.8…1.25)·sqrt(GM_sun/R³)). ``ndim=3``: that 2-D fit, then a 3-D
    least-squares refinement that adds the inclination and node of the orbit (starts at 1° and 3° for six nodes).
    The fit works in units of ``length_unit_au`` and sqrt(L³/GM_sun); t = 0 at ``epoch_jd``.
    """
    from nnphd.explain.parametric import fit_perturber

    if ndim not in (2, 3):
        raise ValueError(f"ndim must be 2 or 3, got {ndim!r}")
    L = _positive(length_unit_au, "length_unit_au")
    T = _time_unit_days(L)
    t = (res.jd - float(epoch_jd)) / T
    q = res.r / L
    fn = res.a_res * (T * T / L)
    r_grid = None if r_grid_au is None else np.asarray(r_grid_au, dtype=np.float64) / L
    f2 = fit_perturber(q[:, :2], t, fn[:, :2], r_grid=r_grid, gm_central=1.0)
    x = np.array([f2.params["GM"], f2.params["R"], f2.params["omega"], f2.params["phi"], 0.0, 0.0])
    rel = f2.rel_rms
    if ndim == 3:
        x, rel = _refine3(q, t, fn, x)
    gm_fit, R, w, ph, inc, node = x
    params = {"GM": float(gm_fit), "R": float(R), "omega": float(w), "phi": float(ph)}
    if ndim == 3:
        params.update(inc=float(inc), node=float(node))
    r0 = _orbit3(x, np.array([0.0]))[0]
    gm_phys = float(gm_fit * L**3 / T**2)
    return PerturberFit(
        gm=gm_phys,
        gm_ratio=gm_phys / gm("sun"),
        radius_au=float(R * L),
        period_yr=float(2 * np.pi / abs(w) * T / DAYS_PER_YEAR),
        longitude_deg=float(np.rad2deg(np.arctan2(r0[1], r0[0])) % 360.0),
        inclination_deg=float(np.rad2deg(inc)) if ndim == 3 else None,
        node_deg=float(np.rad2deg(node) % 360.0) if ndim == 3 else None,
        rel_rms=float(rel),
        ndim=ndim,
        epoch_jd=float(epoch_jd),
        length_unit_au=L,
        time_unit_days=T,
        params=params,
    )


def _refine3(q, t, fn, x2):
    """3-D inclined circular-orbit fit started from the 2-D one (same longitude at t = 0 for every start node)."""

    def resid(x):
        d = _orbit3(x, t) - q
        return (fn - x[0] * d / np.linalg.norm(d, axis=1, keepdims=True) ** 3).ravel()

    best = None
    for node0 in np.deg2rad([0.0, 60.0, 120.0, 180.0, 240.0, 300.0]):
        for inc0 in np.deg2rad([1.0, 3.0]):
            x0 = np.array([x2[0], x2[1], x2[2], x2[3] - node0, inc0, node0])
            r = least_squares(resid, x0, method="lm", x_scale="jac", xtol=1e-12, ftol=1e-12, max_nfev=2000)
            if np.all(np.isfinite(r.fun)) and (best is None or r.cost < best.cost):
                best = r
    x = best.x.copy()
    if x[4] < 0:  # (−i, Ω, u) is the same orbit as (i, Ω + π, u + π)
        x[4], x[5], x[3] = -x[4], x[5] + np.pi, x[3] + np.pi
    x[3] = float(np.mod(x[3] + np.pi, 2 * np.pi) - np.pi)
    x[5] = float(np.mod(x[5], 2 * np.pi))
    rel = float(np.sqrt(np.mean(resid(x) ** 2) / np.mean(fn**2)))
    return x, rel


def compare(fit: PerturberFit, truth: NeptuneTruth) -> dict[str, float]:
    """Relative errors of GM, radius, period and the longitude error (deg, fit − actual, and fit − mean longitude)."""

    def dlon(a, b):
        return float((a - b + 180.0) % 360.0 - 180.0)

    out = {
        "gm_rel": fit.gm / truth.gm - 1.0,
        "radius_rel": fit.radius_au / truth.radius_au - 1.0,
        "period_rel": fit.period_yr / truth.period_yr - 1.0,
        "longitude_deg": dlon(fit.longitude_deg, truth.longitude_deg),
        "mean_longitude_deg": dlon(fit.longitude_deg, truth.mean_longitude_deg),
    }
    if fit.inclination_deg is not None:
        out["inclination_deg"] = fit.inclination_deg - truth.inclination_deg
        out["node_deg"] = dlon(fit.node_deg, truth.node_deg)
    return out


# ---------------------------------------------------------------------------------------------------- NNPhD data
@dataclass(frozen=True)
class UranusData:
    """Uranus for NNPhD, in units of ``length_unit_au`` and ``time_unit_days`` (GM_sun = 1), t = 0 at J2000.

    ``qdd = a_kepler + a_res``: ``a_kepler = −q/|q|³`` is the Sun's field with the Sun fixed at the origin (the
    conservative part, a Lagrangian ½|q̇|² + 1/|q|), ``a_res`` = Uranus' real acceleration minus the pull of the
    known bodies (Sun at its real position, Mercury … Saturn) — essentially Neptune's time-dependent pull, the
    non-conservative "new physics". ``a_neptune`` is that pull from Neptune's ephemeris position (truth),
    ``a_true`` Uranus' real barycentric acceleration. Shapes (N, ndim) and (N,); float64.
    """

    q: np.ndarray
    qd: np.ndarray
    t: np.ndarray
    qdd: np.ndarray
    a_kepler: np.ndarray
    a_res: np.ndarray
    a_neptune: np.ndarray
    a_true: np.ndarray
    jd: np.ndarray
    length_unit_au: float
    time_unit_days: float

    def dataset(self):
        """As :class:`nnphd.engine.data.Dataset` (q, q̇, t, q̈, fc = a_kepler, fn = a_res)."""
        from nnphd.engine.data import Dataset

        return Dataset(q=self.q, qd=self.qd, t=self.t, qdd=self.qdd, fc=self.a_kepler, fn=self.a_res)


def uranus_dataset(
    start_year: float | None = None,
    stop_year: float | None = None,
    step_days: float = 20.0,
    ndim: int = 2,
    known=KNOWN_BODIES,
    kepler: bool = True,
    length_unit_au: float = UNIT_LENGTH_AU,
) -> UranusData:
    """Uranus' real motion with the known perturbations replaced by an exact Kepler field (see :class:`UranusData`).

    q = barycentric position / L (ecliptic; ``ndim=2`` keeps x, y), q̇ = velocity / (L/T), t = (JD − J2000)/T,
    T = sqrt(L³/GM_sun) (13.40 yr for L = 19.2 AU, so |q| ≈ 1, |q̇| ≈ 1, Uranus' period ≈ 2π).
    q̈ = −q/|q|³ + a_res (``kepler=False``: a_res alone, fc = 0). For ``ndim=2`` |q| is the in-plane distance so
    the conservative part is exactly a 2-D central field, and a_res is the in-plane part of the residual.
    q̈ is not d²q/dt² of the data: that would be ``a_true``; q̈ differs from it by exactly the known forces that were
    replaced (the planets' pulls and the Sun's ~0.01 AU wobble about the barycentre). |a_res| is 8e-6 … 1.8e-4 of
    |a_kepler| — about 100× fainter than in the paper's toy Neptune (GM_N = 0.005, r_N = 3, r_U = 2).
    Default: the whole DE405 span (1600–2200, ~7 Uranus orbits, ~3.6 Neptune orbits) every 20 days, 10 978 samples.
    """
    if ndim not in (2, 3):
        raise ValueError(f"ndim must be 2 or 3, got {ndim!r}")
    L = _positive(length_unit_au, "length_unit_au")
    T = _time_unit_days(L)
    jd = epochs(start_year, stop_year, step_days)
    res = uranus_residual(jd, known=known, frame="ecliptic")
    acc = T * T / L
    q = res.r[:, :ndim] / L
    qd = res.v[:, :ndim] * (T / L)
    a_res = res.a_res[:, :ndim] * acc
    a_kep = -q / np.linalg.norm(q, axis=1, keepdims=True) ** 3
    if not kepler:
        a_kep = np.zeros_like(a_kep)
    return UranusData(
        q=q,
        qd=qd,
        t=(jd - J2000_JD) / T,
        qdd=a_kep + a_res,
        a_kepler=a_kep,
        a_res=a_res,
        a_neptune=res.a_neptune[:, :ndim] * acc,
        a_true=res.a[:, :ndim] * acc,
        jd=jd,
        length_unit_au=L,
        time_unit_days=T,
    )


# ---------------------------------------------------------------------------------------------------- checks
def _body(name) -> str:
    if not isinstance(name, str) or name.lower() not in _GM_KEY:
        raise ValueError(f"unknown body {name!r}; expected one of {BODIES}")
    return name.lower()


def _positive(value, name: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a positive number, got {value!r}") from None
    if not (np.isfinite(v) and v > 0):
        raise ValueError(f"{name} must be a positive number, got {value!r}")
    return v


def _check_jd(jd: np.ndarray, lo: float, hi: float) -> None:
    if not np.all(np.isfinite(jd)):
        raise ValueError("epochs must be finite")
    if np.any(jd < lo) or np.any(jd > hi):
        raise ValueError(
            f"epochs must lie in the ephemeris coverage JD {lo} … {hi} "
            f"(years {jd_to_year(lo):.2f} … {jd_to_year(hi):.2f}), got {jd_to_year(jd.min()):.2f} … "
            f"{jd_to_year(jd.max()):.2f}"
        )
