"""The strategy objects of :class:`nnphd.NNPhD`, as pysindy's ``SINDy(differentiation_method=…, feature_library=…)``:
:class:`nnphd.user.derivatives.Derivatives` (how q̇ and q̈ are estimated: by a
:class:`~nnphd.user.derivatives.DerivativeEstimator`, a built-in one or your own) and :class:`LawLibrary` (which
candidate laws are ranked, and how: built-in families by key, :class:`~nnphd.explain.families.Family` objects of
your own, laws as formulas). Their defaults are what ``nnphd detect`` does; each names the ``nnphd detect`` option it
stands for (docs/guide.md, "Strategy objects").
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from nnphd.explain.families import Family, check_law_text, family_keys
from nnphd.user.derivatives import (
    AutoDerivatives,
    DerivativeEstimate,
    DerivativeEstimator,
    Derivatives,
    LocalPolynomial,
    SavitzkyGolay,
    SmoothingSpline,
)

__all__ = [
    "FAMILIES",
    "LAW_FITS",
    "AutoDerivatives",
    "DerivativeEstimate",
    "DerivativeEstimator",
    "Derivatives",
    "Family",
    "LawLibrary",
    "LocalPolynomial",
    "SavitzkyGolay",
    "SmoothingSpline",
    "check_families",
    "family_filter",
    "family_names",
    "with_old_keywords",
]

FAMILIES = family_keys()  # every candidate family's key, in ranking order
LAW_FITS = ("auto", "pointwise", "trajectory")


def _keys(x, what: str) -> tuple[str, ...]:
    """A sequence of strings as a tuple (one str: one item, not its characters); TypeError otherwise."""
    x = (x,) if isinstance(x, str) else x
    try:
        out = tuple(x)
    except TypeError:
        raise TypeError(f"LawLibrary: {what} must be a sequence of strings, got {type(x).__name__}") from None
    bad = [v for v in out if not isinstance(v, str)]
    if bad:
        raise TypeError(f"LawLibrary: {what} must be strings, got {bad[0]!r:.60}")
    return out


def _families(x) -> tuple[str | Family, ...]:
    """The families as a tuple (one str or Family: one item); TypeError unless each is a key or a Family."""
    x = (x,) if isinstance(x, (str, Family)) else x
    try:
        out = tuple(x)
    except TypeError:
        raise TypeError(
            f"LawLibrary: families must be a sequence of strings or Family objects, got {type(x).__name__}"
        ) from None
    bad = [v for v in out if not isinstance(v, (str, Family))]
    if bad:
        raise TypeError(f"LawLibrary: families must be strings (built-in keys) or Family objects, got {bad[0]!r:.60}")
    return out


RESERVED_KEYS = ("none", "perturber")  # the zero law's row and the opt-in perturber: not a key of your own family


def check_families(families: Sequence[str | Family]) -> None:
    """Every key one of :data:`FAMILIES`, and every Family object of your own under a key of its own (not a built-in
    family's, not :data:`RESERVED_KEYS`, not twice); ValueError naming the unknown keys (listing the known) or the
    clash."""
    unknown = [k for k in families if isinstance(k, str) and k not in FAMILIES]
    if unknown:
        raise ValueError(
            f"unknown law famil{'y' if len(unknown) == 1 else 'ies'} {', '.join(repr(k[:60]) for k in unknown[:5])}; "
            f"expected some of {', '.join(FAMILIES)}"
        )
    own = [f.key for f in families if isinstance(f, Family)]
    clash = next((k for k in own if k in FAMILIES or k in RESERVED_KEYS or own.count(k) > 1), None)
    if clash is not None:
        raise ValueError(
            f"your law family's key {clash!r:.60} is a built-in one's or given twice: give it a key of its own"
        )


def family_filter(families: Sequence[str | Family] | None) -> tuple[str | Family, ...] | None:
    """The families to rank as :func:`nnphd.explain.laws.rank_laws`' ``include``: None (all, today's list) when
    ``families`` is None or names every built-in family and holds no Family of your own, else the families
    (checked): keys and your Family objects."""
    if families is None:
        return None
    families = tuple(families)
    check_families(families)
    if all(isinstance(f, str) for f in families) and set(families) >= set(FAMILIES):
        return None
    return families


def family_names(families: Sequence[str | Family]) -> list[str]:
    """The families' keys (a key, or a Family object's ``key``): what a report's ``settings.families`` lists."""
    return [f if isinstance(f, str) else f.key for f in families]


