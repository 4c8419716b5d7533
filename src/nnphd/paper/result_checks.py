"""Reading a result dict back as untrusted input: the checks the typed results share (:mod:`nnphd.paper.sweep_result`,
:mod:`nnphd.paper.study_results`). Each failed check is one ValueError, ``"<where>: <field> …"``. No JAX here."""

from __future__ import annotations

import math
from dataclasses import fields
from typing import Any


def field_error(where: str, what: str) -> ValueError:
    return ValueError(f"{where}: {what}")


def exact_keys(d: Any, keys: tuple[str, ...], name: str, where: str) -> dict:
    """``d`` as an object with exactly ``keys``."""
    if not isinstance(d, dict):
        raise field_error(where, f"{name} must be an object, got {type(d).__name__}")
    missing = [k for k in keys if k not in d]
    extra = [k for k in d if k not in keys]
    if missing:
        raise field_error(where, f"{name} has no {missing[0]!r}")
    if extra:
        raise field_error(where, f"{name} has an unknown key {str(extra[0])!r:.60}")
    return d


def number(v: Any, name: str, where: str, optional: bool = False) -> float | None:
    if v is None and optional:
        return None
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise field_error(where, f"{name} must be a number{' or null' if optional else ''}, got {v!r:.60}")
    return float(v)


def of_type(v: Any, typ: type, name: str, where: str):
    if not isinstance(v, typ):
        raise field_error(where, f"{name} must be a {'string' if typ is str else typ.__name__}, got {v!r:.60}")
    return v


def same_number(a: float | None, b: float | None) -> bool:
    return a == b or (a is not None and b is not None and math.isnan(a) and math.isnan(b))


def numbers(v: Any, name: str, where: str) -> tuple[float, ...]:
    """A list of numbers."""
    return tuple(number(x, f"{name}[{i}]", where) for i, x in enumerate(of_type(v, list, name, where)))


# a flat record's field types (as written in its class, under `from __future__ import annotations`) → their reader
_READERS = {
    "float": lambda v, name, where: number(v, name, where),
    "float | None": lambda v, name, where: number(v, name, where, optional=True),
    "bool": lambda v, name, where: of_type(v, bool, name, where),
    "str": lambda v, name, where: of_type(v, str, name, where),
}


def _key(f) -> str:
    return f.metadata.get("key", f.name)


class FlatRecord:
    """A frozen dataclass of numbers, flags and strings (fields typed ``float``, ``float | None``, ``bool`` or
    ``str``) whose dict is its fields in order, each under its name or its metadata's ``"key"``."""

    def to_dict(self) -> dict:
        return {_key(f): getattr(self, f.name) for f in fields(self)}

    @classmethod
    def from_dict(cls, d: Any, name: str = "row", where: str = "result"):
        """From its dict, checked: exactly its keys, each value of its field's type (ValueError naming it)."""
        fs = fields(cls)
        exact_keys(d, tuple(_key(f) for f in fs), name, where)
        return cls(**{f.name: _READERS[f.type](d[_key(f)], f"{name}.{_key(f)}", where) for f in fs})
