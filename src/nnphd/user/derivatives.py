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
fewer than ``MIN_SAMPLES`` = 7 samples in a trajectory (two windows, 5 and 7, are needed to measure the bias; not
required when every ``_dot`` and ``_ddot`` is given), and all coordinates constant.  Any strictly increasing sampling
is accepted.  :func:`suggest_angles` lists coordinates not declared as angles that look like angles (name, wrapped
values, whole turns), for a report.

Derivative estimation (:func:`estimate_derivatives`, one trajectory and coordinate at a time)
--------------------------------------------------------------------------------------------
1. **Noise level σ** of the positions (:func:`noise_level`).  The k-th order difference of k+1 consecutive
   samples, normalised to unit weight norm (Δᵏy/√C(2k,k) on a uniform grid, the null vector of the local Vandermonde
   matrix on an irregular one), annihilates polynomials of degree < k and has standard deviation exactly σ on white
   noise, while a smooth signal contributes ~(ω dt)ᵏ.  σ is the RMS of these differences at the first k = 1…10 where
   going one order higher no longer lowers it by 10 % (signal gone, noise left).  **Quantized values** (all on a grid
   c + g·ℤ: integer pixels, a fixed number of decimals, encoder counts; g found Euclid-style by :func:`_grid_step`)
   have σ ≥ g/√12: a slow signal in whole pixels is a staircase whose differences hide the rounding (measured 0.11 px
   raw for a ±3 px sine at 30 fps, 0.29 px with the floor).  On noise-free float data σ comes out at the level of the
   data's own roughness.

2. **Sampling and time base** (:func:`_sampling`; with dt̃ the median spacing):

   * *uniform*: t within 1e-6·dt of a uniform grid, or within 0.55 of its own resolution (the common step of the
     recorded times, ≤ dt̃/10) of one — 30 fps with ms timestamps is uniform (before, it took the spline path and
     followed the rounding).  → Savitzky–Golay (:func:`scipy.signal.savgol_filter`, ``mode='interp'``) on that grid.
   * *irregular* (grossly): a spacing above GROSS_RATIO = 5 × dt̃ (more than 4 missing samples in a row) or below
     dt̃/5 (bursts, clustered samples) → quintic smoothing spline (item 6).
   * *near-uniform* (everything else: jitter, gaps of up to 4 missing samples) → local polynomial regression in the
     actual times (item 3).  When t lies within dt/4 of a lattice c + dt·n_k (integer frame numbers, gaps allowed),
     the positions are differentiated in the lattice ("nominal") times if t equals them up to its rounding, or if
     the positions are smoother on them (the product over coordinates of σ̂(nominal)/σ̂(recorded) < 1, σ̂ of item 1):
     a camera with an exact frame clock and jittery timestamps.  With true jitter the recorded times are kept.
     Measured on the pendulum below: 20 of 20 seeds choose right either way; with 10 ms of timestamp jitter q̈ is
     2.7 % in the nominal times vs 3.1 % in the recorded ones (median of 20; the spline 3.8 %).  ``time_base`` says
     which.

3. **Local polynomial regression** (:func:`_local_fit`; Savitzky–Golay generalised): at row i the least-squares
   polynomial of order p in the offsets t_j − t_i over the m samples nearest by index (one-sided at the ends, as
   ``mode='interp'``), differentiated at t_i.  Batched over rows through power sums (only S_k = Σ u_jᵏ and
   Σ u_jˡ(y_j − y_i) touch the samples; weights, ‖w‖² and moments follow from them); on a uniform grid it reproduces
   savgol_filter to ~1e-11.  Orders p = 4 and 6 (ORDERS) and odd windows 5 (7), 7 (9), … growing by ~20 % up to
   min(N, 2001) are tried.  Runtime: 10⁴ rows with windows up to ~300, 0.7–0.9 s (2 busy cores); the window search
   runs on at most 2048 rows and the chosen fits are then evaluated at every row.

