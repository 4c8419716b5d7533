"""Reading a model file written by :meth:`nnphd.NNPhD.save`: the whole file is checked before anything is built.

A model file is untrusted input (it may come from anyone). :func:`read_model_file` reads it within bounds
(:func:`nnphd.io.cache.read_npz`: a regular file of at most :data:`MAX_MODEL_BYTES`, a valid .npz of plain arrays,
no pickle, the JSON metadata bounded in size and nesting), checks every field of the metadata against the tables
below (:data:`META`, :data:`CFG`, ...), then what the fields imply: the coordinates, the scaling, the network's
leaves (count, shapes and dtypes equal to what :func:`nnphd.engine.models.init_lnn` makes for the saved config;
every weight finite), the saved law (built by :func:`nnphd.explain.families.family_from_spec`, which parses a user
law's text without executing it; its coefficients of the right sizes and finite) and the fields of the report that
the model reads. The settings a refit would use get the command line's ranges (``steps`` at most
:data:`nnphd.io.limits.MAX_STEPS`: 2³¹ steps would allocate ~16 GB of minibatch keys; the seed as ``--seed``;
``n_seeds`` and ``sr_time`` at most :data:`MAX_N_SEEDS` and :data:`MAX_SR_TIME`), and the coordinate names hold no
control or bidi characters (those :func:`nnphd.io.escape.terminal` escapes: a name is printed and drawn; ESC or U+202E would send
terminal commands or reorder what is shown). Anything wrong raises one ValueError line: ``<path>: not a valid nnphd
model file: <what>``. (:func:`nnphd.load` then runs the model once at states of the file's own scales and refuses
it in the same form if its forces are not finite.)
"""

from __future__ import annotations

import math
import os
import unicodedata
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from nnphd.explain.families import SIGN_FORMS
from nnphd.io.cache import check_array, one_line, read_npz
from nnphd.io.escape import TERMINAL_ESCAPED
from nnphd.io.limits import MAX_N_SEEDS, MAX_SEED, MAX_SR_TIME, MAX_STEPS
from nnphd.user.derivatives import METHODS as DERIVATIVE_METHODS

__all__ = ["MAX_MODEL_BYTES", "MAX_N_SEEDS", "MAX_SR_TIME", "ModelFile", "read_model_file"]

MAX_MODEL_BYTES = 256 << 20  # a model of 4 layers of 2000 units is 100 MB
MAX_COORDS = 32  # as nnphd.io.limits.MAX_COORDS: no model is trained on more coordinates
MAX_SPARSE_COORDS = 6  # the sparse law's monomials are enumerated over 4^(2n) exponents (n = 6: ~5 s)
MAX_TEXT = 10_000  # characters of a user law


class _Bad(ValueError):
    """What is wrong with the file (the caller adds the path)."""


# ------------------------------------------------------------------------------------------------------------------
# field checkers: check(value, where) returns the value (normalised) or raises _Bad naming ``where``

Check = Callable[[object, str], object]


def _is_num(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool)


def const(v) -> Check:
    def check(x, where):
        if type(x) is not type(v) or x != v:
            raise _Bad(f"{where} is {x!r:.60}, expected {v!r}")
        return x

    return check


def boolean(x, where):
    if not isinstance(x, bool):
        raise _Bad(f"{where} is {x!r:.60}, expected true or false")
    return x


def integer(lo: int, hi: int) -> Check:
    def check(x, where):
        if not isinstance(x, int) or isinstance(x, bool) or not lo <= x <= hi:
            raise _Bad(f"{where} is {x!r:.60}, expected an integer in {lo}..{hi}")
        return x

    return check


def number(*, finite: bool = True, positive: bool = False, nonneg: bool = False, hi: float | None = None) -> Check:
    want = "a positive" if positive else "a non-negative" if nonneg else "a finite" if finite else "a"
    want += " number" + (f" of at most {hi:g}" if hi is not None else "")

    def check(x, where):
        ok = _is_num(x) and (not finite or math.isfinite(x)) and (not positive or x > 0) and (not nonneg or x >= 0)
        if not ok or (hi is not None and x > hi):
            raise _Bad(f"{where} is {x!r:.60}, expected {want}")
        return float(x)

    return check


