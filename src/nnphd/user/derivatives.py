r"""q̇ and q̈ of a user's recording (:mod:`nnphd.user.recording`), per trajectory and coordinate, with error estimates.

Derivative estimation (:func:`estimate_derivatives`, one trajectory and coordinate at a time)
--------------------------------------------------------------------------------------------
1. **Noise level σ** of the positions (:func:`nnphd.user.sampling.noise_level`), at least the quantization noise of
   values on a grid.
2. **Sampling and time base** (:func:`nnphd.user.sampling.classify_sampling`): *uniform* → Savitzky–Golay; *near-uniform*
   (jitter, short gaps) → local polynomial regression in the recorded or the nominal (lattice) times; *grossly
   irregular* → the spline (item 6).
3.–5. **Local polynomial regression, its error model (order and window of least estimated error) and the end rows**:
   :mod:`nnphd.user.localpoly`.

6. **Grossly irregular sampling** (or ``method="spline"``): a quintic smoothing spline
   (:class:`scipy.interpolate.UnivariateSpline`, k=5, s = N·σ²), per-row errors by a parametric bootstrap (8 refits
   to the fitted curve plus fresh noise of size σ): the noise part and the smoothing bias of a similar curve, not the
   truncation error; it misjudges single rows (|error|/estimate up to 14–26 on the cases below).

Measured
--------
θ̈ = −sin θ − 0.1 θ̇ (θ₀ = 2, θ̇₀ = 0, dt = 0.05, 0…20 s, 401 samples; tests/test_userdata.py, noise seed 0), RMS error
over all rows relative to the RMS of the true derivative, reported/actual; in brackets the numbers before orders 6 and
the end treatment (order 4 only):

    position noise (of std θ)   σ̂/σ     q̇ error (rep./actual)    q̈ error (rep./actual)    order, windows
    0                            —        2.0e-9 (1.6)  [3.8e-7]   6.3e-8 (4.7)  [2.9e-6]   6, 7/9    [4, 5/5]
    0.1 %                        1.00     0.16 % (1.0)  [0.19 %]   1.2 % (1.0)   [1.5 %]    6, 55/67  [4, 31/31]
    1 %                          1.00     0.96 % (1.1)  [1.0 %]    5.9 % (0.96)  [6.2 %]    4, 45/45  [4, 45/45]

With trim=True: q̈ 4e-8, 0.62 %, 2.75 % (reported/actual 0.85, 0.73, 0.85), 8, 66 and 66 of 401 rows dropped.

Real sampling (tests/test_userdata.py; "before" = the spline path such data took before):

* pendulum θ̈ = −1.21 sin θ − 0.011 θ̇, θ₀ = 0.5, 6 Hz nominal for 86 s, sampling jitter 2 % of dt, 4 gaps of 2–3
  samples, ms timestamps, σ = 0.0025 (507 rows): q̈ 2.35 % (before 2.37 %), 1.5 % without 20 rows at each end
  (1.4 %), reported/actual 0.97 (0.90); order 6, windows 25/31.  Over 20 seeds: median 2.7 % (2.9 %), worst 3.7 %
  (4.9 %), without the ends 1.4 % (1.8 %).  Per row, |error|/estimate ≤ 5.1 (RMS 1.3); the spline's bootstrap: 14.
* spring cart, 30 fps for 30 s, whole pixels (σ̂ = 0.307 px, 1/√12 = 0.289), ms timestamps: ẍ 1.4 % (before 2.7 %),
  reported/actual 1.11 (0.81); order 6, windows 37/45; |error|/estimate ≤ 4.0 (spline 26).  In the recorded
  (rounded) times instead of the grid: 1.5 %.

On the lab-like recordings of tests/fixtures/recordings.py (q̈ relative error, all rows, one trajectory each, before →
now): damped pendulum 2.07 → 2.06 %, pendulum 3.1 → 1.65 %, cart 1.67 → 1.21 %, coupled carts 1.7/2.3 → 2.1/1.0 %
and 1.9/2.1 → 1.5/0.9 %, disjoint-clock 2.0 → 1.3 % and 1.3 → 2.1 % (its start: the one-sided bias at a turning
point is larger than the trajectory-RMS R predicts; reported/actual 0.43), chaotic double pendulum 20.8/21.2 →
22.0/21.7 % and 22.3/22.5 → 23.1/22.2 % (broadband motion: the Taylor model understates the bias, reported/actual
0.5–0.8 before and now).  Geometric mean over these and the four cases above (three pendulum seeds): 4.3 % → 3.6 %.
"""

from __future__ import annotations

import warnings
from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import UnivariateSpline

from nnphd.user.localpoly import MIN_SAMPLES, MIN_WINDOW, POLYORDER, poly_coordinate
from nnphd.user.recording import DataError, Trajectory, UserData
from nnphd.user.sampling import UNIFORM_RTOL, classify_sampling, grid_step, noise_level

__all__ = [
    "ESTIMATORS",
    "METHODS",
    "AutoDerivatives",
    "DerivativeEstimate",
    "DerivativeEstimator",
    "Derivatives",
    "LocalPolynomial",
    "SavitzkyGolay",
    "SmoothingSpline",
    "derivative_name",
    "estimate_derivatives",
    "estimator_for",
    "to_dataset",
]

_N_BOOTSTRAP = 8
# trim="auto" trims the ends (trim=True) unless that leaves a trajectory less than TRIM_KEEP_MIN of its rows or fewer
# than TRIM_KEEP_ROWS rows
TRIM_KEEP_MIN = 0.6
TRIM_KEEP_ROWS = 12


