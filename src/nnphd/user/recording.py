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
``CSV_CHUNK`` rows at a time.

Hostile or careless files are refused within bounded memory and time (limits in :mod:`nnphd.io.limits`): only
regular files are opened (a link to ``/dev/zero``, a FIFO or a socket is refused from ``os.stat`` before it is
opened); a CSV line or record (quoted fields may span lines) longer than ``MAX_LINE`` = 2²⁰ characters is refused
without reading the rest; the header (the NPZ member names) may name at most ``MAX_COLUMNS`` = 98 columns and
``MAX_COORDS`` = 32 coordinates, each a non-empty name of at most ``MAX_NAME`` = 64 characters without surrounding
whitespace or control characters; a file holds at most ``MAX_CELLS`` = 10⁸ values (rows × columns; raised in
proportion with ``max_rows``), counted while streaming a CSV and from the array headers of an NPZ, whose shapes
(1-D, equal lengths), dtypes (int, uint, float) and members (only ``.npy``, not encrypted, their uncompressed sizes
and header lengths bounded from the zip directory and the first bytes before numpy reads a header) are all checked
before any array is read.  Cells and names in messages are quoted (``repr``) and cut to a few dozen characters, so a
message never carries a file's content.  Any strictly increasing sampling is accepted.  :func:`suggest_angles` lists coordinates not declared as angles that look like angles (name, wrapped
values, whole turns), for a report.
"""

from __future__ import annotations

import csv
import itertools
import math
import numbers
import os
import re
import stat
import unicodedata
import zipfile
import zlib
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from nnphd.io.cache import MAX_NPY_HEADER, npy_header
from nnphd.io.errors import DataError
from nnphd.io.limits import (
    MAX_ABS,
    MAX_CELLS,
    MAX_COLUMNS,
    MAX_COORDS,
    MAX_ID,
    MAX_LINE,
    MAX_NAME,
    MAX_ROWS,
    MIN_RESOLUTION,
    MIN_ROWS,
    Q_SPREAD,
    T_SPAN,
)
from nnphd.user.localpoly import MIN_SAMPLES
from nnphd.user.sampling import grid_step

__all__ = [
    "DataError",
    "Trajectory",
    "UserData",
    "MIN_SAMPLES",
    "MIN_ROWS",
    "from_arrays",
    "from_table",
    "load_trajectories",
    "suggest_angles",
]


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
    markers: Any = None  # a marker recording's constraints and coordinates (nnphd.user.markers.MarkerModel)

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


def load_trajectories(
    path, angles: Sequence[str] = (), max_rows: int | None = None, markers=None, fps: float | None = None
) -> UserData:
    """Read and validate a CSV (header required) or NPZ trajectory file; see the module docstring for the format.

    ``angles`` names the angular coordinates.  A file of more than ``max_rows`` data rows (default MAX_ROWS) is
    refused as soon as the reader gets there.  Raises :class:`DataError` on any problem.

    ``markers``: a camera's marker positions (columns ``<marker>_x``, ``<marker>_y`` [, ``_z``], with ``t`` or a
    ``frame`` column and ``fps``) turned into generalized coordinates by :mod:`nnphd.user.markers` — None (the
    default): when every column but t, frame and traj is one of at least two markers; "auto": the markers found;
    "none": never; or the markers' names. Empty cells are lost markers there. The result's ``markers`` holds the
    constraints and the coordinates chosen.
    """
    max_rows = MAX_ROWS if max_rows is None else int(max_rows)
    max_cells = _max_cells(max_rows)
    path = os.fspath(path)
    try:
        angles = _angle_names(path, angles)
        ext = os.path.splitext(path)[1].lower()
        if ext not in (".csv", ".npz", ".txt"):
            raise DataError(
                f"{path}: unsupported file type {_q(ext) if ext else '(none)'}; expected a .csv or .npz file (or "
                "Tracker's .txt data table)"
            )
        fd = _open_regular(path)
        if ext == ".txt":  # Tracker's exported data table: marker positions
            if isinstance(markers, str) and markers == "none":
                raise DataError(f"{path}: a .txt file is read as Tracker's data table of marker positions; "
                                "expected --markers auto or the markers' names, or a .csv file")  # fmt: skip
            columns, rows = _read_tracker(path, fd, max_rows, max_cells)
            markers = "auto" if markers is None else markers
        elif ext == ".csv":
            columns, rows = _read_csv(path, fd, max_rows, max_cells, markers)
        else:
            columns, rows = _read_npz(path, fd, max_rows, max_cells)
        if _marker_mode(list(columns), markers):
            return _from_markers(path, columns, angles, markers, fps)
        if fps is not None:
            raise DataError(f"{path}: --fps is the frame rate of a marker recording, and this file is none "
                            "(expected columns <marker>_x, <marker>_y with a frame column)")  # fmt: skip
        return _validate(path, columns, rows, angles)
    except DataError as e:
        shown = _shown(path)
        if shown != path and str(e).startswith(path):  # a file name with a line break must not break the line
            raise DataError(shown + str(e)[len(path) :]) from None
        raise


def _marker_mode(names: list[str], markers) -> bool:
    """Whether a table is read as marker positions (:func:`load_trajectories`' ``markers``)."""
    from nnphd.user.markers import looks_like_markers

    if markers is None:
        return looks_like_markers(names)
    return not (isinstance(markers, str) and markers == "none")


def from_marker_columns(columns, markers="auto", fps: float | None = None) -> UserData:
    """A mapping of a marker recording's columns (:func:`nnphd.user.markers.from_columns`) → validated
    :class:`UserData` with its ``markers``; one-line :class:`DataError` on any problem."""
    w = "<arrays>"
    try:
        cols = {
            str(k): _api_numbers(w, _q(str(k)), v) if str(k) != "traj" else _api_ids(w, v) for k, v in columns.items()
        }
    except AttributeError:
        raise DataError(f"{w}: expected a mapping of column names to arrays") from None
    return _from_markers(w, cols, (), markers, fps)


def _from_markers(path: str, columns: dict, angles, markers, fps) -> UserData:
    """A marker recording → its generalized coordinates (:func:`nnphd.user.markers.from_columns`), validated as any
    file's coordinates; ``markers`` in the result. One-line :class:`DataError` naming the file on any problem."""
    from nnphd.user.markers import MarkerError, from_columns

    if angles:
        raise DataError(f"{path}: --angles does not apply to a marker recording: nnphd chooses its coordinates "
                        "(and which are angles) from the markers' constraints")  # fmt: skip
    try:
        mm = from_columns(columns, "auto" if markers is None else markers, fps)
    except MarkerError as e:
        raise DataError(f"{path}: {e}") from None
    cols: dict[str, np.ndarray] = {"t": mm.t, "traj": mm.traj.astype(np.int64)}
    cols |= {c: mm.q[:, j] for j, c in enumerate(mm.names)}
    return replace(_validate(path, cols, _Rows(None), mm.angles), markers=mm)


def _max_cells(max_rows: int) -> int:
    """The cap on values (rows × columns): MAX_CELLS at the default MAX_ROWS, raised in proportion with --max-rows."""
    return max(MAX_CELLS, MAX_CELLS * max_rows // MAX_ROWS)


def _q(text, n: int = 40) -> str:
    """Untrusted text (a cell, a name) for a message: quoted with repr (no line breaks or control characters) and cut
    to ``n`` characters, so that a message never carries long file content."""
    text = str(text)
    return repr(text) if len(text) <= n else repr(text[:n]) + "…"


def _cut(text, n: int = 60) -> str:
    """Text that is not file content (names already checked, shapes, dtypes) cut to ``n`` characters."""
    text = str(text)
    text = text if text.isprintable() else repr(text)
    return text if len(text) <= n else text[:n] + "…"


def _value(v) -> str:
    """A Python value from the caller for a message: a str quoted and cut, anything else its repr cut."""
    return _q(v, 30) if isinstance(v, str) else _cut(repr(v), 30)


def _num_text(c: str) -> str:
    """A cell that parsed as a number, as written (short) or quoted and cut (a 4000-digit integer)."""
    return c if len(c) <= 24 and c.isprintable() else _q(c, 20)


def _err(e: BaseException, n: int = 100) -> str:
    """A library's exception as one short line (its text may quote file content)."""
    text = " ".join(str(e).split())
    text = text if len(text) <= n else text[:n] + "…"
    return f"{e.__class__.__name__}: {text}" if text else e.__class__.__name__


def _shown(path: str) -> str:
    return path if path.isprintable() else repr(path)


_KINDS = (
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISFIFO, "a FIFO (named pipe)"),
    (stat.S_ISSOCK, "a socket"),
)


def _open_regular(path: str) -> int:
    """Open a regular file for reading; anything else (a device such as /dev/zero, a FIFO, a socket, behind a link
    or not) is refused from ``os.stat`` before it is opened, and again from ``os.fstat`` of the descriptor (opened
    non-blocking, so that a FIFO swapped in between cannot block)."""

    def check(st: os.stat_result) -> None:
        if stat.S_ISDIR(st.st_mode):
            raise DataError(f"{path}: is a directory, expected a .csv or .npz file")
        if not stat.S_ISREG(st.st_mode):
            kind = next((k for test, k in _KINDS if test(st.st_mode)), "not a file")
            raise DataError(f"{path}: not a regular file ({kind}); expected a .csv or .npz file")

    try:
        check(os.stat(path))
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOCTTY", 0))
    except FileNotFoundError:
        raise DataError(f"{path}: file not found") from None
    except OSError as e:
        raise DataError(f"{path}: cannot read the file ({e.__class__.__name__}: {e.strerror})") from None
    try:
        check(os.fstat(fd))
        if hasattr(os, "set_blocking"):
            os.set_blocking(fd, True)
    except BaseException:
        os.close(fd)
        raise
    return fd


def _bounded_lines(path: str, fh, record: list[int]):
    """The lines of a CSV file for :func:`csv.reader`, each read with a bound (``readline(MAX_LINE + 1)``): a line,
    or a record spanning lines (a quoted field holding line breaks), longer than MAX_LINE characters is refused
    without reading the rest, so a file without line breaks is never read whole.  ``record[0]`` counts the
    characters of the record being read; the reader's loop sets it to 0 after each record."""
    readline, limit = fh.readline, MAX_LINE + 1
    line = start = 0
    while True:
        if record[0] == 0:
            start = line + 1  # the line the record begins on
        s = readline(limit)
        if not s:
            return
        line += 1
        record[0] += len(s)
        if record[0] > MAX_LINE:
            if line == start:
                raise DataError(
                    f"{path}: line {line} is longer than {MAX_LINE:,} characters; expected lines of at most "
                    f"{MAX_LINE:,} (is this a CSV file with line breaks?)"
                )
            raise DataError(
                f"{path}: the record from line {start} to {line} is longer than {MAX_LINE:,} characters; expected "
                f"rows of at most {MAX_LINE:,} (an unclosed quote '\"'?)"
            )
        yield s


def _read_csv(path: str, fd: int, max_rows: int, max_cells: int, markers=None) -> tuple[dict[str, np.ndarray], _Rows]:
    """Stream the file into float64 columns, CSV_CHUNK rows (at most CSV_CHUNK_CHARS characters) at a time: memory
    is the arrays (8 bytes per cell and one line number per row), never the text of the whole file; lines are read
    with a bound (:func:`_bounded_lines`) and the values are capped (``max_cells``, rows × columns)."""
    header, header_line, lines = None, 0, []
    chunks: dict[str, list[np.ndarray]] = {}
    pending: list[list[str]] = []
    pending_lines: list[int] = []
    n_done = pending_chars = 0
    blank_nan = False  # a marker recording: an empty cell is a marker lost in that frame

    def flush() -> None:
        nonlocal n_done, pending_chars
        pending_chars = 0
        if not pending:
            return
        rows = _Rows(pending_lines, offset=n_done)
        for j, name in enumerate(header):
            cells = [rec[j] for rec in pending]
            if blank_nan and name != "traj":
                cells = [c if c.strip() else "nan" for c in cells]
            chunks[name].append(_csv_ids(path, cells, rows) if name == "traj" else _csv_floats(path, name, cells, rows))
        lines.append(np.asarray(pending_lines, dtype=np.int64))
        n_done += len(pending)
        pending.clear()
        pending_lines.clear()

    try:
        with open(fd, newline="", encoding="utf-8-sig") as fh:
            record = [0]  # characters of the record being read
            reader = csv.reader(_bounded_lines(path, fh, record))
            for rec in reader:
                chars, record[0] = record[0], 0
                if not rec or all(not f.strip() for f in rec):
                    continue  # blank line
                if header is None:
                    header = [f.strip() for f in rec]
                    header_line = reader.line_num
                    _check_header(path, header, header_line)
                    chunks = {name: [] for name in header}
                    blank_nan = _marker_mode(header, markers)
                    continue
                _check_csv_record(path, rec, header, reader.line_num, n_done + len(pending), max_rows, max_cells)
                pending.append(rec)
                pending_lines.append(reader.line_num)
                pending_chars += chars
                if len(pending) >= CSV_CHUNK or pending_chars >= CSV_CHUNK_CHARS:
                    flush()
            flush()
    except UnicodeDecodeError:
        raise DataError(f"{path}: not a UTF-8 text file; expected a CSV file with a header line") from None
    except csv.Error as e:
        raise DataError(
            f"{path}: line {reader.line_num}: not readable as CSV ({_err(e)}); expected a CSV file"
        ) from None
    except OSError as e:
        raise DataError(f"{path}: cannot read the file ({_err(e)})") from None
    if header is None:
        raise DataError(f"{path}: the file is empty; expected a header line (e.g. 't,x') and data rows")
    if n_done == 0:
        raise DataError(f"{path}: no data rows after the header; expected at least one row of numbers")
    columns = {name: np.concatenate(parts) for name, parts in chunks.items()}
    return columns, _Rows(np.concatenate(lines))


def _read_tracker(path: str, fd: int, max_rows: int, max_cells: int) -> tuple[dict[str, np.ndarray], _Rows]:
    """Tracker's (physlets.org/tracker) exported data table: one track — its name on the first line, then a header
    ``t x y …`` — or several (``#multi:``, a line of the tracks' names over their first columns, then the header);
    tab-, comma- or semicolon-delimited; an empty cell where a track has no step. → columns ``t`` and
    ``<track>_x``, ``<track>_y`` (``_z``) of every track (other columns, such as Tracker's velocities, are left
    out), read with the CSV reader's bounds (:func:`_bounded_lines`, ``max_rows``, ``max_cells``)."""
    try:
        with open(fd, newline="", encoding="utf-8-sig") as fh:
            record = [0]
            lines = (ln for ln in _bounded_lines(path, fh, record) if ln.strip())
            head = [next(lines, "") for _ in range(3)]
            multi = head[0].strip().lower().startswith("#multi")
            names_line, header_line = (head[1], head[2]) if multi else (head[0], head[1])
            delim = next((d for d in ("\t", ";", ",") if d in header_line), None)
            header = [h.strip() for h in header_line.rstrip("\r\n").split(delim)] if delim else []
            if not header or header[0] != "t" or not any(h in AXIS_NAMES for h in header):
                raise DataError(f"{path}: not a Tracker data table; expected a track's name (or #multi: and the "
                                "tracks' names), then a header t, x, y, then rows")  # fmt: skip
            tracks = _tracker_tracks(path, names_line.rstrip("\r\n").split(delim), header, multi)
            body = [] if multi else [head[2]]  # one track: its third line is a row already
            cells: list[list[str]] = []
            for rec in csv.reader(itertools.chain(body, lines), delimiter=delim):
                record[0] = 0
                if len(cells) >= max_rows or (len(cells) + 1) * len(header) > max_cells:
                    raise DataError(_too_many(path, max_rows))
                cells.append((rec + [""] * len(header))[: len(header)])
    except UnicodeDecodeError:
        raise DataError(f"{path}: not a UTF-8 text file; expected Tracker's data table") from None
    except csv.Error as e:
        raise DataError(f"{path}: not readable as a data table ({_err(e)})") from None
    except OSError as e:
        raise DataError(f"{path}: cannot read the file ({_err(e)})") from None
    if not cells:
        raise DataError(f"{path}: no data rows after the header; expected rows of t, x, y")
    rows = _Rows(None)
    cols = {"t": _csv_floats(path, "t", [r[0] for r in cells], rows)}
    for j, name in tracks:
        cols[name] = _csv_floats(path, name, [r[j] if r[j].strip() else "nan" for r in cells], rows)
    return cols, rows


AXIS_NAMES = ("x", "y", "z")


def _tracker_tracks(path: str, names: list[str], header: list[str], multi: bool) -> list[tuple[int, str]]:
    """(column, ``<track>_<axis>``) of every x, y, z column of a Tracker table: each column's track is the last
    name at or before it on the names line (one track: the first line's name)."""
    out, track = [], None
    for j, h in enumerate(header):
        if multi and j < len(names) and names[j].strip():
            track = names[j].strip()
        elif not multi:
            track = names[0].strip()
        if h in AXIS_NAMES and j > 0:
            if not track:
                raise DataError(f"{path}: column {j + 1} ({_q(h)}) has no track name above it; expected the "
                                "tracks' names over their columns")  # fmt: skip
            out.append((j, f"{track}_{h}"))
    if len({n for _, n in out}) != len(out):
        raise DataError(f"{path}: a track has two {_q(out[0][1].rsplit('_', 1)[1])} columns; expected one per axis")
    return out


def _check_csv_record(
    path: str, rec: list[str], header: list[str], line: int, n_before: int, max_rows: int, max_cells: int
) -> None:
    """Refuse a data record (``n_before`` data rows precede it, on file line ``line``) whose field count differs from
    the header's, or one that would pass ``max_rows`` rows or ``max_cells`` values."""
    if len(rec) != len(header):
        where = _Rows([line], offset=n_before)(n_before)
        raise DataError(
            f"{path}: {where} has {len(rec)} fields; the header has {len(header)} ({_q(','.join(header), 60)})"
        )
    if n_before >= max_rows:
        raise DataError(_too_many(path, max_rows))
    if (n_before + 1) * len(header) > max_cells:
        raise DataError(_too_many_cells(path, max_cells, len(header)))


def _too_many(path: str, max_rows: int) -> str:
    return (
        f"{path}: more than {max_rows:,} data rows; expected at most {max_rows:,} (thin the file, e.g. keep every "
        "k-th row, or split it into shorter recordings; --max-rows raises the limit)"
    )


def _too_many_cells(path: str, max_cells: int, n_columns: int) -> str:
    return (
        f"{path}: more than {max_cells:,} values ({n_columns} columns × {max_cells // n_columns:,} rows); expected at "
        f"most {max_cells:,} values (rows × columns, {max_cells * 8 / 1e9:.2g} GB as float64): thin the file (keep "
        "every k-th row), split it, or drop columns (--max-rows raises the limit in proportion)"
    )


CSV_CHUNK = 65536  # rows converted to arrays at a time while reading a CSV file
CSV_CHUNK_CHARS = 2**25  # ... or fewer rows when their text reaches this many characters (long cells)


def _check_header(path: str, header: list[str], header_line: int) -> None:
    if len(header) == 1:
        for sep, name in ((";", "semicolon"), ("\t", "tab"), ("|", "vertical bar")):
            if sep in header[0]:
                raise DataError(
                    f"{path}: the header {_q(header[0])} is one field holding {name}s: the file seems "
                    f"{name}-separated; expected comma-separated values (e.g. 't,x')"
                )
    if all(_is_number(f) for f in header):
        raise DataError(
            f"{path}: line {header_line} holds numbers, not a header; the first line must name the columns (e.g. 't,x')"
        )
    _check_names(path, header, "column {} of the header")


def _check_names(path: str, names: Sequence, label: str = "column {}") -> None:
    """Column names that are usable: at most MAX_COLUMNS, each a non-empty str of at most MAX_NAME characters with no
    leading or trailing whitespace and no control, format or line-separator characters, all distinct; at most
    MAX_COORDS coordinates among them.  Checked from the header / array names before any value is converted."""
    if len(names) > MAX_COLUMNS:
        raise DataError(
            f"{path}: {len(names):,} columns; expected at most {MAX_COLUMNS} (t, traj and at most {MAX_COORDS} "
            "coordinates with their _dot and _ddot): keep the columns of one system"
        )
    base = 0 if "[" in label else 1  # names[0] (a Python list), column 1 (a file's header)
    for j, name in enumerate(names):
        where = f"{path}: {label.format(j + base)}"
        if not isinstance(name, str):
            raise DataError(f"{where}: the name {_value(name)} is a {type(name).__name__}; expected a str")
        if not name:
            raise DataError(f"{where} has no name")
        if name != name.strip():
            raise DataError(f"{where}: the name {_q(name)} has leading or trailing whitespace; expected none")
        if len(name) > MAX_NAME:
            raise DataError(f"{where}: the name {_q(name)} has {len(name)} characters; expected at most {MAX_NAME}")
        bad = next((c for c in name if unicodedata.category(c) in _BAD_CATEGORIES), None)
        if bad is not None:
            raise DataError(
                f"{where}: the name {_q(name)} holds the control character {bad!r}; expected printable characters"
            )
    seen: set[str] = set()
    for name in names:
        if name in seen:
            raise DataError(f"{path}: duplicate column name {_q(name)}")
        seen.add(name)
    n_coords = sum(1 for c in names if c not in ("t", "traj") and not c.endswith(("_dot", "_ddot")))
    if n_coords > MAX_COORDS:
        raise DataError(
            f"{path}: {n_coords} coordinate columns; expected at most {MAX_COORDS} coordinates (columns other than "
            "t, traj and <c>_dot/<c>_ddot): keep the coordinates of one system"
        )


_BAD_CATEGORIES = {"Cc", "Cf", "Cs", "Co", "Cn", "Zl", "Zp"}  # control, format, surrogate, private, unassigned, breaks


def _csv_floats(path: str, name: str, cells: list[str], rows: _Rows) -> np.ndarray:
    try:
        return np.array(cells, dtype=np.float64)
    except ValueError:
        i = next((i for i, c in enumerate(cells) if not _is_number(c)), None)
        if i is None:  # a cell that Python's float() reads and numpy's does not
            i = next(i for i, c in enumerate(cells) if not _is_number(c, np.float64))
        what = "is empty" if not cells[i].strip() else f"{_q(cells[i].strip(), 20)} is not a number"
        raise DataError(f"{path}: column {_q(name)} {rows(rows.offset + i)}: {what}; expected a number") from None


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
                what = "is empty" if not c else f"{_q(c, 20)} is not a number"
                raise DataError(
                    f"{path}: column 'traj' {rows(rows.offset + i)}: {what}; expected an integer trajectory id"
                ) from None
            if math.isinf(x) and c.lstrip("+-")[:1].isdigit():  # 1e400, or more digits than int() reads
                x = float(2 * MAX_ID)
            if not math.isfinite(x) or x != round(x):
                raise DataError(
                    f"{path}: column 'traj' {rows(rows.offset + i)}: {_num_text(c)} is not an integer; "
                    "expected integer trajectory ids"
                ) from None
            v = int(x)
            if abs(v) >= MAX_ID:  # a float this large stands for several integers
                v = MAX_ID + 1
        if abs(v) > MAX_ID:
            raise DataError(
                f"{path}: column 'traj' {rows(rows.offset + i)}: trajectory id {_num_text(c)} is beyond ±2**53 = "
                f"{MAX_ID}; expected smaller integer ids (renumber the trajectories)"
            )
        out[i] = v
    return out


def _read_npz(path: str, fd: int, max_rows: int, max_cells: int) -> tuple[dict[str, np.ndarray], _Rows]:
    """Read an .npz archive of 1-D numeric arrays.  Everything is checked from the zip directory and the arrays'
    .npy headers before any array is read: the number of members (at most MAX_COLUMNS, each a ``.npy``, not
    encrypted), each member's uncompressed size (at most a column of ``max_rows`` values) and header length (at most
    MAX_NPY_HEADER) before numpy reads its header (:func:`nnphd.io.cache.npy_header`: a deflated header of 1 GiB of
    spaces is refused, not read), their names, shapes (1-D, one length), dtypes (int, uint or float: never objects,
    text or complex), sizes (rows ≤ ``max_rows``, values ≤ ``max_cells``) and that each header's shape fills its
    member exactly; then each array is read from the archive with :func:`numpy.lib.format.read_array` (no pickle),
    which reads exactly what its header declared."""
    with open(fd, "rb") as fh:
        if os.fstat(fh.fileno()).st_size == 0:
            raise DataError(f"{path}: the file is empty; expected an .npz archive of 1-D arrays (numpy.savez)")
        try:
            endrec = zipfile._EndRecData(fh) if hasattr(zipfile, "_EndRecData") else None
            if endrec is not None and endrec[zipfile._ECD_ENTRIES_TOTAL] > MAX_COLUMNS:
                raise DataError(
                    f"{path}: the archive holds {endrec[zipfile._ECD_ENTRIES_TOTAL]:,} members; expected at most "
                    f"{MAX_COLUMNS} arrays (t, traj and at most {MAX_COORDS} coordinates with their _dot and _ddot)"
                )
            fh.seek(0)
            with zipfile.ZipFile(fh) as zf:
                members = _npz_members(path, zf, max_rows, max_cells)
                columns = {}
                for name, (info, shape, dtype) in members.items():
                    with zf.open(info) as fp:
                        a = np.lib.format.read_array(fp, allow_pickle=False)
                    if a.shape != shape or a.dtype != dtype:  # the file changed under us
                        raise DataError(f"{path}: array {_q(name)} changed while it was read; expected a stable file")
                    columns[name] = _exact_ids(path, "array 'traj'", a) if name == "traj" else a.astype(np.float64)
        except DataError:
            raise
        except _NPZ_ERRORS as e:
            fh.seek(0)
            hint = ": a single .npy array, not an .npz archive" if fh.read(6) == b"\x93NUMPY" else ""
            raise DataError(
                f"{path}: cannot read as .npz ({_err(e)}){hint}; expected an .npz archive of 1-D arrays (numpy.savez)"
            ) from None
    if not columns:
        raise DataError(f"{path}: the file holds no arrays; expected arrays named like CSV columns ('t', ...)")
    return columns, _Rows(None)


MAX_NPY_PREFIX = 12  # an .npy member's bytes before its header text: magic, version, the header length (v2.0, 3.0)
MAX_ITEMSIZE = 16  # bytes of the widest number accepted (int64, float64; longdouble is 16 on most machines)
_NPZ_ERRORS = (OSError, ValueError, EOFError, zipfile.BadZipFile, zlib.error, NotImplementedError, RuntimeError)
try:  # an LZMA member that is corrupt
    import lzma

    _NPZ_ERRORS += (lzma.LZMAError,)
except ImportError:  # pragma: no cover - Python built without lzma
    pass


def _npz_members(path: str, zf: zipfile.ZipFile, max_rows: int, max_cells: int) -> dict:
    """{column name: (ZipInfo, shape, dtype)} from the zip directory and the .npy headers, every limit checked."""
    infos = zf.infolist()
    names = _member_names(path, infos)
    out, n_rows, first, cells = {}, None, None, 0
    max_bytes = MAX_NPY_PREFIX + MAX_NPY_HEADER + max_rows * MAX_ITEMSIZE  # a member: a column of max_rows values
    for name, info in zip(names, infos):
        header = _member_header(path, zf, info, name, max_bytes)
        shape = header.shape
        if n_rows is None:
            n_rows, first = shape[0], name
        elif shape[0] != n_rows:
            raise DataError(
                f"{path}: array {_q(name)} has {shape[0]} values but {_q(first)} has {n_rows}; expected equal lengths"
            )
        if n_rows > max_rows:
            raise DataError(_too_many(path, max_rows))
        cells += shape[0]
        if cells > max_cells:
            raise DataError(_too_many_cells(path, max_cells, len(names)))
        out[name] = (info, header)
    for name, (_, header) in out.items():  # the file-wide limits first: their messages say what to change
        try:
            header.check_size()  # its data fills the member exactly: the header claims no more than is there
        except ValueError as e:
            raise DataError(f"{path}: array {_q(name)} {e}; expected a numpy.savez archive") from None
    if n_rows == 0:
        raise DataError(f"{path}: the arrays are empty; expected at least one row")
    return {name: (info, header.shape, header.dtype) for name, (info, header) in out.items()}


def _member_names(path: str, infos: list[zipfile.ZipInfo]) -> list[str]:
    """The column names of an archive's members, from the zip directory: at most MAX_COLUMNS members, each a
    ``.npy`` that is not encrypted, named as :func:`_check_names` wants."""
    if len(infos) > MAX_COLUMNS:
        raise DataError(f"{path}: the archive holds {len(infos):,} members; expected at most {MAX_COLUMNS} arrays")
    names = []
    for info in infos:
        if not info.filename.endswith(".npy") or info.is_dir():
            raise DataError(
                f"{path}: member {_q(info.filename)} is not a .npy array; expected only arrays (numpy.savez)"
            )
        if info.flag_bits & 0x1:
            raise DataError(f"{path}: member {_q(info.filename)} is encrypted; expected a plain numpy.savez archive")
        names.append(info.filename[: -len(".npy")])
    _check_names(path, names, "array {}")
    return names


def _member_header(path: str, zf: zipfile.ZipFile, info: zipfile.ZipInfo, name: str, max_bytes: int):
    """The .npy header of one member (:func:`nnphd.io.cache.npy_header`: its uncompressed size at most
    ``max_bytes`` and its header length bounded before numpy reads the header), a 1-D array of numbers."""
    try:
        with zf.open(info) as fp:
            header = npy_header(info, fp, max_bytes)
    except ValueError as e:
        raise DataError(f"{path}: array {_q(name)} {e}") from None
    if len(header.shape) != 1:
        raise DataError(
            f"{path}: array {_q(name)} has shape {_cut(header.shape, 30)}; expected a 1-D array (one value per row)"
        )
    if header.dtype.kind not in "iuf" or header.dtype.hasobject:
        raise DataError(
            f"{path}: array {_q(name)} has dtype {_cut(header.dtype, 30)}; expected numbers (int or float: not "
            "complex, text or objects)"
        )
    return header


def _exact_ids(path: str, label: str, a: np.ndarray) -> np.ndarray:
    """Trajectory ids as exact int64: integers within ±2⁵³ (floats must be whole numbers below 2⁵³ in magnitude, since
    a larger float stands for several integers); ``label`` names the array in the message."""
    if a.dtype.kind == "f":
        bad = ~np.isfinite(a) | (a != np.round(a)) | (np.abs(a) >= MAX_ID)
    elif a.dtype.kind == "i":
        bad = (a > MAX_ID) | (a < -MAX_ID)
    elif a.dtype.kind == "u":
        bad = a > np.uint64(MAX_ID)
    else:
        raise DataError(f"{path}: {label} has dtype {a.dtype}; expected integer trajectory ids")
    if bad.any():
        i = int(np.argmax(bad))
        raise DataError(
            f"{path}: {label} index {i}: {_cut(repr(a[i].item()), 30)} is not an integer id within ±2**53 = "
            f"{MAX_ID}; expected integer trajectory ids (renumber the trajectories)"
        )
    return a.astype(np.int64)


# ---- arrays from Python (nnphd.Trajectories) ------------------------------------------------------------------------
def _angle_names(path: str, angles) -> tuple[str, ...]:
    """``angles`` as a tuple of names: a single str is one name (not its letters); None is none."""
    if angles is None:
        return ()
    if isinstance(angles, str):
        return (angles,)
    try:
        out = tuple(angles)
    except TypeError:
        raise DataError(f"{path}: angles must be a name or a list of names, got a {type(angles).__name__}") from None
    for a in out:
        if not isinstance(a, str):
            raise DataError(f"{path}: angle {_value(a)} is a {type(a).__name__}; expected a coordinate name (str)")
    return out


def _api_array(path: str, x, what: str, expected: str) -> np.ndarray:
    """``np.asarray(x)``; a ragged or unconvertible input is one line: ``path: what (numpy's reason); expected …``."""
    try:
        return np.asarray(x)
    except (ValueError, TypeError) as e:
        raise DataError(f"{path}: {what} ({_err(e, 60)}); expected {expected}") from None


def _api_numbers(path: str, what: str, x) -> np.ndarray:
    """``x`` as a float64 array of real numbers; ragged lists, text, objects that are not real numbers, booleans and
    complex numbers (whose imaginary part would be dropped) give one line."""
    a = _api_array(path, x, f"{what} is not an array of numbers", "a rectangular array")
    if a.dtype.kind == "O":
        bad = next((v for v in a.flat if not isinstance(v, numbers.Real) or isinstance(v, (bool, np.bool_))), None)
        if bad is not None or any(v is None for v in a.flat):
            raise DataError(
                f"{path}: {what} holds {_value(bad)} (a {type(bad).__name__}); expected real numbers (int or float)"
            )
        try:
            a = a.astype(np.float64)
        except (OverflowError, ValueError, TypeError) as e:
            raise DataError(f"{path}: {what}: {_err(e, 60)}; expected real numbers within float64") from None
    if a.dtype.kind == "c":
        raise DataError(
            f"{path}: {what} is complex ({a.dtype}); expected real numbers (pass .real if the imaginary part is zero)"
        )
    if a.dtype.kind not in "iuf":
        raise DataError(f"{path}: {what} has dtype {_cut(a.dtype, 30)}; expected real numbers (int or float)")
    return a.astype(np.float64, copy=False)


def _api_ids(path: str, x, n: int | None = None) -> np.ndarray:
    """Trajectory ids given from Python as exact int64 (the CSV reader's rule: integers within ±2⁵³, whole floats),
    a 1-D array of ``n`` ids (one per sample; any length if None)."""
    a = _api_array(path, x, "traj is not an array of ids", "one integer per sample")
    if a.ndim != 1 or (n is not None and a.shape != (n,)):
        raise DataError(f"{path}: traj must have one id per sample ({n or 'N'}), got shape {_cut(a.shape, 30)}")
    if a.dtype.kind == "O":
        out = np.empty(n, dtype=np.int64)
        for i, v in enumerate(a):
            if isinstance(v, (bool, np.bool_)) or not isinstance(v, numbers.Real):
                raise DataError(f"{path}: traj index {i}: {_value(v)} is not an integer; expected integer ids")
            if isinstance(v, numbers.Integral):
                v = int(v)
            else:
                v = float(v)
                if not math.isfinite(v) or v != round(v) or abs(v) >= MAX_ID:
                    raise DataError(
                        f"{path}: traj index {i}: {v!r} is not an integer id within ±2**53; expected integer ids"
                    )
                v = int(v)
            if abs(v) > MAX_ID:
                raise DataError(
                    f"{path}: traj index {i}: {_num_text(str(v))} is beyond ±2**53 = {MAX_ID}; expected smaller ids"
                )
            out[i] = v
        return out
    if a.dtype.kind not in "iuf":
        raise DataError(f"{path}: traj has dtype {_cut(a.dtype, 30)}; expected integer trajectory ids")
    return _exact_ids(path, "traj", a)


def _check_scales(path: str, columns: dict[str, np.ndarray], coords: tuple[str, ...], rows: _Rows) -> None:
    """Units: nnphd works in any units whose numbers stay within the ranges it was checked on (MAX_ABS, T_SPAN,
    Q_SPREAD, MIN_RESOLUTION; the same verdict and law at scales 1e±30 of q and 1e±15 of t, see docs/promises.md).
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


def _is_number(s: str, parse=float) -> bool:
    try:
        parse(s)
    except ValueError:
        return False
    return True


def _validate(path: str, columns: dict[str, np.ndarray], rows: _Rows, angles: tuple[str, ...]) -> UserData:
    """Check the columns (names, shapes, coordinates, angles, finite values, scales) and split them into
    trajectories; the checks run in this order, so the first problem of a file is the one reported."""
    names = list(columns)
    _check_names(path, names)
    n_rows = _check_shapes(path, columns, names)
    coords = _coordinates(path, names, angles)
    _check_finite(path, columns, names, rows)
    _check_scales(path, columns, coords, rows)
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
        _check_trajectory(path, label, t, idx, rows)
        trajectories.append(Trajectory(id=int(tid), t=t, q=q_all[idx], qd=qd_all[idx], qdd=qdd_all[idx], rows=idx))

    if all(np.ptp(q_all[:, j]) == 0 for j in range(len(coords))):
        raise DataError(
            f"{path}: all coordinates are constant ({_cut(', '.join(coords), 60)}); expected motion in at least one coordinate"
        )
    return UserData(
        path=path,
        coords=coords,
        angles=tuple(a for a in coords if a in angles),
        given_qd=given_qd,
        given_qdd=given_qdd,
        trajectories=tuple(trajectories),
    )


def _check_shapes(path: str, columns: dict[str, np.ndarray], names: list[str]) -> int:
    """Require a ``t`` column and 1-D columns of its length, at least one value long; returns that length."""
    if "t" not in columns:
        raise DataError(
            f"{path}: no 't' column; expected a time column named 't' (columns: {_cut(', '.join(names), 60)})"
        )
    n_rows = columns["t"].shape[0]
    for name in names:
        if columns[name].shape != (n_rows,):
            raise DataError(
                f"{path}: column {_q(name)} has shape {_cut(columns[name].shape, 30)} but 't' has {n_rows} values; "
                "expected 1-D columns of equal length"
            )
    if n_rows == 0:
        raise DataError(f"{path}: no samples (the columns are empty); expected at least {MIN_ROWS} per trajectory")
    return n_rows


def _coordinates(path: str, names: list[str], angles: tuple[str, ...]) -> tuple[str, ...]:
    """The coordinate columns in file order (all but ``t``, ``traj`` and ``*_dot``/``*_ddot``): every derivative
    column needs its coordinate, there must be one at least, and every angle must be one."""
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
            raise DataError(
                f"{path}: angle {_q(a)} is not a coordinate column (coordinates: {_cut(', '.join(coords), 60)})"
            )
    return coords


def _check_finite(path: str, columns: dict[str, np.ndarray], names: list[str], rows: _Rows) -> None:
    """Refuse NaN and inf, naming the first such value (columns in order, then rows)."""
    for name in names:
        bad = ~np.isfinite(columns[name])
        if bad.any():
            i = int(np.argmax(bad))
            raise DataError(
                f"{path}: column {_q(name)} {rows(i)}: {float(columns[name][i])!r} is not finite; "
                "expected a finite number (no NaN or inf)"
            )


def _check_trajectory(path: str, label: str, t: np.ndarray, idx: np.ndarray, rows: _Rows) -> None:
    """One trajectory (times ``t`` of the data rows ``idx``): t strictly increasing, then at least MIN_ROWS rows."""
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


# ---- arrays and tables from Python (nnphd.Trajectories) -----------------------------------------------------------
def from_arrays(
    t, q, traj=None, *, names: Sequence[str] | None = None, angles: Sequence[str] = (), qd=None, qdd=None
) -> UserData:
    """Validate arrays as :class:`nnphd.Trajectories` takes them (see there) into :class:`UserData`: the same rules
    as a file, plus the array checks (numbers only — no complex, text or object arrays —, shapes, exact integer
    trajectory ids within ±2⁵³, usable names; a single str of ``names``/``angles`` is one name). One-line
    :class:`DataError` on any problem."""
    w = "<arrays>"  # how messages name these arrays
    if _is_per_trajectory(t):
        t, q, qd, qdd, traj = _join_trajectories(w, t, q, traj, qd, qdd)
    t = _api_numbers(w, "t", t)
    if t.ndim != 1 or not len(t):
        raise DataError(f"{w}: t must be a non-empty 1-D array (one time per sample), got shape {_cut(t.shape, 30)}")
    q = _api_numbers(w, "q", q)
    q = q[:, None] if q.ndim == 1 else q
    if q.ndim != 2 or q.shape[0] != len(t):
        raise DataError(
            f"{w}: q must be (N,) or (N, n) with N = {len(t)} (the length of t), got shape {_cut(q.shape, 30)}"
        )
    names = _coordinate_names(w, names, q.shape[1])
    cols: dict[str, np.ndarray] = {"t": t}
    if traj is not None:
        cols["traj"] = _api_ids(w, traj, len(t))  # exact: 2**53 and 2**53 + 1 stay apart, 0.2 is refused
    for j, c in enumerate(names):
        cols[c] = q[:, j]
    for suffix, arr in (("_dot", qd), ("_ddot", qdd)):
        if arr is not None:
            a = _api_numbers(w, f"q{suffix}", arr)
            a = a[:, None] if a.ndim == 1 else a
            if a.shape != q.shape:
                raise DataError(f"{w}: q{suffix} must have the shape of q {q.shape}, got {_cut(a.shape, 30)}")
            for j, c in enumerate(names):
                cols[c + suffix] = a[:, j]
    return _validate(w, cols, _Rows(None), _angle_names(w, angles))


def _is_per_trajectory(t) -> bool:
    """Whether :func:`from_arrays` got ``t`` as a list of per-trajectory 1-D arrays."""
    try:
        return isinstance(t, (list, tuple)) and len(t) > 0 and np.ndim(t[0]) == 1
    except (ValueError, TypeError):  # a ragged first element: refused below, as t
        return False


def _join_trajectories(w: str, t, q, traj, qd, qdd) -> tuple:
    """Lists of per-trajectory arrays (one list per argument of :func:`from_arrays`) joined into one array each;
    returns (t, q, qd, qdd, traj) with trajectory ids 0, 1, … in list order."""
    if traj is not None:
        raise DataError(f"{w}: give either lists of per-trajectory arrays or traj ids, not both")
    for what, a in (("q", q), ("qd", qd), ("qdd", qdd)):
        if (a is not None or what == "q") and (not isinstance(a, (list, tuple)) or len(a) != len(t)):
            raise DataError(f"{w}: {what} must be a list of {len(t)} arrays, one per array of t")
    ts = [_api_numbers(w, f"t[{i}]", x) for i, x in enumerate(t)]
    for i, x in enumerate(ts):
        if x.ndim != 1 or not len(x):
            raise DataError(f"{w}: t[{i}] must be a non-empty 1-D array, got shape {_cut(x.shape, 30)}")
    ids = np.concatenate([np.full(len(x), i, dtype=np.int64) for i, x in enumerate(ts)])
    return (
        np.concatenate(ts),
        _join_parts(w, q, "q", ts),
        _join_parts(w, qd, "qd", ts),
        _join_parts(w, qdd, "qdd", ts),
        ids,
    )


def _join_parts(w: str, a, what: str, ts: list[np.ndarray]) -> np.ndarray | None:
    """The per-trajectory arrays ``a`` (``what``: q, qd or qdd; None: not given) as one (N, n) array: each (N_i,) or
    (N_i, n) with N_i the length of ``ts[i]`` and n the same for all."""
    if a is None:
        return None
    parts = []
    for i, (x, ti) in enumerate(zip(a, ts)):
        x = _api_numbers(w, f"{what}[{i}]", x)
        x = x[:, None] if x.ndim == 1 else x
        if x.ndim != 2 or x.shape[0] != len(ti) or (parts and x.shape[1] != parts[0].shape[1]):
            cols = f", {parts[0].shape[1]})" if parts else ") or (N, n)"
            raise DataError(f"{w}: {what}[{i}] must have shape ({len(ti)}{cols} like t[{i}], got {_cut(x.shape, 30)}")
        parts.append(x)
    return np.concatenate(parts)


def _coordinate_names(w: str, names, n: int) -> list[str]:
    """The names of the n columns of q (default q1, q2, …; a single str is one name): n distinct, usable names, none
    that a file reserves (t, traj, *_dot, *_ddot)."""
    if names is None:
        names = [f"q{i + 1}" for i in range(n)]
    else:
        names = [names] if isinstance(names, str) else list(names)  # a single str is one name, not its letters
    if len(names) != n:
        raise DataError(f"{w}: names must be {n} distinct names (one per column of q), got {len(names)}")
    _check_names(w, names, "names[{}]")
    bad = [c for c in names if c in ("t", "traj") or c.endswith(("_dot", "_ddot"))]
    if bad:
        raise DataError(f"{w}: coordinate names must not be 't', 'traj' or end in _dot/_ddot, got {_q(bad[0])}")
    return names


def from_table(df, angles: Sequence[str] = ()) -> UserData:
    """Validate a pandas DataFrame (or any mapping of column names to arrays) with a CSV file's columns into
    :class:`UserData`; names are checked before any column is converted. One-line :class:`DataError`."""
    w = "<dataframe>"
    try:
        keys = list(df)  # the column labels
    except TypeError:
        raise DataError(
            f"{w}: expected a DataFrame or a mapping of column names to arrays, got {type(df).__name__}"
        ) from None
    names = [str(k) for k in keys]
    _check_names(w, names)  # how many, usable, distinct: before any column is converted
    cols = {}
    for k, name in zip(keys, names):
        cols[name] = _api_ids(w, df[k]) if name == "traj" else _api_numbers(w, f"column {name!r}", df[k])
    return _validate(w, cols, _Rows(None), _angle_names(w, angles))


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
            if turns is None and np.ptp(y) > 2.0 * two_pi and not _CARTESIAN.match(name) and grid_step(y) < 0.1:
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
