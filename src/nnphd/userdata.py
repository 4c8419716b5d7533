r"""User motion data for ``nnphd detect FILE``: read and validate a trajectory file, estimate q̇ and q̈.

File format
-----------
CSV with a header line, or NPZ whose arrays are named like the CSV columns (1-D, one value per row).

* ``t`` (required): time.
* one column per generalized coordinate, in file order (any name not listed below).
* ``traj`` (optional): integer trajectory id.  Several separate trajectories may share one file; rows are grouped by id
  (trajectories in order of first appearance), keeping file order within a trajectory, so one trajectory's rows need
  not be contiguous.  ``t`` must increase strictly within each trajectory.  Derivatives never cross a trajectory.
* ``<coord>_dot`` / ``<coord>_ddot`` (optional): measured q̇ / q̈, used verbatim instead of estimates.  When only
  ``<coord>_dot`` is given, q̈ is estimated by differentiating the given q̇ once (one order less noise amplification
  than differentiating q twice).
* ``angles`` (argument): angular coordinates; wrapped data (jumps of 2π) is unwrapped with :func:`numpy.unwrap` per
  trajectory before differentiation.  The data set keeps q as given (wrapped if the file is wrapped).

Every problem raises :class:`DataError` (a ``ValueError``) with a one-line message naming the file, column, row
(1-based data row and file line for CSV, 0-based index for NPZ) or trajectory, and what was expected: missing or
unreadable file, extension other than .csv/.npz, empty file or header only, a header of numbers, ragged rows,
duplicate names, no ``t``, no coordinate, ``_dot``/``_ddot`` without its coordinate, an angle that is not a
coordinate, non-numeric or empty cells, NaN/inf, non-integer ``traj``, t not strictly increasing within a trajectory,
fewer than ``MIN_SAMPLES`` = 7 samples in a trajectory (two SG windows, 5 and 7, are needed to measure the bias; not
required when every ``_dot`` and ``_ddot`` is given), and all coordinates constant.  Irregular sampling is accepted
(smoothing spline, below).

Derivative estimation (:func:`estimate_derivatives`, one trajectory and coordinate at a time)
--------------------------------------------------------------------------------------------
1. **Noise level σ** of the positions (:func:`noise_level`).  The k-th order difference of k+1 consecutive
   samples, normalised to unit weight norm (Δᵏy/√C(2k,k) on a uniform grid, the null vector of the local Vandermonde
   matrix on an irregular one), annihilates polynomials of degree < k and has standard deviation exactly σ on white
   noise, while a smooth signal contributes ~(ω dt)ᵏ.  σ is the RMS of these differences at the first k = 1…10 where
   going one order higher no longer lowers it by 10 % (signal gone, noise left).  On noise-free data it comes out at
   the level of the data's own roughness (rounding, integrator interpolation).
2. **Uniform sampling** (every t within 1e-6·dt of a uniform grid): Savitzky–Golay of polynomial order 4
   (:func:`scipy.signal.savgol_filter`, ``mode='interp'``: the edge rows use the polynomial fitted to the first/last
   window, so no row is lost), the window chosen separately for q̇ and q̈ of each coordinate by minimising the
   *estimated* RMS error over the rows used, on a grid of odd windows 5, 7, 9, 11, 13, 17, … ≤ min(N, 2001):

   * noise part: σ·‖w_i‖/dtᵈ for the exact filter weights w_i of every row (interior and edge stencils);
   * bias part from the Taylor expansion, bias_i = Σ_k q⁽ᵏ⁾ dtᵏ⁻ᵈ Mₖ(w_i), Mₖ(w) = Σ_j w_j o_jᵏ/k!, k = 5, 6 (the
     lowest orders a degree-4 fit does not reproduce).  The RMS sizes R₅, R₆ of q⁽⁵⁾, q⁽⁶⁾ are measured Richardson-style from the
     estimates with neighbouring windows a < b: E[Δ²] = R²(ΔMₖ)² dt²⁽ᵏ⁻ᵈ⁾ + σ²‖Δw‖²/dt²ᵈ over the rows interior to
     both.  A pair counts only when its excess over the noise term is significant (> 3 standard deviations and > the
     noise term itself, which absorbs an underestimate of σ by up to 30 %); R is the largest over such pairs (windows
     much longer than the signal's time scale saturate and would understate it).  The grid stops once the bias
     clearly dominates (excess > 10 × noise term) for both derivatives.  Edge rows use the trajectory-RMS R₅, R₆.

   The reported derivative error is this estimated RMS error at the chosen window.
3. **Irregular sampling** (or ``method="spline"``): a quintic smoothing spline
   (:class:`scipy.interpolate.UnivariateSpline`, k=5, s = N·σ², residuals at the noise level; a GCV spline can
   collapse to a straight line, and a cubic natural spline forces q̈ = 0 at the ends).  Its error is estimated by a
   parametric bootstrap (8 refits to the fitted curve plus fresh noise of size σ): this captures the noise part and
   the smoothing bias of a similar curve, not the truncation error of noise-free data.  Note that timestamps
   rounded to a few digits (e.g. 1/30 s printed to 6 decimals) are irregular at this tolerance and take this path.

Method choice ("auto"): Savitzky–Golay on uniform grids, the spline otherwise.  On the pendulum below (median of 20
noise seeds) the two are about as accurate — q̈ 1.4 % (SG) vs 1.25 % (spline) at 0.1 % noise, 5.3 % vs 6.9 % at 1 % —
but the SG error has a closed form with a measured bias, so its reported error is reliable (within a factor 1.8 of the
actual one over 30 seeds) where the spline's is a bootstrap guess.

Edges: the one-sided edge stencils have larger errors than the interior (q̈ at 1 % noise: 6 % RMS over all rows vs
3 % over the interior).  ``trim=True`` drops the first and last half-window of each trajectory (largest window over
coordinates and derivatives; windows are then chosen for the interior rows); ``keep`` / the info's ``kept`` ranges
say which rows remain.  The default keeps every row.

Measured on θ̈ = −sin θ − 0.1 θ̇ (θ₀ = 2, θ̇₀ = 0, dt = 0.05, 0…20 s, 401 samples; tests/test_userdata.py, noise
seed 0), RMS error over all rows relative to the RMS of the true derivative, and reported/actual:

    position noise (of std θ)   σ̂/σ     q̇ error (reported/actual)   q̈ error (reported/actual)   windows
    0                            —        3.8e-7 (1.1)                2.9e-6 (5.4, edge bound)      5, 5
    0.1 %                        1.00     0.19 % (1.06)               1.5 % (1.13)                  31, 31
    1 %                          1.00     1.0 % (1.07)                6.2 % (1.00)                  45, 45

With trim=True: q̈ 3.8e-7, 0.79 %, 2.8 % (reported/actual 1.0, 0.86, 0.85), 4, 36 and 66 of 401 rows dropped.
"""
from __future__ import annotations

