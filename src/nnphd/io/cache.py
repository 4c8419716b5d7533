"""The one cache and checkpoint mechanism: results keyed by their settings, arrays in NPZ + JSON (never pickle).

* :func:`fingerprint` — a short hash of a settings dict (JSON-normalised, key order ignored).
* :class:`Cache` — a directory whose results are valid for one settings dict: ``load(name)`` returns a JSON result
  only when it was saved under the same settings; ``save(name, obj)`` writes it atomically with the fingerprint.
  ``checkpoint``/``restore`` keep the finished steps of a long run (a dict of step → JSON metadata + a pytree of
  arrays) in one .npz, so a run that is stopped resumes where it was.
* :func:`save_npz` / :func:`load_npz` — JSON metadata and named arrays in one .npz (``allow_pickle=False``), used
  by the checkpoints and by saved models.

A result or checkpoint carries an HMAC of its contents with a per-user key (:func:`sign`; the key is kept in the
user's cache folder, mode 600): one without a valid signature — planted in a shared or pre-created ``--out``, or
edited — is ignored with a warning and recomputed. :meth:`Cache.seal` extends that proof to result files written
beside a marker (their SHA-256 goes into the signed marker).

Nothing read back is trusted beyond data, and reading it costs bounded time and memory (:func:`read_npz`,
:func:`read_json`: a regular file, a size limit, JSON of bounded size and nesting, plain numeric arrays only). A file
written under other settings is not used; a damaged, foreign or non-finite one is ignored with one
:class:`IgnoredFileWarning` line naming it and why, and the run starts from scratch: never an exception, never
executed, never NaN weights.
"""

from __future__ import annotations

import hashlib
import io
import json
import math
import os
import stat
import struct
import tempfile
import warnings
import zipfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from nnphd.io.results import atomic_write_bytes, json_default, write_json

# ------------------------------------------------------------------------------------------------------------------
# proof that this user's nnphd wrote a cache: an HMAC with a per-user key

KEY_BYTES = 32
_keys: dict[str, bytes] = {}  # key file → key, read once per process


def key_path() -> Path:
    """The per-user key that signs caches: ``$XDG_CACHE_HOME/nnphd/cache-key`` (``~/.cache/nnphd/cache-key``)."""
    from nnphd._config import default_compile_cache

    return default_compile_cache().parent / "cache-key"


def _valid_key_file(path: Path) -> bytes:
    """The key in ``path`` if it is a regular file (not a link) of :data:`KEY_BYTES` bytes, owned by this user and
    readable by nobody else; ValueError saying why not."""
    st = os.lstat(path)
    if not stat.S_ISREG(st.st_mode):
        raise ValueError("not a regular file")
    if hasattr(os, "getuid") and st.st_uid != os.getuid():
        raise ValueError("owned by another user")
    if st.st_mode & 0o077:
        raise ValueError(f"readable or writable by others (mode {stat.S_IMODE(st.st_mode):o}; expected 600)")
    with open_regular(path, KEY_BYTES) as f:
        key = f.read(KEY_BYTES + 1)
    if len(key) != KEY_BYTES:
        raise ValueError(f"{len(key)} bytes, expected {KEY_BYTES}")
    return key


def _create_key(path: Path) -> None:
    """A fresh random key at ``path`` (mode 600), made whole in a temporary file and linked in place, so that a
    second process never reads half a key; a key already there is kept."""
    path.parent.mkdir(parents=True, exist_ok=True, mode=0o700)
    fd, tmp = tempfile.mkstemp(prefix=".cache-key.", dir=path.parent)  # mode 600
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(os.urandom(KEY_BYTES))
        try:
            os.link(tmp, path)
        except FileExistsError:
            pass
    finally:
        os.unlink(tmp)


