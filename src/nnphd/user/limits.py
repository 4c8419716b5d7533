"""The numbers nnphd accepts in a user's file, in one place (no dependencies: the command line reads them cheaply).

:mod:`nnphd.user.recording` enforces them with a one-line :class:`nnphd.io.errors.DataError`; the README states them.
"""

from __future__ import annotations

MIN_ROWS = 8  # rows per trajectory: the derivative windows (5 and 7) and the training need at least this many
MAX_ROWS = 10_000_000  # data rows per file (memory and time are linear in the rows: see the README)
MAX_ID = 2**53  # trajectory ids: integers within ±2⁵³, which every float64 (and spreadsheet) holds exactly
MAX_ABS = 1e30  # no value beyond ±1e30 in any column
T_SPAN = (1e-15, 1e15)  # the time span of the file (max t − min t)
Q_SPREAD = (1e-30, 1e30)  # the spread (max − min) of every coordinate that moves
MIN_RESOLUTION = 1e-12  # a coordinate's spread relative to its largest |value| (digits of motion left in float64)
