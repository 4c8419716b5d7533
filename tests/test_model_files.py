"""Model files and checkpoints are untrusted input: ``nnphd.load`` checks the whole file and refuses a bad
one with one ValueError line naming the path and the problem (never another exception, never executing a planted
law); a damaged, foreign or non-finite checkpoint or cached result is ignored with one warning line and the run
starts from scratch."""

from __future__ import annotations

import io
import json
import os
import re
import warnings
import zipfile
from dataclasses import fields

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import nnphd
from nnphd.api import NNPhD
from nnphd.engine.models import ModelConfig, lnn_accel
from nnphd.io import cache as cache_mod
from nnphd.io.cache import Cache, IgnoredFileWarning
from nnphd.user import modelfile
from tests.fixtures.modelfiles import CFG, tiny_lnn, tiny_model

REPORT = {
    "status": "detected",
    "new_physics": True,
    "confidence": 1.0,
    "reasons": ["a test model"],
    "statistic": {"value": 3.0},
    "law": None,
}
Q, QD = np.array([0.5, -1.0]), np.array([0.1, 0.3])


@pytest.fixture(scope="module")
def model_file(tmp_path_factory):
    """A valid model file (a small untrained LNN, no law: built, not fitted), loaded with nnphd.load and saved again
    with NNPhD.save, and the network's own acceleration at (Q, QD) (unit scaling: the data's units are the
    network's)."""
    d = tmp_path_factory.mktemp("model")
    path = tiny_model(REPORT, d / "written.npz").save(d / "m.npz")
    with jax.enable_x64(True):
        fc = lnn_accel(tiny_lnn(), jnp.asarray(Q[:, None]), jnp.asarray(QD[:, None]), CFG)
    return path, np.asarray(fc)


def _parts(path):
    with np.load(path, allow_pickle=False) as z:
        return json.loads(str(z["meta"])), {k: np.asarray(z[k]) for k in z.files if k != "meta"}


def _write(path, meta, arrays, meta_text=None):
    np.savez(path, meta=np.array(meta_text if meta_text is not None else json.dumps(meta)), **arrays)
    return path


def _variant(model_file, tmp_path, edit_meta=None, edit_arrays=None, name="v.npz"):
    meta, arrays = _parts(model_file[0])
    if edit_meta:
        edit_meta(meta)
    if edit_arrays:
        edit_arrays(arrays)
    return _write(tmp_path / name, meta, arrays)


def _refused(path, *expected: str) -> str:
    with pytest.raises(ValueError) as e:
        nnphd.load(path)
    msg = str(e.value)
    assert "\n" not in msg and str(path) in msg, msg
    for x in expected:
        assert x in msg, msg
    return msg


def _set(keys, value):
    def edit(meta):
        d = meta
        for k in keys[:-1]:
            d = d[k]
        d[keys[-1]] = value

    return edit


def test_valid_files_load_and_give_the_saved_forces(model_file, tmp_path):
    path, fc = model_file
    loaded = nnphd.load(path)
    np.testing.assert_allclose(loaded.forces(Q, QD)[0], fc, rtol=1e-12)
    assert loaded.status_ == "detected" and loaded.law_ is None and loaded.names_ == ("x",)
    law = {"spec": {"kind": "user", "text": "-c*x_dot"}, "beta": [0.25], "theta": []}
    with_law = nnphd.load(_variant(model_file, tmp_path, _set(["law"], law)))
    np.testing.assert_allclose(with_law.forces(Q, QD)[1], -0.25 * QD[:, None], rtol=1e-12)
    # a built-in dry law: the tanh sign it names, or (a file saved before it named one) the algebraic sign
    dry = {"spec": {"kind": "builtin", "key": "coulomb", "v_rms": [0.5], "sign": "tanh"}, "beta": [2.0], "theta": []}
    eps = 0.02 * 0.5
    tanh_law = nnphd.load(_variant(model_file, tmp_path, _set(["law"], dry), name="t.npz"))
    np.testing.assert_allclose(tanh_law.forces(Q, QD)[1][:, 0], -2.0 * np.tanh(QD / eps), rtol=1e-12)
    dry["spec"].pop("sign")
    old = nnphd.load(_variant(model_file, tmp_path, _set(["law"], dry), name="o.npz"))
    np.testing.assert_allclose(old.forces(Q, QD)[1][:, 0], -2.0 * QD / np.sqrt(QD**2 + eps**2), rtol=1e-12)