4. **Error model and choice.**  Row i's squared error is estimated as σ²‖w_i‖² (noise, from its actual weights)
   plus Σₖ (R_k M_k(w_i))² (Taylor bias, M_k(w) = Σ_j w_j (t_j − t_i)ᵏ/k!, k = p+1, p+2).  The RMS sizes R_k of
   q⁽ᵏ⁾ are measured Richardson-style from the estimates of neighbouring windows a < b over the rows interior to
   both: E[Δ²] = R²⟨ΔM²⟩ + σ²⟨‖w_a‖² − ‖w_b‖²⟩ (‖w_b − w_a‖² = ‖w_a‖² − ‖w_b‖² exactly on any grid, as the larger
   window's least-squares estimate is uncorrelated with its difference to any other unbiased estimate).  A pair
   counts when its excess over the noise term is significant (> 3 standard deviations and > the noise term); R is the
   largest over such pairs; the grid stops once the bias clearly dominates (excess > 10 × noise term) for both
   derivatives.  Per derivative, the (order, window) of least estimated mean squared error over the interior rows of
   the window is used.  Order 6 is dropped when its measured R falls steeply with the window (slope of log R against
   log window < −3 over the first pairs: the signal is not smooth at that scale; measured ≈ −0.8 on the pendulum and
   cart, −2.5…−5.4 on a chaotic double pendulum); when even order 4's R falls faster than −1.5, windows are scored
   over all rows (smaller windows: the bias of mid-sized windows is understated on such signals).

5. **End rows.**  A one-sided fit amplifies noise and bias strongly (q̈ of order 4 at the last row: ‖w‖ ≈ 5× the
   interior's).  The first and last half-window rows whose estimated error is over twice the median choose their own
   order (2, 3, 4, 6) and window (up to 3× the interior one) by σ²‖w_i‖² + 2·bias² (R₃, R₄ measured from order-4
   estimates of q⁽³⁾, q⁽⁴⁾).  The ends stay the least accurate rows (on the pendulum below q̈ at the first and last
   rows is ~0.09, 20× the interior error), and their estimated errors say so.

   **Per-row errors**: ``qd_err_rows``/``qdd_err_rows`` (N, n) are the estimated errors of every row; ``qd_err``/
   ``qdd_err`` their RMS over the kept rows.  ``to_dataset`` returns them in ``info["_rows"]``.  ``trim=True`` drops
   the first and last half-window rows (largest window over coordinates and derivatives) and then chooses windows for
   the interior rows (no end treatment); for the spline, the runs of end rows whose estimated error exceeds twice the
   median.

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

import csv
import math
import os
import re
import warnings
import zipfile
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache

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
    "suggest_angles",
]

POLYORDER = 4  # Savitzky–Golay polynomial order
MIN_WINDOW = POLYORDER + 1  # smallest SG window (exact interpolation of 5 points)
MAX_WINDOW = 2001
MIN_SAMPLES = MIN_WINDOW + 2  # two windows (5, 7) are needed to measure the bias
UNIFORM_RTOL = 1e-6  # t within this fraction of dt of a uniform grid counts as uniform
ROUNDING_TOL = 0.55  # ... or within this many steps of the recorded times' resolution (rounding: up to 0.5)
GROSS_RATIO = 5.0  # spacings beyond this many times the median (or below 1/GROSS_RATIO of it): grossly irregular
LATTICE_TOL = 0.25  # t within this fraction of dt of c + dt·n_k (integer n_k): near a lattice (nominal times exist)
_MAX_DIFF_ORDER = 10
_N_BOOTSTRAP = 8
ORDERS = (4, 6)  # polynomial orders tried for the whole trajectory (the end rows may also use 2 and 3)
MIN_DECLINE_HIGH = -3.0  # order 6 is used only where its bias scales nearly as Taylor's (_OrderFits.decline)
ROUGH_DECLINE = -1.5  # order 4 declining faster: a rough signal, windows scored over all rows (see _poly_coordinate)


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
    the kept rows and ``qd_rms``/``qdd_rms`` the RMS of the estimates there; ``window_qd``/``window_qdd`` and
    ``order_qd``/``order_qdd`` the local-polynomial windows (samples) and orders of the interior rows (None for the
    spline; the end rows may use others); ``q_step`` the common step of the values (0 if none).
    ``qd_err_rows``/``qdd_err_rows`` (N, n) are the estimated errors of every row (their RMS over the kept rows is
    ``qd_err``/``qdd_err``): larger at the ends and next to gaps.  ``method`` is "savgol", "local" or "spline";
    ``dt`` the grid spacing (None unless "savgol"), ``dt_median``/``dt_ratio`` the median spacing and the largest
    spacing over it; ``time_base`` "recorded" or "nominal" (the lattice times of the frames, see the module docstring).
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


# ---- sampling and value grids -------------------------------------------------------------------------------------
def _grid_step(v) -> float:
    """The common step g of the values v (all v lie on c + g·ℤ, g as large as possible), 0.0 if there is none.

    Found Euclid-style on the differences of the sorted distinct values: g starts at the smallest difference and is
    replaced by the smallest non-zero remainder until every difference is a whole multiple of g (within float
    rounding).  Continuous data have no such g: the remainders shrink until float rounding cannot resolve them any
    more (tolerance above 1e-3 of g) and 0.0 is returned.  Integer pixels give 1.0, ms-rounded times 0.001.
    """
    v = np.unique(np.asarray(v, dtype=np.float64))
    if v.size < 2:
        return 0.0
    d = np.diff(v)
    big = 8.0 * np.finfo(np.float64).eps * float(np.max(np.abs(v)))  # absolute float error of a difference
    g = float(d.min())
    for _ in range(64):
        r = d / g
        frac = np.abs(r - np.round(r))
        tol = 1e-9 + big * (1.0 + r) / g
        if tol.max() > 1e-3:
            return 0.0
        bad = frac > tol
        if not bad.any():
            return g
        g = float(np.min(frac[bad])) * g
    return 0.0


@dataclass(frozen=True)
class _Sampling:
    kind: str  # "uniform", "near-uniform" or "irregular"
    dt: float | None  # the grid spacing when uniform
    dt_median: float | None
    ratio: float | None  # max over median spacing
    ratio_min: float | None  # min over median spacing
    t_step: float  # resolution of the recorded times (common step, 0 if none)
    nominal: np.ndarray | None = None  # times c + dt·n_k (integer n_k, gaps allowed) if t is near such a lattice
    rounded: bool = False  # t equals the nominal times up to its own rounding (ROUNDING_TOL·t_step)


def _sampling(t: np.ndarray) -> _Sampling:
    """Classify the sampling times of one trajectory (see the module docstring for the rule)."""
    n = t.shape[0]
    if n < 2:  # a single sample (allowed when every derivative is given)
        return _Sampling("uniform", None, None, None, None, 0.0)
    steps = np.diff(t)
    med = float(np.median(steps))
    ratio, ratio_min = float(steps.max() / med), float(steps.min() / med)
    t_step = _grid_step(t)
    dt = float((t[-1] - t[0]) / (n - 1))
    if np.max(np.abs(t - (t[0] + dt * np.arange(n)))) <= UNIFORM_RTOL * dt:
        return _Sampling("uniform", dt, med, ratio, ratio_min, t_step, t, True)
    nominal, rounded = None, False
    k = np.r_[0, np.cumsum(np.round(steps / med))]  # frame numbers, gaps included
    if np.all(np.diff(k) >= 1):
        dt_ls, c = np.polyfit(k, t, 1)
        res = t - (c + dt_ls * k)
        if np.max(np.abs(res)) < LATTICE_TOL * dt_ls:
            nominal = c + dt_ls * k
            rounded = 0.0 < t_step <= 0.1 * med and \
                0.5 * (res.max() - res.min()) <= ROUNDING_TOL * t_step + UNIFORM_RTOL * dt_ls
            if rounded and k[-1] == n - 1:  # uniform up to the rounding of the recorded times
                return _Sampling("uniform", float(dt_ls), med, ratio, ratio_min, t_step, nominal, True)
    kind = "irregular" if ratio > GROSS_RATIO or ratio_min < 1.0 / GROSS_RATIO else "near-uniform"
    return _Sampling(kind, None, med, ratio, ratio_min, t_step, nominal, rounded)


def _uniform_dt(t: np.ndarray) -> float | None:
    """The spacing if t lies on a uniform grid (within UNIFORM_RTOL·dt, or within the rounding of t), else None."""
    return _sampling(t).dt


# ---- noise level --------------------------------------------------------------------------------------------------
def noise_level(t, y) -> float:
    """Estimate of the white-noise standard deviation σ of samples y(t) (1-D), uniform or irregular t.

    σ_k = RMS of the k-th order differences normalised to unit weight norm (each has standard deviation σ on pure
    noise, while a smooth signal contributes ~(ω dt)ᵏ), k = 1…10; the estimate is σ_k at the first k where the next
    order no longer lowers it by 10 % (the plateau: signal gone, noise left), else the smallest σ_k.  When the values
    lie on a grid of step g (integer pixels, a fixed number of decimals, encoder counts) the result is at least the
    quantization noise g/√12.
    """
    t = np.asarray(t, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    n = y.shape[0]
    if n < 3:
        return 0.0
    uniform = _uniform_dt(t) is not None
    sig = []
    est = None
    for k in range(1, min(_MAX_DIFF_ORDER, n - 2) + 1):
        d = np.diff(y, k) / math.sqrt(math.comb(2 * k, k)) if uniform else _irregular_differences(t, y, k)
        sig.append(float(np.sqrt(np.mean(d**2))))
        if k > 1 and sig[-1] >= 0.9 * sig[-2]:
            est = sig[-2]
            break
    if est is None:
        est = min(sig)
    return max(est, _grid_step(y) / math.sqrt(12.0))


def _irregular_differences(t: np.ndarray, y: np.ndarray, k: int) -> np.ndarray:
    """Unit-norm combinations of k+1 consecutive samples that annihilate polynomials of degree < k."""
    idx = np.arange(y.shape[0] - k)[:, None] + np.arange(k + 1)
    tt = t[idx]
    u = (tt - tt[:, :1]) / (tt[:, -1:] - tt[:, :1]) * 2.0 - 1.0  # scaled to [-1, 1] for conditioning
    vt = u[:, None, :] ** np.arange(k)[None, :, None]  # (m, k, k+1): rows are monomials evaluated at the points
    null = np.linalg.svd(vt)[2][:, -1, :]  # (m, k+1), unit norm
    return np.einsum("ij,ij->i", null, y[idx])


# ---- local polynomial estimates: Savitzky–Golay (uniform) and its generalisation to the actual times ----------------
def _window_grid(n: int, p: int = POLYORDER) -> list[int]:
    """Odd windows p+1 (or p+2), …, growing by ~20 %, up to min(N, MAX_WINDOW)."""
    m_max = min(n if n % 2 else n - 1, MAX_WINDOW)
    grid, m = [], p + 1 if p % 2 == 0 else p + 2
    while m <= m_max:
        grid.append(m)
        nxt = max(m + 2, int(round(m * 1.2)))
        m = nxt if nxt % 2 else nxt + 1
    return grid


def _sg_weights(m: int, d: int, p: int = POLYORDER, edges: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
    """SG weights (units of dt⁻ᵈ) of the d-th derivative with window m and order p, as savgol_filter(mode='interp')
    applies them: the centred interior stencil (m,) and the left-edge stencils (half, m) of rows r = 0…half-1, which
    evaluate the polynomial fitted to the first m samples at row r (the right edge mirrors them: reversed, times
    (-1)ᵈ).  edges=False: the interior stencil only (None for the edges)."""
    half = m // 2
    u = (np.arange(m) - half) / half  # window scaled to [-1, 1] for conditioning
    fit = np.linalg.pinv(u[:, None] ** np.arange(p + 1)[None, :])  # (p+1, m): samples -> coefficients
    ks = np.arange(d, p + 1)
    falling = np.array([math.factorial(k) / math.factorial(k - d) for k in ks])
    at = u[: half + 1] if edges else u[half:half + 1]
    rows = at[:, None] ** (ks - d)[None, :] * falling  # d-th derivative of the monomials at rows 0…half
    w = rows @ fit[ks] / half**d
    return (w[half], w[:half]) if edges else (w[0], None)


@lru_cache(maxsize=512)
def _sg_stats(m: int, d: int, p: int = POLYORDER):
    """What the error model needs of window m and order p on a unit grid: the interior stencil w_c, the squared norms
    of the left-edge stencils (half,), and the Taylor bias moments Mₖ = Σ_j w_j o_jᵏ/k! (k = p+1, p+2; offsets o_j
    from the row) of the interior (2,) and of each left-edge row (half, 2); the right edge has the same norms and
    moments up to the sign (-1)ᵈ⁺ᵏ."""
    w_c, w_e = _sg_weights(m, d, p)
    half = m // 2
    o = (np.arange(m)[None, :] - np.arange(half + 1)[:, None]).astype(np.float64)  # rows 0…half (half: interior)
    w = np.vstack([w_e, w_c])
    mom = np.stack([np.sum(w * o ** (p + 1), axis=1) / math.factorial(p + 1),
                    np.sum(w * o ** (p + 2), axis=1) / math.factorial(p + 2)], axis=1)
    return w_c, np.sum(w_e**2, axis=1), mom[half], mom[:half]


@lru_cache(maxsize=512)
def _pair_acf_sq(a: int, b: int, d: int, p: int) -> float:
    """Σ acf² of the difference of the uniform interior stencils of windows a < b: the correlation of the filtered
    noise, used for the standard deviation of the Richardson statistic (also on non-uniform grids, approximately)."""
    wa, wb = _sg_weights(a, d, p, edges=False)[0], _sg_weights(b, d, p, edges=False)[0]
    pad = (b - a) // 2
    dw = wb - np.pad(wa, (pad, pad))
    acf = np.correlate(dw, dw, mode="full") / np.sum(dw**2)
    return float(np.sum(acf**2))


@dataclass
class _Stencil:
    """Results of one window and order p at some rows (sorted indices) for d = 1, 2: the estimates (2, R), the
    squared weight norms ‖w_i‖² (2, R) in time units (noise variance / σ²) and the Taylor moments Mₖ(w_i) (2, R, 2)
    for k = p+1, p+2."""

    rows: np.ndarray
    est: np.ndarray
    ns: np.ndarray
    mom: np.ndarray


def _uniform_stencil(y: np.ndarray, m: int, h: float, p: int = POLYORDER) -> _Stencil:
    """Savitzky–Golay (scipy's savgol_filter, mode='interp') with window m, order p on a uniform grid of spacing h,
    at every row."""
    n = y.shape[0]
    half = m // 2
    est, ns, mom = np.empty((2, n)), np.empty((2, n)), np.empty((2, n, 2))
    for d in (1, 2):
        w_c, ns_e, mom_c, mom_e = _sg_stats(m, d, p)
        est[d - 1] = savgol_filter(y, m, p, deriv=d, delta=h, mode="interp")
        nsd = np.full(n, float(np.sum(w_c**2)))
        nsd[:half], nsd[n - half:] = ns_e, ns_e[::-1]
        md = np.tile(mom_c, (n, 1))
        md[:half] = mom_e
        md[n - half:] = mom_e[::-1] * [(-1.0) ** (d + p + 1), (-1.0) ** (d + p + 2)]
        ns[d - 1] = nsd / h ** (2 * d)
        mom[d - 1] = md * [h ** (p + 1 - d), h ** (p + 2 - d)]
    return _Stencil(np.arange(n), est, ns, mom)


_CHUNK = 1 << 17  # rows × window elements per batch of the local fits


def _local_fit(t: np.ndarray, y: np.ndarray, m: int, rows: np.ndarray | None = None, degree: int = POLYORDER,
               derivs: Sequence[int] = (1, 2), ks: Sequence[int] | None = None):
    """Local polynomial regression (Savitzky–Golay generalised to the actual sample times) at ``rows`` (all if None).

    Row i uses the m samples nearest by index (one-sided at the ends, as savgol_filter's mode='interp'): the
    least-squares polynomial of order p = ``degree`` in the offsets t_j − t_i, differentiated at t_i.  Returns, for
    each d in ``derivs``, the estimates (D, R), the squared weight norms ‖w_i‖² (D, R) and the Taylor moments
    Mₖ(w_i) = Σ_j w_ij (t_j − t_i)ᵏ/k! (D, R, K) for k in ``ks`` (default p+1, p+2), in time units.

    Batched over rows, in the window's own scaled time u = (t − centre)/half-span ∈ [−1, 1]: only the power sums
    S_k = Σ_j u_jᵏ (k ≤ 2p+2) and Y_l = Σ_j u_jˡ (y_j − y_i) (l ≤ p) touch the m samples.  The weights are
    w_j = Σ_l z_l u_jˡ with G z = (the d-th derivative of 1, u, …, uᵖ at u_i), G_kl = S_{k+l}; then Σ_j w_j y_j = z·Y,
    ‖w‖² = zᵀGz and Σ_j w_j u_jⁱ = Σ_l z_l S_{l+i}, from which the moments follow binomially.
    """
    n = t.shape[0]
    rows = np.arange(n) if rows is None else np.asarray(rows)
    ks = (degree + 1, degree + 2) if ks is None else tuple(ks)
    half = m // 2
    n_d, p1, top = len(derivs), degree + 1, max(ks)
    est, ns, mom = np.empty((n_d, rows.size)), np.empty((n_d, rows.size)), np.empty((n_d, rows.size, len(ks)))
    ar = np.arange(m)
    hank = np.add.outer(np.arange(p1), np.arange(p1))  # G_kl = S_{k+l}
    hank_m = np.add.outer(np.arange(p1), np.arange(top + 1))  # Σ_j w_j u_jⁱ = Σ_l z_l S_{l+i}
    n_s = max(2 * degree, degree + top) + 1
    chunk = max(1, _CHUNK // m)
    for c0 in range(0, rows.size, chunk):
        sel = slice(c0, min(rows.size, c0 + chunk))
        r = rows[sel]
        idx = np.clip(r - half, 0, n - m)[:, None] + ar
        tt = t[idx]
        centre = 0.5 * (tt[:, 0] + tt[:, -1])
        s = 0.5 * (tt[:, -1] - tt[:, 0])
        u = (tt - centre[:, None]) / s[:, None]
        u0 = (t[r] - centre) / s
        yy = y[idx] - y[r, None]
        sums = np.empty((r.size, n_s))
        ysum = np.empty((r.size, p1))
        sums[:, 0] = m
        ysum[:, 0] = yy.sum(axis=1)
        pw, py = u.copy(), yy * u
        sums[:, 1], ysum[:, 1] = pw.sum(axis=1), py.sum(axis=1)
        for k in range(2, n_s):
            pw *= u
            sums[:, k] = pw.sum(axis=1)
            if k < p1:
                py *= u
                ysum[:, k] = py.sum(axis=1)
        gram = sums[:, hank]
        rhs = np.zeros((r.size, p1, n_d))  # d-th derivative of the monomials uᵏ at u0
        for a, d in enumerate(derivs):
            for k in range(d, p1):
                rhs[:, k, a] = math.factorial(k) / math.factorial(k - d) * u0 ** (k - d)
        z = np.linalg.solve(gram, rhs)  # (rows, p+1, D)
        wu = np.einsum("rla,rli->rai", z, sums[:, hank_m])  # (rows, D, top+1): Σ_j w_j u_jⁱ
        for a, d in enumerate(derivs):
            za = z[:, :, a]
            est[a, sel] = np.einsum("rl,rl->r", za, ysum) / s**d
            ns[a, sel] = np.einsum("rl,rlk,rk->r", za, gram, za) / s ** (2 * d)
            for b, k in enumerate(ks):
                acc = np.zeros(r.size)
                for i in range(k + 1):
                    acc += math.comb(k, i) * (-u0) ** (k - i) * wu[:, a, i]
                mom[a, sel, b] = acc * s ** (k - d) / math.factorial(k)
    return est, ns, mom


def _local_stencil(t: np.ndarray, y: np.ndarray, m: int, p: int = POLYORDER) -> _Stencil:
    """Order-p local polynomial q̇, q̈ with window m at every row, with their weight norms and moments."""
    return _stencil(t, y, m, p, None)


def _stencil(tg: np.ndarray, y: np.ndarray, m: int, p: int, dt: float | None, rows=None) -> _Stencil:
    """Order-p q̇, q̈ with window m: Savitzky–Golay at every row on a uniform grid (dt given), else the local
    polynomial at ``rows`` (all if None)."""
    if dt is not None:
        return _uniform_stencil(y, m, dt, p)
    rows = np.arange(y.shape[0]) if rows is None else rows
    return _Stencil(rows, *_local_fit(tg, y, m, rows, p))


def _taylor_pair(sa: _Stencil, sb: _Stencil, a: int, b: int, d: int, sigma: float, r_lead: float, n: int,
                 p: int = POLYORDER):
    """Richardson measurement of the bias of the order-p estimates (leading order k = p+1 for d=1, p+2 for d=2) from
    windows a < b: (a, b, excess, ⟨M_a²⟩, ⟨M_b²⟩, ⟨M_a M_b⟩) of the leading moments when significant, else None.

    Over the rows interior to both windows, E[Δ²] = R² ⟨ΔMₖ²⟩ + σ² ⟨‖w_a‖² − ‖w_b‖²⟩ (the least-squares estimate of
    the larger window is uncorrelated with its difference to any other unbiased estimate, so ‖w_b − w_a‖² =
    ‖w_a‖² − ‖w_b‖² on any grid); for d = 2 the q⁽ᵖ⁺¹⁾ part r_lead² ⟨ΔM_{p+1}²⟩ (non-zero on non-uniform grids) is
    subtracted first, and R = √(excess/⟨ΔMₖ²⟩) (:func:`_pair_r`).  The pair
    counts only when the excess over the noise term is significant: above 3 standard
    deviations (counting the correlation of filtered noise) and above the noise term itself, which absorbs an
    underestimate of σ by up to 30 %.  Also returns whether the bias dominates clearly (excess > 10 × noise term), i.e.
    longer windows can only be worse.  sa and sb hold the same rows (of a trajectory of n samples).
    """
    hb = b // 2
    n_int = n - 2 * hb
    if n_int < 5:
        return None, False
    sl = (sa.rows >= hb) & (sa.rows < n - hb)
    var = sigma**2 * float(np.mean(np.maximum(sa.ns[d - 1, sl] - sb.ns[d - 1, sl], 0.0)))
    delta = sb.est[d - 1, sl] - sa.est[d - 1, sl]
    dmom = sb.mom[d - 1, sl] - sa.mom[d - 1, sl]
    excess = float(np.mean(delta**2)) - var
    if d == 2:
        excess -= r_lead**2 * float(np.mean(dmom[:, 0] ** 2))
    ma, mb = sa.mom[d - 1, sl, d - 1], sb.mom[d - 1, sl, d - 1]  # the leading order k
    dm2 = float(np.mean((mb - ma) ** 2))
    sd = var * math.sqrt(2.0 * _pair_acf_sq(a, b, d, p) / n_int)
    if excess > max(3.0 * sd, var) and dm2 > 0:
        rec = (a, b, excess, float(np.mean(ma * ma)), float(np.mean(mb * mb)), float(np.mean(ma * mb)))
        return rec, excess > 10.0 * var
    return None, False


def _mse_rows(st: _Stencil, d: int, sigma: float, r: np.ndarray) -> np.ndarray:
    """Estimated squared error of the d-th derivative in every row: σ²‖w_i‖² + Σₖ (Rₖ Mₖ(w_i))² (k = p+1, p+2)."""
    return sigma**2 * st.ns[d - 1] + np.sum((st.mom[d - 1] * r) ** 2, axis=1)


@dataclass
class _OrderFits:
    """The windows tried with one polynomial order, their results at the search rows and the significant Richardson
    pairs (see :func:`_taylor_pair`) for R_{p+1} (from q̇) and R_{p+2} (from q̈)."""

    p: int
    used: list
    stencils: dict
    pairs: tuple

    def __post_init__(self):
        # R per significant pair, by window; R_{p+1}, R_{p+2}: the largest (windows much longer than the signal's
        # time scale saturate and would understate them), 0 where no pair is significant
        self.rj = [[(rec[1], _pair_r(rec)) for rec in pr] for pr in self.pairs]
        self.r = np.array([max((r for _, r in rj), default=0.0) for rj in self.rj])

    def decline(self) -> float | None:
        """How fast the measured R falls with the window over the smallest significant pairs: the least-squares slope
        of log R_b against log b over up to _SCALE_PAIRS pairs, the steeper of q̇ and q̈ (None with fewer than 2).

        Near 0 while the signal is smooth at the window scale (the Taylor bias ∝ m^(k−d) holds); −0.8 on the
        pendulum and the cart below at the windows that matter, −2.5 to −5.4 on broadband motion (a chaotic double
        pendulum), where a pair's excess no longer follows Taylor and the higher order loses to order 4."""
        slopes = []
        for rj in self.rj:
            use = rj[:_SCALE_PAIRS]
            if len(use) >= 2:
                slopes.append(float(np.polyfit(np.log([b for b, _ in use]), np.log([r for _, r in use]), 1)[0]))
        return min(slopes) if slopes else None


_SCALE_PAIRS = 3  # the smallest significant pairs used to judge how R depends on the window


def _pair_r(rec) -> float:
    """R = √(excess/⟨ΔMₖ²⟩) of a significant pair (a, b, excess, ⟨M_a²⟩, ⟨M_b²⟩, ⟨M_a M_b⟩)."""
    _, _, exc, maa, mbb, mab = rec
    return math.sqrt(exc / max(mbb - 2.0 * mab + maa, 1e-300))


_SEARCH_ROWS = 2048  # on non-uniform grids, the window search uses at most this many rows (evenly spread)


def _search_rows(n: int) -> np.ndarray | None:
    return None if n <= _SEARCH_ROWS else np.unique(np.linspace(0, n - 1, _SEARCH_ROWS).round().astype(int))


def _grow_windows(tg, y, sigma, dt, p, rows) -> _OrderFits:
    """Order-p fits along the window grid until the bias clearly dominates both derivatives; R_{p+1}, R_{p+2} are the
    largest significant values over the neighbouring pairs (windows much longer than the signal's time scale
    saturate and would understate them), 0 where no pair is significant."""
    n = y.shape[0]
    stencils: dict[int, _Stencil] = {}
    pairs: tuple[list, list] = ([], [])
    strong = [False, False]
    used: list[int] = []
    for m in _window_grid(n, p):
        stencils[m] = _stencil(tg, y, m, p, dt, rows)
        if used:
            a = used[-1]
            r_lead = max((_pair_r(rec) for rec in pairs[0]), default=0.0)
            for d in (1, 2):
                rec, s = _taylor_pair(stencils[a], stencils[m], a, m, d, sigma, r_lead, n, p)
                if rec is not None:
                    pairs[d - 1].append(rec)
                strong[d - 1] |= s
        used.append(m)
        if all(strong):
            break
    return _OrderFits(p, used, stencils, pairs)


def _poly_coordinate(tg: np.ndarray, y: np.ndarray, sigma: float, trim: bool, dt: float | None = None,
                     ends: bool = True):
    """q̇, q̈ of one coordinate by local polynomials: order (4 or 6) and window chosen per derivative by the estimated
    RMS error over the interior rows of each window.

    tg: the sample times; dt: the spacing when they are uniform (scipy's savgol_filter is then used).  On long
    non-uniform trajectories the search runs on _SEARCH_ROWS rows and the chosen fits are then evaluated at every row.
    Order 6 is dropped when its measured R falls steeply with the window (``decline`` < MIN_DECLINE_HIGH: the signal
    is not smooth at that scale and the order-6 Taylor bias model fails).  Unless ``trim`` (or not ``ends``), the end
    rows then choose their own order and window (:func:`_end_rows`).  Where even order 4's R declines fast
    (< ROUGH_DECLINE: broadband motion), the bias model understates the bias of mid-sized windows, and windows are
    scored over all rows as before the end treatment existed (the one-sided end rows then keep windows small); the same
    when ``ends`` is False.  Returns (qd, qdd, (m1, m2), (p1, p2), err_rows (2, N)).
    """
    n = y.shape[0]
    rows = _search_rows(n) if dt is None else None
    fits = [_grow_windows(tg, y, sigma, dt, p, rows) for p in ORDERS if len(_window_grid(n, p)) >= 2]
    fits = [f for f in fits if f.p == POLYORDER or (f.decline() or 0.0) >= MIN_DECLINE_HIGH]
    interior = trim or (ends and (fits[0].decline() or 0.0) >= ROUGH_DECLINE)
    out, windows, orders, err_rows = [], [], [], []
    for d in (1, 2):
        best = None
        for f in fits:
            for m in f.used:
                st = f.stencils[m]
                mse = _mse_rows(st, d, sigma, f.r)
                half = m // 2
                inner = (st.rows >= half) & (st.rows < n - half)
                score = float(np.mean(mse[inner] if interior else mse))
                if best is None or score < best[0]:
                    best = (score, f, m)
        _, f, m = best
        st = f.stencils[m]
        if st.rows.size < n:
            st = f.stencils[m] = _stencil(tg, y, m, f.p, dt)  # every row
        out.append(st.est[d - 1].copy())
        windows.append(m)
        orders.append(f.p)
        err_rows.append(_mse_rows(st, d, sigma, f.r))
    if ends and not trim:
        r34 = _low_order_sizes(tg, y, sigma, fits[0])
        for d in (1, 2):
            _end_rows(tg, y, sigma, d, windows[d - 1], fits, r34, out[d - 1], err_rows[d - 1])
    return out[0], out[1], tuple(windows), tuple(orders), np.sqrt(np.array(err_rows))


_R34_ROWS = 512  # interior rows sampled to measure R₃, R₄
_END_LOW_ORDERS = (2, 3)  # lower orders the end rows may also use
_END_MAX_FACTOR = 3.0  # end rows consider windows up to this many times the interior one
_END_BIAS_SAFETY = 2.0  # end rows choose by σ²‖w‖² + this × bias² (their one-sided bias model is the least reliable)


def _low_order_sizes(tg: np.ndarray, y: np.ndarray, sigma: float, fit: _OrderFits) -> np.ndarray:
    """RMS sizes R₃, R₄ of q⁽³⁾, q⁽⁴⁾ (needed for the bias of the order-2 and -3 end fits), inf where not measurable.

    q⁽ᵈ⁾ (d = 3, 4) is estimated by the order-4 local polynomial at up to _R34_ROWS interior rows for every window
    tried; at the window with the least estimated error e² = σ²⟨‖w‖²⟩ + R₅²⟨M₅²⟩ + R₆²⟨M₆²⟩, R_d² = ⟨est²⟩ − e².
    The estimate must stand clearly above its error (⟨est²⟩ > 4 e²), else R_d = inf and the lower orders are not used.
    """
    n = y.shape[0]
    out = np.full(2, np.inf)
    best = [None, None]
    for m in fit.used:
        half = m // 2
        if n - 2 * half < 5:
            continue
        rows = np.unique(np.linspace(half, n - half - 1, min(_R34_ROWS, n - 2 * half)).round().astype(int))
        est, ns, mom = _local_fit(tg, y, m, rows, fit.p, (3, 4))
        for a in range(2):
            e2 = sigma**2 * float(np.mean(ns[a])) + float(np.mean(np.sum((mom[a] * fit.r) ** 2, axis=1)))
            if best[a] is None or e2 < best[a][0]:
                best[a] = (e2, float(np.mean(est[a] ** 2)))
    for a in range(2):
        if best[a] is not None and best[a][1] > 4.0 * best[a][0]:
            out[a] = math.sqrt(best[a][1] - best[a][0])
    return out


def _end_rows(tg, y, sigma, d, m_star, fits, r34, est, mse):
    """Re-choose order and window in those of the first and last m_star//2 rows whose estimated squared error is
    more than twice the median (modified in place: est, mse).

    A one-sided fit amplifies noise strongly at the ends (order 4, q̈ at the last row: ‖w‖ ≈ 5× the interior's with
    the same window).  Each end row takes, among orders 2, 3 and those of ``fits`` and the windows tried (up to
    3·m_star), the candidate of least estimated squared error σ²‖w_i‖² + Σ (R_k M_k(w_i))² over its two leading
    Taylor orders k = p+1, p+2 (R₃, R₄: ``r34``; R₅…R₈ from the fits of orders 4 and 6 at that window).
    """
    n = y.shape[0]
    e = m_star // 2
    if e == 0:
        return
    rows = np.r_[0:e, n - e:n]
    rows = rows[mse[rows] > 2.0 * np.median(mse)]  # only where the one-sided fit is clearly worse than the interior
    if rows.size == 0:
        return
    best_mse, best_est = mse[rows].copy(), est[rows].copy()
    best_score = best_mse.copy()

    def take(ce, noise, bias2):
        cm = noise + bias2
        score = noise + _END_BIAS_SAFETY * bias2
        better = score < best_score
        best_score[better], best_mse[better], best_est[better] = score[better], cm[better], ce[better]

    for f in fits:
        for m in f.used:
            if m > _END_MAX_FACTOR * m_star:
                break
            st = f.stencils[m]
            r = f.r
            if st.rows.size == n:
                take(st.est[d - 1][rows], sigma**2 * st.ns[d - 1][rows], np.sum((st.mom[d - 1][rows] * r) ** 2, axis=1))
            else:
                ep, nsp, mp = _local_fit(tg, y, m, rows, f.p, (d,))
                take(ep[0], sigma**2 * nsp[0], np.sum((mp[0] * r) ** 2, axis=1))
    for p in _END_LOW_ORDERS:
        ks = (p + 1, p + 2)
        for m in fits[0].used:
            if m > _END_MAX_FACTOR * m_star:
                break
            r = np.array([r34[0], r34[1]]) if p == 2 else np.array([r34[1], fits[0].r[0]])
            if not np.all(np.isfinite(r)):
                break
            ep, nsp, mp = _local_fit(tg, y, m, rows, p, (d,), ks)
            take(ep[0], sigma**2 * nsp[0], np.sum((mp[0] * r) ** 2, axis=1))
    est[rows], mse[rows] = best_est, best_mse


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
    if method not in ("auto", "savgol", "local", "spline"):
        raise ValueError(f"method must be 'auto', 'savgol', 'local' or 'spline', got {method!r}")
    smp = _sampling(t)
    if method == "savgol" and smp.dt is None:
        raise DataError("Savitzky–Golay needs uniform sampling: t deviates from a uniform grid by more than "
                        f"{UNIFORM_RTOL:g}·dt (and more than the rounding of t); use method='local', 'spline' or "
                        "'auto'")
    time_base = "recorded"
    tg = t  # the times the derivatives are taken in
    noise = np.array([noise_level(t, q2[:, j]) for j in range(n)])
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

    qd = np.zeros((n_rows, n))
    qdd = np.zeros((n_rows, n))
    err_rows = np.zeros((2, n_rows, n))
    q_step = np.array([_grid_step(q2[:, j]) for j in range(n)])
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
            qd[:, j], qdd[:, j], win, order, e = _poly_coordinate(tg, y, noise[j], trim,
                                                                  smp.dt if method == "savgol" else None)
            orders[j] = order
        windows.append(win)
        err_rows[:, :, j] = e
    keep = np.ones(n_rows, dtype=bool)
    if trim:
        if method == "spline":
            lead, trail = _spline_trim(err_rows.transpose(0, 2, 1).reshape(2 * n, n_rows))
        else:
            lead = trail = max(max(w) for w in windows) // 2
        if n_rows - lead - trail < 1:
            raise DataError(f"trimming {lead} + {trail} edge samples leaves none of {n_rows}; use trim=False")
        keep[:lead] = False
        keep[n_rows - trail:] = False
    std = q2.std(axis=0)
    return DerivativeEstimate(
        qd=qd, qdd=qdd, keep=keep, method=method, dt=smp.dt if method == "savgol" else None, noise=noise,
        noise_rel=np.divide(noise, std, out=np.zeros(n), where=std > 0),
        qd_err=np.sqrt(np.mean(err_rows[0][keep] ** 2, axis=0)),
        qdd_err=np.sqrt(np.mean(err_rows[1][keep] ** 2, axis=0)),
        qd_rms=np.sqrt(np.mean(qd[keep] ** 2, axis=0)), qdd_rms=np.sqrt(np.mean(qdd[keep] ** 2, axis=0)),
        window_qd=tuple(w[0] for w in windows), window_qdd=tuple(w[1] for w in windows),
        order_qd=tuple(o[0] for o in orders), order_qdd=tuple(o[1] for o in orders),
        qd_err_rows=err_rows[0], qdd_err_rows=err_rows[1], q_step=q_step, dt_median=smp.dt_median,
        dt_ratio=smp.ratio, time_base=time_base)


# ---- data set -----------------------------------------------------------------------------------------------------
def _trajectory_derivatives(ud: UserData, tr: Trajectory, method: str, trim: bool) -> dict:
    """q̇, q̈ (N, n) of one trajectory (given columns verbatim, the rest estimated), the kept rows, per-row error
    estimates (N, n; NaN in given columns) and per-coordinate statistics (arrays (n,); errors/windows of given
    derivatives are NaN/None)."""
    n = ud.n
    given_qd, given_qdd = np.array(ud.given_qd), np.array(ud.given_qdd)
    qd, qdd = tr.qd.copy(), tr.qdd.copy()
    keep = np.ones(len(tr), dtype=bool)
    smp = _sampling(tr.t)
    stats = {"noise": np.zeros(n), "noise_rel": np.zeros(n), "q_step": np.zeros(n), "qd_err": np.full(n, np.nan),
             "qdd_err": np.full(n, np.nan), "qd_rms": np.full(n, np.nan), "qdd_rms": np.full(n, np.nan),
             "window_qd": [None] * n, "window_qdd": [None] * n, "order_qd": [None] * n, "order_qdd": [None] * n,
             "method": "given", "time_base": "recorded",
             "dt": smp.dt, "dt_median": smp.dt_median, "dt_ratio": smp.ratio, "sampling": smp.kind,
             "qd_err_rows": np.full((len(tr), n), np.nan), "qdd_err_rows": np.full((len(tr), n), np.nan)}
    q = tr.q.copy()
    q[:, ud.is_angle] = np.unwrap(q[:, ud.is_angle], axis=0)
    if given_qd.all():  # positions are not differentiated: noise level only
        std = q.std(axis=0)
        stats["noise"] = np.array([noise_level(tr.t, q[:, j]) for j in range(n)])
        stats["noise_rel"] = np.divide(stats["noise"], std, out=np.zeros(n), where=std > 0)
        stats["q_step"] = np.array([_grid_step(q[:, j]) for j in range(n)])
    else:
        est = estimate_derivatives(tr.t, q, method, trim=trim)
        stats.update(noise=est.noise, noise_rel=est.noise_rel, q_step=est.q_step, method=est.method, dt=est.dt,
                     time_base=est.time_base)
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


def to_dataset(userdata: UserData, *, method: str = "auto", trim: bool = False):
    """Stack all trajectories into a :class:`nnphd.engine.data.Dataset` (q as given, q̇/q̈ given or estimated per trajectory).

    Returns ``(dataset, info)``.  ``info`` is JSON-ready except for ``info["_rows"]``, which callers should pop before
    serialising:

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
      order, so its file rows are ``np.concatenate([tr.rows[a:b] for tr, (a, b) in ...])``;
    * ``_rows`` (not JSON): ``{"qd_err": ndarray, "qdd_err": ndarray}``, each (data set rows, n), the estimated error
      of every row's q̇ / q̈ (NaN in given columns) — larger at the trajectory ends and next to gaps, for weighting or
      trimming rows.
    """
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
        for name, arr in (("q", tr.q), ("qd", r["qd"]), ("qdd", r["qdd"]), ("t", tr.t),
                          ("qd_err_rows", r["qd_err_rows"]), ("qdd_err_rows", r["qdd_err_rows"])):
            parts[name].append(arr[start:stop])
        results.append(r)
        weights.append(stop - start)
        per_traj.append({"id": tr.id, "n_samples": len(tr), "kept": [start, stop], "method": r["method"],
                         "sampling": r["sampling"], "time_base": r["time_base"], "dt": r["dt"],
                         "dt_median": r["dt_median"], "dt_ratio": r["dt_ratio"]})
    rows = {"qd_err": np.concatenate(parts.pop("qd_err_rows")), "qdd_err": np.concatenate(parts.pop("qdd_err_rows"))}
    ds = Dataset(**{k: np.concatenate(v) for k, v in parts.items()})

    w = np.asarray(weights, dtype=np.float64) / sum(weights)

    def pooled(key, j):  # RMS over trajectories weighted by their kept rows
        return float(np.sqrt(np.sum(w * np.array([r[key][j] for r in results]) ** 2)))

    per_coord = {}
    for j, name in enumerate(userdata.coords):
        entry = {"noise": pooled("noise", j), "noise_relative": pooled("noise_rel", j),
                 "quantization_step": max(float(r["q_step"][j]) for r in results)}
        for key, given in (("qd", userdata.given_qd[j]), ("qdd", userdata.given_qdd[j])):
            if given:
                entry[key] = {"source": "given", "error": None, "relative_error": None, "error_max": None,
                              "windows": [], "orders": []}
                continue
            err, size = pooled(f"{key}_err", j), pooled(f"{key}_rms", j)
            from_qd = key == "qdd" and userdata.given_qd[j]
            entry[key] = {"source": "estimated from q_dot" if from_qd else "estimated from q", "error": err,
                          "relative_error": err / size if size > 0 else None,
                          "error_max": float(np.max(rows[f"{key}_err"][:, j])),
                          "windows": sorted({int(r[f"window_{key}"][j]) for r in results
                                             if r[f"window_{key}"][j] is not None}),
                          "orders": sorted({int(r[f"order_{key}"][j]) for r in results
                                            if r[f"order_{key}"][j] is not None})}
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
        "_rows": rows,
    }
    return ds, info


# ---- angle hints --------------------------------------------------------------------------------------------------
_ANGLE_WORDS = ("theta", "phi", "psi", "angle", "ang", "th", "yaw", "pitch", "roll", "θ", "φ", "ϕ", "ψ")
_ANGLE_PREFIXES = ("theta", "angle", "phi", "psi")  # also as a prefix of a longer word: thetas, angles, phi2a
_CARTESIAN = re.compile(r"^(x|y|z|px|py|pz|pos|position)(_?\d+)?$", re.IGNORECASE)


def _name_tokens(name: str) -> list[str]:
    """Words of a column name: split at non-alphanumerics, lower→upper case changes and letter↔digit changes."""
    parts = re.split(r"[^0-9A-Za-zα-ωΑ-Ωϕ]+", name)
    tokens = []
    for p in parts:
        tokens += re.findall(r"[A-Z]?[a-zα-ωϕ]+|[A-ZΑ-Ω]+(?![a-z])|\d+", p)
    return [tok.lower() for tok in tokens if tok]


def _angle_name(name: str) -> str | None:
    for tok in _name_tokens(name):
        if tok in _ANGLE_WORDS:
            return tok
        for p in _ANGLE_PREFIXES:
            if tok.startswith(p):
                return tok
    return None


def suggest_angles(userdata: UserData) -> list[tuple[str, str]]:
    """Coordinates not declared in ``angles`` that look like angles, as (coordinate, reason), in file order.

    * **name**: a word of the column name (split at ``_``, digits and case changes, case-insensitive) is theta, phi,
      psi, angle, ang, th, yaw, pitch, roll (or θ, φ, ψ), or starts with theta, angle, phi or psi: ``theta1``,
      ``th_2``, ``armAngle``, ``Phi``;
    * **wrapped values**: in some trajectory, consecutive samples jump by more than π (close to 2π: within π/2),
      the values stay within a range of 2π (plus 1 %), and unwrapping (:func:`numpy.unwrap`) leaves no step above
      π/2 — an angle wrapped to an interval such as [−π, π);
    * **whole turns**: the values of a trajectory span more than 4π — an unwrapped angle that turns over; not
      reported for conventional Cartesian names (x, y, z, x1, pos, …) nor for values on a grid of step ≥ 0.1
      (pixels, millimetres), where a large range is just a length.

    Declaring an angle only unwraps it before differentiation; the hints are for a report, never applied silently.
    """
    out = []
    two_pi = 2.0 * math.pi
    for j, name in enumerate(userdata.coords):
        if name in userdata.angles:
            continue
        reasons = []
        word = _angle_name(name)
        if word is not None:
            reasons.append(f"the name ({word!r}) suggests an angle")
        wrapped = turns = None
        for tr in userdata.trajectories:
            y = tr.q[:, j]
            if y.shape[0] < 3 or np.ptp(y) == 0:
                continue
            step = np.abs(np.diff(y))
            big = step > math.pi
            if (wrapped is None and big.any() and np.all(np.abs(step[big] - two_pi) < 0.5 * math.pi)
                    and np.ptp(y) <= 1.01 * two_pi and np.max(np.abs(np.diff(np.unwrap(y)))) < 0.5 * math.pi):
                wrapped = (tr.id, int(big.sum()))
            if turns is None and np.ptp(y) > 2.0 * two_pi and not _CARTESIAN.match(name) and _grid_step(y) < 0.1:
                turns = (tr.id, float(np.ptp(y)))
        if wrapped is not None:
            label = f" in trajectory {wrapped[0]}" if userdata.n_traj > 1 else ""
            reasons.append(f"values jump by about 2π ({wrapped[1]} time{'s' if wrapped[1] > 1 else ''}{label}) "
                           "within a 2π range: wrapped angle")
        if turns is not None:
            label = f" in trajectory {turns[0]}" if userdata.n_traj > 1 else ""
            reasons.append(f"values span {turns[1]:.3g} > 4π{label}: whole turns if this is an angle in radians")
        if reasons:
            out.append((name, "; ".join(reasons)))
    return out