def string(*, nonempty: bool = False, max_len: int = 1000) -> Check:
    def check(x, where):
        if not isinstance(x, str) or (nonempty and not x.strip()) or len(x) > max_len:
            raise _Bad(f"{where} is {x!r:.60}, expected a{' non-empty' if nonempty else ''} string")
        return x

    return check


def coord_name(x, where):
    """A coordinate name: a non-empty string without a character the terminal would be sent as a command or that
    reorders text — those :func:`nnphd.io.escape.terminal` shows as escapes (controls such as ESC, the bidi marks
    and overrides such as U+202E: :data:`nnphd.io.escape.TERMINAL_ESCAPED`)."""
    string(nonempty=True, max_len=100)(x, where)
    bad = next((c for c in x if unicodedata.category(c) in TERMINAL_ESCAPED), None)
    if bad is not None:
        raise _Bad(
            f"{where} holds the control or bidi character U+{ord(bad):04X}; expected a name without control or "
            "bidi characters"
        )
    return x


def law_text(x, where):
    """A law the model's settings name (used again by a refit): read by the safe parser, never run."""
    from nnphd.explain.families import check_law_text

    string(nonempty=True, max_len=MAX_TEXT)(x, where)
    try:
        check_law_text(x)
    except ValueError as e:
        raise _Bad(f"{where}: {e}") from None
    return x


def one_of(*values) -> Check:
    def check(x, where):
        if not any(type(x) is type(v) and x == v for v in values):
            raise _Bad(f"{where} is {x!r:.60}, expected one of {', '.join(map(repr, values))}")
        return x

    return check


def either(*checks: Check) -> Check:
    def check(x, where):
        for c in checks[:-1]:
            try:
                return c(x, where)
            except _Bad:
                pass
        return checks[-1](x, where)

    return check


def optional(c: Check) -> Check:
    return lambda x, where: None if x is None else c(x, where)


def list_of(item: Check, max_len: int = 100_000) -> Check:
    def check(x, where):
        if not isinstance(x, list) or len(x) > max_len:
            raise _Bad(f"{where} is {type(x).__name__}, expected a list (at most {max_len} items)")
        return [item(v, f"{where}[{i}]") for i, v in enumerate(x)]

    return check


def dict_of(value: Check) -> Check:
    def check(x, where):
        if not isinstance(x, dict):
            raise _Bad(f"{where} is {type(x).__name__}, expected an object")
        return {k: value(v, f"{where}.{k}") for k, v in x.items()}

    return check


def anything(x, where):
    return x


def obj(schema: dict[str, Check], *, required: tuple[str, ...] | None = None, others: bool = False) -> Check:
    """An object with the fields of ``schema`` (all of them required unless ``required`` names some); unknown
    fields are an error unless ``others``."""
    need = tuple(schema) if required is None else required

    def check(x, where):
        if not isinstance(x, dict):
            raise _Bad(f"{where} is {type(x).__name__}, expected an object")
        missing = [k for k in need if k not in x]
        unknown = [k for k in x if k not in schema]
        if missing:
            raise _Bad(f"{where} has no field {missing[0]!r}")
        if unknown and not others:
            raise _Bad(f"{where} has an unknown field {unknown[0]!r:.60}")
        return {**x, **{k: c(x[k], f"{where}.{k}") for k, c in schema.items() if k in x}}

    return check


# ------------------------------------------------------------------------------------------------------------------
# the tables: what a model file holds (as NNPhD.save writes it)

WIDTHS = list_of(integer(1, 1 << 16), max_len=64)
ACTIVATION = string(nonempty=True, max_len=100)