def signing_key() -> bytes:
    """This user's key for :func:`sign` (created on first use). Where it cannot be created or is not safe (another
    owner, readable by others, a link), one warning line says so and a key of this process only is used: caches are
    then recomputed by the next run, never trusted."""
    path = key_path()
    k = str(path)
    if k not in _keys:
        try:
            if not os.path.lexists(path):
                _create_key(path)
            _keys[k] = _valid_key_file(path)
        except (OSError, ValueError) as e:
            why = getattr(e, "strerror", None) or e
            msg = one_line(f"{path}: not usable as nnphd's cache key ({why}); caches are recomputed, not reused")
            warnings.warn_explicit(msg, IgnoredFileWarning, "<nnphd>", 0, module=__name__)
            _keys[k] = os.urandom(KEY_BYTES)
    return _keys[k]


def sign(obj, *blobs: bytes) -> str:
    """The HMAC-SHA256 (hex) of ``obj`` as canonical JSON (as it reads back) and of ``blobs``, with
    :func:`signing_key`: a cache carries it as proof that this user's nnphd wrote it."""
    import hmac

    h = hmac.new(signing_key(), json.dumps(normalise(obj), sort_keys=True).encode(), hashlib.sha256)
    for b in blobs:
        h.update(hashlib.sha256(b).digest())
    return h.hexdigest()


def signed_by_us(obj: dict, *blobs: bytes) -> bool:
    """Whether ``obj["signature"]`` is :func:`sign` of the rest of ``obj`` (and ``blobs``)."""
    import hmac

    sig = obj.get("signature")
    rest = {k: v for k, v in obj.items() if k != "signature"}
    return isinstance(sig, str) and hmac.compare_digest(sig, sign(rest, *blobs))


def _arrays_blob(arrays: dict[str, np.ndarray]) -> bytes:
    """The arrays of a checkpoint as bytes for :func:`sign`: names, dtypes, shapes and contents, in name order."""
    h = hashlib.sha256()
    for name in sorted(arrays):
        a = np.ascontiguousarray(arrays[name])
        h.update(json.dumps([name, a.dtype.str, list(a.shape)]).encode())
        h.update(a.tobytes())
    return h.digest()


def normalise(obj):
    """``obj`` as it reads back from JSON (tuples → lists, numpy scalars → numbers)."""
    return json.loads(json.dumps(obj, default=json_default))


def fingerprint(settings: dict) -> str:
    return hashlib.sha256(json.dumps(normalise(settings), sort_keys=True).encode()).hexdigest()[:16]


def save_npz(path: str | os.PathLike, meta: dict, arrays: dict[str, np.ndarray]) -> None:
    """``meta`` (JSON) and ``arrays`` in one .npz, written atomically."""
    buf = io.BytesIO()
    np.savez(
        buf, __meta__=np.array(json.dumps(meta, default=json_default)), **{k: np.asarray(v) for k, v in arrays.items()}
    )
    atomic_write_bytes(path, buf.getvalue())


def load_npz(path: str | os.PathLike) -> tuple[dict, dict[str, np.ndarray]]:
    """(meta, arrays) of a file written by :func:`save_npz`; ValueError (one line, naming ``path``) if it is not one."""
    try:
        meta, arrays = read_npz(path, "__meta__")
        if not isinstance(meta, dict):
            raise ValueError("its metadata is not a JSON object")
    except ValueError as e:
        raise ValueError(one_line(f"{path}: not an nnphd .npz file ({e})")) from None
    return meta, arrays


# ------------------------------------------------------------------------------------------------------------------
# reading untrusted files within bounds

MAX_NPZ_BYTES = 1 << 30  # an .npz (file and uncompressed contents); a checkpoint of a whole sweep is ~10 MB
MAX_JSON_BYTES = 64 << 20  # a JSON file, or the JSON metadata inside an .npz
MAX_JSON_DEPTH = 64  # nesting of JSON objects/arrays (a report nests 7 deep, a model file 8)
MAX_NPZ_ENTRIES = 10_000
_NPZ_COMPRESSION = (zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED)  # np.savez / np.savez_compressed (deflate: bounded)
_ARRAY_KINDS = "biuf"  # bool, integers, floats: plain numbers, nothing to unpickle
# bytes of one .npy member's header text: numpy writes < 1 KiB (the dict, padded to 64 bytes) and parses at most
# 10 000 characters, but only after reading and decoding all that the 4-byte length field declares (up to 4 GiB)
MAX_NPY_HEADER = 10_000
_NPY_MAGIC = b"\x93NUMPY"
_NPY_LENGTH_FIELD = {(1, 0): "<H", (2, 0): "<I", (3, 0): "<I"}  # the .npy versions: the header length's width


