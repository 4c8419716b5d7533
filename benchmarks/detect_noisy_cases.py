"""Constructed trust cases written as noisy position-only CSV files (0.1% noise) and run through nnphd detect.

.venv/bin/python benchmarks/detect_noisy_cases.py morse,pendulum,kepler2d-eccentric,magnetic2d,anharmonic+drag,kepler2d+drag,anharmonic+drive,vanderpol
"""

import os
import sys
import tempfile
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

import nnphd

nnphd.configure()  # float64 and the XLA:CPU setting, as the CLI

from nnphd.user.detect import detect_file
from tests.fixtures.cases import make_case

names = sys.argv[1].split(",")
for name in names:
    d, traj = make_case(name, n_traj=8, seed=3)
    rng = np.random.default_rng(1)
    q = d.q + 1e-3 * d.q.std(axis=0) * rng.standard_normal(d.q.shape)
    cols = [f"q{i + 1}" for i in range(d.n)]
    path = os.path.join(tempfile.gettempdir(), f"noisy_{name}.csv")
    with open(path, "w") as fh:
        fh.write("traj,t," + ",".join(cols) + "\n")
        fh.writelines(f"{k},{ti:.6f}," + ",".join(f"{v:.10g}" for v in row) + "\n" for k, ti, row in zip(traj, d.t, q))
    t0 = time.time()
    r = detect_file(path, out=None, sr_time=0)
    print(
        f"{name:22s} {r['status']:13s} conf {r['confidence']:.2f} z {(r['statistic']['value'] if r['statistic']['value'] is not None else float('nan')):.1f} {time.time() - t0:.0f}s | {r['reasons'][0][:150]}",
        flush=True,
    )