@dataclass(frozen=True)
class DerivativeEstimate:
    """Estimated q̇, q̈ (N, n) of one trajectory, with what was done and how accurate it should be.

    ``keep`` (N,) marks the rows to use (all True unless edges were trimmed).  Per coordinate (shape (n,)): ``noise``
    is the estimated position noise σ, ``noise_rel`` = σ / std(q); ``qd_err``/``qdd_err`` the estimated RMS errors over
    the kept rows and ``qd_rms``/``qdd_rms`` the RMS of the estimates there; ``window_qd``/``window_qdd`` and
    ``order_qd``/``order_qdd`` the local-polynomial windows (samples) and orders of the interior rows (None for the
    spline; the end rows may use others); ``q_step`` the common step of the values (0 if none).
    ``qd_err_rows``/``qdd_err_rows`` (N, n) are the estimated errors of every row (their RMS over the kept rows is
    ``qd_err``/``qdd_err``): larger at the ends and next to gaps.  ``method`` is "savgol", "local" or "spline" (or your
    estimator's name);
    ``dt`` the grid spacing (None unless "savgol"), ``dt_median``/``dt_ratio`` the median spacing and the largest
    spacing over it; ``time_base`` "recorded" or "nominal" (the lattice times of the frames, see
    :mod:`nnphd.user.sampling`).
    """

    qd: np.ndarray
    qdd: np.ndarray
    keep: np.ndarray
    method: str
    dt: float | None
    noise: np.ndarray
    noise_rel: np.ndarray
    qd_err: np.ndarray
    qdd_err: np.ndarray
    qd_rms: np.ndarray
    qdd_rms: np.ndarray
    window_qd: tuple
    window_qdd: tuple
    order_qd: tuple
    order_qdd: tuple
    qd_err_rows: np.ndarray
    qdd_err_rows: np.ndarray
    q_step: np.ndarray
    dt_median: float
    dt_ratio: float
    time_base: str

    @property
    def trimmed(self) -> int:
        return int((~self.keep).sum())

    @classmethod
    def from_values(cls, t, q, qd, qdd, *, method: str, keep=None, errors=None) -> DerivativeEstimate:
        """The estimate of your own :class:`DerivativeEstimator`: q̇, q̈ of the shape of q at the times t, with the
        rest measured as the built-in estimators measure it (the position noise σ, the value step, the sampling).
        ``keep`` (N,): the rows to use (None: all); ``errors``: the estimated errors of every row's q̇ and q̈, shape
        (2, N) or (2, N, n) (None: zero — the derivatives are taken as exact, and the law's rows are then weighted
        by the q̈ scatter of each coordinate alone). ``method``: the estimator's name. No windows or orders (None);
        ``dt`` None, ``time_base`` "recorded"."""
        t, q2 = _checked_inputs(t, q)
        n_rows, n = q2.shape
        qd, qdd = (np.asarray(a, dtype=np.float64) for a in (qd, qdd))
        if qd.size != n_rows * n or qdd.size != n_rows * n:
            raise ValueError(f"{method}: q̇ and q̈ must have the shape of q {np.shape(q)}, got {qd.shape}, {qdd.shape}")
        qd, qdd = qd.reshape(n_rows, n), qdd.reshape(n_rows, n)
        keep = np.ones(n_rows, dtype=bool) if keep is None else np.asarray(keep, dtype=bool).reshape(n_rows)
        if not keep.any():
            raise DataError(f"{method}: no row is kept")
        err = np.zeros((2, n_rows, n)) if errors is None else np.asarray(errors, np.float64).reshape(2, n_rows, -1)
        err = np.broadcast_to(err, (2, n_rows, n))
        smp = classify_sampling(t)
        noise = np.array([noise_level(t, q2[:, j]) for j in range(n)])
        std = q2.std(axis=0)
        return cls(
            qd=qd,
            qdd=qdd,
            keep=keep,
            method=str(method),
            dt=None,
            noise=noise,
            noise_rel=np.divide(noise, std, out=np.zeros(n), where=std > 0),
            qd_err=np.sqrt(np.mean(err[0][keep] ** 2, axis=0)),
            qdd_err=np.sqrt(np.mean(err[1][keep] ** 2, axis=0)),
            qd_rms=np.sqrt(np.mean(qd[keep] ** 2, axis=0)),
            qdd_rms=np.sqrt(np.mean(qdd[keep] ** 2, axis=0)),
            window_qd=(None,) * n,
            window_qdd=(None,) * n,
            order_qd=(None,) * n,
            order_qdd=(None,) * n,
            qd_err_rows=np.array(err[0]),
            qdd_err_rows=np.array(err[1]),
            q_step=np.array([grid_step(q2[:, j]) for j in range(n)]),
            dt_median=smp.dt_median,
            dt_ratio=smp.ratio,
            time_base="recorded",
        )