class IgnoredFileWarning(UserWarning):
    """A cache or checkpoint file that could not be used (damaged, foreign or non-finite) was ignored."""


def one_line(text: str, limit: int = 400) -> str:
    """``text`` as one line of at most ``limit`` characters before escaping (:func:`nnphd.io.escape.one_line`): line
    breaks as spaces, and every other control or bidi character of a quoted name shown as an escape (``\\x1b``,
    ``\\u202e``), so a message or warning that quotes a path never sends it raw to a terminal."""
    from nnphd.io.escape import one_line as _one_line

    return _one_line(text, limit)


def warn_ignored(path: str | os.PathLike, why: str) -> None:
    """One warning line ``<path>: ignored (<why>); starting from scratch`` (an :class:`IgnoredFileWarning`; the path's
    control and bidi characters shown as escapes, :func:`one_line`). It is issued without a source location, so
    Python prints it on one line of stderr and reads no file to show it."""
    msg = one_line(f"{path}: ignored ({why}); starting from scratch")
    warnings.warn_explicit(msg, IgnoredFileWarning, "<nnphd>", 0, module=__name__)


def open_regular(path: str | os.PathLike, max_bytes: int):
    """``path`` opened for binary reading if it is a regular file of at most ``max_bytes`` bytes; else ValueError
    saying why (a FIFO or device is refused without blocking on it)."""
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOCTTY", 0) | getattr(os, "O_BINARY", 0)
    try:
        fd = os.open(path, flags)
    except FileNotFoundError:
        raise ValueError("no such file") from None
    except OSError as e:
        raise ValueError(f"cannot be read ({e.strerror or e})") from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise ValueError("not a regular file")
        if st.st_size > max_bytes:
            raise ValueError(f"{st.st_size} bytes, more than the limit of {max_bytes}")
        return os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise


def parse_json(text: str, max_depth: int | None = None):
    """JSON ``text`` of at most :data:`MAX_JSON_BYTES` characters whose objects/arrays nest at most ``max_depth``
    (default :data:`MAX_JSON_DEPTH`) deep (ValueError otherwise; the depth is checked without recursion)."""
    max_depth = MAX_JSON_DEPTH if max_depth is None else max_depth
    if len(text) > MAX_JSON_BYTES:
        raise ValueError(f"JSON of {len(text)} characters, more than the limit of {MAX_JSON_BYTES}")
    try:
        obj = json.loads(text)
    except RecursionError:  # the C parser's own guard, far beyond max_depth
        raise ValueError(f"JSON nested more than {max_depth} levels deep") from None
    except ValueError as e:
        raise ValueError(f"not valid JSON ({e})") from None
    stack = [(obj, 1)]
    while stack:
        o, depth = stack.pop()
        if isinstance(o, (dict, list)):
            if depth > max_depth:
                raise ValueError(f"JSON nested more than {max_depth} levels deep")
            stack.extend((v, depth + 1) for v in (o.values() if isinstance(o, dict) else o))
    return obj


def read_json(path: str | os.PathLike, max_bytes: int | None = None):
    """The JSON value in ``path`` (at most ``max_bytes``, default :data:`MAX_JSON_BYTES`), read within bounds
    (:func:`open_regular`, :func:`parse_json`); ValueError saying why not."""
    return decode_json(read_bytes(path, MAX_JSON_BYTES if max_bytes is None else max_bytes))