import csv
import math
import os
import warnings
import zipfile
from dataclasses import dataclass
from functools import lru_cache
from typing import Sequence

import numpy as np
from scipy.interpolate import UnivariateSpline
from scipy.signal import savgol_filter

__all__ = [
    "DataError",
    "Trajectory",
    "UserData",
    "DerivativeEstimate",
    "MIN_SAMPLES",
    "load_trajectories",
    "noise_level",
    "estimate_derivatives",
    "to_dataset",
]

POLYORDER = 4  # Savitzky–Golay polynomial order
MIN_WINDOW = POLYORDER + 1  # smallest SG window (exact interpolation of 5 points)
MAX_WINDOW = 2001
MIN_SAMPLES = MIN_WINDOW + 2  # two windows (5, 7) are needed to measure the bias
UNIFORM_RTOL = 1e-6  # t within this fraction of dt of a uniform grid counts as uniform
_MAX_DIFF_ORDER = 10
_N_BOOTSTRAP = 8
_LEAD_ORDER = {1: POLYORDER + 1, 2: POLYORDER + 2}  # leading Taylor order of the interior SG bias


class DataError(ValueError):
    """A user data file that cannot be used; the message is one line naming what is wrong and what was expected."""


# ---- records ------------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Trajectory:
    """One trajectory: t (N,), q (N, n); qd/qdd (N, n) hold the given derivatives (NaN in columns not given);
    rows (N,) are the 0-based data-row indices in the file."""

    id: int
    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    rows: np.ndarray

    def __len__(self) -> int:
        return self.t.shape[0]


@dataclass(frozen=True)
class UserData:
    """A validated trajectory file: coordinate names, angular coordinates, which derivatives the file gives."""

    path: str
    coords: tuple[str, ...]
    angles: tuple[str, ...]
    given_qd: tuple[bool, ...]
    given_qdd: tuple[bool, ...]
    trajectories: tuple[Trajectory, ...]

    @property
    def n(self) -> int:
        return len(self.coords)

    @property
    def n_traj(self) -> int:
        return len(self.trajectories)

    @property
    def n_samples(self) -> int:
        return sum(len(tr) for tr in self.trajectories)

    @property
    def is_angle(self) -> np.ndarray:
        return np.array([c in self.angles for c in self.coords], dtype=bool)