# ---- smoothing spline ---------------------------------------------------------------------------------------------
def _spline_fit(t, y, sigma):
    """Quintic smoothing spline with residual sum of squares N·σ².  Where FITPACK cannot meet that target (s ≈ 0 on
    noise-free data; its knot search then varies from sample to sample) the interpolating spline (s = 0) is used."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", UserWarning)
        spl = UnivariateSpline(t, y, k=5, s=y.shape[0] * sigma**2)
    if caught:
        spl = UnivariateSpline(t, y, k=5, s=0.0)
    return spl


def _spline_coordinate(t: np.ndarray, y: np.ndarray, sigma: float):
    """Quintic smoothing spline q̇, q̈ (s = Nσ²) with per-row bootstrap error estimates (2, N)."""
    spl = _spline_fit(t, y, sigma)
    d1, d2 = spl.derivative(1), spl.derivative(2)
    qd, qdd = d1(t), d2(t)
    if sigma == 0.0:
        return qd, qdd, np.zeros((2, t.shape[0]))
    rng = np.random.default_rng(0)
    base = spl(t)
    sq = np.zeros((2, t.shape[0]))
    for _ in range(_N_BOOTSTRAP):
        b = _spline_fit(t, base + sigma * rng.standard_normal(y.shape[0]), sigma)
        sq[0] += (b.derivative(1)(t) - qd) ** 2
        sq[1] += (b.derivative(2)(t) - qdd) ** 2
    return qd, qdd, np.sqrt(sq / _N_BOOTSTRAP)


def _spline_trim(err_rows: np.ndarray) -> tuple[int, int]:
    """Rows to drop at the start and end of a spline estimate: the runs from each end whose estimated error exceeds
    twice the median (any coordinate, q̇ or q̈).  err_rows: (k, N)."""
    lead = trail = 0
    for e in err_rows:
        if not np.any(e > 0):
            continue
        high = e > 2.0 * np.median(e)
        lead = max(lead, int(np.argmin(high)) if not high.all() else e.size)
        trail = max(trail, int(np.argmin(high[::-1])) if not high.all() else e.size)
    return lead, trail


# ---- the estimators -----------------------------------------------------------------------------------------------
class DerivativeEstimator(ABC):
    """How q̇ and q̈ of ONE trajectory are estimated from its positions: what ``Derivatives(method=...)`` takes (as
    pysindy's ``differentiation_method``).

    The built-in ones are :class:`SavitzkyGolay`, :class:`LocalPolynomial`, :class:`SmoothingSpline` and
    :class:`AutoDerivatives` (the strings "savgol", "local", "spline" and "auto" name them). Your own: subclass it,
    give it a ``name`` (the report's ``settings.derivative_method``) and an :meth:`estimate`; its result may be built
    with :meth:`DerivativeEstimate.from_values` from your q̇ and q̈ alone::

        class Gradient(nnphd.DerivativeEstimator):
            name = "gradient"

            def estimate(self, t, q, trim=False):
                qd = np.gradient(q, t, axis=0)
                return nnphd.DerivativeEstimate.from_values(t, q, qd, np.gradient(qd, t, axis=0), method=self.name)

        nnphd.NNPhD(derivatives=nnphd.Derivatives(Gradient())).fit(data)
    """

    name: str = "custom"

    @abstractmethod
    def estimate(self, t, q, trim: bool = False) -> DerivativeEstimate:
        """q̇ and q̈ of ONE trajectory sampled at t (N,), q (N,) or (N, n) (a coordinate per column). ``trim``: the
        end rows, where the estimates are least accurate, may be dropped (``keep`` False); an estimator without
        such rows may ignore it."""

    def __repr__(self) -> str:
        return f"{type(self).__name__}()"


class _Coordinatewise(DerivativeEstimator):
    """The built-in estimators: each coordinate differentiated separately, with per-row error estimates (the module
    docstring, items 1–6). A subclass says in :meth:`_plan` who differentiates the trajectory, in which times and with
    which noise levels; the one chosen differentiates each coordinate (:meth:`_coordinate`) and says which end rows
    ``trim`` drops (:meth:`_trim_counts`). Stateless: two of one class are equal."""

    _constant: tuple = ((None, None), (None, None))  # (windows, orders) of a constant coordinate

    def __eq__(self, other) -> bool:
        return type(other) is type(self)

    def __hash__(self) -> int:
        return hash(type(self))

    def estimate(self, t, q, trim: bool = False) -> DerivativeEstimate:
        t, q2 = _checked_inputs(t, q)
        smp = classify_sampling(t)
        noise = np.array([noise_level(t, q2[:, j]) for j in range(q2.shape[1])])
        est, time_base, tg, noise = self._plan(t, q2, smp, noise)
        return est._run(q2, smp, tg, noise, time_base, trim)

    def _plan(self, t: np.ndarray, q2: np.ndarray, smp, noise: np.ndarray) -> tuple:
        """(the estimator that differentiates, the time base, the times the derivatives are taken in, the noise
        levels in those times); here: this one, in the recorded times."""
        return self, "recorded", t, noise

    def _grid_dt(self, smp) -> float | None:
        """The grid spacing the estimates use (Savitzky–Golay's), None for any other."""
        return None

    def _coordinate(self, tg: np.ndarray, y: np.ndarray, sigma: float, trim: bool, smp) -> tuple:
        """(q̇, q̈, (window q̇, window q̈), (order q̇, order q̈), per-row errors (2, N)) of one coordinate."""
        raise NotImplementedError

    def _trim_counts(self, windows: list[tuple], err_rows: np.ndarray) -> tuple[int, int]:
        """Rows to drop at the start and at the end with ``trim=True``."""
        raise NotImplementedError

    def _run(self, q2, smp, tg, noise, time_base: str, trim: bool) -> DerivativeEstimate:
        """Every coordinate of q2 (N, n) differentiated in the times tg."""
        n_rows, n = q2.shape
        qd = np.zeros((n_rows, n))
        qdd = np.zeros((n_rows, n))
        err_rows = np.zeros((2, n_rows, n))
        q_step = np.array([grid_step(q2[:, j]) for j in range(n)])
        windows: list[tuple] = []
        orders: list[tuple] = [self._constant[1]] * n
        for j in range(n):
            if np.ptp(q2[:, j]) == 0:  # a constant coordinate: exact zeros
                windows.append(self._constant[0])
                continue
            qd[:, j], qdd[:, j], win, orders[j], err_rows[:, :, j] = self._coordinate(tg, q2[:, j], noise[j], trim, smp)
            windows.append(win)
        keep = np.ones(n_rows, dtype=bool)
        if trim:
            lead, trail = self._trim_counts(windows, err_rows)
            if n_rows - lead - trail < 1:
                raise DataError(f"trimming {lead} + {trail} edge samples leaves none of {n_rows}; use trim=False")
            keep[:lead] = False
            keep[n_rows - trail :] = False
        std = q2.std(axis=0)
        return DerivativeEstimate(
            qd=qd,
            qdd=qdd,
            keep=keep,
            method=self.name,
            dt=self._grid_dt(smp),
            noise=noise,
            noise_rel=np.divide(noise, std, out=np.zeros(n), where=std > 0),
            qd_err=np.sqrt(np.mean(err_rows[0][keep] ** 2, axis=0)),
            qdd_err=np.sqrt(np.mean(err_rows[1][keep] ** 2, axis=0)),
            qd_rms=np.sqrt(np.mean(qd[keep] ** 2, axis=0)),
            qdd_rms=np.sqrt(np.mean(qdd[keep] ** 2, axis=0)),
            window_qd=tuple(w[0] for w in windows),
            window_qdd=tuple(w[1] for w in windows),
            order_qd=tuple(o[0] for o in orders),
            order_qdd=tuple(o[1] for o in orders),
            qd_err_rows=err_rows[0],
            qdd_err_rows=err_rows[1],
            q_step=q_step,
            dt_median=smp.dt_median,
            dt_ratio=smp.ratio,
            time_base=time_base,
        )


class LocalPolynomial(_Coordinatewise):
    """Local polynomial regression in the recorded times, any sampling (:mod:`nnphd.user.localpoly`: order and
    window of least estimated error per derivative, the end rows their own); ``trim`` drops half the largest window
    at each end. ``"local"``."""

    name = "local"
    _constant = ((MIN_WINDOW, MIN_WINDOW), (POLYORDER, POLYORDER))

    def _coordinate(self, tg, y, sigma, trim, smp) -> tuple:
        qd, qdd, win, order, e = poly_coordinate(tg, y, sigma, trim, self._grid_dt(smp))
        return qd, qdd, win, order, e

    def _trim_counts(self, windows, err_rows) -> tuple[int, int]:
        lead = max(max(w) for w in windows) // 2
        return lead, lead


class SavitzkyGolay(LocalPolynomial):
    """Local polynomials on a uniform grid (scipy's Savitzky–Golay filter), in the grid's times; a trajectory that is
    not uniformly sampled is a :class:`~nnphd.user.recording.DataError`. ``"savgol"``."""

    name = "savgol"

    def _plan(self, t, q2, smp, noise) -> tuple:
        if smp.dt is None:
            raise DataError(
                "Savitzky–Golay needs uniform sampling: t deviates from a uniform grid by more than "
                f"{UNIFORM_RTOL:g}·dt (and more than the rounding of t); use method='local', 'spline' or "
                "'auto'"
            )
        return self, "recorded", t[0] + smp.dt * np.arange(q2.shape[0]), noise

    def _grid_dt(self, smp) -> float | None:
        return smp.dt


class SmoothingSpline(_Coordinatewise):
    """A quintic smoothing spline (s = N·σ²) with bootstrap per-row errors (the module docstring, item 6); ``trim``
    drops the end rows whose estimated error exceeds twice the median. ``"spline"``."""

    name = "spline"

    def _coordinate(self, tg, y, sigma, trim, smp) -> tuple:
        qd, qdd, e = _spline_coordinate(tg, y, sigma)
        return qd, qdd, (None, None), (None, None), e

    def _trim_counts(self, windows, err_rows) -> tuple[int, int]:
        _, n_rows, n = err_rows.shape
        return _spline_trim(err_rows.transpose(0, 2, 1).reshape(2 * n, n_rows))


class AutoDerivatives(_Coordinatewise):
    """The estimator chosen by the sampling (the module docstring, item 2): :class:`SavitzkyGolay` on uniform grids
    (in the nominal times where the recorded ones are rounded), :class:`LocalPolynomial` on near-uniform ones (in the
    recorded or the nominal lattice times, whichever the positions are smoother on), :class:`SmoothingSpline` on
    grossly irregular ones. ``"auto"``, the default."""

    name = "auto"

    def _plan(self, t, q2, smp, noise) -> tuple:
        if smp.kind == "uniform":
            est, _, tg, noise = SavitzkyGolay()._plan(t, q2, smp, noise)
            return est, "nominal" if smp.rounded else "recorded", tg, noise
        if smp.kind == "irregular":
            return SmoothingSpline()._plan(t, q2, smp, noise)
        use_nominal = False
        if smp.nominal is not None:
            if smp.rounded:
                use_nominal = True
            else:  # which clock are the positions smoother on: the recorded times or the nominal ones?
                noise_nom = np.array([noise_level(smp.nominal, q2[:, j]) for j in range(q2.shape[1])])
                moving = (noise > 0) & (noise_nom > 0)
                use_nominal = bool(moving.any() and np.sum(np.log(noise_nom[moving] / noise[moving])) < 0)
                if use_nominal:
                    noise = noise_nom
        if use_nominal:
            return LocalPolynomial(), "nominal", smp.nominal, noise
        return LocalPolynomial(), "recorded", t, noise


ESTIMATORS = {"auto": AutoDerivatives, "savgol": SavitzkyGolay, "local": LocalPolynomial, "spline": SmoothingSpline}
METHODS = tuple(ESTIMATORS)  # the names of the built-in estimators: what :func:`estimate_derivatives` takes


def estimator_for(method: str | DerivativeEstimator) -> DerivativeEstimator:
    """The estimator a method names (:data:`ESTIMATORS`), or the estimator given; ValueError otherwise."""
    if isinstance(method, DerivativeEstimator):
        return method
    if isinstance(method, str) and method in ESTIMATORS:
        return ESTIMATORS[method]()
    raise ValueError(f"method must be 'auto', 'savgol', 'local', 'spline' or a DerivativeEstimator, got {method!r:.60}")


def estimate_derivatives(t, q, method: str | DerivativeEstimator = "auto", *, trim: bool = False) -> DerivativeEstimate:
    """q̇ and q̈ of ONE trajectory sampled at t (N,), q (N,) or (N, n), each coordinate separately.

    method: ``"auto"`` (Savitzky–Golay on uniform grids, local polynomials on near-uniform ones, the spline on grossly
    irregular ones, and the time base; see the module docstring, item 2), ``"savgol"`` (uniform grids only),
    ``"local"`` (local polynomials in the recorded times, any sampling) or ``"spline"`` — or a
    :class:`DerivativeEstimator` (:data:`ESTIMATORS`). ``trim=True`` drops the first and last half-window rows
    (largest window over coordinates and derivatives; for the spline, the end rows whose estimated error exceeds
    twice the median) via ``keep``, and chooses windows for the interior rows.
    """
    return estimator_for(method).estimate(t, q, trim=trim)


def _checked_inputs(t, q) -> tuple[np.ndarray, np.ndarray]:
    """t (N,) and q as (N, n) float64, refused unless of equal lengths, at least MIN_SAMPLES long and t strictly
    increasing."""
    t = np.asarray(t, dtype=np.float64).reshape(-1)
    q = np.asarray(q, dtype=np.float64)
    q2 = q.reshape(q.shape[0], -1)
    n_rows = q2.shape[0]
    if t.shape[0] != n_rows:
        raise DataError(f"t has {t.shape[0]} samples but q has {n_rows}; expected equal lengths")
    if n_rows < MIN_SAMPLES:
        raise DataError(f"{n_rows} samples; at least {MIN_SAMPLES} are needed to estimate derivatives")
    if not np.all(np.diff(t) > 0):
        raise DataError("t must be strictly increasing")
    return t, q2


# ---- data set -----------------------------------------------------------------------------------------------------
def _estimated(estimator: DerivativeEstimator, t, q, trim: bool) -> DerivativeEstimate:
    """``estimator.estimate(t, q, trim)``, refused (TypeError/ValueError, one line) unless a DerivativeEstimate of
    q's shape."""
    est = estimator.estimate(t, q, trim=trim)
    name = getattr(estimator, "name", type(estimator).__name__)
    if not isinstance(est, DerivativeEstimate):
        raise TypeError(f"the derivative estimator {name!r} returned a {type(est).__name__}, not a DerivativeEstimate")
    shape = (len(t), int(np.prod(np.shape(q)[1:], dtype=int)))
    for what, a in (
        ("qd", est.qd),
        ("qdd", est.qdd),
        ("qd_err_rows", est.qd_err_rows),
        ("qdd_err_rows", est.qdd_err_rows),
    ):
        if np.shape(a) != shape:
            raise ValueError(
                f"the derivative estimator {name!r} returned {what} of shape {np.shape(a)}; expected {shape}"
            )
    if np.shape(est.keep) != (len(t),):
        raise ValueError(
            f"the derivative estimator {name!r} returned keep of shape {np.shape(est.keep)}; expected ({len(t)},)"
        )
    return est


def _trajectory_derivatives(ud: UserData, tr: Trajectory, estimator: DerivativeEstimator, trim: bool) -> dict:
    """q̇, q̈ (N, n) of one trajectory (given columns verbatim, the rest estimated by ``estimator``), the kept rows, per-row error
    estimates (N, n; NaN in given columns) and per-coordinate statistics (arrays (n,); errors/windows of given
    derivatives are NaN/None)."""
    n = ud.n
    given_qd, given_qdd = np.array(ud.given_qd), np.array(ud.given_qdd)
    qd, qdd = tr.qd.copy(), tr.qdd.copy()
    keep = np.ones(len(tr), dtype=bool)
    smp = classify_sampling(tr.t)
    stats = {
        "noise": np.zeros(n),
        "noise_rel": np.zeros(n),
        "q_step": np.zeros(n),
        "qd_err": np.full(n, np.nan),
        "qdd_err": np.full(n, np.nan),
        "qd_rms": np.full(n, np.nan),
        "qdd_rms": np.full(n, np.nan),
        "window_qd": [None] * n,
        "window_qdd": [None] * n,
        "order_qd": [None] * n,
        "order_qdd": [None] * n,
        "method": "given",
        "time_base": "recorded",
        "dt": smp.dt,
        "dt_median": smp.dt_median,
        "dt_ratio": smp.ratio,
        "sampling": smp.kind,
        "qd_err_rows": np.full((len(tr), n), np.nan),
        "qdd_err_rows": np.full((len(tr), n), np.nan),
    }
    q = tr.q.copy()
    q[:, ud.is_angle] = np.unwrap(q[:, ud.is_angle], axis=0)
    if given_qd.all():  # positions are not differentiated: noise level only
        std = q.std(axis=0)
        stats["noise"] = np.array([noise_level(tr.t, q[:, j]) for j in range(n)])
        stats["noise_rel"] = np.divide(stats["noise"], std, out=np.zeros(n), where=std > 0)
        stats["q_step"] = np.array([grid_step(q[:, j]) for j in range(n)])
    else:
        est = _estimated(estimator, tr.t, q, trim)
        stats.update(
            noise=est.noise,
            noise_rel=est.noise_rel,
            q_step=est.q_step,
            method=est.method,
            dt=est.dt,
            time_base=est.time_base,
        )
        keep &= est.keep
        for j in np.flatnonzero(~given_qd):
            qd[:, j] = est.qd[:, j]
            stats["qd_err"][j], stats["qd_rms"][j] = est.qd_err[j], est.qd_rms[j]
            stats["window_qd"][j], stats["order_qd"][j] = est.window_qd[j], est.order_qd[j]
            stats["qd_err_rows"][:, j] = est.qd_err_rows[:, j]
            if not given_qdd[j]:
                qdd[:, j] = est.qdd[:, j]
                stats["qdd_err"][j], stats["qdd_rms"][j] = est.qdd_err[j], est.qdd_rms[j]
                stats["window_qdd"][j], stats["order_qdd"][j] = est.window_qdd[j], est.order_qdd[j]
                stats["qdd_err_rows"][:, j] = est.qdd_err_rows[:, j]
    cols = np.flatnonzero(given_qd & ~given_qdd)
    if cols.size:  # q̈ by differentiating the given q̇ once
        est_v = _estimated(estimator, tr.t, tr.qd[:, cols], trim)
        stats.update(method=est_v.method, dt=est_v.dt, time_base=est_v.time_base)
        keep &= est_v.keep
        for i, j in enumerate(cols):
            qdd[:, j] = est_v.qd[:, i]
            stats["qdd_err"][j], stats["qdd_rms"][j] = est_v.qd_err[i], est_v.qd_rms[i]
            stats["window_qdd"][j], stats["order_qdd"][j] = est_v.window_qd[i], est_v.order_qd[i]
            stats["qdd_err_rows"][:, j] = est_v.qd_err_rows[:, i]
    return {"qd": qd, "qdd": qdd, "keep": keep, **stats}


@dataclass(frozen=True)
class DerivedData:
    """A record's stacked data set with its derivatives (:func:`derive`): ``data`` (a Dataset), ``info`` (JSON-ready,
    :func:`to_dataset`), ``row_errors`` = {"qd_err", "qdd_err"}: each (data set rows, n), the estimated error of
    every row's q̇ / q̈ (NaN in given columns) — larger at the trajectory ends and next to gaps, for weighting or
    trimming rows — and ``trim``: whether the ends were trimmed."""

    data: object
    info: dict
    row_errors: dict
    trim: bool


def to_dataset(userdata: UserData, *, method: str | DerivativeEstimator = "auto", trim: bool = False):
    """Stack all trajectories into a :class:`nnphd.engine.data.Dataset` (q as given, q̇/q̈ given or estimated per trajectory).

    Returns ``(dataset, info)`` (:func:`derive` keeps the per-row errors too).  ``info`` is JSON-ready:

    * ``coordinates``, ``angles``, ``n_traj``, ``n_rows`` (file rows), ``n_samples`` (data set rows), ``trimmed``
      (rows dropped), ``trim``, ``method`` ("savgol", "local", "spline", "given" or "mixed");
    * ``per_coordinate[name]``: ``noise`` (σ), ``noise_relative`` (σ/std q) and ``quantization_step`` (the common step
      of the values, 0 if none; σ ≥ step/√12), and for ``qd`` and ``qdd`` the ``source`` ("given", "estimated from
      q", "estimated from q_dot"), the estimated RMS ``error`` and ``relative_error`` (over the RMS of the
      derivative), ``error_max`` (the largest per-row estimated error), the ``windows`` (samples) and ``orders`` used
      — pooled over trajectories as RMS weighted by their rows (``error_max``: the maximum);
    * ``trajectories``: per trajectory ``id``, ``n_samples``, ``method``, ``sampling`` ("uniform", "near-uniform",
      "irregular"), ``time_base`` ("recorded" or "nominal"), ``dt`` (the grid spacing, None unless uniform),
      ``dt_median``, ``dt_ratio`` (largest over median spacing; None for a single sample) and ``kept`` =
      [start, stop): the data set holds rows start…stop-1 of each trajectory, in trajectory
      order, so its file rows are ``np.concatenate([tr.rows[a:b] for tr, (a, b) in ...])``.
    """
    d = derive(userdata, method=method, trim=trim)
    return d.data, d.info


def derive(userdata: UserData, *, method: str | DerivativeEstimator = "auto", trim: bool = False) -> DerivedData:
    """:func:`to_dataset`'s data set and info with the per-row errors of its derivative estimates; ``method`` a name
    of :data:`METHODS` or a :class:`DerivativeEstimator` (each trajectory's q̇, q̈ are its :meth:`estimate`)."""
    from nnphd.engine.data import Dataset

    estimator = estimator_for(method)
    parts = {"q": [], "qd": [], "qdd": [], "t": [], "qd_err_rows": [], "qdd_err_rows": []}
    results, per_traj, weights = [], [], []
    for tr in userdata.trajectories:
        try:
            r = _trajectory_derivatives(userdata, tr, estimator, trim)
        except DataError as e:
            raise DataError(f"{userdata.path}: trajectory {tr.id}: {e}") from None
        start = int(np.argmax(r["keep"]))
        stop = len(tr) - int(np.argmax(r["keep"][::-1]))
        for name, arr in (
            ("q", tr.q),
            ("qd", r["qd"]),
            ("qdd", r["qdd"]),
            ("t", tr.t),
            ("qd_err_rows", r["qd_err_rows"]),
            ("qdd_err_rows", r["qdd_err_rows"]),
        ):
            parts[name].append(arr[start:stop])
        results.append(r)
        weights.append(stop - start)
        per_traj.append(
            {
                "id": tr.id,
                "n_samples": len(tr),
                "kept": [start, stop],
                "method": r["method"],
                "sampling": r["sampling"],
                "time_base": r["time_base"],
                "dt": r["dt"],
                "dt_median": r["dt_median"],
                "dt_ratio": r["dt_ratio"],
            }
        )
    rows = {"qd_err": np.concatenate(parts.pop("qd_err_rows")), "qdd_err": np.concatenate(parts.pop("qdd_err_rows"))}
    ds = Dataset(**{k: np.concatenate(v) for k, v in parts.items()})

    w = np.asarray(weights, dtype=np.float64) / sum(weights)

    def pooled(key, j):  # RMS over trajectories weighted by their kept rows
        return float(np.sqrt(np.sum(w * np.array([r[key][j] for r in results]) ** 2)))

    per_coord = {}
    for j, name in enumerate(userdata.coords):
        entry = {
            "noise": pooled("noise", j),
            "noise_relative": pooled("noise_rel", j),
            "quantization_step": max(float(r["q_step"][j]) for r in results),
        }
        for key, given in (("qd", userdata.given_qd[j]), ("qdd", userdata.given_qdd[j])):
            if given:
                entry[key] = {
                    "source": "given",
                    "error": None,
                    "relative_error": None,
                    "error_max": None,
                    "windows": [],
                    "orders": [],
                }
                continue
            err, size = pooled(f"{key}_err", j), pooled(f"{key}_rms", j)
            from_qd = key == "qdd" and userdata.given_qd[j]
            entry[key] = {
                "source": "estimated from q_dot" if from_qd else "estimated from q",
                "error": err,
                "relative_error": err / size if size > 0 else None,
                "error_max": float(np.max(rows[f"{key}_err"][:, j])),
                "windows": sorted({int(r[f"window_{key}"][j]) for r in results if r[f"window_{key}"][j] is not None}),
                "orders": sorted({int(r[f"order_{key}"][j]) for r in results if r[f"order_{key}"][j] is not None}),
            }
        per_coord[name] = entry
    methods = sorted({p["method"] for p in per_traj})
    info = {
        "coordinates": list(userdata.coords),
        "angles": list(userdata.angles),
        "n_traj": userdata.n_traj,
        "n_rows": userdata.n_samples,
        "n_samples": len(ds),
        "trimmed": userdata.n_samples - len(ds),
        "trim": bool(trim),
        "method": methods[0] if len(methods) == 1 else "mixed",
        "per_coordinate": per_coord,
        "trajectories": per_traj,
    }
    return DerivedData(ds, info, rows, bool(trim))


# ---- the strategy object --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Derivatives:
    """How q̇ and q̈ are estimated from the positions: ``nnphd.NNPhD(derivatives=Derivatives(...))``.

    ``method``: a :class:`DerivativeEstimator` — your own, or a built-in one — or a built-in one's name: "auto" (the
    default, :class:`AutoDerivatives`: Savitzky–Golay on uniform grids, local polynomials on near-uniform ones, the
    smoothing spline on grossly irregular ones; see the module docstring), "savgol" (:class:`SavitzkyGolay`, uniform
    grids only), "local" (:class:`LocalPolynomial`, in the recorded times) or "spline" (:class:`SmoothingSpline`).
    ``trim``: drop the first and last half-window rows of each trajectory, where the one-sided estimates are ~20x
    worse — True, False, or "auto" (the default: True unless that leaves a trajectory less than
    :data:`TRIM_KEEP_MIN` of its rows or fewer than :data:`TRIM_KEEP_ROWS` rows).  ``thin``: a dense record (over
    :data:`nnphd.user.derivatives.THIN_ROWS` rows) is thinned once its derivatives are estimated at the full rate
    (:func:`nnphd.user.derivatives.dense_thinned`; False: every row is used).  ``Derivatives()`` is what ``nnphd detect``
    does (``--trim``, ``--thin/--no-thin``).  A bad field is a ValueError naming it and what is expected.
    """

    method: str | DerivativeEstimator = "auto"
    trim: bool | str = "auto"
    thin: bool = True

    def __post_init__(self) -> None:
        if not isinstance(self.method, DerivativeEstimator) and not (
            isinstance(self.method, str) and self.method in METHODS
        ):
            raise ValueError(
                f"Derivatives: method must be one of {', '.join(map(repr, METHODS))} or a DerivativeEstimator, "
                f"got {self.method!r:.60}"
            )
        if isinstance(self.trim, np.bool_):
            object.__setattr__(self, "trim", bool(self.trim))
        if not (isinstance(self.trim, bool) or (isinstance(self.trim, str) and self.trim == "auto")):
            raise ValueError(f"Derivatives: trim must be 'auto', True or False, got {self.trim!r:.60}")
        if isinstance(self.thin, np.bool_):
            object.__setattr__(self, "thin", bool(self.thin))
        if not isinstance(self.thin, bool):
            raise ValueError(f"Derivatives: thin must be True or False, got {self.thin!r:.60}")

    @property
    def estimator(self) -> DerivativeEstimator:
        """The estimator ``method`` is or names (:func:`estimator_for`)."""
        return estimator_for(self.method)

    @property
    def name(self) -> str:
        """The method's name: the string given, or the estimator's ``name`` (the report's
        ``settings.derivative_method``)."""
        return derivative_name(self.method)

    def estimate(self, t, q) -> DerivativeEstimate:
        """q̇ and q̈ of ONE trajectory (t (N,), q (N,) or (N, n)): :attr:`estimator`'s estimate with this trim
        ("auto": trimmed when :data:`TRIM_KEEP_MIN` and :data:`TRIM_KEEP_ROWS` allow; ``.keep`` says)."""
        est = self.estimator
        if self.trim != "auto":
            return est.estimate(t, q, trim=self.trim)
        try:
            out = est.estimate(t, q, trim=True)
        except DataError:  # trimming would leave no row
            return est.estimate(t, q, trim=False)
        if not trim_keeps_enough([(int(out.keep.sum()), out.keep.size)]):
            return est.estimate(t, q, trim=False)
        return out

    def dataset(self, userdata: UserData) -> DerivedData:
        """All trajectories of ``userdata`` stacked (:func:`derive` with this estimator and trim; "auto": trimmed when
        every trajectory keeps enough rows; the trim used is the result's ``trim``)."""
        est = self.estimator
        if self.trim != "auto":
            return derive(userdata, method=est, trim=self.trim)
        try:
            d = derive(userdata, method=est, trim=True)
        except DataError:
            return derive(userdata, method=est, trim=False)
        kept = [(b - a, tr["n_samples"]) for tr in d.info["trajectories"] for a, b in [tr["kept"]]]
        return d if trim_keeps_enough(kept) else derive(userdata, method=est, trim=False)


def derivative_name(method: str | DerivativeEstimator | Derivatives) -> str:
    """The name of a derivative method (a name, an estimator's ``name``, a :class:`Derivatives`' method's name): what
    a report's ``settings.derivative_method`` says."""
    if isinstance(method, Derivatives):
        method = method.method
    return method if isinstance(method, str) else str(getattr(method, "name", type(method).__name__))


def trim_keeps_enough(kept: list[tuple[int, int]]) -> bool:
    """Whether trimming leaves every trajectory enough rows: ``kept`` = (rows kept, rows) per trajectory; at least
    :data:`TRIM_KEEP_MIN` of its rows and :data:`TRIM_KEEP_ROWS` rows each."""
    return min(k / n for k, n in kept) >= TRIM_KEEP_MIN and min(k for k, _ in kept) >= TRIM_KEEP_ROWS


# A dense record is thinned once its derivatives are estimated at the full rate: a record of more than THIN_ROWS rows
# (after trimming) keeps every k-th row of each trajectory, k the smallest that brings it to ≤ THIN_ROWS rows, but
# never fewer than THIN_MIN_PER_PERIOD rows per period and never more than half the shortest derivative window (so
# every dropped row's q̇ and q̈ come from a smoothing window that a kept row's window mostly shares: neighbouring
# estimates are strongly correlated, and the dropped rows add little). The real double pendulum at its full 400 Hz
# (18 038 rows, Savitzky–Golay windows of 21–31 rows, 333 rows per period) took 221 s, 133 of them in the
# trajectory-level fits; thinned to every 4th row it takes about what its 100-Hz record takes, with better
# derivatives. Records with given q̇ or q̈ (no window) and records that do not oscillate are not thinned.
THIN_ROWS = 5000


THIN_MIN_PER_PERIOD = 80


def dense_thinned(data, info: dict, row_err, traj, ud):
    """(data, row errors, trajectory ids) of a dense record thinned as the comment above says, or as given; the
    thinning, when there is one, is recorded in ``info["thinned"]`` (every, rows_before, rows, period_rows,
    text)."""
    from nnphd.explain.jointfit import trajectory_segments
    from nnphd.user.assess import motion_period

    n = len(data)
    if n <= THIN_ROWS:
        return data, row_err, traj
    pc = info["per_coordinate"]
    wins = [pc[c][k].get("windows") for c in ud.coords for k in ("qd", "qdd")]
    if not all(wins):
        return data, row_err, traj
    period = motion_period(data, traj, [bool(a) for a in ud.is_angle], [pc[c]["noise"] for c in ud.coords])
    segs = trajectory_segments(traj)
    dts = np.concatenate([np.diff(data.t[s]) for s in segs if len(s) > 1] or [np.ones(1)])
    dt = float(np.median(dts))
    if not (np.isfinite(period) and dt > 0):
        return data, row_err, traj
    per_period = period / dt
    k = min(-(-n // THIN_ROWS), int(per_period // THIN_MIN_PER_PERIOD), min(min(w) for w in wins) // 2)
    if k <= 1:
        return data, row_err, traj
    keep = np.concatenate([s[::k] for s in segs])
    info["thinned"] = {
        "every": k,
        "rows_before": n,
        "rows": len(keep),
        "period_rows": per_period,
        "text": (
            f"a dense record: one row in {k} of its {n} is used ({len(keep)} rows, {per_period / k:.0f} per "
            f"period), its derivatives estimated at the full rate first (windows of {min(min(w) for w in wins)} "
            f"rows or more)"
        ),
    }
    errs = None if row_err is None else {name: np.asarray(v)[keep] for name, v in row_err.items()}
    return data.subset(keep), errs, np.asarray(traj)[keep]