def read_bytes(path: str | os.PathLike, max_bytes: int) -> bytes:
    """The contents of ``path``, a regular file of at most ``max_bytes`` (:func:`open_regular`); ValueError if not."""
    with open_regular(path, max_bytes) as f:
        data = f.read(max_bytes + 1)
    if len(data) > max_bytes:
        raise ValueError(f"more than the limit of {max_bytes} bytes")
    return data


def decode_json(data: bytes):
    """:func:`parse_json` of UTF-8 ``data``."""
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        raise ValueError("not UTF-8 text") from None
    return parse_json(text)


@dataclass(frozen=True)
class NpyHeader:
    """An .npy member's header, read by :func:`npy_header`: ``offset`` is where its data starts, ``size`` the
    member's uncompressed size from the zip directory."""

    version: tuple[int, int]
    shape: tuple
    fortran_order: bool
    dtype: np.dtype
    offset: int
    size: int

    def check_size(self) -> None:
        """ValueError unless the data the header declares fills the member exactly (so that reading it allocates
        what the member holds, and a header cannot claim more than is there)."""
        shape = self.shape
        if any(d < 0 for d in shape) or self.offset + math.prod(shape) * self.dtype.itemsize != self.size:
            raise ValueError(f"has shape {shape}, which does not match its size ({self.size:,} bytes)")


def npy_header(info: zipfile.ZipInfo, fp, max_bytes: int) -> NpyHeader:
    """The header of the .npy member ``info`` of an archive, ``fp`` its open stream (at its start), read within
    bounds before numpy sees it: its uncompressed size from the zip directory (``info.file_size``, which also bounds
    what the stream yields) at most ``max_bytes``; the magic, the version (1.0 to 3.0) and the header-length field
    read here, the length at most :data:`MAX_NPY_HEADER` and within the member; only then the header text itself,
    parsed by numpy (a literal dict, never code). numpy's own reader takes whatever the length field declares (up to
    4 GiB: a 1 MB .npz of deflated spaces cost 4 GB) and checks the size after reading and decoding it. ValueError
    otherwise, phrased to follow "array 'x' " in a message. :meth:`NpyHeader.check_size` checks the data's size."""
    from numpy.lib import format as npy

    size = info.file_size
    if size > max_bytes:
        raise ValueError(f"is {size:,} bytes uncompressed, more than the limit of {max_bytes:,}")
    prefix = fp.read(len(_NPY_MAGIC) + 2)
    if len(prefix) < len(_NPY_MAGIC) + 2 or not prefix.startswith(_NPY_MAGIC):
        raise ValueError("is not a .npy array (its first bytes are not the .npy magic string)")
    version = (prefix[-2], prefix[-1])
    if version not in _NPY_LENGTH_FIELD:
        raise ValueError(f"has .npy format version {version}; expected 1.0 to 3.0")
    fmt = _NPY_LENGTH_FIELD[version]
    field = fp.read(struct.calcsize(fmt))
    if len(field) < struct.calcsize(fmt):
        raise ValueError("is cut short in its .npy header")
    length = struct.unpack(fmt, field)[0]
    offset = len(prefix) + len(field) + length
    if length > MAX_NPY_HEADER:
        raise ValueError(f"has a .npy header of {length:,} bytes, more than the limit of {MAX_NPY_HEADER:,}")
    if offset > size:
        raise ValueError(f"has a .npy header of {length:,} bytes, more than its {size:,} bytes hold")
    text = fp.read(length)
    if len(text) < length:
        raise ValueError("is cut short in its .npy header")
    # version 3.0 differs from 2.0 only in the header's encoding (utf-8: for field names, which are refused)
    read = npy.read_array_header_1_0 if version == (1, 0) else npy.read_array_header_2_0
    try:
        shape, fortran_order, dtype = read(io.BytesIO(field + text))
    except (ValueError, TypeError, SyntaxError, MemoryError, RecursionError) as e:
        raise ValueError(f"has an invalid .npy header ({one_line(e, 100)})") from None
    return NpyHeader(version, shape, fortran_order, dtype, offset, size)


