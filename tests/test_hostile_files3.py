"""Hostile files: NPZ header bombs, model files with settings or scales nnphd would not run, and
a report that is a FIFO. Every hostile file is built here, at run time; each is refused with one line naming it,
before numpy reads what it declares (the NPZ cases: shown by numpy's header readers made to fail if called, and by
the peak of Python memory while refusing a 240 MiB header bomb), and without blocking (the FIFO: in a process that
a timeout would end)."""

from __future__ import annotations

import io
import json
import os
import struct
import subprocess
import sys
import tracemalloc
import zipfile

import numpy as np
import pytest

import nnphd
from nnphd.cli.common import MAX_SEED, MAX_STEPS
from nnphd.io.cache import MAX_NPY_HEADER, npy_header, read_npz
from nnphd.io.limits import MAX_ROWS
from nnphd.user.modelfile import MAX_MODEL_BYTES, MAX_N_SEEDS, MAX_SR_TIME, read_model_file
from nnphd.user.recording import MAX_ITEMSIZE, MAX_NPY_PREFIX, DataError, load_trajectories
from tests.fixtures.modelfiles import tiny_model

# ---- NPZ: a member's uncompressed size and .npy header length are bounded before numpy reads its header ----------
BOMB_HEADER = 240 << 20  # a header of 240 MiB of spaces: over a data column's bound, under read_npz's and a model's
HEADER_DICT = b"{'descr': '<f8', 'fortran_order': False, 'shape': (0,), }"
CHUNK = 1 << 20


