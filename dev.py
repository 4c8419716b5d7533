#!/usr/bin/env python3
"""Set up the project in ./.venv (if needed) and run the demo or the tests. Needs only python3 (≥ 3.11).

python3 dev.py demo    # λ-sweeps on HO+LD (friction: a jump at λ=1) and HO+MF (conservative: no jump); exit 1 if wrong
python3 dev.py test    # the test suite (pytest), without the end-to-end runs marked slow (under 5 min on 2 cores)
python3 dev.py test --slow   # only the slow ones (CI, .ci/run, runs both)
python3 dev.py docs    # the documentation site with its API reference (mkdocs build --strict) into site/
"""

import hashlib
import os
import subprocess
import sys
import venv
from pathlib import Path

ROOT = Path(__file__).resolve().parent
VENV = ROOT / ".venv"
BIN = VENV / ("Scripts" if os.name == "nt" else "bin")
STAMP = VENV / ".nnphd-installed"


def run(*cmd: str) -> None:
    r = subprocess.run(cmd, cwd=ROOT)
    if r.returncode:
        sys.exit(r.returncode)


def setup() -> None:
    if sys.version_info < (3, 11):  # noqa: UP036 — dev.py runs under any python3, to say this
        sys.exit(f"error: nnphd needs Python ≥ 3.11, this is {sys.version.split()[0]}")
    if not (BIN / "python").exists():
        print(f"creating {VENV}", flush=True)
        venv.EnvBuilder(with_pip=True).create(VENV)
    want = hashlib.sha256((ROOT / "pyproject.toml").read_bytes()).hexdigest()
    if not STAMP.exists() or STAMP.read_text() != want:
        print("installing nnphd and its dependencies into .venv (first run: a few minutes)", flush=True)
        run(str(BIN / "python"), "-m", "pip", "install", "-q", "--upgrade", "pip")
        run(str(BIN / "python"), "-m", "pip", "install", "-q", "-e", ".[all,test,docs]")
        STAMP.write_text(want)


def demo() -> None:
    """λ-sweeps (``--mode fast``: four λ, each until converged) of HO+LD and HO+MF, then their verdicts; exit 1 when a
    verdict is not the truth (friction: a jump at λ = 1; the magnetic field: none), so CI can run the demo too."""
    import json

    wrong = []
    for system, truth in (("ho+ld", True), ("ho+mf", False)):
        out = ROOT / "out" / "demo" / system
        run(str(BIN / "nnphd"), "sweep", "--system", system, "--mode", "fast", "--out", str(out))
        v = json.loads((out / "results.json").read_text())["verdict"]
        if v["new_physics"] is not truth:
            wrong.append(f"{system}: new physics = {v['new_physics']}, expected {truth}")
    print("\nresults: out/demo/ho+ld/ and out/demo/ho+mf/ (results.json, loss_vs_lambda.png); the paper's own")
    print("protocol (13 λ × 2000 steps, 1–2 min each): .venv/bin/nnphd sweep --system ho+ld")
    if wrong:
        sys.exit("error: the demo's verdicts are wrong: " + "; ".join(wrong))


def docs() -> None:
    """The site of docs/ and the API reference from the docstrings (mkdocs.yml), into site/ (git ignores it); strict:
    a broken link, a missing anchor or a cross-reference that does not resolve fails the build."""
    run(str(BIN / "mkdocs"), "build", "--strict", "--quiet", "--site-dir", str(ROOT / "site"))
    print(f"documentation built: {ROOT / 'site' / 'index.html'}")


def main() -> None:
    what = sys.argv[1] if len(sys.argv) > 1 else ""
    if what not in ("demo", "test", "docs", "setup"):
        sys.exit("usage: python3 dev.py demo|test|docs|setup [--slow] [extra pytest arguments for test]")
    setup()
    if what == "demo":
        demo()
    elif what == "docs":
        docs()
    elif what == "test":
        # lint and format check (ruff, settings in pyproject.toml) beside the tests: all run, any failing fails
        paths = ["src", "tests", "benchmarks", "dev.py"]
        lint = subprocess.run([str(BIN / "ruff"), "check", *paths], cwd=ROOT).returncode
        lint = subprocess.run([str(BIN / "ruff"), "format", "--check", *paths], cwd=ROOT).returncode or lint
        # one pytest process per core (pytest-xdist; a module's tests stay together): nnphd holds XLA to one
        # thread per process (nnphd.configure), so the cores are filled by processes
        # the slowest tests are listed at the end: where a tier's time goes (budgets: 5 min fast, 30 min in all)
        # in the order tests/conftest.py gives (the longest modules first), not xdist's by number of tests
        xdist = ["-n", "auto", "--dist", "loadfile", "--no-loadscope-reorder", "--durations", "30"]
        extra = sys.argv[2:]
        # the tests marked slow (end-to-end runs at realistic sizes) only with --slow, unless -m chooses otherwise
        tier = ["-m", "slow"] if "--slow" in extra else [] if "-m" in extra else ["-m", "not slow"]
        extra = [a for a in extra if a != "--slow"]
        tests = subprocess.run(
            [str(BIN / "python"), "-m", "pytest", *xdist, *tier, "tests", *extra], cwd=ROOT
        ).returncode
        if lint or tests:
            sys.exit(tests or lint)


if __name__ == "__main__":
    main()
