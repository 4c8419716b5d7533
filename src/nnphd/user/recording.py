r"""A user's recording for ``nnphd detect FILE``: read and validate a trajectory file into :class:`UserData`.

The derivatives are estimated from it by :mod:`nnphd.user.derivatives`.

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
fewer than ``MIN_ROWS`` = 8 samples in a trajectory (two windows, 5 and 7, are needed to measure the bias, and the
training holds rows out), and all coordinates constant.  Units: any, as long as the numbers stay in the ranges
checked by :func:`_check_scales` (values within ±1e30, a time span within 1e±15, every moving coordinate's spread
within 1e±30 and at least 1e-12 of its values); outside them the message says which column to rescale.  Trajectory
ids are parsed exactly and must lie within ±2⁵³.  A file with one field per line that holds ``;``, tabs or ``|`` is
reported as separated by that character (only commas are read).  CSV files are streamed into arrays
``CSV_CHUNK`` rows at a time.  Any strictly increasing sampling
is accepted.  :func:`suggest_angles` lists coordinates not declared as angles that look like angles (name, wrapped
values, whole turns), for a report.
"""

from __future__ import annotations

import csv
import math
import os
import re
import zipfile
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from nnphd.io.errors import DataError
from nnphd.user.limits import MAX_ABS, MAX_ID, MAX_ROWS, MIN_RESOLUTION, MIN_ROWS, Q_SPREAD, T_SPAN
from nnphd.user.localpoly import MIN_SAMPLES
from nnphd.user.sampling import _grid_step

__all__ = ["DataError", "Trajectory", "UserData", "MIN_SAMPLES", "MIN_ROWS", "load_trajectories", "suggest_angles"]


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


# ---- reading ------------------------------------------------------------------------------------------------------
class _Rows:
    """How to name data row i in messages: CSV rows are 1-based with their file line, NPZ rows 0-based indices."""

    def __init__(self, lines, offset: int = 0):
        self.lines = lines  # file line of each data row from ``offset`` on (None for NPZ)
        self.offset = offset

    def __call__(self, i: int) -> str:
        i = int(i)
        if self.lines is None:
            return f"index {i}"
        return f"row {i + 1} (line {int(self.lines[i - self.offset])})"


def load_trajectories(path, angles: Sequence[str] = (), max_rows: int | None = None) -> UserData:
    """Read and validate a CSV (header required) or NPZ trajectory file; see the module docstring for the format.

    ``angles`` names the angular coordinates.  A file of more than ``max_rows`` data rows (default MAX_ROWS) is
    refused as soon as the reader gets there.  Raises :class:`DataError` on any problem.
    """
    max_rows = MAX_ROWS if max_rows is None else int(max_rows)
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
    columns, rows = _read_csv(path, max_rows) if ext == ".csv" else _read_npz(path, max_rows)
    return _validate(path, columns, rows, tuple(angles))