CFG = {  # nnphd.engine.models.ModelConfig's fields (the dataclass also checks the activation names and periodic)
    "n": integer(1, MAX_COORDS),
    "lnn_widths": WIDTHS,
    "lnn_activation": ACTIVATION,
    "split_mass": number(),
    "uan_widths": WIDTHS,
    "uan_activation": ACTIVATION,
    "leaky_slope": number(),
    "guard_eps": number(positive=True),
    "dtype": one_of("float32", "float64"),
    "lnn_out_scale": number(),
    "input_shift": optional(list_of(number(), max_len=2 * MAX_COORDS + 1)),
    "input_scale": optional(list_of(number(positive=True), max_len=2 * MAX_COORDS + 1)),
    "periodic": list_of(integer(0, MAX_COORDS - 1), max_len=MAX_COORDS),
}

SCALING = {
    "mu_q": list_of(number(), max_len=MAX_COORDS),
    "s_q": list_of(number(positive=True), max_len=MAX_COORDS),
    "t0": number(),
    "s_t": number(positive=True),
}

LAW_SPECS = {  # nnphd.explain.families.family_from_spec's kinds
    "builtin": {
        "kind": anything,
        "key": string(nonempty=True),
        "v_rms": list_of(number(nonneg=True), MAX_COORDS),
        "sign": one_of(*SIGN_FORMS),  # optional: a file saved before the tanh sign has none
    },
    "sparse": {"kind": anything, "support": list_of(list_of(boolean))},
    "user": {"kind": anything, "text": string(nonempty=True, max_len=MAX_TEXT)},
    "perturber": {"kind": anything},
}


LAW_SPECS_OPTIONAL = {"builtin": ("sign",)}


def law_spec(x, where):
    kind = obj({"kind": one_of(*LAW_SPECS)}, others=True)(x, where)["kind"]
    need = tuple(k for k in LAW_SPECS[kind] if k not in LAW_SPECS_OPTIONAL.get(kind, ()))
    return obj(LAW_SPECS[kind], required=need)(x, where)


LAW = {"spec": law_spec, "beta": list_of(number(), 10_000), "theta": list_of(number(), 10_000)}

REPORTED_LAW = {  # the report's law.law: what NNPhD.law_ shows
    "law": string(),
    "title": string(),
    "formula": dict_of(string(max_len=MAX_TEXT)),
    "latex": dict_of(string(max_len=MAX_TEXT)),
    "params": dict_of(optional(number(finite=False))),
    "stderr": dict_of(optional(number(finite=False))),
    "method": string(),
}

REPORT = {  # the fields NNPhD reads; the report may hold more
    "status": string(nonempty=True),
    "new_physics": boolean,
    "confidence": number(finite=False),
    "reasons": list_of(string(max_len=MAX_TEXT)),
    "statistic": optional(obj({"value": optional(number(finite=False))}, required=(), others=True)),
    "law": optional(
        obj(
            {"law": optional(obj(REPORTED_LAW, others=True)), "candidates": list_of(anything)}, required=(), others=True
        )
    ),
}

OPTIONAL_SETTINGS = ("field", "derivative_method", "families", "thin")  # absent from older files, or at their default
SETTINGS = {  # NNPhD's arguments
    # the command line's ranges (a refit uses these), but steps from 0: NNPhD(steps=1) is saved (and loads)
    "seed": integer(0, MAX_SEED),
    "steps": integer(0, MAX_STEPS),
    "n_seeds": integer(1, MAX_N_SEEDS),
    "laws": list_of(law_text, max_len=100),
    "law_fit": one_of("auto", "pointwise", "trajectory"),
    "sr_time": number(nonneg=True, hi=MAX_SR_TIME),
    "trim": either(boolean, string(max_len=100)),
    "field": one_of("learned", "uniform", "vertical"),  # (files saved before it was a setting have none: "learned")
    # written only when not the default (nnphd.Derivatives' method "auto"; nnphd.LawLibrary's families: all)
    "derivative_method": one_of(*DERIVATIVE_METHODS),
    "families": list_of(string(nonempty=True, max_len=100), max_len=100),
    "thin": boolean,  # (nnphd.Derivatives' thin: written only when False)
}