def _bomb(path, header_bytes: int = BOMB_HEADER):
    """An .npz whose member 't.npy' is a v2.0 .npy with a header of ``header_bytes`` (a real dict, then spaces),
    deflated (~250:1 at level 1), written in 1 MiB chunks: a ~1 MB file, built without holding the header."""
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED, compresslevel=1) as zf:
        with zf.open("t.npy", "w", force_zip64=True) as m:
            m.write(b"\x93NUMPY\x02\x00" + struct.pack("<I", header_bytes) + HEADER_DICT)
            spaces, left = b" " * CHUNK, header_bytes - len(HEADER_DICT) - 1
            for _ in range(left // CHUNK):
                m.write(spaces)
            m.write(b" " * (left % CHUNK) + b"\n")
    return path


def _peak(read, path) -> tuple[str, int]:
    """The one-line message of the ValueError ``read(path)`` raises, and the peak of Python memory (tracemalloc: bytes,
    str and numpy's arrays) allocated until then."""
    tracemalloc.start()
    try:
        read(path)
    except ValueError as e:
        msg = str(e)
    else:
        msg = "read without an error"
    finally:
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
    return msg, peak


def test_an_npy_header_bomb_is_refused_by_every_npz_reader_within_bounded_memory(tmp_path):
    """A header bomb: numpy reads and decodes all the header that its length field declares before checking its
    size — 240 MiB here, which cost ≥ 480 MiB in each reader. A data column's member is refused from the zip
    directory (it is larger than a column of MAX_ROWS values); read_npz and a model file, whose size bounds it passes,
    refuse it from the header-length field. Each reader runs once first (on a missing file), so that what is
    measured is the refusal, not the imports."""
    path = _bomb(tmp_path / "bomb.npz")
    assert path.stat().st_size < 2 << 20  # a small file ...
    size = zipfile.ZipFile(path).getinfo("t.npy").file_size
    assert size == 12 + BOMB_HEADER and size < MAX_MODEL_BYTES  # ... that declares 240 MiB, under a model's bound
    column = MAX_NPY_PREFIX + MAX_NPY_HEADER + MAX_ROWS * MAX_ITEMSIZE
    readers = {  # reader → what it says
        load_trajectories: f"array 't' is {size:,} bytes uncompressed, more than the limit of {column:,}",
        nnphd.Trajectories.from_npz: f"array 't' is {size:,} bytes uncompressed, more than the limit of {column:,}",
        lambda p: read_npz(
            p, "meta"
        ): f"array 't' has a .npy header of {BOMB_HEADER:,} bytes, more than the limit of 10,000",  # fmt: skip
        nnphd.load: f"array 't' has a .npy header of {BOMB_HEADER:,} bytes, more than the limit of 10,000",
    }
    for read, part in readers.items():
        with pytest.raises(ValueError):
            read(tmp_path / "missing.npz")
        msg, peak = _peak(read, path)
        assert part in msg and "\n" not in msg, msg
        assert peak < 4 << 20, (msg, peak)  # 4 MiB; reading the header took ≥ 480 MiB
        if read is nnphd.load or read is load_trajectories:  # (read_npz says why; its callers name the file)
            assert msg.startswith(str(path)), msg


@pytest.fixture
def numpy_reads_no_header(monkeypatch):
    """numpy's .npy header readers, made to fail: a file refused with them in place was refused before numpy read
    its header."""

    def boom(*args, **kwargs):
        raise AssertionError("numpy was asked to read an .npy header")

    from numpy.lib import format as npy

    for name in ("read_array_header_1_0", "read_array_header_2_0", "read_array", "read_magic"):
        monkeypatch.setattr(npy, name, boom)
    impl = getattr(np.lib, "_format_impl", None)
    if impl is not None and hasattr(impl, "_read_array_header"):
        monkeypatch.setattr(impl, "_read_array_header", boom)


def _member(path, data: bytes, name="t.npy", compression=zipfile.ZIP_DEFLATED):
    with zipfile.ZipFile(path, "w", compression) as zf:
        zf.writestr(name, data)
    return path


def _all_refuse(path, *parts):
    """load_trajectories (a DataError), read_npz and nnphd.load each refuse ``path`` with one line holding every
    part (load_trajectories and nnphd.load naming the file; read_npz says why, its callers name the file)."""
    for read, error, named in ((load_trajectories, DataError, True), (read_npz, ValueError, False), (nnphd.load, ValueError, True)):  # fmt: skip
        with pytest.raises(error) as e:
            read(path, "meta") if read is read_npz else read(path)
        msg = str(e.value)
        assert "\n" not in msg and all(p in msg for p in parts), msg
        assert msg.startswith(f"{path}: ") or not named, msg


def test_a_header_length_beyond_the_bound_is_refused_before_numpy_reads_it(tmp_path, numpy_reads_no_header):
    # the length field of a v2.0 header says 4 GiB (the member holds a few bytes): refused from the field
    lying = b"\x93NUMPY\x02\x00" + struct.pack("<I", 2**32 - 1) + HEADER_DICT + b"\n"
    _all_refuse(_member(tmp_path / "v2.npz", lying), f"has a .npy header of {2**32 - 1:,} bytes", "limit of 10,000")
    # a v1.0 header of 60 000 bytes (its length field holds at most 65 535), all there: refused all the same
    v1 = b"\x93NUMPY\x01\x00" + struct.pack("<H", 60_000) + HEADER_DICT + b" " * (60_000 - len(HEADER_DICT) - 1)
    _all_refuse(_member(tmp_path / "v1.npz", v1 + b"\n"), "has a .npy header of 60,000 bytes", "limit of 10,000")
    # within the bound, but longer than the member: the header claims more bytes than there are
    short = b"\x93NUMPY\x01\x00" + struct.pack("<H", 5000) + HEADER_DICT + b"\n"
    _all_refuse(
        _member(tmp_path / "short.npz", short),
        f"has a .npy header of 5,000 bytes, more than its {len(short)} bytes hold",
    )
    _all_refuse(_member(tmp_path / "magic.npz", b"PK\x03\x04" * 4), "is not a .npy array")
    _all_refuse(_member(tmp_path / "cut.npz", b"\x93NUMPY\x02\x00\x10"), "is cut short in its .npy header")


def _npy(a, version=None) -> bytes:
    buf = io.BytesIO()
    np.lib.format.write_array(buf, a, version=version)
    return buf.getvalue()


def test_a_data_member_larger_than_a_column_is_refused_from_the_zip_directory(tmp_path, numpy_reads_no_header):
    """A column holds at most max_rows values of at most MAX_ITEMSIZE bytes (after a bounded header): a member the
    zip directory declares larger is refused before its first byte is read."""
    t = np.arange(100.0)
    path = _member(tmp_path / "big.npz", _npy(t) + bytes(30_000))  # 30 kB of zeros after a 100-row column
    bound = MAX_NPY_PREFIX + MAX_NPY_HEADER + 1000 * MAX_ITEMSIZE
    with pytest.raises(DataError) as e:
        load_trajectories(path, max_rows=1000)
    assert f"{path}: array 't' is 30,928 bytes uncompressed, more than the limit of {bound:,}" in str(e.value)


def test_a_header_whose_shape_does_not_fill_its_member_is_refused(tmp_path):
    """The shape a header declares must fill its member exactly: neither more (read_array would hit the end) nor
    less (bytes nobody reads, up to the size bound) than the member holds."""
    t, x = np.arange(10.0), np.cos(np.arange(10.0))
    for extra, claims in ((bytes(1000), "(10,)"), (b"", "(20,)")):
        with zipfile.ZipFile(tmp_path / "m.npz", "w") as zf:
            for name, a in (("t", t), ("x", x)):
                zf.writestr(
                    f"{name}.npy", _npy(a)[: -a.nbytes].replace(b"(10,)", claims.encode()) + a.tobytes() + extra
                )
        with pytest.raises(DataError) as e:
            load_trajectories(tmp_path / "m.npz")
        size = len(_npy(t)) + len(extra)
        assert f"array 't' has shape {claims}, which does not match its size ({size:,} bytes)" in str(e.value)
        with pytest.raises(ValueError, match="does not match its size"):
            read_npz(tmp_path / "m.npz", "meta")


@pytest.mark.parametrize("version", [(1, 0), (2, 0), (3, 0)])
def test_npy_header_reads_what_numpy_writes(tmp_path, version):
    a = np.asfortranarray(np.arange(12.0).reshape(3, 4))
    path = _member(tmp_path / "a.npz", _npy(a, version), compression=zipfile.ZIP_STORED)
    with zipfile.ZipFile(path) as zf, zf.open("t.npy") as m:
        h = npy_header(zf.getinfo("t.npy"), m, 10**6)
    assert (h.version, h.shape, h.fortran_order, h.dtype) == (version, (3, 4), True, np.dtype("<f8"))
    h.check_size()
    with pytest.raises(ValueError, match="more than the limit of 100"):
        with zipfile.ZipFile(path) as zf, zf.open("t.npy") as m:
            npy_header(zf.getinfo("t.npy"), m, 100)


# ---- model files: the command line's ranges, plain names, a finite forward pass -----------------------------------

REPORT = {"status": "detected", "new_physics": True, "confidence": 1.0, "reasons": ["a test model"], "law": None}


@pytest.fixture(scope="module")
def model_parts(tmp_path_factory):
    """(meta, arrays) of a valid model file: a small untrained LNN, no law (built, not fitted)."""
    d = tmp_path_factory.mktemp("model")
    path = tiny_model(REPORT, d / "written.npz").save(d / "m.npz")
    with np.load(path, allow_pickle=False) as z:
        return json.loads(str(z["meta"])), {k: np.asarray(z[k]) for k in z.files if k != "meta"}


def _model(model_parts, path, edit=None, edit_arrays=None):
    meta, arrays = json.loads(json.dumps(model_parts[0])), dict(model_parts[1])
    if edit:
        edit(meta)
    if edit_arrays:
        edit_arrays(arrays)
    np.savez(path, meta=np.array(json.dumps(meta)), **arrays)
    return path


def _refused(path, *parts) -> str:
    with pytest.raises(ValueError) as e:
        nnphd.load(path)
    msg = str(e.value)
    assert "\n" not in msg and msg.startswith(f"{path}: not a valid nnphd model file: "), msg
    assert all(p in msg for p in parts), msg
    return msg


def _setting(key, value):
    return lambda meta: meta["settings"].__setitem__(key, value)


SETTINGS = {  # key → (the largest value a file may hold, a value beyond it, part of the message)
    "steps": (MAX_STEPS, 2**31, f"meta.settings.steps is 2147483648, expected an integer in 0..{MAX_STEPS}"),
    "n_seeds": (MAX_N_SEEDS, 1000, f"meta.settings.n_seeds is 1000, expected an integer in 1..{MAX_N_SEEDS}"),
    "sr_time": (
        MAX_SR_TIME,
        1e300,
        f"meta.settings.sr_time is 1e+300, expected a non-negative number of at most {MAX_SR_TIME:g}",
    ),
    "seed": (MAX_SEED, MAX_SEED + 1, f"meta.settings.seed is {MAX_SEED + 1}, expected an integer in 0..{MAX_SEED}"),
}


@pytest.mark.parametrize("key", list(SETTINGS))
def test_model_file_settings_get_the_command_lines_ranges(model_parts, tmp_path, key):
    ok, beyond, message = SETTINGS[key]
    loaded = nnphd.load(_model(model_parts, tmp_path / "ok.npz", _setting(key, ok)))
    assert getattr(loaded, key) == ok
    _refused(_model(model_parts, tmp_path / "bad.npz", _setting(key, beyond)), message)
    if key == "seed":
        _refused(_model(model_parts, tmp_path / "neg.npz", _setting(key, -1)), "meta.settings.seed is -1")


UNSAFE = ["\x00", "\x07", "\t", "\n", "\x1b", "\x7f", "\x85", "\x9b", "\u061c", "\u200e", "\u200f", "\u202a", "\u202e", "\u2066", "\u2069"]  # fmt: skip


@pytest.mark.parametrize("char", UNSAFE, ids=[f"U+{ord(c):04X}" for c in UNSAFE])
def test_coordinate_names_with_control_or_bidi_characters_are_refused(model_parts, tmp_path, char):
    path = _model(model_parts, tmp_path / "n.npz", lambda m: m.__setitem__("names", [f"x{char}]0;pwned"]))
    msg = _refused(path, f"meta.names[0] holds the control or bidi character U+{ord(char):04X}")
    assert msg.isprintable(), msg  # the message names the character; it does not carry it


@pytest.mark.parametrize("name", ["θ", "x y", "Δx_1", "ü"])
def test_plain_unicode_names_load(model_parts, tmp_path, name):
    path = _model(model_parts, tmp_path / "u.npz", lambda m: m.__setitem__("names", [name]))
    assert nnphd.load(path).names_ == (name,)


def _scaled(**kw):
    def edit(meta):
        meta["scaling"].update(kw)

    return edit


def _weights(factor):
    def edit(arrays):
        for k in arrays:
            arrays[k] = arrays[k] * factor

    return edit


def _with_law(beta):
    def edit(meta):
        meta["scaling"]["s_q"] = [10.0]
        meta["law"] = {"spec": {"kind": "user", "text": "-c*x_dot"}, "beta": [beta], "theta": []}

    return edit


OVERFLOWS = {  # case → (edit of meta, edit of the arrays, what the message names)
    "weights 1e200": (None, _weights(1e200), "the conservative force f_c (the network) is not finite"),
    "input_scale 1e-300": (
        lambda m: m["cfg"].update(input_shift=[0.0] * 3, input_scale=[1e-300] * 3),
        None,
        "the conservative force f_c (the network) is not finite",
    ),
    "s_t 1e-200": (_scaled(s_t=1e-200), None, "the conservative force f_c (the network) is not finite"),
    "mu_q and s_q 1e308": (_scaled(mu_q=[1e308], s_q=[1e308]), None, "its scaling overflows"),
    "law 1e308": (_with_law(1e308), None, "the law's force f_n is not finite"),
}


@pytest.mark.parametrize("case", list(OVERFLOWS))
def test_extreme_finite_scales_that_overflow_the_forward_pass_are_refused(model_parts, tmp_path, case):
    edit, edit_arrays, expected = OVERFLOWS[case]
    path = _model(model_parts, tmp_path / "x.npz", edit, edit_arrays)
    _refused(path, expected, "at states of its own scales" if "force" in expected else "μ_q ± s_q")
    # every field is finite and within its table (the file's own checks pass): only the forward pass at states of
    # its own scales finds the forces that are not
    q, qd, _, fc, fn = _probe_forces(read_model_file(path))
    named = next((f for key, f in (("f_c", fc), ("f_n", fn)) if key in expected), np.r_[q.ravel(), qd.ravel()])
    assert not np.isfinite(named).all(), case  # what the message names is what is not finite


def _probe_forces(mf):
    """(q, q̇, t, f_c, f_n) of a checked model file at nnphd.api.PROBE_STATES (q = μ_q + a·s_q, q̇ = b·s_q/s_t,
    t = t₀ + a·s_t), computed here from its parts: the LNN's acceleration in the file's units, the law's basis times
    its coefficients (zeros without a law)."""
    import jax
    import jax.numpy as jnp

    from nnphd.engine.models import lnn_accel

    sc, (a, b) = mf.meta["scaling"], np.asarray(nnphd.api.PROBE_STATES).T
    mu, s_q, t0, s_t = (np.asarray(sc[k], float) for k in ("mu_q", "s_q", "t0", "s_t"))
    with np.errstate(all="ignore"), jax.enable_x64(True):
        q, qd, t = mu + a[:, None] * s_q, b[:, None] * s_q / s_t, t0 + a * s_t
        lnn = jax.tree_util.tree_unflatten(mf.treedef, [jnp.asarray(x) for x in mf.leaves])
        fc = np.asarray(lnn_accel(lnn, jnp.asarray((q - mu) / s_q), jnp.asarray(qd * s_t / s_q), mf.cfg))
        fc = fc * s_q / s_t**2
        fn = np.zeros_like(q)
        if mf.family is not None:
            fn = np.einsum("snk,k->sn", mf.family.basis(np, mf.theta, q, qd, t), mf.beta)
            if mf.family.fixed is not None:
                fn = fn + mf.family.fixed(np, mf.theta, q, qd, t)
    return q, qd, t, fc, fn


def test_a_model_of_far_but_sane_scales_passes_the_forward_pass(model_parts, tmp_path):
    path = _model(model_parts, tmp_path / "ok.npz", _scaled(mu_q=[1e6], s_q=[1e-3], s_t=1e3))
    m = nnphd.load(path)
    fc, fn = m.forces([1e6 + 1e-3], [1e-6])
    assert np.isfinite(fc).all() and (fn == 0).all()
    q, qd, t, fc, fn = _probe_forces(read_model_file(path))  # the probe's forces are forces()'s own
    np.testing.assert_allclose(m.forces(q, qd, t)[0], fc, rtol=1e-12)
    assert np.isfinite(fc).all() and (fn == 0).all()


def test_a_declared_field_and_a_law_pass_the_forward_pass(model_parts, tmp_path):
    """The forward pass runs what forces() runs: a declared field's fitted acceleration instead of the network, the
    law beside it."""
    field = {"law": "uniform", "g": {"x": -9.8}, "stderr": {"x": 0.1}, "coefficients": [9.8], "center": None}
    law = {"spec": {"kind": "user", "text": "-c*x_dot"}, "beta": [0.25], "theta": []}

    def edit(meta):
        meta.update(field=field, law=law)
        meta["settings"]["field"] = "uniform"

    m = nnphd.load(_model(model_parts, tmp_path / "f.npz", edit))
    fc, fn = m.forces([0.5, 1.0], [0.1, -0.2])
    np.testing.assert_allclose(fc[:, 0], 9.8, rtol=1e-12)  # the field's coefficient, whatever the network says
    np.testing.assert_allclose(fn[:, 0], [-0.025, 0.05], rtol=1e-12)


# ---- nnphd.read_report: a FIFO or a device is refused at once ------------------------------------------------------
_READ_REPORTS = r"""
import sys
import nnphd
for p in sys.argv[1:]:
    try:
        nnphd.read_report(p)
        print("read")
    except ValueError as e:
        print(str(e).replace("\n", "\\n"))
"""


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs FIFOs")
def test_read_report_refuses_a_fifo_and_a_device_without_blocking(tmp_path):
    """Before: ``open()`` of a FIFO waited for a writer, forever; a link to /dev/zero read 256 MB. Now each is
    refused from ``fstat`` of a non-blocking descriptor. (In a fresh process: were it to block, the timeout ends
    it and the test fails, rather than hanging the suite.)"""
    fifo = tmp_path / "report.json"
    os.mkfifo(fifo)
    paths = [fifo]
    if os.path.exists("/dev/zero"):
        (tmp_path / "zero.json").symlink_to("/dev/zero")
        paths.append(tmp_path / "zero.json")
    res = subprocess.run(
        [sys.executable, "-c", _READ_REPORTS, *map(str, paths)], capture_output=True, text=True, timeout=120
    )
    assert res.returncode == 0, res.stderr[-2000:]
    lines = res.stdout.strip().splitlines()
    assert len(lines) == len(paths), lines
    for p, line in zip(paths, lines):
        assert line == f"{p}: not a readable report.json (not a regular file)", line


def test_read_report_still_reads_a_report(tmp_path):
    path = tmp_path / "report.json"
    path.write_text(json.dumps({**REPORT, "statistic": {"value": 3.0}}))
    assert nnphd.read_report(path).status == "detected"


@pytest.mark.parametrize(
    "kw,name",
    [
        ({"seed": -1}, "seed"),
        ({"steps": 2**31}, "steps"),
        ({"n_seeds": 1000}, "n_seeds"),
        ({"sr_time": 1e300}, "sr_time"),
        ({"sr_time": float("nan")}, "sr_time"),
    ],  # fmt: skip
)
def test_nnphd_takes_the_ranges_a_model_file_must_keep(kw, name):
    """What NNPhD accepts, save() writes and load() reads back: the same ranges as the command line's options."""
    with pytest.raises(ValueError, match=f"^{name} must be between"):
        nnphd.NNPhD(**kw)


def test_the_command_line_bounds_repeats_and_sr_time(tmp_path, capsys):
    from nnphd.cli import main
    from nnphd.io.limits import MAX_N_SEEDS, MAX_SR_TIME

    data = tmp_path / "a.csv"
    data.write_text("t,x\n0,1\n")
    for opt, value in (("--n-seeds", MAX_N_SEEDS + 1), ("--sr-time", MAX_SR_TIME + 1)):
        assert main(["detect", str(data), "--out", str(tmp_path / "o"), opt, str(value)]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and opt in err, err