def _read_csv(path: str, max_rows: int) -> tuple[dict[str, np.ndarray], _Rows]:
    """Stream the file into float64 columns, CSV_CHUNK rows at a time: memory is the arrays (8 bytes per cell and
    one line number per row), never the text of the whole file."""
    header, header_line, lines = None, 0, []
    chunks: dict[str, list[np.ndarray]] = {}
    pending: list[list[str]] = []
    pending_lines: list[int] = []
    n_done = 0

    def flush() -> None:
        nonlocal n_done
        if not pending:
            return
        rows = _Rows(pending_lines, offset=n_done)
        for j, name in enumerate(header):
            cells = [rec[j] for rec in pending]
            chunks[name].append(_csv_ids(path, cells, rows) if name == "traj" else _csv_floats(path, name, cells, rows))
        lines.append(np.asarray(pending_lines, dtype=np.int64))
        n_done += len(pending)
        pending.clear()
        pending_lines.clear()

    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            reader = csv.reader(fh)
            for rec in reader:
                if not rec or all(not f.strip() for f in rec):
                    continue  # blank line
                if header is None:
                    header = [f.strip() for f in rec]
                    header_line = reader.line_num
                    _check_header(path, header, header_line)
                    chunks = {name: [] for name in header}
                    continue
                if len(rec) != len(header):
                    where = _Rows([reader.line_num], offset=n_done + len(pending))(n_done + len(pending))
                    raise DataError(
                        f"{path}: {where} has {len(rec)} fields; the header has {len(header)} ({','.join(header)})"
                    )
                if n_done + len(pending) >= max_rows:
                    raise DataError(_too_many(path, max_rows))
                pending.append(rec)
                pending_lines.append(reader.line_num)
                if len(pending) >= CSV_CHUNK:
                    flush()
            flush()
    except UnicodeDecodeError:
        raise DataError(f"{path}: not a UTF-8 text file; expected a CSV file with a header line") from None
    except (OSError, csv.Error) as e:
        raise DataError(f"{path}: cannot read the file ({e.__class__.__name__}: {e})") from None
    if header is None:
        raise DataError(f"{path}: the file is empty; expected a header line (e.g. 't,x') and data rows")
    if n_done == 0:
        raise DataError(f"{path}: no data rows after the header; expected at least one row of numbers")
    columns = {name: np.concatenate(parts) for name, parts in chunks.items()}
    return columns, _Rows(np.concatenate(lines))


def _too_many(path: str, max_rows: int) -> str:
    return (
        f"{path}: more than {max_rows:,} data rows; expected at most {max_rows:,} (thin the file, e.g. keep every "
        "k-th row, or split it into shorter recordings; --max-rows raises the limit)"
    )


CSV_CHUNK = 65536  # rows converted to arrays at a time while reading a CSV file


def _check_header(path: str, header: list[str], header_line: int) -> None:
    if len(header) == 1:
        for sep, name in ((";", "semicolon"), ("\t", "tab"), ("|", "vertical bar")):
            if sep in header[0]:
                raise DataError(
                    f"{path}: the header {header[0]!r} is one field holding {name}s: the file seems {name}-separated; "
                    "expected comma-separated values (e.g. 't,x')"
                )
    if all(_is_number(f) for f in header):
        raise DataError(
            f"{path}: line {header_line} holds numbers, not a header; the first line must name the columns (e.g. 't,x')"
        )
    for j, name in enumerate(header):
        if not name:
            raise DataError(f"{path}: column {j + 1} of the header has no name")
    dup = sorted({h for h in header if header.count(h) > 1})
    if dup:
        raise DataError(f"{path}: duplicate column name {dup[0]!r} in the header")


def _csv_floats(path: str, name: str, cells: list[str], rows: _Rows) -> np.ndarray:
    try:
        return np.array(cells, dtype=np.float64)
    except ValueError:
        i = next(i for i, c in enumerate(cells) if not _is_number(c))
        what = "is empty" if not cells[i].strip() else f"{cells[i].strip()!r} is not a number"
        raise DataError(f"{path}: column {name!r} {rows(rows.offset + i)}: {what}; expected a number") from None


def _csv_ids(path: str, cells: list[str], rows: _Rows) -> np.ndarray:
    """Trajectory ids parsed exactly (an integer literal as an int, not through float64, so 2⁵³ and 2⁵³+1 differ)."""
    out = np.empty(len(cells), dtype=np.int64)
    for i, c in enumerate(cells):
        c = c.strip()
        try:
            v = int(c)
        except ValueError:
            try:
                x = float(c)
            except ValueError:
                what = "is empty" if not c else f"{c!r} is not a number"
                raise DataError(
                    f"{path}: column 'traj' {rows(rows.offset + i)}: {what}; expected an integer trajectory id"
                ) from None
            if not math.isfinite(x) or x != round(x):
                raise DataError(
                    f"{path}: column 'traj' {rows(rows.offset + i)}: {c} is not an integer; "
                    "expected integer trajectory ids"
                ) from None
            v = int(x)
            if abs(v) >= MAX_ID:  # a float this large stands for several integers
                v = MAX_ID + 1
        if abs(v) > MAX_ID:
            raise DataError(
                f"{path}: column 'traj' {rows(rows.offset + i)}: trajectory id {c} is beyond ±2**53 = {MAX_ID}; "
                "expected smaller integer ids (renumber the trajectories)"
            )
        out[i] = v
    return out


