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
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import UnivariateSpline

from nnphd.user.localpoly import MIN_SAMPLES, MIN_WINDOW, POLYORDER, poly_coordinate
from nnphd.user.recording import DataError, Trajectory, UserData
from nnphd.user.sampling import UNIFORM_RTOL, classify_sampling, grid_step, noise_level

__all__ = ["METHODS", "DerivativeEstimate", "Derivatives", "estimate_derivatives", "to_dataset"]

_N_BOOTSTRAP = 8
METHODS = ("auto", "savgol", "local", "spline")  # what :func:`estimate_derivatives` takes
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
    ``qd_err``/``qdd_err``): larger at the ends and next to gaps.  ``method`` is "savgol", "local" or "spline";
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


# ---- estimate -----------------------------------------------------------------------------------------------------
def estimate_derivatives(t, q, method: str = "auto", *, trim: bool = False) -> DerivativeEstimate:
    """q̇ and q̈ of ONE trajectory sampled at t (N,), q (N,) or (N, n), each coordinate separately.

    method: ``"auto"`` (Savitzky–Golay on uniform grids, local polynomials on near-uniform ones, the spline on grossly
    irregular ones, and the time base; see the module docstring, item 2), ``"savgol"`` (uniform grids only),
    ``"local"`` (local polynomials in the recorded times, any sampling) or ``"spline"``.  ``trim=True`` drops the
    first and last half-window rows (largest window over coordinates and derivatives; for the spline, the end rows
    whose estimated error exceeds twice the median) via ``keep``, and chooses windows for the interior rows.
    """
    t, q2 = _checked_inputs(t, q, method)
    n_rows, n = q2.shape
    smp = classify_sampling(t)
    if method == "savgol" and smp.dt is None:
        raise DataError(
            "Savitzky–Golay needs uniform sampling: t deviates from a uniform grid by more than "
            f"{UNIFORM_RTOL:g}·dt (and more than the rounding of t); use method='local', 'spline' or "
            "'auto'"
        )
    noise = np.array([noise_level(t, q2[:, j]) for j in range(n)])
    method, time_base, tg, noise = _method_and_time_base(t, q2, smp, method, noise)

    qd = np.zeros((n_rows, n))
    qdd = np.zeros((n_rows, n))
    err_rows = np.zeros((2, n_rows, n))
    q_step = np.array([grid_step(q2[:, j]) for j in range(n)])
    windows: list[tuple] = []
    orders: list[tuple] = [(None, None) if method == "spline" else (POLYORDER, POLYORDER)] * n
    for j in range(n):
        if np.ptp(q2[:, j]) == 0:  # a constant coordinate: exact zeros
            windows.append((None, None) if method == "spline" else (MIN_WINDOW, MIN_WINDOW))
            continue
        y = q2[:, j]
        if method == "spline":
            qd[:, j], qdd[:, j], e = _spline_coordinate(t, y, noise[j])
            win = (None, None)
        else:
            qd[:, j], qdd[:, j], win, order, e = poly_coordinate(
                tg, y, noise[j], trim, smp.dt if method == "savgol" else None
            )
            orders[j] = order
        windows.append(win)
        err_rows[:, :, j] = e
    keep = np.ones(n_rows, dtype=bool)
    if trim:
        lead, trail = _trim_counts(method, windows, err_rows)
        keep[:lead] = False
        keep[n_rows - trail :] = False
    std = q2.std(axis=0)
    return DerivativeEstimate(
        qd=qd,
        qdd=qdd,
        keep=keep,
        method=method,
        dt=smp.dt if method == "savgol" else None,
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


def _checked_inputs(t, q, method: str) -> tuple[np.ndarray, np.ndarray]:
    """t (N,) and q as (N, n) float64, refused unless of equal lengths, at least MIN_SAMPLES long, t strictly
    increasing, and ``method`` one of those known."""
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
    if method not in METHODS:
        raise ValueError(f"method must be 'auto', 'savgol', 'local' or 'spline', got {method!r}")
    return t, q2


def _method_and_time_base(t: np.ndarray, q2: np.ndarray, smp, method: str, noise: np.ndarray) -> tuple:
    """The method ("auto" resolved from the sampling ``smp``), the time base, the times the derivatives are taken in
    and the noise levels (those in the nominal times where these are chosen): (method, time_base, tg, noise)."""
    n_rows, n = q2.shape
    time_base = "recorded"
    tg = t  # the times the derivatives are taken in
    if method == "auto":
        method = {"uniform": "savgol", "near-uniform": "local", "irregular": "spline"}[smp.kind]
        if smp.kind == "uniform" and smp.rounded:
            time_base = "nominal"
        elif method == "local" and smp.nominal is not None:
            if smp.rounded:
                use_nominal = True
            else:  # which clock are the positions smoother on: the recorded times or the nominal ones?
                noise_nom = np.array([noise_level(smp.nominal, q2[:, j]) for j in range(n)])
                moving = (noise > 0) & (noise_nom > 0)
                use_nominal = bool(moving.any() and np.sum(np.log(noise_nom[moving] / noise[moving])) < 0)
                if use_nominal:
                    noise = noise_nom
            if use_nominal:
                time_base, tg = "nominal", smp.nominal
    if method == "savgol":
        tg = t[0] + smp.dt * np.arange(n_rows)
    return method, time_base, tg, noise


def _trim_counts(method: str, windows: list[tuple], err_rows: np.ndarray) -> tuple[int, int]:
    """Rows to drop at the start and at the end with ``trim=True``: half the largest window, or for the spline the
    end rows of high estimated error (:func:`_spline_trim`); refused when no row would be left."""
    _, n_rows, n = err_rows.shape
    if method == "spline":
        lead, trail = _spline_trim(err_rows.transpose(0, 2, 1).reshape(2 * n, n_rows))
    else:
        lead = trail = max(max(w) for w in windows) // 2
    if n_rows - lead - trail < 1:
        raise DataError(f"trimming {lead} + {trail} edge samples leaves none of {n_rows}; use trim=False")
    return lead, trail


# ---- data set -----------------------------------------------------------------------------------------------------
def _trajectory_derivatives(ud: UserData, tr: Trajectory, method: str, trim: bool) -> dict:
    """q̇, q̈ (N, n) of one trajectory (given columns verbatim, the rest estimated), the kept rows, per-row error
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
        est = estimate_derivatives(tr.t, q, method, trim=trim)
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
        est_v = estimate_derivatives(tr.t, tr.qd[:, cols], method, trim=trim)
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


def to_dataset(userdata: UserData, *, method: str = "auto", trim: bool = False):
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


def derive(userdata: UserData, *, method: str = "auto", trim: bool = False) -> DerivedData:
    """:func:`to_dataset`'s data set and info with the per-row errors of its derivative estimates."""
    from nnphd.engine.data import Dataset

    parts = {"q": [], "qd": [], "qdd": [], "t": [], "qd_err_rows": [], "qdd_err_rows": []}
    results, per_traj, weights = [], [], []
    for tr in userdata.trajectories:
        try:
            r = _trajectory_derivatives(userdata, tr, method, trim)
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

    ``method``: "auto" (the default: Savitzky–Golay on uniform grids, local polynomials on near-uniform ones, the
    smoothing spline on grossly irregular ones; see the module docstring), "savgol" (uniform grids only), "local"
    (local polynomials in the recorded times) or "spline" (:func:`estimate_derivatives`).  ``trim``: drop the first
    and last half-window rows of each trajectory, where the one-sided estimates are ~20x worse — True, False, or
    "auto" (the default: True unless that leaves a trajectory less than :data:`TRIM_KEEP_MIN` of its rows or fewer
    than :data:`TRIM_KEEP_ROWS` rows).  ``thin``: a dense record (over :data:`nnphd.user.detect.THIN_ROWS` rows) is
    thinned once its derivatives are estimated at the full rate (:func:`nnphd.user.detect.dense_thinned`; False:
    every row is used).  ``Derivatives()`` is what ``nnphd detect`` does (``--trim``, ``--thin/--no-thin``).  A bad
    field is a ValueError naming it and what is expected.
    """

    method: str = "auto"
    trim: bool | str = "auto"
    thin: bool = True

    def __post_init__(self) -> None:
        if not isinstance(self.method, str) or self.method not in METHODS:
            raise ValueError(
                f"Derivatives: method must be one of {', '.join(map(repr, METHODS))}, got {self.method!r:.60}"
            )
        if isinstance(self.trim, np.bool_):
            object.__setattr__(self, "trim", bool(self.trim))
        if not (isinstance(self.trim, bool) or (isinstance(self.trim, str) and self.trim == "auto")):
            raise ValueError(f"Derivatives: trim must be 'auto', True or False, got {self.trim!r:.60}")
        if isinstance(self.thin, np.bool_):
            object.__setattr__(self, "thin", bool(self.thin))
        if not isinstance(self.thin, bool):
            raise ValueError(f"Derivatives: thin must be True or False, got {self.thin!r:.60}")

    def estimate(self, t, q) -> DerivativeEstimate:
        """q̇ and q̈ of ONE trajectory (t (N,), q (N,) or (N, n)): :func:`estimate_derivatives` with this method and
        trim ("auto": trimmed when :data:`TRIM_KEEP_MIN` and :data:`TRIM_KEEP_ROWS` allow; ``.keep`` says)."""
        if self.trim != "auto":
            return estimate_derivatives(t, q, self.method, trim=self.trim)
        try:
            est = estimate_derivatives(t, q, self.method, trim=True)
        except DataError:  # trimming would leave no row
            return estimate_derivatives(t, q, self.method, trim=False)
        if not trim_keeps_enough([(int(est.keep.sum()), est.keep.size)]):
            return estimate_derivatives(t, q, self.method, trim=False)
        return est

    def dataset(self, userdata: UserData) -> DerivedData:
        """All trajectories of ``userdata`` stacked (:func:`derive` with this method and trim; "auto": trimmed when
        every trajectory keeps enough rows; the trim used is the result's ``trim``)."""
        if self.trim != "auto":
            return derive(userdata, method=self.method, trim=self.trim)
        try:
            d = derive(userdata, method=self.method, trim=True)
        except DataError:
            return derive(userdata, method=self.method, trim=False)
        kept = [(b - a, tr["n_samples"]) for tr in d.info["trajectories"] for a, b in [tr["kept"]]]
        return d if trim_keeps_enough(kept) else derive(userdata, method=self.method, trim=False)


def trim_keeps_enough(kept: list[tuple[int, int]]) -> bool:
    """Whether trimming leaves every trajectory enough rows: ``kept`` = (rows kept, rows) per trajectory; at least
    :data:`TRIM_KEEP_MIN` of its rows and :data:`TRIM_KEEP_ROWS` rows each."""
    return min(k / n for k, n in kept) >= TRIM_KEEP_MIN and min(k for k, _ in kept) >= TRIM_KEEP_ROWS
