r"""Conservative records for negative controls: real orbits from DE405 and a constructed satellite with known truth.

A detector of new physics is only as trustworthy as its false-detection rate on records with *no* new physics that
look unlike the ones it was tuned on. Orbits are such records: smooth to ~10⁻⁹ of their size (the ephemeris' own
precision), 2-D and 3-D, one trajectory each, and a Lagrangian system in any frame that does not accelerate —
inertial or uniformly rotating (Coriolis and centrifugal forces come from L = ½|ṙ + Ω×r|² − V(r)). The right verdict
on every record here is "none" (or "inconclusive" where the record cannot decide), never "detected".

The records (:func:`records`; each a single trajectory, times in days or hours, lengths in AU or 1000 km):

* heliocentric planets from DE405 (planet − Sun, ecliptic or equatorial axes, 2-D projections or 3-D), over 6–10
  orbits: Mercury, Venus, the Earth–Moon barycentre, Mars, Jupiter, Saturn. The planets' mutual pulls are ~10⁻⁵–10⁻³
  of the Sun's and change the energy only periodically (no secular change of the semi-major axes, Laplace);
* the Moon about the Earth from DE405 over a year (13 orbits); the Sun's tide is ~1 % of the Earth's pull and
  periodic — but in a geocentric frame it depends on time explicitly (the Sun's direction turns): its part that no
  function of the Moon's state can stand in for varies at ω = |n + Ω − 2n☉| (n the Moon's sidereal mean motion, n☉
  the Sun's, Ω the frame's rate; the tide 3(r·ŝ)ŝ − r with r at n − Ω and ŝ at n☉ − Ω), kept as
  :attr:`Control.drive_omega`. A drive found there is the real Sun, so "inconclusive" is right there too;
* uniformly rotating frames of the same data (about the ecliptic pole, at a rate Ω chosen per record);
* a constructed laser-ranging satellite (:func:`satellite_j2`, LAGEOS' orbit: a = 12 270 km, e = 0.0045,
  i = 109.8°): the Earth's point mass plus its oblateness J2 (both conservative), integrated to 10⁻¹³, one day of
  positions every 2 min in 1000 km and hours with 1 cm noise, in the inertial and in the Earth-fixed frame.

Each :class:`Control` says which frame and what the forces are. The DE405 records need the ``astro`` extra.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Control", "records", "satellite_j2", "NAMES"]


@dataclass(frozen=True)
class Control:
    """One conservative record: ``t`` (N,), ``q`` (N, n), coordinate ``names``, what it is (``what``), its frame and
    its ``source`` ("DE405" or "constructed")."""

    name: str
    t: np.ndarray
    q: np.ndarray
    names: tuple[str, ...]
    what: str
    frame: str
    source: str
    drive_omega: float | None = None  # rad per time unit of a known explicit-time force in this frame (the Moon's)

    def write_csv(self, path) -> None:
        """The file ``nnphd detect`` reads: ``t,<names>``, full precision."""
        cols = np.column_stack([self.t, self.q])
        header = ",".join(("t", *self.names))
        np.savetxt(path, cols, delimiter=",", header=header, comments="", fmt="%.17g")


def _rotate(q: np.ndarray, t: np.ndarray, omega: float) -> np.ndarray:
    """Positions in a frame turning at ``omega`` (rad per time unit) about the third axis (counter-clockwise)."""
    a = -omega * (t - t[0])
    c, s = np.cos(a), np.sin(a)
    out = q.copy()
    out[:, 0] = c * q[:, 0] - s * q[:, 1]
    out[:, 1] = s * q[:, 0] + c * q[:, 1]
    return out


def _helio(body: str, start_year: float, years: float, step_days: float, frame: str) -> tuple[np.ndarray, np.ndarray]:
    from nnphd.astro import ephemeris as E

    jd = E.year_to_jd(start_year) + np.arange(0.0, years * E.DAYS_PER_YEAR, step_days)
    r, _, _ = E.state(body, jd, frame)
    rs, _, _ = E.state("sun", jd, frame)
    return jd - jd[0], r - rs


# name: (body, start year, years, step in days, axes, dims, rotation rate in rad/day or 0)
_PLANETS = {
    "mercury-2d": ("mercury", 1950.0, 2.0, 1.0, "ecliptic", 2, 0.0),
    "venus-3d-icrf": ("venus", 1900.0, 5.0, 2.0, "icrf", 3, 0.0),
    "earth-3d-icrf": ("earthmoon", 2000.0, 8.0, 4.0, "icrf", 3, 0.0),
    "mars-2d": ("mars", 1700.0, 15.0, 7.0, "ecliptic", 2, 0.0),
    "jupiter-3d": ("jupiter", 1800.0, 95.0, 60.0, "ecliptic", 3, 0.0),
    "saturn-2d": ("saturn", 1610.0, 236.0, 120.0, "ecliptic", 2, 0.0),
    # rotating frames: Mercury seen from a frame turning with the Earth's mean motion; the Earth–Moon barycentre
    # from one turning with Jupiter's (3-D)
    "mercury-rotating-2d": ("mercury", 2050.0, 2.0, 1.0, "ecliptic", 2, 2 * np.pi / 365.25),
    "earth-rotating-3d-icrf": ("earthmoon", 1850.0, 8.0, 4.0, "icrf", 3, 2 * np.pi / 4332.59),
}
_MOON = {
    "moon-3d": (2010.0, 1.0, 0.5, "icrf", 3, 0.0),
    "moon-rotating-2d": (1750.0, 1.0, 0.5, "ecliptic", 2, 2 * np.pi / 10.0),
}
_MOON_N = 2 * np.pi / 27.321662  # the Moon's sidereal mean motion, rad/day
_SUN_N = 2 * np.pi / 365.256363  # the Sun's apparent (the Earth's sidereal) mean motion, rad/day
_SATELLITE = {"satellite-j2-inertial": False, "satellite-j2-earth-fixed": True}
NAMES = (*_PLANETS, *_MOON, *_SATELLITE)

_FORCES_SUN = "the Sun's pull; the planets' pulls (10⁻⁵–10⁻³ of it, periodic)"


def records(names=None, seed: int = 0) -> list[Control]:
    """The control records (default: all of :data:`NAMES`); ``seed`` draws the satellite's 1 cm noise only."""
    from nnphd.astro import ephemeris as E

    out = []
    for name in NAMES if names is None else names:
        if name in _PLANETS:
            body, y0, years, step, axes, dims, om = _PLANETS[name]
            t, q = _helio(body, y0, years, step, axes)
            frame = f"heliocentric, {axes} axes" + (f", turning at {om:.4g} rad/day" if om else ", inertial")
            q = _rotate(q, t, om)[:, :dims] if om else q[:, :dims]
            out.append(Control(name, t, q, ("x", "y", "z")[:dims], _FORCES_SUN, frame, "DE405"))
        elif name in _MOON:
            y0, years, step, axes, dims, om = _MOON[name]
            jd = E.year_to_jd(y0) + np.arange(0.0, years * E.DAYS_PER_YEAR, step)
            r, _, _ = E.moon_geocentric(jd, axes)
            t = jd - jd[0]
            q = (_rotate(r, t, om) if om else r)[:, :dims] * 1e3  # 1000ths of an AU (~150 000 km)
            frame = f"geocentric, {axes} axes" + (f", turning at {om:.4g} rad/day" if om else ", inertial")
            what = "the Earth's pull; the Sun's tide (~1 % of it, periodic, explicit in time in this frame)"
            tide = abs(_MOON_N + om - 2 * _SUN_N)
            out.append(Control(name, t, q, ("x", "y", "z")[:dims], what, frame, "DE405", tide))
        elif name in _SATELLITE:
            t, q = satellite_j2(earth_fixed=_SATELLITE[name], seed=seed)
            frame = (
                "geocentric, Earth-fixed (turning once a sidereal day)" if _SATELLITE[name] else "geocentric, inertial"
            )
            what = "the Earth's point mass and oblateness J2 (both conservative)"
            out.append(Control(name, t, q, ("x", "y", "z"), what, frame, "constructed"))
        else:
            raise ValueError(f"unknown control {name!r}; expected one of {NAMES}")
    return out