def _read_npz(path: str, max_rows: int) -> tuple[dict[str, np.ndarray], _Rows]:
    try:
        _npz_row_limit(path, max_rows)  # from the array headers, before any array is loaded
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
            raise DataError(
                f"{path}: array {name!r} has {a.shape[0]} values but {first!r} has {n_rows}; expected equal lengths"
            )
        columns[name] = _npz_ids(path, a) if name == "traj" else a.astype(np.float64)
    if n_rows == 0:
        raise DataError(f"{path}: the arrays are empty; expected at least one row")
    if n_rows > max_rows:
        raise DataError(_too_many(path, max_rows))
    return columns, _Rows(None)


def _npz_row_limit(path: str, max_rows: int) -> None:
    with zipfile.ZipFile(path) as zf:
        for member in zf.namelist():
            if not member.endswith(".npy"):
                continue
            with zf.open(member) as fp:
                version = np.lib.format.read_magic(fp)
                read = np.lib.format.read_array_header_1_0 if version == (1, 0) else np.lib.format.read_array_header_2_0
                shape = read(fp)[0]
            if shape and shape[0] > max_rows:
                raise DataError(_too_many(path, max_rows))


def _npz_ids(path: str, a: np.ndarray) -> np.ndarray:
    """An NPZ 'traj' array as exact int64 ids (integers within ±2⁵³; floats must be whole numbers below 2⁵³)."""
    if a.dtype.kind == "f":
        bad = ~np.isfinite(a) | (a != np.round(a)) | (np.abs(a) >= MAX_ID)
    else:
        bad = (a > MAX_ID) | (a < -MAX_ID) if a.dtype.kind == "i" else a > np.uint64(MAX_ID)
    if bad.any():
        i = int(np.argmax(bad))
        raise DataError(
            f"{path}: array 'traj' index {i}: {a[i]!r} is not an integer id within ±2**53 = {MAX_ID}; "
            "expected integer trajectory ids (renumber the trajectories)"
        )
    return a.astype(np.int64)