FIELD = {  # a declared uniform field as fitted (nnphd.explain.search.fitted_field)
    "law": string(max_len=100),
    "g": dict_of(number()),
    "stderr": dict_of(number(nonneg=True)),
    "coefficients": list_of(number(), max_len=2 * MAX_COORDS),
    "center": optional(list_of(list_of(number(), max_len=MAX_COORDS), max_len=2)),
    "library": one_of("minimal", "vertical"),  # (files saved before the vertical field have none: "minimal")
}

META = obj(
    {
        "format": const("nnphd-model"),
        "version": const(1),
        "names": list_of(coord_name, max_len=MAX_COORDS),
        "angles": list_of(boolean, max_len=MAX_COORDS),
        "cfg": obj(CFG, required=("n",)),
        "scaling": obj(SCALING),
        "law": optional(obj(LAW)),
        "report": obj(REPORT, required=("status", "new_physics", "confidence", "reasons"), others=True),
        "n_leaves": integer(1, 1000),
        "settings": obj(SETTINGS, required=tuple(k for k in SETTINGS if k not in OPTIONAL_SETTINGS)),
        "field": optional(obj(FIELD, required=tuple(k for k in FIELD if k != "library"))),
    },
    required=("format", "version", "names", "angles", "cfg", "scaling", "law", "report", "n_leaves", "settings"),
)


# ------------------------------------------------------------------------------------------------------------------
# reading


@dataclass
class ModelFile:
    """A checked model file: its metadata (as saved), the config, the LNN's leaves (numpy, in
    ``jax.tree_util`` order, with their treedef) and the saved law's family (or None)."""

    meta: dict
    cfg: object  # ModelConfig
    leaves: list[np.ndarray]
    treedef: object
    family: object | None
    beta: np.ndarray | None
    theta: np.ndarray | None


def read_model_file(path: str | os.PathLike) -> ModelFile:
    """The model file ``path``, checked as the module doc says; ValueError (one line: the path and what is wrong)."""
    try:
        try:
            meta, arrays = read_npz(path, "meta", MAX_MODEL_BYTES)
        except ValueError as e:
            raise _Bad(str(e)) from None
        meta = META(meta, "meta")
        n = _check_coords(meta)
        cfg = _check_cfg(meta["cfg"], n)
        leaves, treedef = _check_leaves(meta["n_leaves"], arrays, cfg)
        family, beta, theta = _check_law(meta["law"], meta["names"])
        _check_field(meta.get("field"), meta["angles"])
    except _Bad as e:
        raise ValueError(one_line(f"{path}: not a valid nnphd model file: {e}")) from None
    return ModelFile(meta, cfg, leaves, treedef, family, beta, theta)


def _check_coords(meta: dict) -> int:
    names, n = meta["names"], len(meta["names"])
    if n == 0 or len(set(names)) != n:
        raise _Bad(f"meta.names must be distinct coordinate names, got {names!r:.80}")
    lengths = {"meta.angles": meta["angles"], "meta.scaling.mu_q": meta["scaling"]["mu_q"]}
    lengths["meta.scaling.s_q"] = meta["scaling"]["s_q"]
    for where, v in lengths.items():
        if len(v) != n:
            raise _Bad(f"{where} has {len(v)} entries, expected {n} (one per coordinate)")
    if meta["cfg"]["n"] != n:
        raise _Bad(f"meta.cfg.n is {meta['cfg']['n']}, expected {n} (the number of coordinates)")
    return n