def _npy_header(info: zipfile.ZipInfo, m, name: str, max_bytes: int) -> None:
    """Check one .npy entry's header against its size in the archive (so reading it allocates only that)."""
    try:
        h = npy_header(info, m, max_bytes)
        dtype = h.dtype
        if dtype.hasobject or dtype.itemsize == 0 or dtype.fields is not None or dtype.kind not in _ARRAY_KINDS + "U":
            raise ValueError(f"has dtype {dtype}, not plain numbers")
        h.check_size()
    except ValueError as e:
        raise ValueError(f"array {name!r} {e}") from None


def _read_entries(f, max_bytes: int) -> dict[str, np.ndarray]:
    from numpy.lib import format as npy

    with zipfile.ZipFile(f) as zf:
        infos = zf.infolist()
        names = [i.filename for i in infos]
        if len(infos) > MAX_NPZ_ENTRIES:
            raise ValueError(f"{len(infos)} entries, more than the limit of {MAX_NPZ_ENTRIES}")
        if len(set(names)) != len(names) or not all(n.endswith(".npy") for n in names):
            raise ValueError("entries that are not distinct .npy arrays")
        if sum(i.file_size for i in infos) > max_bytes:
            raise ValueError(f"more than {max_bytes} bytes uncompressed")
        out = {}
        for info in infos:
            name = info.filename[:-4]
            if info.compress_type not in _NPZ_COMPRESSION or info.flag_bits & 0x1:
                raise ValueError(f"array {name!r} is encrypted or compressed with an unsupported method")
            with zf.open(info) as m:
                _npy_header(info, m, name, max_bytes)
            with zf.open(info) as m:
                out[name] = npy.read_array(m, allow_pickle=False)
    return out


def read_npz(path: str | os.PathLike, meta_key: str, max_bytes: int | None = None) -> tuple[object, dict]:
    """(meta, arrays) of an .npz of plain numeric arrays and the JSON string ``meta_key``, read within bounds: a
    regular file of at most ``max_bytes`` (default :data:`MAX_NPZ_BYTES`; as many uncompressed, from the zip
    directory), stored or deflated ``.npy`` entries whose headers (each read within bounds by :func:`npy_header`
    before numpy sees it) match their sizes, no pickle, the JSON as :func:`parse_json`. ValueError (saying why)
    otherwise."""
    max_bytes = MAX_NPZ_BYTES if max_bytes is None else max_bytes
    with open_regular(path, max_bytes) as f:
        try:
            arrays = _read_entries(f, max_bytes)
        except ValueError:
            raise
        except Exception as e:  # zipfile, zlib and struct raise many types on damaged input: all mean "damaged"
            raise ValueError(f"not a valid .npz archive ({type(e).__name__}: {e})") from None
    meta = arrays.pop(meta_key, None)
    if meta is None:
        raise ValueError(f"no {meta_key!r} entry")
    if meta.dtype.kind != "U" or meta.ndim != 0:
        raise ValueError(f"{meta_key!r} is not a JSON string")
    bad = next((k for k, a in arrays.items() if a.dtype.kind not in _ARRAY_KINDS), None)
    if bad is not None:
        raise ValueError(f"array {bad!r} has dtype {arrays[bad].dtype}, not plain numbers")
    return parse_json(str(meta)), arrays


def tree_arrays(tree, prefix: str = "") -> dict[str, np.ndarray]:
    """The leaves of a pytree as named numpy arrays (in ``jax.tree_util`` order)."""
    import jax

    return {f"{prefix}{i}": np.asarray(x) for i, x in enumerate(jax.tree_util.tree_leaves(tree))}