def _check_scales(path: str, columns: dict[str, np.ndarray], coords: tuple[str, ...], rows: _Rows) -> None:
    """Units: nnphd works in any units whose numbers stay within the ranges it was checked on (MAX_ABS, T_SPAN,
    Q_SPREAD, MIN_RESOLUTION; the same verdict and law at scales 1e±30 of q and 1e±15 of t, see the README).
    Outside them, powers and squares of the data over- or underflow float64: refuse, naming the column and a fix."""
    fix = "express it in other units (multiply the column by a power of ten)"
    for name, v in columns.items():
        if name == "traj" or not len(v):
            continue
        i = int(np.argmax(np.abs(v)))
        if abs(v[i]) > MAX_ABS:
            raise DataError(
                f"{path}: column {name!r} {rows(i)}: {float(v[i]):.3g} is beyond ±{MAX_ABS:.0e}; "
                f"expected values within ±{MAX_ABS:.0e}: {fix}"
            )
    span = float(np.ptp(columns["t"]))
    if span > 0 and not (T_SPAN[0] <= span <= T_SPAN[1]):
        raise DataError(
            f"{path}: column 't' spans {span:.3g}; expected a time span within [{T_SPAN[0]:.0e}, {T_SPAN[1]:.0e}]: "
            f"{fix}"
        )
    for c in coords:
        v = columns[c]
        spread = float(np.ptp(v))
        if spread == 0:
            continue
        if not (Q_SPREAD[0] <= spread <= Q_SPREAD[1]):
            raise DataError(
                f"{path}: column {c!r} varies by {spread:.3g}; expected a spread (max − min) within "
                f"[{Q_SPREAD[0]:.0e}, {Q_SPREAD[1]:.0e}]: {fix}"
            )
        big = float(np.max(np.abs(v)))
        if spread < MIN_RESOLUTION * big:
            raise DataError(
                f"{path}: column {c!r} varies by only {spread:.3g} around {big:.3g} (float64 keeps ~16 digits); "
                f"expected a spread of at least {MIN_RESOLUTION:.0e} of its values: subtract a constant offset"
            )


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
        raise DataError(
            f"{path}: no coordinate column; expected at least one column besides 't', 'traj' and '*_dot'/'*_ddot'"
        )
    for a in angles:
        if a not in coords:
            raise DataError(f"{path}: angle {a!r} is not a coordinate column (coordinates: {', '.join(coords)})")
    for name in names:
        bad = ~np.isfinite(columns[name])
        if bad.any():
            i = int(np.argmax(bad))
            raise DataError(
                f"{path}: column {name!r} {rows(i)}: {float(columns[name][i])!r} is not finite; "
                "expected a finite number (no NaN or inf)"
            )
    _check_scales(path, columns, coords, rows)
    n_rows = columns["t"].shape[0]
    if "traj" in columns:
        ids = columns["traj"]  # exact int64, checked by the reader
    else:
        ids = np.zeros(n_rows, dtype=np.int64)
    _, first = np.unique(ids, return_index=True)
    order = ids[np.sort(first)]  # trajectory ids in order of first appearance

    given_qd = tuple(f"{c}_dot" in columns for c in coords)
    given_qdd = tuple(f"{c}_ddot" in columns for c in coords)
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
            raise DataError(
                f"{path}: {label}: t is not strictly increasing at {rows(idx[k])} ({kind} time "
                f"{float(t[k])!r} after {float(t[k - 1])!r}); expected strictly increasing t within a "
                "trajectory"
            )
        if len(idx) < MIN_ROWS:
            what = f"a single sample ({rows(idx[0])})" if len(idx) == 1 else f"{len(idx)} samples"
            raise DataError(
                f"{path}: {label} has {what}; at least {MIN_ROWS} per trajectory are needed (derivative "
                "estimates and the training's held-out rows)"
            )
        trajectories.append(Trajectory(id=int(tid), t=t, q=q_all[idx], qd=qd_all[idx], qdd=qdd_all[idx], rows=idx))

    if all(np.ptp(q_all[:, j]) == 0 for j in range(len(coords))):
        raise DataError(
            f"{path}: all coordinates are constant ({', '.join(coords)}); expected motion in at least one coordinate"
        )
    return UserData(
        path=path,
        coords=coords,
        angles=tuple(a for a in coords if a in angles),
        given_qd=given_qd,
        given_qdd=given_qdd,
        trajectories=tuple(trajectories),
    )


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
            if (
                wrapped is None
                and big.any()
                and np.all(np.abs(step[big] - two_pi) < 0.5 * math.pi)
                and np.ptp(y) <= 1.01 * two_pi
                and np.max(np.abs(np.diff(np.unwrap(y)))) < 0.5 * math.pi
            ):
                wrapped = (tr.id, int(big.sum()))
            if turns is None and np.ptp(y) > 2.0 * two_pi and not _CARTESIAN.match(name) and _grid_step(y) < 0.1:
                turns = (tr.id, float(np.ptp(y)))
        if wrapped is not None:
            label = f" in trajectory {wrapped[0]}" if userdata.n_traj > 1 else ""
            reasons.append(
                f"values jump by about 2π ({wrapped[1]} time{'s' if wrapped[1] > 1 else ''}{label}) "
                "within a 2π range: wrapped angle"
            )
        if turns is not None:
            label = f" in trajectory {turns[0]}" if userdata.n_traj > 1 else ""
            reasons.append(f"values span {turns[1]:.3g} > 4π{label}: whole turns if this is an angle in radians")
        if reasons:
            out.append((name, "; ".join(reasons)))
    return out