@dataclass(frozen=True)
class LawLibrary:
    """Which candidate laws of f_n are ranked, and how: ``nnphd.NNPhD(library=LawLibrary(...))``.

    ``families``: the families to rank — the keys of built-in ones (default: all of :data:`FAMILIES` — "linear"
    viscous, "quadratic" drag, "coulomb" dry friction, their sums, "power", "rayleigh", "vanderpol", "rayleigh-vdp",
    "drive", "sparse"; the "-diag"/"-full" variants apply to two or more coordinates; ``nnphd detect --families``)
    and :class:`nnphd.explain.families.Family` objects of your own (a law linear in its coefficients given a few
    nonlinear parameters, for the data's coordinates; e.g. ``LawLibrary(families=(*FAMILIES, my_family))``), each
    under a key of its own. Your Family objects are code: a saved model (:meth:`nnphd.NNPhD.save`) keeps the keys of
    the built-in families only.
    ``laws``: your own candidate laws, SymPy-like strings in the coordinates, ``<name>_dot`` and ``t`` (e.g.
    ``"c*x_dot*abs(x_dot)"``; read by the safe parser, never evaluated; checked here without the coordinate names and
    again on the data's in ``fit``); ``--law``. ``fit``: how the candidates are ranked, "auto" (pointwise joint fits,
    then multiple shooting on the positions when the data oscillate), "pointwise" or "trajectory"; ``--law-fit``.
    The zero law ("no law") is always a row. A bad field is a ValueError naming it and what is expected.
    """

    families: tuple[str | Family, ...] = FAMILIES
    laws: tuple[str, ...] = ()
    fit: str = "auto"

    def __post_init__(self) -> None:
        object.__setattr__(self, "families", _families(self.families))
        object.__setattr__(self, "laws", _keys(self.laws, "laws"))
        try:
            check_families(self.families)
        except ValueError as e:
            raise ValueError(f"LawLibrary: {e}") from None
        if not self.families and not self.laws:
            raise ValueError("LawLibrary: nothing to rank: give some families or laws of your own")
        for text in self.laws:
            check_law_text(text)  # ValueError naming the law and what is wrong
        if not isinstance(self.fit, str) or self.fit not in LAW_FITS:
            raise ValueError(f"LawLibrary: fit must be one of {', '.join(map(repr, LAW_FITS))}, got {self.fit!r:.60}")


OLD_KEYWORDS = ("trim", "laws", "law_fit")  # NNPhD's older keywords for the strategy objects' fields


def with_old_keywords(
    derivatives: Derivatives | None,
    library: LawLibrary | None,
    *,
    trim: bool | str | None = None,
    laws: Sequence[str] | None = None,
    law_fit: str | None = None,
) -> tuple[Derivatives, LawLibrary]:
    """The strategy objects of ``NNPhD(...)`` with its older keywords mapped onto them (``trim`` →
    ``Derivatives.trim``, ``laws`` → ``LawLibrary.laws``, ``law_fit`` → ``LawLibrary.fit``; None: not given). An
    old keyword given beside an object that says otherwise is a ValueError saying so."""
    if derivatives is None:
        derivatives = Derivatives() if trim is None else Derivatives(trim=trim)
    elif not isinstance(derivatives, Derivatives):
        raise TypeError(f"derivatives must be an nnphd.Derivatives, got {type(derivatives).__name__}")
    elif trim is not None and Derivatives(trim=trim).trim != derivatives.trim:
        raise ValueError(f"trim={trim!r} disagrees with derivatives={derivatives!r}: give one of them")
    if library is None:
        old = {"laws": laws, "fit": law_fit}
        library = LawLibrary(**{k: v for k, v in old.items() if v is not None})
    elif not isinstance(library, LawLibrary):
        raise TypeError(f"library must be an nnphd.LawLibrary, got {type(library).__name__}")
    else:
        if laws is not None and _keys(laws, "laws") != library.laws:
            raise ValueError(f"laws={laws!r:.200} disagrees with library.laws={library.laws!r:.200}: give one of them")
        if law_fit is not None and law_fit != library.fit:
            raise ValueError(f"law_fit={law_fit!r:.60} disagrees with library.fit={library.fit!r}: give one of them")
    return derivatives, library