# LAGEOS-like orbit, units of 1000 km and hours
GM_EARTH = 398600.4418 * 3600.0**2 / 1e9  # (1000 km)³/h²
R_EARTH = 6.378137
J2 = 1.08263e-3
OMEGA_EARTH = 7.2921159e-5 * 3600.0  # rad/h


def _j2_accel(r: np.ndarray) -> np.ndarray:
    x, y, z = r
    rr = float(np.sqrt(r @ r))
    k = 1.5 * J2 * GM_EARTH * R_EARTH**2 / rr**5
    zz = 5.0 * z * z / (rr * rr)
    return -GM_EARTH * r / rr**3 + k * np.array([x * (zz - 1.0), y * (zz - 1.0), z * (zz - 3.0)])


def satellite_j2(
    earth_fixed: bool = False, hours: float = 24.0, step_min: float = 2.0, noise: float = 1e-8, seed: int = 0
) -> tuple[np.ndarray, np.ndarray]:
    """(t in hours, positions (N, 3) in 1000 km) of a LAGEOS-like satellite under the Earth's J2 field.

    a = 12 270 km, e = 0.0045, i = 109.8°, integrated by DOP853 (rtol 1e-13); ``noise``: Gaussian σ of the positions
    (1e-8 = 1 cm); ``earth_fixed``: positions in the frame turning with the Earth (J2 is axisymmetric, so the
    field is static there too and the motion stays Lagrangian)."""
    from scipy.integrate import solve_ivp

    a, e, inc = 12.270, 0.0045, np.deg2rad(109.8)
    rp = a * (1 - e)
    vp = np.sqrt(GM_EARTH * (1 + e) / rp)
    node, argp = 0.6, 1.1
    Rz = lambda ang: np.array([[np.cos(ang), -np.sin(ang), 0], [np.sin(ang), np.cos(ang), 0], [0, 0, 1.0]])  # noqa: E731
    Rx = np.array([[1, 0, 0], [0, np.cos(inc), -np.sin(inc)], [0, np.sin(inc), np.cos(inc)]])
    M = Rz(node) @ Rx @ Rz(argp)
    y0 = np.concatenate([M @ [rp, 0.0, 0.0], M @ [0.0, vp, 0.0]])
    t = np.arange(0.0, hours, step_min / 60.0)
    sol = solve_ivp(lambda _t, y: np.concatenate([y[3:], _j2_accel(y[:3])]), (0.0, t[-1]), y0, method="DOP853",
                    t_eval=t, rtol=1e-13, atol=1e-15)  # fmt: skip
    q = sol.y[:3].T
    if earth_fixed:
        q = _rotate(q, t, OMEGA_EARTH)
    q = q + noise * np.random.default_rng(seed).standard_normal(q.shape)
    return t, q
