"""The one cache and checkpoint mechanism: results keyed by their settings, arrays in NPZ + JSON (never pickle).

* :func:`fingerprint` — a short hash of a settings dict (JSON-normalised, key order ignored).
* :class:`Cache` — a directory whose results are valid for one settings dict: ``load(name)`` returns a JSON result
  only when it was saved under the same settings; ``save(name, obj)`` writes it atomically with the fingerprint.
  ``checkpoint``/``restore`` keep the finished steps of a long run (a dict of step → JSON metadata + a pytree of
  arrays) in one .npz, so a run that is stopped resumes where it was.
* :func:`save_npz` / :func:`load_npz` — JSON metadata and named arrays in one .npz (``allow_pickle=False``), used
  by the checkpoints and by saved models.

Nothing read back is trusted beyond data: a file that does not parse, or that was written under other settings, is
ignored (treated as absent), never executed.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
from pathlib import Path

import numpy as np

from nnphd.io.results import _json_default, atomic_write_bytes, write_json


def normalise(obj):
    """``obj`` as it reads back from JSON (tuples → lists, numpy scalars → numbers)."""
    return json.loads(json.dumps(obj, default=_json_default))


def fingerprint(settings: dict) -> str:
    return hashlib.sha256(json.dumps(normalise(settings), sort_keys=True).encode()).hexdigest()[:16]


def save_npz(path: str | os.PathLike, meta: dict, arrays: dict[str, np.ndarray]) -> None:
    """``meta`` (JSON) and ``arrays`` in one .npz, written atomically."""
    buf = io.BytesIO()
    np.savez(
        buf, __meta__=np.array(json.dumps(meta, default=_json_default)), **{k: np.asarray(v) for k, v in arrays.items()}
    )
    atomic_write_bytes(path, buf.getvalue())


def load_npz(path: str | os.PathLike) -> tuple[dict, dict[str, np.ndarray]]:
    """(meta, arrays) of a file written by :func:`save_npz`; ValueError if it is not one."""
    try:
        with np.load(path, allow_pickle=False) as z:
            meta = json.loads(str(z["__meta__"]))
            arrays = {k: np.asarray(z[k]) for k in z.files if k != "__meta__"}
    except (OSError, KeyError, ValueError, EOFError) as e:
        raise ValueError(f"{path}: not an nnphd .npz file ({e.__class__.__name__}: {e})") from None
    return meta, arrays


def tree_arrays(tree, prefix: str = "") -> dict[str, np.ndarray]:
    """The leaves of a pytree as named numpy arrays (in ``jax.tree_util`` order)."""
    import jax

    return {f"{prefix}{i}": np.asarray(x) for i, x in enumerate(jax.tree_util.tree_leaves(tree))}


def tree_from_arrays(like, arrays: dict[str, np.ndarray], prefix: str = ""):
    """The pytree of the structure of ``like`` from :func:`tree_arrays`' output (ValueError if the leaves do not
    match ``like``'s count and shapes)."""
    import jax
    import jax.numpy as jnp

    leaves, treedef = jax.tree_util.tree_flatten(like)
    try:
        new = [arrays[f"{prefix}{i}"] for i in range(len(leaves))]
    except KeyError as e:
        raise ValueError(f"missing array {e}") from None
    if any(np.shape(a) != np.shape(b) for a, b in zip(new, leaves)):
        raise ValueError("array shapes do not match the model")
    return jax.tree_util.tree_unflatten(treedef, [jnp.asarray(a, dtype=b.dtype) for a, b in zip(new, leaves)])


class Cache:
    """Results in ``directory`` that are valid for exactly ``settings`` (see the module docstring)."""

    CHECKPOINT = ".checkpoint.npz"

    def __init__(self, directory: str | os.PathLike | None, settings: dict):
        self.dir = Path(directory) if directory is not None else None
        self.settings = normalise(settings)
        self.fingerprint = fingerprint(self.settings)

    def load(self, name: str = "results.json") -> dict | None:
        """The result saved as ``name`` under the same settings, or None."""
        if self.dir is None:
            return None
        try:
            res = json.loads((self.dir / name).read_text())
        except (OSError, ValueError):
            return None
        return res if isinstance(res, dict) and res.get("fingerprint") == self.fingerprint else None

    def save(self, obj: dict, name: str = "results.json") -> dict:
        """Write ``obj`` with the fingerprint (atomically); return it as it reads back."""
        obj = normalise({**obj, "fingerprint": self.fingerprint})
        if self.dir is not None:
            write_json(self.dir / name, obj)
        return obj

    def checkpoint(self, steps: dict[float, tuple[dict, object]]) -> None:
        """Save finished steps: key (a number) → (JSON metadata, pytree of arrays)."""
        if self.dir is None:
            return
        meta = {"fingerprint": self.fingerprint, "steps": [[k, m] for k, (m, _) in steps.items()]}
        arrays = {}
        for i, (_, tree) in enumerate(steps.values()):
            arrays.update(tree_arrays(tree, f"s{i}_"))
        save_npz(self.dir / self.CHECKPOINT, meta, arrays)

    def restore(self, like) -> dict[float, tuple[dict, object]]:
        """The steps saved by :meth:`checkpoint` under the same settings (pytrees shaped as ``like``); {} if none."""
        if self.dir is None or not (self.dir / self.CHECKPOINT).exists():
            return {}
        try:
            meta, arrays = load_npz(self.dir / self.CHECKPOINT)
            if meta.get("fingerprint") != self.fingerprint:
                return {}
            return {float(k): (m, tree_from_arrays(like, arrays, f"s{i}_")) for i, (k, m) in enumerate(meta["steps"])}
        except (ValueError, KeyError, TypeError):
            return {}

    def clear_checkpoint(self) -> None:
        if self.dir is not None and (self.dir / self.CHECKPOINT).exists():
            (self.dir / self.CHECKPOINT).unlink()
