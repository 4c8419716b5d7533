"""Programs traced and lowered once per machine (nnphd.engine.stored): exported beside the compilation cache, read
back by the next process with the same numbers; a damaged or foreign file is ignored and written again."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax import export

from nnphd.engine import stored


@pytest.fixture
def store(tmp_path, monkeypatch):
    # the folder beside a compilation cache of the test's own (the session's cache is not touched)
    monkeypatch.setattr(stored, "folder", lambda: tmp_path / stored.FOLDER)
    stored.clear_memo()
    yield tmp_path / stored.FOLDER
    stored.clear_memo()


def _f(x, params):
    w, b = params
    return jnp.tanh(x @ w + b).sum(axis=1), {"sq": x * x}


def _args(seed=0):
    r = np.random.default_rng(seed)
    return (jnp.asarray(r.normal(size=(5, 3))), (jnp.asarray(r.normal(size=(3, 4))), jnp.asarray(r.normal(size=4))))


def _exports(monkeypatch):
    calls = []
    real = export.export

    def counting(*a, **k):
        calls.append(1)
        return real(*a, **k)

    monkeypatch.setattr(export, "export", counting)
    return calls


def test_a_program_is_stored_once_and_read_back_by_the_next_process(store, monkeypatch):
    calls = _exports(monkeypatch)
    want = jax.jit(_f)(*_args())
    got = stored.run("f", _f, "test-f", _args())
    assert len(calls) == 1 and len(list(store.iterdir())) == 1
    stored.clear_memo()  # as a new process: the memo gone, the folder kept
    again = stored.run("f", _f, "test-f", _args(1))
    assert len(calls) == 1  # read, not exported again
    for a, b in zip(jax.tree_util.tree_leaves(got), jax.tree_util.tree_leaves(want)):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))  # the jitted program's numbers, bit for bit
    np.testing.assert_array_equal(np.asarray(again[1]["sq"]), np.asarray(_args(1)[0]) ** 2)
    stored.run("f", _f, "test-f", (jnp.ones((7, 3)), _args()[1]))  # another shape: another program
    assert len(calls) == 2 and len(list(store.iterdir())) == 2


def test_a_program_another_key_describes_is_another(store, monkeypatch):
    calls = _exports(monkeypatch)
    stored.run("f", _f, "test-f", _args())
    stored.run("f", lambda x, p: _f(2 * x, p), "test-f doubled", _args())
    assert len(calls) == 2 and len(list(store.iterdir())) == 2


@pytest.mark.parametrize("damage", ["garbage", "empty", "other shapes"])
def test_a_damaged_or_foreign_file_is_ignored_and_written_again(store, monkeypatch, damage):
    stored.run("f", _f, "test-f", _args())
    (path,) = store.iterdir()
    if damage == "garbage":
        path.write_bytes(b"\x00\xff not a program" * 100)
    elif damage == "empty":
        path.write_bytes(b"")
    else:  # a program of other inputs under this name
        path.write_bytes(export.export(jax.jit(_f))(jnp.ones((2, 3)), _args()[1]).serialize())
    stored.clear_memo()
    calls = _exports(monkeypatch)
    got = stored.run("f", _f, "test-f", _args())
    assert len(calls) == 1
    np.testing.assert_array_equal(np.asarray(got[0]), np.asarray(jax.jit(_f)(*_args())[0]))
    stored.clear_memo()
    stored.run("f", _f, "test-f", _args())
    assert len(calls) == 1  # the file written again is read


def test_without_a_key_or_a_cache_nothing_is_stored(store, monkeypatch):
    calls = _exports(monkeypatch)
    got = stored.run("f", _f, None, _args())
    assert calls == [] and not store.exists()
    np.testing.assert_array_equal(np.asarray(got[0]), np.asarray(jax.jit(_f)(*_args())[0]))
    monkeypatch.setattr(stored, "folder", lambda: None)  # no compilation cache
    stored.clear_memo()
    stored.run("f", _f, "test-f", _args())
    assert calls == [] and not store.exists()


def test_the_shooting_programs_of_a_described_model_are_the_plain_ones(store):
    # a right-hand side that says what it computes (export_key) runs the stored programs: the residuals and
    # derivatives of the plain compiled ones, bit for bit
    from nnphd.engine.shooting import Integrator, ShootingWindows, model_jac, model_residuals

    def rhs(theta, q, v, t, aux):
        return -theta[0] * jnp.sin(q) - theta[1] * v + aux * jnp.cos(t)[:, None]

    def described(theta, q, v, t, aux):
        return rhs(theta, q, v, t, aux)

    described.export_key = "test pendulum"
    W, L = 20, 9
    tw = np.tile(np.linspace(0.0, 0.8, L), (W, 1))
    r = np.random.default_rng(0)
    wins = ShootingWindows(jnp.asarray(tw), jnp.asarray(np.arange(W) * 0.5), jnp.asarray(r.normal(size=(W, L, 1))),
                           jnp.ones((W, L)), jnp.ones(1), None)  # fmt: skip
    s, theta, aux = r.normal(size=(W, 2)), np.array([4.0, 0.1]), jnp.asarray(0.3)
    for fn in (model_residuals, model_jac):
        a = np.asarray(fn(s, theta, aux, wins, Integrator(rhs, 2)))
        b = np.asarray(fn(s, theta, aux, wins, Integrator(described, 2)))
        assert np.abs(a).max() > 0.1
        np.testing.assert_array_equal(a, b)
    assert len(list(store.iterdir())) == 2  # the residuals' and the derivatives' programs (16 windows a call)


def test_the_folder_is_beside_the_compilation_cache(monkeypatch):
    from pathlib import Path

    cache = jax.config.jax_compilation_cache_dir  # the test session's (conftest: nnphd.configure)
    monkeypatch.delenv(stored.ENV, raising=False)
    assert cache and stored.folder() == Path(cache) / "nnphd-exported"
    for off in ("0", "off"):
        monkeypatch.setenv(stored.ENV, off)
        assert stored.folder() is None


def test_a_stored_program_under_a_transformation_is_the_jitted_one(store, monkeypatch):
    # a λ-sweep vmaps the trainer: under vmap (or grad) the call is jax.jit's, which transformations go through
    calls = _exports(monkeypatch)
    x, params = _args()
    xs = jnp.stack([x, 2 * x, -x])
    got = jax.vmap(lambda xi: stored.run("f", _f, "test-f", (xi, params))[0])(xs)
    want = jax.vmap(lambda xi: _f(xi, params)[0])(xs)
    np.testing.assert_allclose(np.asarray(got), np.asarray(want), rtol=1e-14)
    grad = jax.grad(lambda xi: stored.run("f", _f, "test-f", (xi, params))[0].sum())(x)
    np.testing.assert_allclose(
        np.asarray(grad), np.asarray(jax.grad(lambda xi: _f(xi, params)[0].sum())(x)), rtol=1e-14
    )
    assert calls == [] and not store.exists()