def _check_field(fld: dict | None, angles: list) -> None:
    """A declared field's sizes: one column per position feature of the uniform-field library (an angle has two:
    sin, cos; the vertical field one), a centring (mean, std) of one entry per coordinate with positive spreads."""
    if fld is None:
        return
    want = 1 if fld.get("library") == "vertical" else sum(2 if a else 1 for a in angles)
    if len(fld["coefficients"]) != want:
        raise _Bad(f"meta.field.coefficients has {len(fld['coefficients'])} entries, expected {want}")
    c = fld["center"]
    if c is not None and (len(c) != 2 or any(len(x) != len(angles) for x in c) or min(c[1], default=1.0) <= 0):
        raise _Bad(f"meta.field.center must be (mean, std) with {len(angles)} entries each, std > 0")


def _check_cfg(cd: dict, n: int):
    from nnphd.engine.models import ModelConfig

    for k in ("input_shift", "input_scale"):
        if cd.get(k) is not None and len(cd[k]) != 2 * n + 1:
            raise _Bad(f"meta.cfg.{k} has {len(cd[k])} entries, expected {2 * n + 1}")
    try:
        return ModelConfig(**{k: tuple(v) if isinstance(v, list) else v for k, v in cd.items()})
    except ValueError as e:
        raise _Bad(f"meta.cfg: {e}") from None


def _check_leaves(n_leaves: int, arrays: dict, cfg):
    import jax

    from nnphd.engine.models import init_lnn

    with jax.enable_x64(True):  # shapes and dtypes only: nothing is allocated
        expected = jax.eval_shape(lambda k: init_lnn(k, cfg), jax.ShapeDtypeStruct((2,), np.uint32))
    want, treedef = jax.tree_util.tree_flatten(expected)
    if n_leaves != len(want):
        raise _Bad(f"meta.n_leaves is {n_leaves}, expected {len(want)} for meta.cfg")
    names = [f"lnn_{i}" for i in range(len(want))]
    extra = sorted(set(arrays) - set(names))
    if extra:
        raise _Bad(f"unexpected array {extra[0]!r:.60}")
    for name, w in zip(names, want):
        if name in arrays and arrays[name].dtype != w.dtype:
            raise _Bad(f"weight {name} has dtype {arrays[name].dtype}, expected {w.dtype}")
        try:
            check_array(name, arrays.get(name), w.shape, w.dtype)
        except ValueError as e:
            raise _Bad(str(e).replace(f"array {name!r}", f"weight {name}")) from None
    return [arrays[k] for k in names], treedef


def _sparse_size(n: int) -> int:
    """len(families._odd_monomials(n)), counted: monomials in (q, q̇) of degree ≤ SPARSE_DEGREE, odd in q̇."""
    from nnphd.explain.families import SPARSE_DEGREE as D

    def count(d):  # monomials of degree d in n variables
        return math.comb(d + n - 1, n - 1)

    return sum(count(dv) * count(dq) for dv in range(1, D + 1, 2) for dq in range(D - dv + 1))


def _check_law(law: dict | None, names: list[str]):
    if law is None:
        return None, None, None
    from nnphd.explain.families import family_from_spec

    spec, n = law["spec"], len(names)
    if spec["kind"] == "sparse":
        m = _sparse_size(n) if n <= MAX_SPARSE_COORDS else -1
        if n > MAX_SPARSE_COORDS or any(len(row) != m for row in spec["support"]) or len(spec["support"]) != n:
            raise _Bad(f"meta.law.spec.support is not a {n} × {m} table of booleans")
    if spec["kind"] == "builtin" and len(spec["v_rms"]) != n:
        raise _Bad(f"meta.law.spec.v_rms has {len(spec['v_rms'])} entries, expected {n}")
    try:
        fam = family_from_spec(spec, names)
    except (ValueError, TypeError, KeyError, IndexError) as e:  # the spec's values, refused by the law's builder
        raise _Bad(f"meta.law: {e}") from None
    sizes = {"beta": len(fam.coef_names), "theta": len(fam.nl_names)}
    for k, size in sizes.items():
        if len(law[k]) != size:
            raise _Bad(f"meta.law.{k} has {len(law[k])} values, expected {size} for the law {fam.key!r}")
    return fam, np.asarray(law["beta"], float), np.asarray(law["theta"], float)