def check_array(name: str, a, shape: tuple, dtype) -> None:
    """ValueError unless ``a`` is a numpy array of ``shape``, of ``dtype``'s kind (float/int/bool) and finite."""
    if not isinstance(a, np.ndarray):
        raise ValueError(f"array {name!r} is missing")
    if a.shape != tuple(shape):
        raise ValueError(f"array {name!r} has shape {a.shape}, expected {tuple(shape)}")
    if a.dtype.kind != np.dtype(dtype).kind:
        raise ValueError(f"array {name!r} has dtype {a.dtype}, expected {np.dtype(dtype)}")
    if a.dtype.kind == "f" and not np.isfinite(a).all():
        raise ValueError(f"array {name!r} has non-finite values")


def tree_from_arrays(like, arrays: dict[str, np.ndarray], prefix: str = ""):
    """The pytree of the structure of ``like`` from :func:`tree_arrays`' output (ValueError if the leaves do not
    match ``like``'s count, shapes and dtype kinds, or are not finite)."""
    import jax
    import jax.numpy as jnp

    leaves, treedef = jax.tree_util.tree_flatten(like)
    new = [arrays.get(f"{prefix}{i}") for i in range(len(leaves))]
    for i, (a, b) in enumerate(zip(new, leaves)):
        check_array(f"{prefix}{i}", a, np.shape(b), b.dtype)
    return jax.tree_util.tree_unflatten(treedef, [jnp.asarray(a, dtype=b.dtype) for a, b in zip(new, leaves)])


NOT_OURS = "not signed by this user's nnphd (written elsewhere, by another version, or edited)"


class Cache:
    """Results in ``directory`` that are valid for exactly ``settings`` (see the module docstring). Every result and
    checkpoint carries an HMAC (:func:`sign`, with this user's key) of its contents: one that does not is ignored
    with a warning and recomputed, so a cache planted in a shared or pre-created folder never changes a result."""

    CHECKPOINT = ".checkpoint.npz"

    def __init__(self, directory: str | os.PathLike | None, settings: dict):
        self.dir = Path(directory) if directory is not None else None
        self.settings = normalise(settings)
        self.fingerprint = fingerprint(self.settings)

    def load(self, name: str = "results.json") -> dict | None:
        """The result saved as ``name`` under the same settings, or None."""
        if self.dir is None or not os.path.lexists(self.dir / name):
            return None
        try:
            res = read_json(self.dir / name)
            if not isinstance(res, dict):
                raise ValueError("not a JSON object")
        except ValueError as e:
            warn_ignored(self.dir / name, f"not a valid cached result: {e}")
            return None
        if res.get("fingerprint") != self.fingerprint:
            return None
        if not signed_by_us(res):
            warn_ignored(self.dir / name, NOT_OURS)
            return None
        return {k: v for k, v in res.items() if k != "signature"}

    def save(self, obj: dict, name: str = "results.json") -> dict:
        """Write ``obj`` with the fingerprint and its signature (atomically); return it as :meth:`load` reads it."""
        obj = normalise({**obj, "fingerprint": self.fingerprint})
        if self.dir is not None:
            write_json(self.dir / name, {**obj, "signature": sign(obj)})
        return obj

    def seal(self, obj: dict, name: str, files: tuple[str, ...]) -> dict:
        """:meth:`save` ``obj`` as the marker ``name`` with the SHA-256 of each of ``files`` (in the folder, written by
        this run), so that :meth:`load_sealed` can trust them."""
        digests = {f: hashlib.sha256(read_bytes(self.dir / f, MAX_JSON_BYTES)).hexdigest() for f in files}
        return self.save({**obj, "files": digests}, name)

    def load_sealed(self, name: str, file: str):
        """(marker, the JSON in ``file``) when the marker ``name`` was saved by :meth:`seal` under the same settings
        and ``file`` is unchanged since (read within bounds); None otherwise (a changed or unreadable file: with a
        warning)."""
        marker = self.load(name)
        if marker is None:
            return None
        try:
            data = read_bytes(self.dir / file, MAX_JSON_BYTES)
            if hashlib.sha256(data).hexdigest() != (marker.get("files") or {}).get(file):
                raise ValueError(f"changed since nnphd wrote it, or {NOT_OURS}")
            return marker, decode_json(data)
        except ValueError as e:
            warn_ignored(self.dir / file, f"not a valid cached result: {e}")
            return None

    def checkpoint(self, steps: dict[float, tuple[dict, object]]) -> None:
        """Save finished steps: key (a number) → (JSON metadata, pytree of arrays)."""
        if self.dir is None:
            return
        meta = {"fingerprint": self.fingerprint, "steps": [[k, m] for k, (m, _) in steps.items()]}
        arrays = {}
        for i, (_, tree) in enumerate(steps.values()):
            arrays.update(tree_arrays(tree, f"s{i}_"))
        meta = normalise(meta)
        save_npz(self.dir / self.CHECKPOINT, {**meta, "signature": sign(meta, _arrays_blob(arrays))}, arrays)

    def restore(self, like, build: Callable[[float, dict, object], object] | None = None) -> dict:
        """The steps saved by :meth:`checkpoint` under the same settings: key → (metadata, pytree shaped as
        ``like``), or key → ``build(key, metadata, pytree)``; {} if none. A damaged or foreign checkpoint (not an
        .npz of ours, another layout, leaves not of ``like``'s shapes and dtypes, non-finite values, metadata that
        ``build`` refuses with TypeError/ValueError/KeyError) is ignored with an :class:`IgnoredFileWarning`."""
        if self.dir is None or not os.path.lexists(self.dir / self.CHECKPOINT):
            return {}
        path = self.dir / self.CHECKPOINT
        try:
            meta, arrays = read_npz(path, "__meta__")
            if (
                isinstance(meta, dict)
                and isinstance(meta.get("fingerprint"), str)
                and meta["fingerprint"] != self.fingerprint
            ):
                return {}  # written under other settings: not this run's
            steps = _checkpoint_steps(meta, self.fingerprint)  # its layout first, then who wrote it
            restored = _restore_steps(steps, arrays, like)
            if not signed_by_us(meta, _arrays_blob(arrays)):
                raise ValueError(NOT_OURS)
            return restored if build is None else {k: build(k, m, tree) for k, (m, tree) in restored.items()}
        except (ValueError, TypeError, KeyError) as e:
            warn_ignored(path, f"not a valid checkpoint of this run: {e}")
            return {}

    def clear_checkpoint(self) -> None:
        if self.dir is not None and (self.dir / self.CHECKPOINT).exists():
            (self.dir / self.CHECKPOINT).unlink()


