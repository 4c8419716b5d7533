"""io/: the one cache (settings-keyed JSON, NPZ checkpoints, never pickle) and the one progress interface."""

import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from nnphd.io.cache import Cache, IgnoredFileWarning, fingerprint, load_npz, save_npz
from nnphd.io.progress import Stages


def test_fingerprint_ignores_key_order_and_tuples():
    assert fingerprint({"a": 1, "b": (1, 2)}) == fingerprint({"b": [1, 2], "a": 1})
    assert fingerprint({"a": 1}) != fingerprint({"a": 2})


def test_result_cache_is_keyed_by_settings(tmp_path):
    c = Cache(tmp_path, {"seed": 0, "steps": 10})
    assert c.load() is None
    saved = c.save({"x": np.float64(1.5), "v": np.arange(3)})
    assert saved["x"] == 1.5 and saved["v"] == [0, 1, 2]
    assert Cache(tmp_path, {"steps": 10, "seed": 0}).load() == saved
    assert Cache(tmp_path, {"seed": 1, "steps": 10}).load() is None  # other settings: not used
    (tmp_path / "results.json").write_text("{not json")
    with pytest.warns(IgnoredFileWarning, match="not valid JSON"):
        assert c.load() is None  # unreadable: treated as absent, with a warning
    (tmp_path / "results.json").write_text("[1]")
    with pytest.warns(IgnoredFileWarning, match="not a JSON object"):
        assert c.load() is None  # valid JSON but not a result: absent, no crash


def test_checkpoint_round_trip_without_pickle(tmp_path):
    tree = [{"w": jnp.arange(6.0).reshape(2, 3), "b": jnp.zeros(3)}, {"w": jnp.ones((3, 1)), "b": jnp.ones(1)}]
    c = Cache(tmp_path, {"k": 1})
    c.checkpoint({0.5: ({"L_e": 0.25}, tree), 2.0: ({"L_e": 0.75}, jax.tree_util.tree_map(lambda a: a + 1, tree))})
    back = c.restore(tree)
    assert sorted(back) == [0.5, 2.0] and back[2.0][0] == {"L_e": 0.75}
    np.testing.assert_array_equal(back[2.0][1][0]["w"], np.arange(6.0).reshape(2, 3) + 1)
    with np.load(tmp_path / Cache.CHECKPOINT, allow_pickle=False) as z:  # plain arrays and a JSON string
        assert json.loads(str(z["__meta__"]))["fingerprint"] == c.fingerprint
    assert Cache(tmp_path, {"k": 2}).restore(tree) == {}  # other settings
    with pytest.warns(IgnoredFileWarning, match=r"has shape \(2, 3\), expected \(2, 2\)"):
        assert c.restore([{"w": jnp.zeros((2, 2)), "b": jnp.zeros(3)}, tree[1]]) == {}  # other shapes
    c.clear_checkpoint()
    assert not (tmp_path / Cache.CHECKPOINT).exists() and c.restore(tree) == {}


def test_npz_rejects_a_foreign_file(tmp_path):
    np.savez(tmp_path / "x.npz", a=np.ones(2))
    with pytest.raises(ValueError, match="not an nnphd .npz file"):
        load_npz(tmp_path / "x.npz")
    save_npz(tmp_path / "y.npz", {"a": [1, 2]}, {"z": np.eye(2)})
    meta, arrays = load_npz(tmp_path / "y.npz")
    assert meta == {"a": [1, 2]} and np.array_equal(arrays["z"], np.eye(2))


def test_stages_count_up_to_the_total():
    calls = []
    say = Stages(lambda d, t, m: calls.append((d, t, m)), 3, prefix="job: ")
    for m in ("read", "fit", "write", "extra"):
        say(m)
    assert calls == [(0, 3, "job: read"), (1, 3, "job: fit"), (2, 3, "job: write"), (3, 3, "job: extra")]
    Stages(None, 2)("nothing happens")
