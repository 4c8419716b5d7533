"""Bad input at the edges gives one line and exit 2 with nothing written; the --out folder is claimed by one
run at a time; a defect gives one line and exit 1; big inputs are read and evaluated in bounded chunks; and the
numbers do not depend on the units (within the checked ranges)."""

from __future__ import annotations

import fcntl
import os

import numpy as np
import pytest

from nnphd.cli import main

T = np.linspace(0.0, 10.0, 60)
X = np.cos(2.0 * T) * np.exp(-0.05 * T)


def _write(path, header, cols, sep=","):
    lines = [sep.join(header)] + [
        sep.join(repr(float(v)) if not isinstance(v, str) else v for v in row) for row in zip(*cols)
    ]
    path.write_text("\n".join(lines) + "\n")
    return path


def _one_error_line(capsys) -> str:
    cap = capsys.readouterr()
    lines = [ln for ln in cap.err.splitlines() if ln.strip()]
    assert len(lines) == 1, cap.err
    assert lines[0].startswith("error: ") and "Traceback" not in cap.err + cap.out
    return lines[0]


def _ids(n: int, a: int, b: int) -> list[str]:
    return [str(a)] * (n // 2) + [str(b)] * (n - n // 2)


EDGE_CASES = {
    # name: (header, columns, separator, message parts)
    "seven samples": (["t", "x"], [T[:7], X[:7]], ",", ["has 7 samples", "at least 8 per trajectory"]),
    "positions 1e300": (["t", "x"], [T, X * 1e300], ",", ["column 'x'", "is beyond ±1e+30", "other units"]),
    "times 1e300": (["t", "x"], [T * 1e300, X], ",", ["column 't'", "is beyond ±1e+30"]),
    "time span 1e20": (["t", "x"], [T * 1e20, X], ",", ["column 't' spans 1e+21", "[1e-15, 1e+15]"]),
    "scaled by 1e-300": (["t", "x"], [T, X * 1e-300], ",", ["column 'x' varies by", "[1e-30, 1e+30]"]),
    "motion below float64 resolution": (["t", "x"], [T, 1e20 + X * 1e4], ",", ["varies by only", "offset"]),
    "semicolons": (["t", "x"], [T, X], ";", ["the file seems semicolon-separated", "expected comma-separated"]),
    "tabs": (["t", "x"], [T, X], "\t", ["the file seems tab-separated"]),
    "ids beyond 2**63": (
        ["traj", "t", "x"],
        [_ids(60, 2**63 + 5, 2**63 + 5), T, X],
        ",",
        ["trajectory id 9223372036854775813 is beyond ±2**53"],
    ),
    "ids 2**53 and 2**53+1": (
        ["traj", "t", "x"],
        [_ids(60, 2**53, 2**53 + 1), np.r_[T[:30], T[:30]], X],
        ",",
        ["row 31 (line 32)", "trajectory id 9007199254740993 is beyond ±2**53"],
    ),
}


@pytest.mark.parametrize("case", list(EDGE_CASES))
def test_edge_inputs_give_one_line_exit_2_and_write_nothing(case, tmp_path, capsys):
    header, cols, sep, parts = EDGE_CASES[case]
    path = _write(tmp_path / "data.csv", header, cols, sep)
    out = tmp_path / "out"
    assert main(["detect", str(path), "--out", str(out), "--steps", "4", "--repeats", "1", "--sr-time", "0"]) == 2
    line = _one_error_line(capsys)
    for p in parts:
        assert p in line, (p, line)
    assert not out.exists()


def test_exact_ids_keep_distinct_large_trajectory_ids(tmp_path):
    """2⁵³ − 1 and 2⁵³ are different trajectories (parsed as integers, not through float64); NPZ uint64 ids ≥ 2⁶³ are
    refused, not wrapped."""
    from nnphd.user.recording import DataError, load_trajectories

    path = _write(tmp_path / "d.csv", ["traj", "t", "x"], [_ids(60, 2**53 - 1, 2**53), np.r_[T[:30], T[:30]], X])
    ud = load_trajectories(path)
    assert [tr.id for tr in ud.trajectories] == [2**53 - 1, 2**53] and [len(tr) for tr in ud.trajectories] == [30, 30]
    npz = tmp_path / "d.npz"
    np.savez(npz, t=T, x=X, traj=np.full(60, 2**63 + 7, dtype=np.uint64))
    with pytest.raises(DataError, match=r"array 'traj' index 0: .* within ±2\*\*53"):
        load_trajectories(npz)


def test_trimming_below_the_minimum_is_bad_input(tmp_path, capsys):
    """--trim yes on a trajectory that trimming leaves too short: found mid-run, still one line, exit 2, no --out."""
    path = _write(tmp_path / "d.csv", ["t", "x"], [T[:9], X[:9]])
    out = tmp_path / "out"
    argv = ["detect", str(path), "--out", str(out), "--steps", "4", "--repeats", "1", "--sr-time", "0", "--trim", "yes"]
    assert main(argv) == 2
    line = _one_error_line(capsys)
    assert "trimming the ends of trajectory 0 leaves" in line and "--trim no" in line
    assert not out.exists()


def test_a_second_run_into_a_claimed_out_folder_is_refused(tmp_path, capsys):
    """Another process holding the --out folder (its flock) → exit 2, one line, the folder untouched; once released,
    the folder can be claimed again (the kernel drops the lock when its holder ends)."""
    from nnphd.io.outdir import claim_out_dir, release_out_dirs

    out = tmp_path / "out"
    out.mkdir()
    (out / "results.json").write_text("{}")
    fd = os.open(out, os.O_RDONLY)  # stands in for the other run: a separate open file description
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        assert main(["sweep", "--system", "ho+ld", "--out", str(out), "--steps", "4"]) == 2
        line = _one_error_line(capsys)
        assert "is in use by another nnphd run" in line and str(out) in line
        assert [p.name for p in out.iterdir()] == ["results.json"] and (out / "results.json").read_text() == "{}"
        with pytest.raises(ValueError, match="in use by another nnphd run"):
            claim_out_dir(out)
    finally:
        os.close(fd)
    claim_out_dir(out)
    claim_out_dir(out)  # re-entrant within a process
    release_out_dirs()


def test_a_defect_gives_one_line_and_exit_1(tmp_path, capsys, monkeypatch):
    import nnphd.paper.sweep as sweep_mod

    def broken(*a, **k):
        raise RuntimeError("boom\nsecond line")

    monkeypatch.setattr(sweep_mod, "run_sweep", broken)
    out = tmp_path / "o"
    monkeypatch.delenv("NNPHD_TRACEBACK", raising=False)
    assert main(["sweep", "--system", "ho+ld", "--out", str(out)]) == 1
    line = _one_error_line(capsys)
    assert line.startswith("error: internal error (RuntimeError: boom second line)") and "NNPHD_TRACEBACK=1" in line
    assert not out.exists()
    monkeypatch.setenv("NNPHD_TRACEBACK", "1")
    with pytest.raises(RuntimeError, match="boom"):
        main(["sweep", "--system", "ho+ld", "--out", str(out)])


# ---- bounded memory: the same numbers in chunks ------------------------------------------------------------------
def test_csv_is_streamed_in_chunks_with_the_same_arrays_and_row_numbers(tmp_path, monkeypatch):
    import nnphd.user.recording as rec

    rng = np.random.default_rng(0)
    t = np.cumsum(rng.uniform(0.5, 1.5, 50))
    x = rng.normal(size=50)
    path = _write(tmp_path / "d.csv", ["t", "x", "traj"], [t, x, ["3"] * 25 + ["1"] * 25])
    whole = rec.load_trajectories(path)
    monkeypatch.setattr(rec, "CSV_CHUNK", 7)
    chunked = rec.load_trajectories(path)
    for a, b in zip(whole.trajectories, chunked.trajectories):
        assert a.id == b.id
        np.testing.assert_array_equal(a.t, b.t)
        np.testing.assert_array_equal(a.q, b.q)
        np.testing.assert_array_equal(a.rows, b.rows)
    np.testing.assert_array_equal(np.concatenate([tr.t for tr in chunked.trajectories]), t)
    lines = path.read_text().splitlines()
    lines[40] = lines[40].replace(lines[40].split(",")[1], "oops")  # data row 40, in the sixth chunk
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(rec.DataError, match=r"column 'x' row 40 \(line 41\): 'oops' is not a number"):
        rec.load_trajectories(path)


def test_by_rows_equals_the_whole_call():
    import jax
    import jax.numpy as jnp

    from nnphd.engine.batching import by_rows

    @jax.jit
    def f(w, a, b):
        return jnp.tanh(a @ w) * b[:, None], jnp.sum(a, axis=1)

    rng = np.random.default_rng(1)
    w, a, b = rng.normal(size=(3, 4)), rng.normal(size=(50, 3)), rng.normal(size=50)
    whole = f(w, a, b)
    for chunk in (7, 25, 50, 64):
        got = by_rows(f, w, a, b, chunk=chunk)
        assert got[0].shape == (50, 4) and got[1].shape == (50,)
        np.testing.assert_allclose(got[0], np.asarray(whole[0]), rtol=1e-14, atol=1e-15)
        np.testing.assert_allclose(got[1], np.asarray(whole[1]), rtol=1e-14, atol=1e-15)


def test_drive_frequencies_do_not_depend_on_the_lomb_scargle_chunking(monkeypatch):
    import nnphd.explain.laws as laws

    rng = np.random.default_rng(2)
    t = np.sort(rng.uniform(0, 60, 400))
    r = np.c_[np.sin(1.7 * t) + 0.1 * rng.normal(size=400), 0.3 * np.cos(0.4 * t)]
    whole = laws.drive_start_omegas(t, r, [np.arange(400)])
    monkeypatch.setattr(laws, "LS_CELLS", 1000)  # the samples summed in chunks of a few
    chunked = laws.drive_start_omegas(t, r, [np.arange(400)])
    np.testing.assert_allclose(chunked, whole, rtol=1e-12)
    assert abs(whole[0] - 1.7) < 0.02


@pytest.mark.parametrize("n, m, uneven", [(400, 3200, True), (1179, 9432, False), (37, 200, True), (5, 7, True)])
def test_the_lomb_scargle_grid_is_scipys_periodogram(n, m, uneven):
    """lomb_scargle_grid's factored sums give scipy.signal.lombscargle's unnormalised power at every frequency
    of the grid (uneven samples, or a jittered clock up to the Nyquist frequency)."""
    from scipy.signal import lombscargle

    from nnphd.explain.laws import lomb_scargle_grid

    rng = np.random.default_rng(n)
    t = np.sort(rng.uniform(0, 60, n)) if uneven else np.arange(n) * 0.1 + rng.normal(0, 0.002, n)
    y = np.sin(1.7 * t) + 0.3 * rng.normal(size=n)
    y -= y.mean()
    w = np.linspace(2 * np.pi / np.ptp(t), np.pi / np.median(np.diff(t)), m)
    got = lomb_scargle_grid(t, y, w[0], (w[-1] - w[0]) / (m - 1), m)
    # scipy's reference at <= ~400 of the grid's frequencies, its peak among them (scipy loops over the samples in
    # Python: the whole 9432-frequency grid costs it 12 s), the grid's own peak included
    at = np.unique(np.r_[np.arange(0, m, max(1, m // 400)), m - 1, np.argmax(got)])
    ref = lombscargle(t, y, w[at], normalize=False)
    np.testing.assert_allclose(got[at], ref, rtol=1e-9, atol=1e-12 * ref.max())
    assert at[np.argmax(ref)] == np.argmax(got)


# ---- units -------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("k_q, k_t", [(-100, 0), (60, 0), (0, -50), (-100, 40)])
def test_standardisation_is_unit_free(k_q, k_t):
    """Scaling q by 2^k_q and t by 2^k_t (exact in floating point) leaves the standardised data unchanged: the scales
    are relative, never floored at an absolute 1e-12 (which made q × 1e-40 'constant')."""
    from nnphd.engine.data import Dataset
    from nnphd.engine.models import ModelConfig
    from nnphd.user.scaling import fit_scaling

    rng = np.random.default_rng(3)
    t = np.linspace(0, 20, 200)
    q = np.c_[np.cos(t), 0.3 * np.sin(2 * t) + 5.0] + 1e-3 * rng.normal(size=(200, 2))
    qd = np.c_[-np.sin(t), 0.6 * np.cos(2 * t)]
    qdd = np.c_[-np.cos(t), -1.2 * np.sin(2 * t)]
    sq, st = 2.0**k_q, 2.0**k_t
    a, b = Dataset(q=q, qd=qd, t=t, qdd=qdd), Dataset(q=q * sq, qd=qd * sq / st, t=t * st, qdd=qdd * sq / st**2)
    for x, y in zip(fit_scaling(a).apply(a), fit_scaling(b).apply(b)):
        np.testing.assert_allclose(x, y, rtol=1e-12, atol=1e-12)
    cfg = ModelConfig(n=2)
    ca, cb = cfg.standardized(a.q, a.qd, a.t), cfg.standardized(b.q, b.qd, b.t)
    scale = np.array([sq, sq, sq / st, sq / st, st])
    np.testing.assert_allclose(np.array(cb.input_scale) / scale, ca.input_scale, rtol=1e-12)


def test_coulomb_smoothing_scales_with_the_speeds():
    """The smoothed sign(q̇) of Coulomb friction is relative to the rms speed: at speeds ~1e-40 it is still a sign,
    not (through an absolute floor) a linear friction."""
    from nnphd.explain.families import families

    v = np.linspace(-1.0, 1.0, 41)[:, None]
    q, t = np.zeros_like(v), np.zeros(41)
    for s in (1.0, 1e-40, 1e40):
        fam = next(f for f in families(1, ["x"], np.array([np.sqrt(np.mean((v * s) ** 2))])) if f.key == "coulomb")
        b = np.asarray(fam.basis(np, np.zeros(0), q, v * s, t))[:, 0, 0]
        if s == 1.0:
            ref = b
        np.testing.assert_allclose(b, ref, rtol=1e-10, atol=1e-12)
    assert abs(ref[-1]) > 0.99 and abs(ref[20]) < 1e-12


@pytest.mark.parametrize("ext", ["csv", "npz"])
def test_row_limit_refuses_before_reading_everything(ext, tmp_path, capsys):
    """Beyond --max-rows the file is refused with one line (a CSV as soon as the reader passes the limit, an NPZ from
    its array headers), exit 2, nothing written — the scaled-down path of a file of millions of rows."""
    t = np.arange(100) * 0.1
    if ext == "csv":
        path = _write(tmp_path / "big.csv", ["t", "x"], [t, np.cos(t)])
    else:
        path = tmp_path / "big.npz"
        np.savez(path, t=t, x=np.cos(t))
    out = tmp_path / "out"
    assert main(["detect", str(path), "--out", str(out), "--max-rows", "50"]) == 2
    line = _one_error_line(capsys)
    assert "more than 50 data rows; expected at most 50" in line and "thin the file" in line
    assert not out.exists()
