"""The numbers nnphd accepts in a user's file, in one place (no dependencies: the command line reads them cheaply).

:mod:`nnphd.user.recording` enforces them with a one-line :class:`nnphd.io.errors.DataError`; docs/promises.md states them.
"""

from __future__ import annotations

MIN_ROWS = 8  # rows per trajectory: the derivative windows (5 and 7) and the training need at least this many
MAX_ROWS = 10_000_000  # data rows per file (memory and time are linear in the rows: see docs/promises.md)
MAX_ID = 2**53  # trajectory ids: integers within ±2⁵³, which every float64 (and spreadsheet) holds exactly
MAX_ABS = 1e30  # no value beyond ±1e30 in any column
T_SPAN = (1e-15, 1e15)  # the time span of the file (max t − min t)
Q_SPREAD = (1e-30, 1e30)  # the spread (max − min) of every coordinate that moves
MIN_RESOLUTION = 1e-12  # a coordinate's spread relative to its largest |value| (digits of motion left in float64)

# Run settings (the command line's options, NNPhD's arguments and a model file's saved settings get the same ranges):
MAX_SEED = 2**32 - 1  # JAX and NumPy take seeds of up to 64 bits; 32 are plenty and portable
MAX_STEPS = 10**7  # training steps per run: more would allocate the minibatch keys of the whole scan at once
MAX_N_SEEDS = 100  # seeds of a verdict: each is a whole training of every model (2 by default)
MAX_SR_TIME = 24 * 3600  # seconds of genetic symbolic regression per component (10 by default; 1e300 never ends)

# Bounds on the size and shape of a file, checked before (NPZ: from the array headers) or while (CSV: streamed) it is
# read, so that a hostile or careless file gives one line within bounded memory and time, never a swap storm:
MAX_COORDS = 32  # coordinates per file: the model is n×n per row; a 1000-coordinate CSV once took 2.5 GB, no output
MAX_COLUMNS = 2 + 3 * MAX_COORDS  # columns: t, traj, and each coordinate with its <c>_dot and <c>_ddot
MAX_CELLS = 10**8  # values per file (rows × columns: 800 MB as float64) at the default MAX_ROWS; scales with --max-rows
MAX_LINE = 2**20  # characters of one CSV line or record (a quoted field may span lines; a real row is < 4 KiB)
MAX_NAME = 64  # characters of a column (coordinate) name