_SCALARS = (str, int, float, bool, type(None))


def _checkpoint_steps(meta, fp: str) -> list[tuple[float, dict]]:
    """The (key, metadata) of each step of a checkpoint's JSON, checked (ValueError why not)."""
    if not isinstance(meta, dict) or meta.get("fingerprint") != fp or not isinstance(meta.get("steps"), list):
        raise ValueError("not a checkpoint's metadata")
    out = []
    for step in meta["steps"]:
        ok = isinstance(step, list) and len(step) == 2 and isinstance(step[1], dict)
        if not ok or isinstance(step[0], bool) or not isinstance(step[0], (int, float)) or not math.isfinite(step[0]):
            raise ValueError(f"a step is not [finite number, object]: {json.dumps(step)[:80]}")
        if not all(isinstance(v, _SCALARS) for v in step[1].values()):
            raise ValueError(f"step {step[0]}: metadata values must be numbers, strings or null")
        out.append((float(step[0]), step[1]))
    if len({k for k, _ in out}) != len(out):
        raise ValueError("repeated step keys")
    return out


def _restore_steps(steps, arrays: dict, like) -> dict:
    import jax

    n = len(jax.tree_util.tree_leaves(like))
    if set(arrays) != {f"s{i}_{j}" for i in range(len(steps)) for j in range(n)}:
        raise ValueError(f"its arrays are not {len(steps)} step(s) of {n} leaves")
    out = {}
    for i, (k, m) in enumerate(steps):
        tree = tree_from_arrays(like, arrays, f"s{i}_")
        out[k] = (m, tree)
    return out