@dataclass(frozen=True)
class DerivativeEstimate:
    """Estimated q̇, q̈ (N, n) of one trajectory, with what was done and how accurate it should be.

    ``keep`` (N,) marks the rows to use (all True unless edges were trimmed).  Per coordinate (shape (n,)): ``noise``
    is the estimated position noise σ, ``noise_rel`` = σ / std(q); ``qd_err``/``qdd_err`` the estimated RMS errors over
    the kept rows and ``qd_rms``/``qdd_rms`` the RMS of the estimates there; ``window_qd``/``window_qdd`` the
    Savitzky–Golay windows in samples (None for the spline).
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

    @property
    def trimmed(self) -> int:
        return int((~self.keep).sum())


# ---- reading ------------------------------------------------------------------------------------------------------
class _Rows:
    """How to name data row i in messages: CSV rows are 1-based with their file line, NPZ rows 0-based indices."""

    def __init__(self, lines: list[int] | None):
        self.lines = lines

    def __call__(self, i: int) -> str:
        i = int(i)
        if self.lines is None:
            return f"index {i}"
        return f"row {i + 1} (line {self.lines[i]})"


def load_trajectories(path, angles: Sequence[str] = ()) -> UserData:
    """Read and validate a CSV (header required) or NPZ trajectory file; see the module docstring for the format.

    ``angles`` names the angular coordinates.  Raises :class:`DataError` on any problem.
    """
    path = os.fspath(path)
    if isinstance(angles, str):
        angles = (angles,)
    ext = os.path.splitext(path)[1].lower()
    if ext not in (".csv", ".npz"):
        raise DataError(f"{path}: unsupported file type {ext or '(none)'!r}; expected a .csv or .npz file")
    if not os.path.exists(path):
        raise DataError(f"{path}: file not found")
    if os.path.isdir(path):
        raise DataError(f"{path}: is a directory, expected a .csv or .npz file")
    columns, rows = _read_csv(path) if ext == ".csv" else _read_npz(path)
    return _validate(path, columns, rows, tuple(angles))


def _read_csv(path: str) -> tuple[dict[str, np.ndarray], _Rows]:
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            reader = csv.reader(fh)
            header, records, lines = None, [], []
            for rec in reader:
                if not rec or all(not f.strip() for f in rec):
                    continue  # blank line
                if header is None:
                    header = [f.strip() for f in rec]
                    header_line = reader.line_num
                    continue
                records.append(rec)
                lines.append(reader.line_num)
    except UnicodeDecodeError:
        raise DataError(f"{path}: not a UTF-8 text file; expected a CSV file with a header line") from None
    except (OSError, csv.Error) as e:
        raise DataError(f"{path}: cannot read the file ({e.__class__.__name__}: {e})") from None
    if header is None:
        raise DataError(f"{path}: the file is empty; expected a header line (e.g. 't,x') and data rows")
    if all(_is_number(f) for f in header):
        raise DataError(f"{path}: line {header_line} holds numbers, not a header; the first line must name the "
                        "columns (e.g. 't,x')")
    for j, name in enumerate(header):
        if not name:
            raise DataError(f"{path}: column {j + 1} of the header has no name")
    dup = sorted({h for h in header if header.count(h) > 1})
    if dup:
        raise DataError(f"{path}: duplicate column name {dup[0]!r} in the header")
    if not records:
        raise DataError(f"{path}: no data rows after the header; expected at least one row of numbers")
    rows = _Rows(lines)
    for i, rec in enumerate(records):
        if len(rec) != len(header):
            raise DataError(f"{path}: {rows(i)} has {len(rec)} fields; the header has {len(header)} "
                            f"({','.join(header)})")
    columns = {}
    for j, name in enumerate(header):
        cells = [rec[j] for rec in records]
        try:
            columns[name] = np.array(cells, dtype=np.float64)
        except ValueError:
            i = next(i for i, c in enumerate(cells) if not _is_number(c))
            what = "is empty" if not cells[i].strip() else f"{cells[i].strip()!r} is not a number"
            raise DataError(f"{path}: column {name!r} {rows(i)}: {what}; expected a number") from None
    return columns, rows


def _read_npz(path: str) -> tuple[dict[str, np.ndarray], _Rows]:
    try:
        with np.load(path, allow_pickle=False) as z:
            arrays = {name: z[name] for name in z.files}
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as e:
        raise DataError(f"{path}: cannot read as .npz ({e.__class__.__name__}: {e})") from None
    if not arrays:
        raise DataError(f"{path}: the file holds no arrays; expected arrays named like CSV columns ('t', ...)")
    columns, n_rows = {}, None
    for name, a in arrays.items():
        if a.ndim != 1:
            raise DataError(f"{path}: array {name!r} has shape {a.shape}; expected a 1-D array (one value per row)")
        if a.dtype.kind not in "iuf":
            raise DataError(f"{path}: array {name!r} has dtype {a.dtype}; expected numbers (int or float)")
        if n_rows is None:
            n_rows = a.shape[0]
        elif a.shape[0] != n_rows:
            first = next(iter(arrays))
            raise DataError(f"{path}: array {name!r} has {a.shape[0]} values but {first!r} has {n_rows}; "
                            "expected equal lengths")
        columns[name] = a.astype(np.float64)
    if n_rows == 0:
        raise DataError(f"{path}: the arrays are empty; expected at least one row")
    return columns, _Rows(None)


def _is_number(s: str) -> bool:
    try:
        float(s)
    except ValueError:
        return False
    return True


def _validate(path: str, columns: dict[str, np.ndarray], rows: _Rows, angles: tuple[str, ...]) -> UserData:
    names = list(columns)
    if "t" not in columns:
        raise DataError(f"{path}: no 't' column; expected a time column named 't' (columns: {', '.join(names)})")
    derived = [c for c in names if c.endswith("_dot") or c.endswith("_ddot")]
    coords = tuple(c for c in names if c not in ("t", "traj") and c not in derived)
    for c in derived:
        base = c[: -len("_ddot")] if c.endswith("_ddot") else c[: -len("_dot")]
        if base not in coords:
            raise DataError(f"{path}: column {c!r} has no coordinate column {base!r}; expected '{base}' beside it")
    if not coords:
        raise DataError(f"{path}: no coordinate column; expected at least one column besides 't', 'traj' and "
                        "'*_dot'/'*_ddot'")
    for a in angles:
        if a not in coords:
            raise DataError(f"{path}: angle {a!r} is not a coordinate column (coordinates: {', '.join(coords)})")
    for name in names:
        bad = ~np.isfinite(columns[name])
        if bad.any():
            i = int(np.argmax(bad))
            raise DataError(f"{path}: column {name!r} {rows(i)}: {float(columns[name][i])!r} is not finite; "
                            "expected a finite number (no NaN or inf)")
    n_rows = columns["t"].shape[0]
    if "traj" in columns:
        ids = columns["traj"]
        bad = ids != np.round(ids)
        if bad.any():
            i = int(np.argmax(bad))
            raise DataError(f"{path}: column 'traj' {rows(i)}: {float(ids[i])!r} is not an integer; expected integer "
                            "trajectory ids")
        ids = ids.astype(np.int64)
    else:
        ids = np.zeros(n_rows, dtype=np.int64)
    _, first = np.unique(ids, return_index=True)
    order = ids[np.sort(first)]  # trajectory ids in order of first appearance

    given_qd = tuple(f"{c}_dot" in columns for c in coords)
    given_qdd = tuple(f"{c}_ddot" in columns for c in coords)
    need_estimates = not (all(given_qd) and all(given_qdd))
    q_all = np.stack([columns[c] for c in coords], axis=1)
    nan = np.full(n_rows, np.nan)
    qd_all = np.stack([columns.get(f"{c}_dot", nan) for c in coords], axis=1)
    qdd_all = np.stack([columns.get(f"{c}_ddot", nan) for c in coords], axis=1)

    trajectories = []
    for tid in order:
        idx = np.flatnonzero(ids == tid)
        label = f"trajectory {tid}" if "traj" in columns else "the trajectory"
        t = columns["t"][idx]
        step = np.diff(t)
        if (step <= 0).any():
            k = int(np.argmax(step <= 0)) + 1
            kind = "duplicate" if step[k - 1] == 0 else "decreasing"
            raise DataError(f"{path}: {label}: t is not strictly increasing at {rows(idx[k])} ({kind} time "
                            f"{float(t[k])!r} after {float(t[k - 1])!r}); expected strictly increasing t within a "
                            "trajectory")
        if len(idx) == 1 and need_estimates:
            raise DataError(f"{path}: {label} has a single sample ({rows(idx[0])}); at least {MIN_SAMPLES} samples "
                            "per trajectory are needed to estimate derivatives")
        if len(idx) < MIN_SAMPLES and need_estimates:
            raise DataError(f"{path}: {label} has {len(idx)} samples; at least {MIN_SAMPLES} per trajectory are "
                            "needed to estimate derivatives (or give every '<coord>_dot' and '<coord>_ddot' column)")
        trajectories.append(Trajectory(id=int(tid), t=t, q=q_all[idx], qd=qd_all[idx], qdd=qdd_all[idx], rows=idx))

    if all(np.ptp(q_all[:, j]) == 0 for j in range(len(coords))):
        raise DataError(f"{path}: all coordinates are constant ({', '.join(coords)}); expected motion in at least "
                        "one coordinate")
    return UserData(path=path, coords=coords, angles=tuple(a for a in coords if a in angles), given_qd=given_qd,
                    given_qdd=given_qdd, trajectories=tuple(trajectories))


# ---- noise level --------------------------------------------------------------------------------------------------
def _uniform_dt(t: np.ndarray) -> float | None:
    """The spacing if t lies within UNIFORM_RTOL·dt of a uniform grid, else None."""
    n = t.shape[0]
    dt = (t[-1] - t[0]) / (n - 1)
    grid = t[0] + dt * np.arange(n)
    return float(dt) if np.max(np.abs(t - grid)) <= UNIFORM_RTOL * dt else None


def noise_level(t, y) -> float:
    """Estimate of the white-noise standard deviation σ of samples y(t) (1-D), uniform or irregular t.

    σ_k = RMS of the k-th order differences normalised to unit weight norm (each has standard deviation σ on pure
    noise, while a smooth signal contributes ~(ω dt)ᵏ), k = 1…10; the result is σ_k at the first k where the next
    order no longer lowers it by 10 % (the plateau: signal gone, noise left), else the smallest σ_k.
    """
    t = np.asarray(t, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    n = y.shape[0]
    if n < 3:
        return 0.0
    uniform = _uniform_dt(t) is not None
    sig = []
    for k in range(1, min(_MAX_DIFF_ORDER, n - 2) + 1):
        d = np.diff(y, k) / math.sqrt(math.comb(2 * k, k)) if uniform else _irregular_differences(t, y, k)
        sig.append(float(np.sqrt(np.mean(d**2))))
        if k > 1 and sig[-1] >= 0.9 * sig[-2]:
            return sig[-2]
    return min(sig)


def _irregular_differences(t: np.ndarray, y: np.ndarray, k: int) -> np.ndarray:
    """Unit-norm combinations of k+1 consecutive samples that annihilate polynomials of degree < k."""
    idx = np.arange(y.shape[0] - k)[:, None] + np.arange(k + 1)
    tt = t[idx]
    u = (tt - tt[:, :1]) / (tt[:, -1:] - tt[:, :1]) * 2.0 - 1.0  # scaled to [-1, 1] for conditioning
    vt = u[:, None, :] ** np.arange(k)[None, :, None]  # (m, k, k+1): rows are monomials evaluated at the points
    null = np.linalg.svd(vt)[2][:, -1, :]  # (m, k+1), unit norm
    return np.einsum("ij,ij->i", null, y[idx])


# ---- Savitzky–Golay with window selection -------------------------------------------------------------------------
def _window_grid(n: int) -> list[int]:
    m_max = min(n if n % 2 else n - 1, MAX_WINDOW)
    grid, m = [], MIN_WINDOW
    while m <= m_max:
        grid.append(m)
        nxt = max(m + 2, int(round(m * 1.2)))
        m = nxt if nxt % 2 else nxt + 1
    return grid


def _sg_weights(m: int, d: int) -> tuple[np.ndarray, np.ndarray]:
    """SG weights (units of dt⁻ᵈ) of the d-th derivative with window m, as savgol_filter(mode='interp') applies them:
    the centred interior stencil (m,) and the left-edge stencils (half, m) of rows r = 0…half-1, which evaluate the
    polynomial fitted to the first m samples at row r (the right edge mirrors them: reversed, times (-1)ᵈ)."""
    half = m // 2
    u = (np.arange(m) - half) / half  # window scaled to [-1, 1] for conditioning
    fit = np.linalg.pinv(u[:, None] ** np.arange(POLYORDER + 1)[None, :])  # (p+1, m): samples -> coefficients
    ks = np.arange(d, POLYORDER + 1)
    falling = np.array([math.factorial(k) / math.factorial(k - d) for k in ks])
    rows = u[: half + 1, None] ** (ks - d)[None, :] * falling  # d-th derivative of the monomials at rows 0…half
    w = rows @ fit[ks] / half**d
    return w[half], w[:half]


@lru_cache(maxsize=256)
def _sg_stats(m: int, d: int):
    """What the error model needs of window m: the interior stencil w_c, Σ‖w_r‖² over the left-edge rows, and the
    Taylor bias moments Mₖ = Σ_j w_j o_jᵏ/k! (k = 5, 6; offsets o_j from the row) of the interior (2,) and of each
    left-edge row (half, 2); the right edge has the same norms and moments up to sign."""
    w_c, w_e = _sg_weights(m, d)
    half = m // 2
    ks = (POLYORDER + 1, POLYORDER + 2)
    o = (np.arange(m)[None, :] - np.arange(half + 1)[:, None]).astype(np.float64)  # rows 0…half (half: interior)
    wo5 = np.vstack([w_e, w_c]) * (o * o) ** 2 * o
    mom = np.stack([wo5.sum(axis=1), (wo5 * o).sum(axis=1)], axis=1) / [math.factorial(k) for k in ks]
    return w_c, float(np.sum(w_e**2)), mom[half], mom[:half]


def _sg_mse(m: int, d: int, n: int, h: float, sigma: float, r56: np.ndarray, interior_only: bool) -> float:
    """Estimated mean squared error of the d-th derivative with window m over the rows used (noise + Taylor bias),
    r56 being the RMS sizes of q⁽⁵⁾ and q⁽⁶⁾.  interior_only: the half-window rows at each end are trimmed."""
    w_c, edge_sq, m_c, m_e = _sg_stats(m, d)
    half = m // 2
    hpow = np.array([h ** (k - d) for k in (POLYORDER + 1, POLYORDER + 2)])
    noise_c = sigma**2 * np.sum(w_c**2) / h ** (2 * d)
    bias_c = np.sum((r56 * hpow * m_c) ** 2)
    if interior_only:
        return float(noise_c + bias_c)
    noise_e = sigma**2 * edge_sq / h ** (2 * d)
    bias_e = np.sum((r56 * hpow * m_e) ** 2)
    return float(((n - 2 * half) * (noise_c + bias_c) + 2.0 * (noise_e + bias_e)) / n)


def _taylor_pair(est_a: np.ndarray, est_b: np.ndarray, a: int, b: int, d: int, h: float, sigma: float):
    """RMS size R of q⁽ᵏ⁾ (k = 5 for d=1, 6 for d=2) from the SG estimates with windows a < b, or None.

    Over the rows interior to both windows, E[Δ²] = (R hᵏ⁻ᵈ ΔMₖ)² + σ²‖Δw‖²/h²ᵈ.  R is returned only when the excess
    over the noise term is significant: above 3 standard deviations (counting the correlation of filtered noise) and
    above the noise term itself, which absorbs an underestimate of σ by up to 30 %.  Also returns whether the bias
    dominates clearly (excess > 10 × noise term), i.e. longer windows can only be worse.
    """
    n = est_a.shape[0]
    hb = b // 2
    n_int = n - 2 * hb
    if n_int < 5:
        return None, False
    k_index = _LEAD_ORDER[d] - (POLYORDER + 1)
    wa, _, ma, _ = _sg_stats(a, d)
    wb, _, mb, _ = _sg_stats(b, d)
    pad = (b - a) // 2
    dw = wb - np.pad(wa, (pad, pad))
    var = sigma**2 * np.sum(dw**2) / h ** (2 * d)
    delta = est_b[hb:n - hb] - est_a[hb:n - hb]
    excess = float(np.mean(delta**2)) - var
    acf = np.correlate(dw, dw, mode="full") / np.sum(dw**2)
    sd = var * math.sqrt(2.0 * np.sum(acf**2) / n_int)
    dm = abs(mb[k_index] - ma[k_index]) * h ** (_LEAD_ORDER[d] - d)
    if excess > max(3.0 * sd, var) and dm > 0:
        return math.sqrt(excess) / dm, excess > 10.0 * var
    return None, False


def _savgol_coordinate(y: np.ndarray, h: float, sigma: float, trim: bool):
    """SG q̇, q̈ of one coordinate on a uniform grid; returns (qd, qdd, (m1, m2), (err1, err2)): the windows chosen
    by the estimated RMS error over the rows used, and those errors.

    Windows grow along the grid until the bias clearly dominates both derivatives; R₅, R₆ are the largest
    significant values over the neighbouring pairs (windows much longer than the signal's time scale saturate and
    would understate them), 0 where no pair is significant.
    """
    n = y.shape[0]
    est: dict[int, dict[int, np.ndarray]] = {1: {}, 2: {}}
    r56 = np.zeros(2)
    strong = [False, False]
    used: list[int] = []
    for m in _window_grid(n):
        for d in (1, 2):
            est[d][m] = savgol_filter(y, m, POLYORDER, deriv=d, delta=h, mode="interp")
            if used:
                r, s = _taylor_pair(est[d][used[-1]], est[d][m], used[-1], m, d, h, sigma)
                if r is not None:
                    r56[d - 1] = max(r56[d - 1], r)
                strong[d - 1] |= s
        used.append(m)
        if all(strong):
            break
    out, windows, errors = [], [], []
    for d in (1, 2):
        mse = [_sg_mse(m, d, n, h, sigma, r56, trim) for m in used]
        i = int(np.argmin(mse))
        out.append(est[d][used[i]])
        windows.append(used[i])
        errors.append(math.sqrt(mse[i]))
    return out[0], out[1], tuple(windows), tuple(errors)


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
    """Quintic smoothing spline q̇, q̈ (s = Nσ²) with bootstrap error estimates; returns (qd, qdd, (err1, err2))."""
    spl = _spline_fit(t, y, sigma)
    d1, d2 = spl.derivative(1), spl.derivative(2)
    qd, qdd = d1(t), d2(t)
    if sigma == 0.0:
        return qd, qdd, (0.0, 0.0)
    rng = np.random.default_rng(0)
    base = spl(t)
    sq1 = sq2 = 0.0
    for _ in range(_N_BOOTSTRAP):
        b = _spline_fit(t, base + sigma * rng.standard_normal(y.shape[0]), sigma)
        sq1 += np.mean((b.derivative(1)(t) - qd) ** 2)
        sq2 += np.mean((b.derivative(2)(t) - qdd) ** 2)
    return qd, qdd, (math.sqrt(sq1 / _N_BOOTSTRAP), math.sqrt(sq2 / _N_BOOTSTRAP))


# ---- estimate -----------------------------------------------------------------------------------------------------
def estimate_derivatives(t, q, method: str = "auto", *, trim: bool = False) -> DerivativeEstimate:
    """q̇ and q̈ of ONE trajectory sampled at t (N,), q (N,) or (N, n), each coordinate separately.

    method: ``"auto"`` (Savitzky–Golay on uniform grids, spline otherwise), ``"savgol"`` (uniform grids only) or
    ``"spline"``.  ``trim=True`` (Savitzky–Golay only) drops the first and last half-window rows (largest window over
    coordinates and derivatives) via ``keep`` and chooses windows for the interior rows.  See the module docstring.
    """
    t = np.asarray(t, dtype=np.float64).reshape(-1)
    q = np.asarray(q, dtype=np.float64)
    q2 = q.reshape(q.shape[0], -1)
    n_rows, n = q2.shape
    if t.shape[0] != n_rows:
        raise DataError(f"t has {t.shape[0]} samples but q has {n_rows}; expected equal lengths")
    if n_rows < MIN_SAMPLES:
        raise DataError(f"{n_rows} samples; at least {MIN_SAMPLES} are needed to estimate derivatives")
    if not np.all(np.diff(t) > 0):
        raise DataError("t must be strictly increasing")
    if method not in ("auto", "savgol", "spline"):
        raise ValueError(f"method must be 'auto', 'savgol' or 'spline', got {method!r}")
    dt = _uniform_dt(t)
    if method == "savgol" and dt is None:
        raise DataError("Savitzky–Golay needs uniform sampling: t deviates from a uniform grid by more than "
                        f"{UNIFORM_RTOL:g}·dt; use method='spline' or 'auto'")
    use_sg = method == "savgol" or (method == "auto" and dt is not None)

    qd = np.empty((n_rows, n))
    qdd = np.empty((n_rows, n))
    noise = np.array([noise_level(t, q2[:, j]) for j in range(n)])
    errs = np.zeros((2, n))
    windows: list[tuple] = []
    for j in range(n):
        if np.ptp(q2[:, j]) == 0:  # a constant coordinate: exact zeros
            qd[:, j] = qdd[:, j] = 0.0
            windows.append((MIN_WINDOW, MIN_WINDOW) if use_sg else (None, None))
            continue
        if use_sg:
            qd[:, j], qdd[:, j], win, err = _savgol_coordinate(q2[:, j], dt, noise[j], trim)
        else:
            qd[:, j], qdd[:, j], err = _spline_coordinate(t, q2[:, j], noise[j])
            win = (None, None)
        windows.append(win)
        errs[:, j] = err
    keep = np.ones(n_rows, dtype=bool)
    if trim and use_sg:
        half = max(max(w) for w in windows) // 2
        if n_rows - 2 * half < 1:
            raise DataError(f"trimming half-windows of {half} samples leaves none of {n_rows}; use trim=False")
        keep[:half] = False
        keep[n_rows - half:] = False
    std = q2.std(axis=0)
    return DerivativeEstimate(
        qd=qd, qdd=qdd, keep=keep, method="savgol" if use_sg else "spline", dt=dt, noise=noise,
        noise_rel=np.divide(noise, std, out=np.zeros(n), where=std > 0),
        qd_err=errs[0], qdd_err=errs[1],
        qd_rms=np.sqrt(np.mean(qd[keep] ** 2, axis=0)), qdd_rms=np.sqrt(np.mean(qdd[keep] ** 2, axis=0)),
        window_qd=tuple(w[0] for w in windows), window_qdd=tuple(w[1] for w in windows))


# ---- data set -----------------------------------------------------------------------------------------------------
def _trajectory_derivatives(ud: UserData, tr: Trajectory, method: str, trim: bool) -> dict:
    """q̇, q̈ (N, n) of one trajectory (given columns verbatim, the rest estimated), the kept rows and per-coordinate
    statistics (arrays (n,); errors/windows of given derivatives are NaN/None)."""
    n = ud.n
    given_qd, given_qdd = np.array(ud.given_qd), np.array(ud.given_qdd)
    qd, qdd = tr.qd.copy(), tr.qdd.copy()
    keep = np.ones(len(tr), dtype=bool)
    stats = {"noise": np.zeros(n), "noise_rel": np.zeros(n), "qd_err": np.full(n, np.nan),
             "qdd_err": np.full(n, np.nan), "qd_rms": np.full(n, np.nan), "qdd_rms": np.full(n, np.nan),
             "window_qd": [None] * n, "window_qdd": [None] * n, "method": "given", "dt": None}
    q = tr.q.copy()
    q[:, ud.is_angle] = np.unwrap(q[:, ud.is_angle], axis=0)
    if given_qd.all():  # positions are not differentiated: noise level only
        std = q.std(axis=0)
        stats["noise"] = np.array([noise_level(tr.t, q[:, j]) for j in range(n)])
        stats["noise_rel"] = np.divide(stats["noise"], std, out=np.zeros(n), where=std > 0)
    else:
        est = estimate_derivatives(tr.t, q, method, trim=trim)
        stats.update(noise=est.noise, noise_rel=est.noise_rel, method=est.method, dt=est.dt)
        keep &= est.keep
        for j in np.flatnonzero(~given_qd):
            qd[:, j] = est.qd[:, j]
            stats["qd_err"][j], stats["qd_rms"][j] = est.qd_err[j], est.qd_rms[j]
            stats["window_qd"][j] = est.window_qd[j]
            if not given_qdd[j]:
                qdd[:, j] = est.qdd[:, j]
                stats["qdd_err"][j], stats["qdd_rms"][j] = est.qdd_err[j], est.qdd_rms[j]
                stats["window_qdd"][j] = est.window_qdd[j]
    cols = np.flatnonzero(given_qd & ~given_qdd)
    if cols.size:  # q̈ by differentiating the given q̇ once
        est_v = estimate_derivatives(tr.t, tr.qd[:, cols], method, trim=trim)
        stats.update(method=est_v.method, dt=est_v.dt)
        keep &= est_v.keep
        for i, j in enumerate(cols):
            qdd[:, j] = est_v.qd[:, i]
            stats["qdd_err"][j], stats["qdd_rms"][j] = est_v.qd_err[i], est_v.qd_rms[i]
            stats["window_qdd"][j] = est_v.window_qd[i]
    return {"qd": qd, "qdd": qdd, "keep": keep, **stats}


def to_dataset(userdata: UserData, *, method: str = "auto", trim: bool = False):
    """Stack all trajectories into a :class:`nnphd.data.Dataset` (q as given, q̇/q̈ given or estimated per trajectory).

    Returns ``(dataset, info)`` with ``info`` JSON-ready:

    * ``coordinates``, ``angles``, ``n_traj``, ``n_rows`` (file rows), ``n_samples`` (data set rows), ``trimmed``
      (rows dropped), ``trim``, ``method`` ("savgol", "spline", "given" or "mixed");
    * ``per_coordinate[name]``: ``noise`` (σ) and ``noise_relative`` (σ/std q), and for ``qd`` and ``qdd`` the
      ``source`` ("given", "estimated from q", "estimated from q_dot"), the estimated RMS ``error`` and
      ``relative_error`` (over the RMS of the derivative) and the SG ``windows`` used (samples) — pooled over
      trajectories as RMS weighted by their rows;
    * ``trajectories``: per trajectory ``id``, ``n_samples``, ``method``, ``dt`` (None if irregular) and ``kept``
      = [start, stop): the data set holds rows start…stop-1 of each trajectory, in trajectory order, so its file rows
      are ``np.concatenate([tr.rows[a:b] for tr, (a, b) in ...])``.
    """
    from .data import Dataset

    parts = {"q": [], "qd": [], "qdd": [], "t": []}
    results, per_traj, weights = [], [], []
    for tr in userdata.trajectories:
        try:
            r = _trajectory_derivatives(userdata, tr, method, trim)
        except DataError as e:
            raise DataError(f"{userdata.path}: trajectory {tr.id}: {e}") from None
        start = int(np.argmax(r["keep"]))
        stop = len(tr) - int(np.argmax(r["keep"][::-1]))
        for name, arr in (("q", tr.q), ("qd", r["qd"]), ("qdd", r["qdd"]), ("t", tr.t)):
            parts[name].append(arr[start:stop])
        results.append(r)
        weights.append(stop - start)
        per_traj.append({"id": tr.id, "n_samples": len(tr), "kept": [start, stop], "method": r["method"],
                         "dt": r["dt"]})
    ds = Dataset(**{k: np.concatenate(v) for k, v in parts.items()})

    w = np.asarray(weights, dtype=np.float64) / sum(weights)

    def pooled(key, j):  # RMS over trajectories weighted by their kept rows
        return float(np.sqrt(np.sum(w * np.array([r[key][j] for r in results]) ** 2)))

    per_coord = {}
    for j, name in enumerate(userdata.coords):
        entry = {"noise": pooled("noise", j), "noise_relative": pooled("noise_rel", j)}
        for key, given in (("qd", userdata.given_qd[j]), ("qdd", userdata.given_qdd[j])):
            if given:
                entry[key] = {"source": "given", "error": None, "relative_error": None, "windows": []}
                continue
            err, size = pooled(f"{key}_err", j), pooled(f"{key}_rms", j)
            from_qd = key == "qdd" and userdata.given_qd[j]
            entry[key] = {"source": "estimated from q_dot" if from_qd else "estimated from q", "error": err,
                          "relative_error": err / size if size > 0 else None,
                          "windows": sorted({int(r[f"window_{key}"][j]) for r in results
                                             if r[f"window_{key}"][j] is not None})}
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
    return ds, info