def test_the_strategy_objects_survive_save_and_load(model_file, tmp_path):
    """A model with a non-default derivative method and a restricted law library loads with both (a default one
    writes neither, so its file is what it always was)."""
    path, _ = model_file
    assert {"derivative_method", "families", "thin"}.isdisjoint(_parts(path)[0]["settings"])
    m = nnphd.load(path)
    assert m.derivatives.thin is True
    m.derivatives = nnphd.Derivatives(method="spline", trim=m.derivatives.trim, thin=False)
    m.library = nnphd.LawLibrary(families=("linear", "coulomb"), laws=m.library.laws, fit=m.library.fit)
    again = nnphd.load(m.save(tmp_path / "s.npz"))
    assert again.derivatives.method == "spline" and again.library.families == ("linear", "coulomb")
    assert again.derivatives.thin is False
    assert _refused(_variant(model_file, tmp_path, _set(["settings", "families"], ["warp"])), "warp")
    assert _refused(_variant(model_file, tmp_path, _set(["settings", "thin"], "no")), "thin")


def test_the_cfg_table_names_every_model_config_field():
    assert set(modelfile.CFG) == {f.name for f in fields(ModelConfig)}


def _truncate(p):
    p.write_bytes(p.read_bytes()[: len(p.read_bytes()) // 2])


def _deep(meta):
    meta["report"]["deep"] = "@"


CASES = {  # name → (edit_meta, edit_arrays, what the message says)
    "wrong weight shape": (
        None,
        lambda a: a.update(lnn_1=np.zeros((3, 4))),
        "weight lnn_1 has shape (3, 4), expected (2, 4)",
    ),
    "NaN weight": (None, lambda a: a["lnn_3"].__setitem__((1, 2), np.nan), "weight lnn_3 has non-finite values"),
    "float32 weight": (None, lambda a: a.update(lnn_2=a["lnn_2"].astype(np.float32)), "weight lnn_2 has dtype float32"),
    "missing weight": (None, lambda a: a.pop("lnn_3"), "weight lnn_3 is missing"),
    "extra array": (None, lambda a: a.update(x=np.zeros(2)), "unexpected array 'x'"),
    "n_leaves": (_set(["n_leaves"], 3), None, "meta.n_leaves is 3, expected"),
    "zero scale": (_set(["scaling", "s_q"], [0.0]), None, "meta.scaling.s_q[0] is 0.0, expected a positive number"),
    "negative s_t": (_set(["scaling", "s_t"], -1.0), None, "meta.scaling.s_t is -1.0, expected a positive number"),
    "NaN s_t": (_set(["scaling", "s_t"], float("nan")), None, "meta.scaling.s_t is nan"),
    "NaN mu": (_set(["scaling", "mu_q"], [float("inf")]), None, "meta.scaling.mu_q[0] is inf, expected a finite"),
    "scaling length": (_set(["scaling", "mu_q"], [0.0, 1.0]), None, "meta.scaling.mu_q has 2 entries, expected 1"),
    "unknown cfg key": (_set(["cfg", "evil"], 1), None, "meta.cfg has an unknown field 'evil'"),
    "cfg type": (_set(["cfg", "lnn_widths"], "44"), None, "meta.cfg.lnn_widths is str, expected a list"),
    "cfg value": (_set(["cfg", "lnn_activation"], "nope"), None, "meta.cfg:"),
    "cfg n": (_set(["cfg", "n"], 2), None, "meta.cfg.n is 2, expected 1"),
    "format": (_set(["format"], "other"), None, "meta.format is 'other', expected 'nnphd-model'"),
    "version": (_set(["version"], True), None, "meta.version is True, expected 1"),
    "names repeat": (_set(["names"], ["x", "x"]), None, "meta.names must be distinct"),
    "empty name": (_set(["names"], [""]), None, "meta.names[0] is '', expected a non-empty string"),
    "angles": (_set(["angles"], [1]), None, "meta.angles[0] is 1, expected true or false"),
    "angles length": (_set(["angles"], [False, True]), None, "meta.angles has 2 entries, expected 1"),
    "report": (_set(["report"], [1]), None, "meta.report is list, expected an object"),
    "report status": (lambda m: m["report"].pop("status"), None, "meta.report has no field 'status'"),
    "settings": (_set(["settings", "steps"], "many"), None, "meta.settings.steps is 'many'"),
    "law kind": (_set(["law"], {"spec": {"kind": "pickle"}, "beta": [], "theta": []}), None, "meta.law.spec.kind"),
    "law sizes": (
        _set(["law"], {"spec": {"kind": "user", "text": "-c*x_dot"}, "beta": [1.0, 2.0], "theta": []}),
        None,
        "meta.law.beta has 2 values, expected 1",
    ),
    "law NaN": (
        _set(["law"], {"spec": {"kind": "user", "text": "-c*x_dot"}, "beta": [float("nan")], "theta": []}),
        None,
        "meta.law.beta[0] is nan",
    ),
    "law not a dict": (_set(["law"], "c*x_dot"), None, "meta.law is str, expected an object"),
    "law sign": (
        _set(
            ["law"],
            {"spec": {"kind": "builtin", "key": "coulomb", "v_rms": [1.0], "sign": "erf"}, "beta": [1.0], "theta": []},
        ),
        None,
        "meta.law.spec.sign",
    ),
    "sparse support": (
        _set(["law"], {"spec": {"kind": "sparse", "support": [[True]]}, "beta": [1.0], "theta": []}),
        None,
        "meta.law.spec.support is not a 1 × 4 table",
    ),
}


@pytest.mark.parametrize("case", list(CASES))
def test_a_bad_field_is_named_in_one_line(model_file, tmp_path, case):
    edit_meta, edit_arrays, expected = CASES[case]
    _refused(_variant(model_file, tmp_path, edit_meta, edit_arrays), "not a valid nnphd model file", expected)


def test_damaged_foreign_and_odd_files_are_refused_in_one_line(model_file, tmp_path, monkeypatch):
    meta, arrays = _parts(model_file[0])
    good = model_file[0].read_bytes()
    cases = {
        "truncated.npz": (good[: len(good) // 2], "not a valid .npz archive"),
        "empty.npz": (b"", "not a valid .npz archive"),
        "text.npz": (b"hello", "not a valid .npz archive"),
    }
    for name, (data, expected) in cases.items():
        (tmp_path / name).write_bytes(data)
        _refused(tmp_path / name, expected)
    _refused(tmp_path / "absent.npz", "no such file")
    (tmp_path / "dir.npz").mkdir()
    _refused(tmp_path / "dir.npz", "not a regular file")
    os.mkfifo(tmp_path / "fifo.npz")  # refused without blocking on it
    _refused(tmp_path / "fifo.npz", "not a regular file")
    np.savez(tmp_path / "nometa.npz", **arrays)
    _refused(tmp_path / "nometa.npz", "no 'meta' entry")
    np.savez(tmp_path / "pickled.npz", meta=np.array(json.dumps(meta)), lnn_0=np.array([{"a": 1}], dtype=object))
    _refused(tmp_path / "pickled.npz", "array 'lnn_0' has dtype object, not plain numbers")
    _refused(_write(tmp_path / "badjson.npz", meta, arrays, "{meta"), "not valid JSON")
    _refused(_write(tmp_path / "list.npz", meta, arrays, "[1]"), "meta is list, expected an object")
    deep = json.dumps(meta).replace('"reasons":', '"deep": ' + "[" * 100_000 + "]" * 100_000 + ', "reasons":')
    _refused(_write(tmp_path / "deep.npz", meta, arrays, deep), "JSON nested more than 64 levels deep")
    deep70 = json.dumps(meta).replace('"reasons":', '"deep": ' + "[" * 70 + "]" * 70 + ', "reasons":')
    _refused(_write(tmp_path / "deep70.npz", meta, arrays, deep70), "JSON nested more than 64 levels deep")
    monkeypatch.setattr(modelfile, "MAX_MODEL_BYTES", 1000)
    _refused(model_file[0], f"{len(good)} bytes, more than the limit of 1000")


def test_a_zip_bomb_and_a_lying_header_are_refused_before_reading(model_file, tmp_path, monkeypatch):
    meta, arrays = _parts(model_file[0])
    buf = io.BytesIO()
    np.save(buf, np.zeros(4, np.float64))
    header = buf.getvalue()[:-32].replace(b"(4,)", b"(9999999999,)")  # claims 80 GB, holds nothing
    with zipfile.ZipFile(tmp_path / "lie.npz", "w") as zf:
        zf.writestr("meta.npy", _npy(np.array(json.dumps(meta))))
        zf.writestr("lnn_0.npy", header)
    _refused(tmp_path / "lie.npz", "does not match its size")
    monkeypatch.setattr(modelfile, "MAX_MODEL_BYTES", 1 << 20)  # as the real limit, at a test's size
    with zipfile.ZipFile(tmp_path / "bomb.npz", "w", compression=zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("meta.npy", _npy(np.array(json.dumps(meta))))
        zf.writestr("lnn_0.npy", b"\0" * (8 << 20))  # 8 MB uncompressed, 8 kB in the file
    assert (tmp_path / "bomb.npz").stat().st_size < 1 << 15
    _refused(tmp_path / "bomb.npz", "more than 1048576 bytes uncompressed")


def _npy(a):
    buf = io.BytesIO()
    np.save(buf, a)
    return buf.getvalue()


def test_a_planted_law_is_not_executed(model_file, tmp_path):
    marker = tmp_path / "MARKER"
    text = f"__import__('os').system('touch {marker}') + c*x_dot"
    law = {"spec": {"kind": "user", "text": text}, "beta": [1.0], "theta": []}
    path = _variant(model_file, tmp_path, _set(["law"], law))
    _refused(path, "not a valid nnphd model file", "meta.law")
    assert not marker.exists()
    # the laws of its settings too (a refit would parse them): refused on load, not only later
    path = _variant(model_file, tmp_path, _set(["settings", "laws"], [text]), name="s.npz")
    _refused(path, "meta.settings.laws[0]", "attribute access")
    assert not marker.exists()


def test_a_law_given_as_one_string_is_one_law():
    assert NNPhD(laws="c*x_dot*abs(x_dot)").laws == ("c*x_dot*abs(x_dot)",)


FUZZ = settings(max_examples=50, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


@FUZZ
@given(data=st.data())
def test_random_damage_gives_a_valid_load_or_one_line(model_file, tmp_path, data):
    """Bytes changed anywhere (headers, central directory, arrays, JSON), or the file cut short."""
    good = bytearray(model_file[0].read_bytes())
    if data.draw(st.booleans()):
        for _ in range(data.draw(st.integers(1, 4))):
            good[data.draw(st.integers(0, len(good) - 1))] = data.draw(st.integers(0, 255))
    else:
        good = good[: data.draw(st.integers(0, len(good) - 1))]
    _load_or_one_line(tmp_path / "damaged.npz", bytes(good))


JSON = st.recursive(
    st.none() | st.booleans() | st.integers(-5, 100) | st.floats(-1e3, 1e3) | st.sampled_from([float("nan"), "x", ""]),
    lambda c: st.lists(c, max_size=3) | st.dictionaries(st.sampled_from(["kind", "text", "a", "n"]), c, max_size=3),
    max_leaves=5,
)


def _paths(o, at=()):
    yield at
    items = o.items() if isinstance(o, dict) else enumerate(o) if isinstance(o, list) else ()
    for k, v in items:
        yield from _paths(v, (*at, k))


@FUZZ
@given(data=st.data())
def test_random_metadata_gives_a_valid_load_or_one_line(model_file, tmp_path, data):
    """A field anywhere in the metadata replaced by another JSON value or removed (in a well-formed .npz)."""
    meta, arrays = _parts(model_file[0])
    at = data.draw(st.sampled_from(list(_paths(meta))[1:]))
    parent = meta
    for k in at[:-1]:
        parent = parent[k]
    if data.draw(st.booleans()) and isinstance(parent, dict):
        del parent[at[-1]]
    else:
        parent[at[-1]] = data.draw(JSON)
    buf = io.BytesIO()
    np.savez(buf, meta=np.array(json.dumps(meta)), **arrays)
    _load_or_one_line(tmp_path / "fuzzed.npz", buf.getvalue())


def _load_or_one_line(path, data: bytes):
    path.write_bytes(data)
    try:
        loaded = nnphd.load(path)
    except ValueError as e:
        assert "\n" not in str(e) and str(path) in str(e), str(e)
    else:
        assert np.isfinite(loaded.forces(Q, QD)[0]).all()


# ------------------------------------------------------------------------------------------------------------------
# checkpoints and cached results

LIKE = [{"w": jnp.arange(6.0).reshape(2, 3), "b": jnp.zeros(3)}, {"w": jnp.ones((3, 1)), "b": jnp.ones(1)}]
KEYS = (0.5, 1.0, 2.0)


def _run(directory, stop_after=None, build=None):
    """A resumable toy run: step k's pytree is LIKE + k, checkpointed after each step; ``stop_after`` steps: the
    run is interrupted. Returns (steps done, how many were restored)."""
    directory.mkdir(exist_ok=True)
    cache = Cache(directory, {"run": "toy"})
    done = cache.restore(LIKE, build=build)
    restored = len(done)
    for k in KEYS[: stop_after or len(KEYS)]:
        if k not in done:
            tree = jax.tree_util.tree_map(lambda a, k=k: a + k, LIKE)
            done[k] = ({"L_e": k / 4}, tree) if build is None else build(k, {"L_e": k / 4}, tree)
            cache.checkpoint(done if build is None else {k: (v[0], v[1]) for k, v in done.items()})
    return done, restored


def _same(a, b):
    assert sorted(a) == sorted(b)
    for k in a:
        assert a[k][0] == b[k][0]
        jax.tree_util.tree_map(np.testing.assert_array_equal, a[k][1], b[k][1])


def _ckpt_edits():
    def meta_edit(f):
        def edit(d):
            with np.load(d / Cache.CHECKPOINT, allow_pickle=False) as z:
                meta, arrays = json.loads(str(z["__meta__"])), {k: z[k] for k in z.files if k != "__meta__"}
            f(meta)
            np.savez(d / Cache.CHECKPOINT, __meta__=np.array(json.dumps(meta)), **arrays)

        return edit

    def nan(d):
        with np.load(d / Cache.CHECKPOINT, allow_pickle=False) as z:
            arrays = {k: np.array(z[k]) for k in z.files}
        arrays["s0_1"][0, 0] = np.nan
        np.savez(d / Cache.CHECKPOINT, **arrays)

    def truncate(d):
        _truncate(d / Cache.CHECKPOINT)

    return {
        "truncated": (truncate, "not a valid .npz archive"),
        "empty": (lambda d: (d / Cache.CHECKPOINT).write_bytes(b""), "not a valid .npz archive"),
        "NaN weights": (nan, "array 's0_1' has non-finite values"),
        "steps not a list": (meta_edit(lambda m: m.update(steps={"0.5": 1})), "not a checkpoint's metadata"),
        "step keys": (meta_edit(lambda m: m.update(steps=[["a", {}]])), "a step is not [finite number, object]"),
        "nested metadata": (meta_edit(lambda m: m["steps"][0][1].update(x=[1])), "metadata values must be numbers"),
        "no fingerprint": (meta_edit(lambda m: m.pop("fingerprint")), "not a checkpoint's metadata"),
        "deep JSON": (meta_edit(lambda m: m.update(x=json.loads("[" * 500 + "]" * 500))), "nested more than 64"),
        "extra arrays": (meta_edit(lambda m: m["steps"].pop()), "its arrays are not 1 step(s) of 4 leaves"),
    }


@pytest.mark.parametrize("case", list(_ckpt_edits()))
def test_a_bad_checkpoint_is_ignored_with_a_warning_and_the_run_starts_afresh(tmp_path, case):
    edit, why = _ckpt_edits()[case]
    clean, _ = _run(tmp_path / "clean")
    d = tmp_path / "out"
    d.mkdir()
    _run(d, stop_after=2)  # interrupted after 2 steps: a valid checkpoint...
    edit(d)  # ...damaged
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        done, restored = _run(d)
    assert restored == 0
    _same(done, clean)
    _one_warning(caught, d / Cache.CHECKPOINT, why)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert _run(d)[1] == 3  # the run rewrote a valid checkpoint: used next time, without a warning


def test_a_checkpoint_that_is_not_a_regular_file_is_ignored(tmp_path):
    (tmp_path / Cache.CHECKPOINT).mkdir()
    os.mkfifo(tmp_path / "fifo")
    (tmp_path / "link").symlink_to(tmp_path / "fifo")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert Cache(tmp_path, {"run": "toy"}).restore(LIKE) == {}
    _one_warning(caught, tmp_path / Cache.CHECKPOINT, "not a regular file")
    (tmp_path / Cache.CHECKPOINT).rmdir()
    (tmp_path / "link").rename(tmp_path / Cache.CHECKPOINT)  # a link to a FIFO: refused without blocking
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert Cache(tmp_path, {"run": "toy"}).restore(LIKE) == {}
    _one_warning(caught, tmp_path / Cache.CHECKPOINT, "not a regular file")


def test_metadata_the_caller_refuses_is_ignored_too(tmp_path):
    def build(k, m, tree):
        if set(m) != {"L_e"}:
            raise TypeError(f"unexpected fields {sorted(m)}")
        return m, tree

    _run(tmp_path, stop_after=2)
    Cache(tmp_path, {"run": "toy"}).checkpoint({1.0: ({"L_e": 1.0, "evil": 2.0}, LIKE)})
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        done, restored = _run(tmp_path, build=build)
    assert restored == 0 and sorted(done) == list(KEYS)
    _one_warning(caught, tmp_path / Cache.CHECKPOINT, "unexpected fields ['L_e', 'evil']")


def test_a_valid_checkpoint_resumes_and_other_settings_are_silently_not_used(tmp_path):
    clean, _ = _run(tmp_path / "clean")
    _run(tmp_path, stop_after=2)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        done, restored = _run(tmp_path)
        assert restored == 2
        assert Cache(tmp_path, {"run": "other"}).restore(LIKE) == {}
    _same(done, clean)


def test_a_bad_cached_result_is_ignored_with_a_warning(tmp_path, monkeypatch):
    c = Cache(tmp_path, {"a": 1})
    path = tmp_path / "results.json"
    cases = {
        "{not json": "not valid JSON",
        "[1]": "not a JSON object",
        "[" * 100_000 + "]" * 100_000: "nested more than 64 levels deep",
        b"\xff\xfe": "not UTF-8",
    }
    for data, why in cases.items():
        path.write_bytes(data if isinstance(data, bytes) else data.encode())
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            assert c.load() is None
        _one_warning(caught, path, why)
    c.save({"x": 1})
    monkeypatch.setattr(cache_mod, "MAX_JSON_BYTES", 10)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert Cache(tmp_path, {"a": 1}).load() is None
    _one_warning(caught, path, "more than the limit of 10")


def _one_warning(caught, path, why):
    ours = [w for w in caught if issubclass(w.category, IgnoredFileWarning)]
    assert len(ours) == 1, [str(w.message) for w in caught]
    msg = str(ours[0].message)
    assert str(path) in msg and why in msg and "starting from scratch" in msg, msg
    shown = warnings.formatwarning(ours[0].message, ours[0].category, ours[0].filename, ours[0].lineno)
    assert shown.count("\n") == 1 and shown.endswith("\n"), shown  # what Python prints on stderr: one line


def test_a_sweep_checkpoint_of_another_layout_is_ignored(tmp_path):
    """The λ-sweep's checkpoint builder: a checkpoint with the sweep's fingerprint but other step metadata (the
    TypeError of SweepPoint(**m) before) or non-finite losses is refused, so restore ignores it with the warning."""
    from nnphd.paper.sweep import checkpointed_point

    good = {"L_e": 0.1, "L_b": 0.2, "L_e_train": 0.1, "L_b_train": 0.2, "m_c": None, "m_n": 0.9}
    assert checkpointed_point(0.5, good, None).L_b == 0.2
    for bad, why in (
        ({**good, "evil": 1.0}, "not the numbers of a λ-sweep point"),
        ({k: v for k, v in good.items() if k != "m_c"}, "not the numbers of a λ-sweep point"),
        ({**good, "L_e": float("nan")}, "L_e is nan, expected a finite number"),
        ({**good, "m_n": "0.9"}, "m_n is '0.9'"),
        ({**good, "L_b": True}, "L_b is True"),
    ):
        with pytest.raises(ValueError, match=re.escape(why)):
            checkpointed_point(0.5, bad, None)
    Cache(tmp_path, {"run": "toy"}).checkpoint({1.0: ({"L_e": 1.0}, LIKE)})
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert Cache(tmp_path, {"run": "toy"}).restore(LIKE, build=checkpointed_point) == {}
    _one_warning(caught, tmp_path / Cache.CHECKPOINT, "not the numbers of a λ-sweep point")
