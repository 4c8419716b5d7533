"""The README's picture: two figures of one ``nnphd detect`` report side by side, under its verdict and law.

    .venv/bin/python benchmarks/readme_figure.py [--out docs/img/report.png]

Writes the damped oscillator of the README's test (q̈ = −q − 0.1 q̇, one trajectory of 40 s at 20 Hz, 1e-4 noise)
as data.csv in a temporary folder, runs ``nnphd detect data.csv`` at its defaults (seed 0) through the installed
console script, and puts the report's L_e(λ) (the jump at λ = 1) and amplitude envelope (the law) side by side, the
report's verdict and law as the title. Run it again after a change to the report's figures.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default=os.path.join(ROOT, "docs", "img", "report.png"))
    a = ap.parse_args()
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.image as mpimg
    import matplotlib.pyplot as plt

    with tempfile.TemporaryDirectory() as tmp:
        t = np.arange(0.0, 40.0, 0.05)
        q = np.exp(-0.05 * t) * np.cos(np.sqrt(1 - 0.05**2) * t)
        q += 1e-4 * np.random.default_rng(0).standard_normal(t.size)
        np.savetxt(os.path.join(tmp, "data.csv"), np.c_[t, q], delimiter=",", header="t,q", comments="", fmt="%.6f")
        exe = os.path.join(os.path.dirname(sys.executable), "nnphd")
        subprocess.run([exe, "detect", "data.csv", "--out", "rep", "--seed", "0"], cwd=tmp, check=True)
        rep = json.load(open(os.path.join(tmp, "rep", "report.json")))
        law = rep["law"]["law"]
        title = (
            f"nnphd detect data.csv: {rep['status'].upper()} (confidence {rep['confidence']:.2f}); "
            f"law {law['title']}: {next(iter(law['formula'].values()))}   (truth: −0.1 q̇)"
        )
        fig, axes = plt.subplots(1, 2, figsize=(12, 4.3))
        for ax, name in zip(axes, ("loss_vs_lambda.png", "envelope.png")):
            ax.imshow(mpimg.imread(os.path.join(tmp, "rep", name)))
            ax.axis("off")
        fig.suptitle(title, fontsize=11)
        fig.tight_layout()
        os.makedirs(os.path.dirname(os.path.abspath(a.out)), exist_ok=True)
        tmp_png = a.out + ".tmp.png"
        fig.savefig(tmp_png, dpi=100)
        os.replace(tmp_png, a.out)
    print(f"wrote {a.out} ({os.path.getsize(a.out) // 1024} KB): {title}")


if __name__ == "__main__":
    main()
