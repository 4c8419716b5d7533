"""The measured recordings in data/real/ (see data/real/README.md) load with nnphd's reader and have the documented
rows, trajectories and sampling."""

import math
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from nnphd.user.recording import load_trajectories  # noqa: E402

DATA = ROOT / "data" / "real"

# file: (coordinate, angles, rows per trajectory, sample interval in s, first t of each trajectory)
EXPECTED = {
    "encoder_pendulum_free_swing.csv": ("theta", ("theta",), [4456, 4585, 4714], 0.001, [0.0, 0.0, 0.0]),
    "video_string_pendulum_lab1.csv": ("theta", ("theta",), [2322], 0.05, [0.4]),
    "video_string_pendulum_lab2.csv": ("theta", ("theta",), [478], 1 / 29.583, [0.7774648]),
    "seismometer_blow.csv": ("x", (), [1179], 0.1, [0.0]),
    "seismometer_blow5.csv": ("x", (), [1180], 0.1, [0.0]),
}


def test_every_file_is_documented():
    files = sorted(p.name for p in DATA.glob("*.csv"))
    assert files == sorted(EXPECTED)
    readme = (DATA / "README.md").read_text()
    for name in files:
        assert f"## {name}" in readme


def test_the_folder_stays_small():
    assert sum(p.stat().st_size for p in DATA.iterdir()) < 3_000_000


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_loads_with_the_documented_shape_and_rate(name):
    coord, angles, rows, dt, t0 = EXPECTED[name]
    data = load_trajectories(DATA / name, angles=angles)
    assert data.coords == (coord,)
    assert data.angles == angles
    assert [len(tr) for tr in data.trajectories] == rows
    assert data.n_samples == sum(rows)
    for tr, first in zip(data.trajectories, t0):
        steps = np.diff(tr.t)
        assert np.median(steps) == pytest.approx(dt, rel=2e-3)
        assert steps.min() > 0.99 * dt * (0.99 if "lab1" in name else 1.0)  # video frame times jitter by < 1 %
        assert steps.max() < 1.01 * dt * (1.01 if "lab1" in name else 1.0)
        assert tr.t[0] == pytest.approx(first, abs=1e-6)
        assert np.all(np.isfinite(tr.q))
        assert np.ptp(tr.q) > 0


def test_the_encoder_angles_are_whole_counts():
    """theta = counts * 2 pi / 4000 (README): the conversion from the source's degrees is exact."""
    data = load_trajectories(DATA / "encoder_pendulum_free_swing.csv", angles=("theta",))
    for tr in data.trajectories:
        counts = tr.q[:, 0] * 4000 / (2 * math.pi)
        assert np.max(np.abs(counts - np.round(counts))) < 1e-3
