"""Typed results of the paper's studies: :class:`LambdaPResult` (what :func:`nnphd.paper.lambda_p.lambda_p_study`
returns, Fig. 5), :class:`DataQualityResult` (:func:`nnphd.paper.data_quality.data_quality_study`, Fig. 6) and
:class:`PredictionResult` (:func:`nnphd.paper.predict.run_prediction`, Fig. 4).

Dicts only at the JSON boundary, as :class:`nnphd.SweepResult`: ``to_dict()`` is results.json's content (the keys,
order and values it always had), ``from_dict()`` reads such a dict back, checked as untrusted input — every field's
type, no missing or unknown keys, and the copies a dict keeps agreeing with what they repeat (the cached sub-runs and
the summed training times, each λ/p verdict's ``correct``, HO+LD's alignment table beside its curves, the settings'
systems, losses and λ beside the curves). A field that is wrong gives one ValueError naming it. Importing this module
does not load JAX.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, field, fields
from typing import Any

from nnphd.paper.result_checks import FlatRecord, exact_keys, field_error, number, numbers, of_type, same_number

__all__ = [
    "Claim",
    "LambdaPResult",
    "CurveRow",
    "LambdaPVerdict",
    "AlignmentRow",
    "Alignment",
    "LearnedForces",
    "ForcesAt",
    "DataQualityResult",
    "DataQualityGrid",
    "AlphaRow",
    "BetaRow",
    "PredictionResult",
    "ModelMetrics",
    "EnergyTruth",
    "LnnEnergyConstancy",
    "Decomposition",
    "EnergyBalance",
]

MODELS = ("nnphd", "lnn", "blackbox")  # the models of the prediction experiment, in the order of its results
THETA_TOL = 0.1  # rad: the θ1 error whose first crossing the prediction experiment reports
TRANSITIONS = ("jump", "smooth", "ambiguous", "none")  # the kinds of transition_sharpness


def _list(v: Any, name: str, where: str) -> list:
    return of_type(v, list, name, where)


def _object(v: Any, name: str, where: str) -> dict:
    if not isinstance(v, dict):
        raise field_error(where, f"{name} must be an object, got {type(v).__name__}")
    return v


def _settings(v: Any, where: str) -> dict:
    return copy.deepcopy(of_type(v, dict, "settings", where))


def _label(p) -> str:
    """A loss's key: "1", "2", "mse" (a number as the studies write it)."""
    return p if isinstance(p, str) else f"{p:g}"


@dataclass(frozen=True)
class Claim(FlatRecord):
    """One of the paper's claims, judged: what it says, our numbers, and whether they meet it."""

    claim: str
    ours: str
    met: bool


def _claims(v: Any, where: str) -> tuple[Claim, ...]:
    return tuple(Claim.from_dict(c, f"claims[{i}]", where) for i, c in enumerate(_list(v, "claims", where)))


def _copy_agrees(d: dict, key: str, derived, where: str) -> None:
    """The dict's ``key`` repeats ``derived`` (a number, NaN equal to NaN, or a list of strings)."""
    if isinstance(derived, tuple):
        if _list(d[key], key, where) != list(derived):
            raise field_error(where, f"{key} is {d[key]!r:.80}, the parts' are {list(derived)!r:.80}")
    elif not same_number(number(d[key], key, where), derived):
        raise field_error(where, f"{key} is {d[key]!r}, the sum of the parts' is {derived!r}")


# ------------------------------------------------------------------------------------------------------------------
# the λ/p study (Fig. 5)


@dataclass(frozen=True)
class CurveRow(FlatRecord):
    """One λ of a (system, loss) sweep of the λ/p study: L_e, L_b on the test set and on the training set, the
    misalignments m_c, m_n (rms of f^NN − f^PHY over the test samples) and their medians, and the rms of the learned
    f_n. Its dict is a row of results.json's ``curves[system][p]``."""

    lam: float
    L_e: float
    L_b: float
    L_e_train: float
    L_b_train: float
    m_c: float
    m_n: float
    fn_rms: float
    m_c_median: float
    m_n_median: float


@dataclass(frozen=True)
class LambdaPVerdict(FlatRecord):
    """The verdict of one (system, loss) sweep (results.json's ``verdicts``): the phase transition's numbers
    (``ratio`` of the median L_e above λ = 1 to the median below, …), whether it is ``correct`` against the truth,
    and how step-like the rise across λ = 1 is (``sharpness``, ``transition`` one of jump / smooth / ambiguous /
    none, ``rise_fraction``; :func:`nnphd.paper.lambda_p.transition_sharpness`)."""

    system: str
    p: str
    truth_conservative: bool
    new_physics: bool
    correct: bool
    ratio: float
    L_below: float
    L_above: float
    relative_size: float
    reason: str
    sharpness: float | None
    transition: str
    rise_fraction: float | None
    train_wall_time_s: float
    cached: bool

    @classmethod
    def from_dict(cls, d: Any, name: str = "verdict", where: str = "λ/p study result") -> LambdaPVerdict:
        v = super().from_dict(d, name, where)
        if v.correct != (v.new_physics != v.truth_conservative):
            raise field_error(
                where, f"{name}.correct is {v.correct}, but new_physics and truth_conservative say otherwise"
            )
        if v.transition not in TRANSITIONS:
            raise field_error(
                where, f"{name}.transition must be one of {', '.join(TRANSITIONS)}, got {v.transition!r:.60}"
            )
        return v


@dataclass(frozen=True)
class AlignmentRow(FlatRecord):
    """HO+LD at one λ: m_c, m_n and the rms of the learned f_n (a row of results.json's ``alignment.by_p[p]``)."""

    lam: float
    m_c: float
    m_n: float
    fn_rms: float


@dataclass(frozen=True)
class ForcesAt:
    """The learned f_c, f_n at one λ on the points of :class:`LearnedForces`."""

    lam: float
    fc: tuple[float, ...]
    fn: tuple[float, ...]

    def to_dict(self) -> dict:
        return {"lam": self.lam, "fc": list(self.fc), "fn": list(self.fn)}


@dataclass(frozen=True)
class LearnedForces:
    """HO+LD's learned forces for one loss (Fig. 5 e–f): the test points (``q``, ``qd``) with the true ``fc_true``,
    ``fn_true``, and the learned ones at a few λ (``by_lambda``, in increasing λ)."""

    evaluated_on: str
    q: tuple[float, ...]
    qd: tuple[float, ...]
    fc_true: tuple[float, ...]
    fn_true: tuple[float, ...]
    by_lambda: tuple[ForcesAt, ...]

    def to_dict(self) -> dict:
        return {
            "evaluated_on": self.evaluated_on,
            **{k: list(getattr(self, k)) for k in ("q", "qd", "fc_true", "fn_true")},
            "by_lambda": {f"{f.lam:g}": f.to_dict() for f in self.by_lambda},
        }

    @classmethod
    def from_dict(cls, d: Any, name: str = "forces", where: str = "λ/p study result") -> LearnedForces:
        exact_keys(d, ("evaluated_on", "q", "qd", "fc_true", "fn_true", "by_lambda"), name, where)
        arrays = {k: numbers(d[k], f"{name}.{k}", where) for k in ("q", "qd", "fc_true", "fn_true")}
        n = len(arrays["q"])
        by_lambda = []
        for key, at in _object(d["by_lambda"], f"{name}.by_lambda", where).items():
            here = f"{name}.by_lambda.{key}"
            exact_keys(at, ("lam", "fc", "fn"), here, where)
            lam = number(at["lam"], f"{here}.lam", where)
            if key != f"{lam:g}":
                raise field_error(where, f"{here}: the key must be its λ, {lam:g}")
            by_lambda.append(
                ForcesAt(lam, numbers(at["fc"], f"{here}.fc", where), numbers(at["fn"], f"{here}.fn", where))
            )
            arrays[f"by_lambda.{key}.fc"], arrays[f"by_lambda.{key}.fn"] = by_lambda[-1].fc, by_lambda[-1].fn
        for k, a in arrays.items():
            if len(a) != n:
                raise field_error(where, f"{name}.{k} has {len(a)} values, q has {n}")
        return cls(
            of_type(d["evaluated_on"], str, f"{name}.evaluated_on", where),
            **{k: arrays[k] for k in ("q", "qd", "fc_true", "fn_true")},
            by_lambda=tuple(by_lambda),
        )


@dataclass(frozen=True)
class Alignment:
    """HO+LD in the λ/p study (Fig. 5 e–h): the true split (``truth``), the rms of the true f_n on the test set,
    m_c, m_n and the learned f_n's rms per loss and λ (``by_p``: loss → rows), and the learned forces per loss
    (``forces``: loss → :class:`LearnedForces`, None where no λ of ``force_lambdas`` was in the grid)."""

    system: str
    truth: str
    fn_true_rms: float
    by_p: dict[str, tuple[AlignmentRow, ...]]
    forces: dict[str, LearnedForces | None]

    def to_dict(self) -> dict:
        return {
            "system": self.system,
            "truth": self.truth,
            "fn_true_rms": self.fn_true_rms,
            "by_p": {l: [r.to_dict() for r in rows] for l, rows in self.by_p.items()},
            "forces": {l: None if f is None else f.to_dict() for l, f in self.forces.items()},
        }

    @classmethod
    def from_dict(cls, d: Any, where: str = "λ/p study result") -> Alignment:
        exact_keys(d, ("system", "truth", "fn_true_rms", "by_p", "forces"), "alignment", where)
        by_p = {
            l: tuple(
                AlignmentRow.from_dict(r, f"alignment.by_p.{l}[{i}]", where)
                for i, r in enumerate(_list(rows, f"alignment.by_p.{l}", where))
            )
            for l, rows in _object(d["by_p"], "alignment.by_p", where).items()
        }
        forces = _object(d["forces"], "alignment.forces", where)
        if list(forces) != list(by_p):
            raise field_error(where, f"alignment.forces has the losses {list(forces)}, by_p {list(by_p)}")
        return cls(
            system=of_type(d["system"], str, "alignment.system", where),
            truth=of_type(d["truth"], str, "alignment.truth", where),
            fn_true_rms=number(d["fn_true_rms"], "alignment.fn_true_rms", where),
            by_p=by_p,
            forces={
                l: None if f is None else LearnedForces.from_dict(f, f"alignment.forces.{l}", where)
                for l, f in forces.items()
            },
        )


LAMBDA_P_KEYS = (
    "settings",
    "evaluated_on",
    "curves",
    "verdicts",
    "alignment",
    "claims",
    "cached",
    "train_wall_time_s",
    "compile_time_s",
    "wall_time_s",
    "jax_version",
)


@dataclass(frozen=True)
class LambdaPResult:
    """The λ/p study (Fig. 5, :func:`nnphd.paper.lambda_p.lambda_p_study`), typed.

    ``curves``: system → loss ("1", "2", "3", "mse") → one :class:`CurveRow` per λ; ``verdicts``: one
    :class:`LambdaPVerdict` per (system, loss), in the curves' order (:meth:`verdict` finds one); ``alignment``:
    HO+LD's misalignments and learned forces (:class:`Alignment`; None without HO+LD); ``claims``: the paper's claims,
    judged; ``settings``: everything the sweeps depended on; ``compile_time_s``: JAX compilation in this call;
    ``wall_time_s``: this call's. ``cached`` (the sweeps loaded from the cache) and ``train_wall_time_s`` (of the
    sweeps when they were trained) are read off the verdicts. :meth:`to_dict` is results.json's content."""

    settings: dict
    evaluated_on: str
    curves: dict[str, dict[str, tuple[CurveRow, ...]]]
    verdicts: tuple[LambdaPVerdict, ...]
    alignment: Alignment | None
    claims: tuple[Claim, ...]
    compile_time_s: float
    wall_time_s: float
    jax_version: str

    @property
    def cached(self) -> tuple[str, ...]:
        """The sweeps loaded from the cache instead of trained, as "<system>/p=<loss>"."""
        return tuple(f"{v.system}/p={v.p}" for v in self.verdicts if v.cached)

    @property
    def train_wall_time_s(self) -> float:
        """The training time of the sweeps, when they were trained (cached ones included)."""
        return sum(v.train_wall_time_s for v in self.verdicts)

    @property
    def all_claims_met(self) -> bool:
        return all(c.met for c in self.claims)

    def verdict(self, system: str, p: str | float) -> LambdaPVerdict:
        """The verdict of ``system`` under the loss ``p`` (1, 2, 3, "1", "mse", …); KeyError if not studied."""
        for v in self.verdicts:
            if v.system == system and v.p == _label(p):
                return v
        raise KeyError(f"no verdict for {system} with p={_label(p)}")

    def to_dict(self) -> dict:
        """results.json's content (a copy: changing it changes nothing here)."""
        return {
            "settings": copy.deepcopy(self.settings),
            "evaluated_on": self.evaluated_on,
            "curves": {
                s: {l: [r.to_dict() for r in rows] for l, rows in by_p.items()} for s, by_p in self.curves.items()
            },
            "verdicts": [v.to_dict() for v in self.verdicts],
            "alignment": None if self.alignment is None else self.alignment.to_dict(),
            "claims": [c.to_dict() for c in self.claims],
            "cached": list(self.cached),
            "train_wall_time_s": self.train_wall_time_s,
            "compile_time_s": self.compile_time_s,
            "wall_time_s": self.wall_time_s,
            "jax_version": self.jax_version,
        }

    @classmethod
    def from_dict(cls, d: Any, where: str = "λ/p study result") -> LambdaPResult:
        """From a results dict (results.json's content), checked as untrusted input; ValueError with one line naming
        the field when it is not one."""
        exact_keys(d, LAMBDA_P_KEYS, "the result", where)
        res = cls(
            settings=_settings(d["settings"], where),
            evaluated_on=of_type(d["evaluated_on"], str, "evaluated_on", where),
            curves=_curves(d["curves"], where),
            verdicts=tuple(
                LambdaPVerdict.from_dict(v, f"verdicts[{i}]", where)
                for i, v in enumerate(_list(d["verdicts"], "verdicts", where))
            ),
            alignment=None if d["alignment"] is None else Alignment.from_dict(d["alignment"], where),
            claims=_claims(d["claims"], where),
            compile_time_s=number(d["compile_time_s"], "compile_time_s", where),
            wall_time_s=number(d["wall_time_s"], "wall_time_s", where),
            jax_version=of_type(d["jax_version"], str, "jax_version", where),
        )
        res._check(d, where)
        return res

    def _check(self, d: dict, where: str) -> None:
        """The settings, verdicts and alignment agree with the curves; the dict's copies with the verdicts."""
        _check_grid(self.settings, self.curves, where)
        pairs = [(s, l) for s, by_p in self.curves.items() for l in by_p]
        got = [(v.system, v.p) for v in self.verdicts]
        if got != pairs:
            raise field_error(where, f"verdicts are for {got!r:.80}, the curves for {pairs!r:.80}")
        if self.alignment is not None:
            _check_alignment(self.alignment, self.curves, where)
        _copy_agrees(d, "cached", self.cached, where)
        _copy_agrees(d, "train_wall_time_s", self.train_wall_time_s, where)


def _curves(v: Any, where: str) -> dict[str, dict[str, tuple[CurveRow, ...]]]:
    return {
        s: {
            l: tuple(
                CurveRow.from_dict(r, f"curves.{s}.{l}[{i}]", where)
                for i, r in enumerate(_list(rows, f"curves.{s}.{l}", where))
            )
            for l, rows in _object(by_p, f"curves.{s}", where).items()
        }
        for s, by_p in _object(v, "curves", where).items()
    }


def _check_grid(settings: dict, curves: dict, where: str) -> None:
    """settings.systems, .ps and .lambdas (what the figures read) are the curves' systems, losses and λ."""
    for k in ("systems", "ps", "lambdas"):
        if k not in settings:
            raise field_error(where, f"settings has no {k!r}")
    if settings["systems"] != list(curves):
        raise field_error(
            where, f"settings.systems is {settings['systems']!r:.80}, the curves' are {list(curves)!r:.80}"
        )
    for s, by_p in curves.items():
        if list(by_p) != settings["ps"]:
            raise field_error(
                where, f"curves.{s} has the losses {list(by_p)!r:.80}, settings.ps {settings['ps']!r:.80}"
            )
        for l, rows in by_p.items():
            if [r.lam for r in rows] != settings["lambdas"]:
                raise field_error(where, f"curves.{s}.{l}: its λ are not settings.lambdas {settings['lambdas']!r:.80}")


def _check_alignment(al: Alignment, curves: dict, where: str) -> None:
    """The alignment table repeats columns of its system's curves."""
    if al.system not in curves:
        raise field_error(where, f"alignment.system {al.system!r:.60} has no curves")
    if list(al.by_p) != list(curves[al.system]):
        raise field_error(
            where, f"alignment.by_p has the losses {list(al.by_p)!r:.80}, the curves {list(curves[al.system])!r:.80}"
        )
    for l, rows in al.by_p.items():
        curve = curves[al.system][l]
        same = len(rows) == len(curve) and all(
            same_number(getattr(a, k), getattr(c, k))
            for a, c in zip(rows, curve)
            for k in ("lam", "m_c", "m_n", "fn_rms")
        )
        if not same:
            raise field_error(
                where, f"alignment.by_p.{l} does not repeat curves.{al.system}.{l} (lam, m_c, m_n, fn_rms)"
            )


# ------------------------------------------------------------------------------------------------------------------
# the data-quality study (Fig. 6)


@dataclass(frozen=True)
class _GridRow(FlatRecord):
    """One grid point of the data-quality study, trained from scratch at a fixed λ: L_e, L_b on a held-out test set
    of the same α or β, L_e on the training set and on a full Gaussian test set, the size ‖f_n‖₁ of the true f_n
    there, the misalignments m_c, m_n (test set, training set, full set, and the medians on the test set), and the
    fraction of training samples at q̇ > 0. The grid's own value (``alpha`` or ``beta``) is the subclass's field,
    the first key of its dict."""

    L_e: float
    L_b: float
    L_e_train: float
    L_e_full: float
    fn_size: float
    m_c: float
    m_n: float
    m_c_train: float
    m_n_train: float
    m_c_full: float
    m_n_full: float
    m_c_median: float
    m_n_median: float
    frac_qd_pos: float

    @property
    def fraction(self) -> float:
        """α or β: the grid's value."""
        return getattr(self, fields(self)[-1].name)

    def to_dict(self) -> dict:
        d = super().to_dict()
        grid = fields(self)[-1].name
        return {grid: d.pop(grid), **d}


@dataclass(frozen=True)
class AlphaRow(_GridRow):
    """HO+CD at λ = 10 on data in a phase-plane pie of angular fraction ``alpha`` (a row of ``alpha.table``)."""

    alpha: float


@dataclass(frozen=True)
class BetaRow(_GridRow):
    """HO+LD at λ = 0.5 on data with a fraction ``beta`` at q̇ > 0 (a row of ``beta.table``)."""

    beta: float


GRID_ROWS = {"alpha": AlphaRow, "beta": BetaRow}


@dataclass(frozen=True)
class DataQualityGrid:
    """One grid of the data-quality study as trained (and cached: ``fingerprint`` marks the settings, ``cached``
    whether this call loaded it): its ``settings`` (``kind`` "alpha" or "beta", the system, λ, …), the ``table``
    (:class:`AlphaRow` or :class:`BetaRow` per grid point), its training time and what it was evaluated on."""

    settings: dict
    table: tuple[AlphaRow, ...] | tuple[BetaRow, ...]
    train_wall_time_s: float
    evaluated_on: str
    fingerprint: str
    cached: bool

    @property
    def kind(self) -> str:
        """ "alpha" (pie coverage) or "beta" (imbalance)."""
        return self.settings["kind"]

    def to_dict(self) -> dict:
        return {
            "settings": copy.deepcopy(self.settings),
            "table": [r.to_dict() for r in self.table],
            "train_wall_time_s": self.train_wall_time_s,
            "evaluated_on": self.evaluated_on,
            "fingerprint": self.fingerprint,
            "cached": self.cached,
        }

    @classmethod
    def from_dict(cls, d: Any, kind: str, where: str = "data-quality study result") -> DataQualityGrid:
        exact_keys(d, ("settings", "table", "train_wall_time_s", "evaluated_on", "fingerprint", "cached"), kind, where)
        settings = copy.deepcopy(of_type(d["settings"], dict, f"{kind}.settings", where))
        if settings.get("kind") != kind:
            raise field_error(where, f"{kind}.settings.kind must be {kind!r}, got {settings.get('kind')!r:.60}")
        row = GRID_ROWS[kind]
        return cls(
            settings=settings,
            table=tuple(
                row.from_dict(r, f"{kind}.table[{i}]", where)
                for i, r in enumerate(_list(d["table"], f"{kind}.table", where))
            ),
            train_wall_time_s=number(d["train_wall_time_s"], f"{kind}.train_wall_time_s", where),
            evaluated_on=of_type(d["evaluated_on"], str, f"{kind}.evaluated_on", where),
            fingerprint=of_type(d["fingerprint"], str, f"{kind}.fingerprint", where),
            cached=of_type(d["cached"], bool, f"{kind}.cached", where),
        )


DATA_QUALITY_KEYS = (
    "settings",
    "evaluated_on",
    "alpha",
    "beta",
    "claims",
    "cached",
    "train_wall_time_s",
    "wall_time_s",
    "jax_version",
)


@dataclass(frozen=True)
class DataQualityResult:
    """The data-quality study (Fig. 6, :func:`nnphd.paper.data_quality.data_quality_study`), typed: ``alpha`` (HO+CD's
    L_e against pie coverage α) and ``beta`` (HO+LD's misalignment against imbalance β), each a
    :class:`DataQualityGrid`; the paper's ``claims``, judged; the ``settings``; this call's ``wall_time_s``.
    ``evaluated_on``, ``cached`` and ``train_wall_time_s`` are read off the two grids. :meth:`to_dict` is
    results.json's content."""

    settings: dict
    alpha: DataQualityGrid
    beta: DataQualityGrid
    claims: tuple[Claim, ...]
    wall_time_s: float
    jax_version: str

    @property
    def evaluated_on(self) -> str:
        return self.alpha.evaluated_on

    @property
    def cached(self) -> tuple[str, ...]:
        """The grids loaded from the cache instead of trained ("alpha", "beta")."""
        return tuple(k for k, g in (("alpha", self.alpha), ("beta", self.beta)) if g.cached)

    @property
    def train_wall_time_s(self) -> float:
        """The two grids' training time, when they were trained."""
        return self.alpha.train_wall_time_s + self.beta.train_wall_time_s

    @property
    def all_claims_met(self) -> bool:
        return all(c.met for c in self.claims)

    def to_dict(self) -> dict:
        """results.json's content (a copy: changing it changes nothing here)."""
        return {
            "settings": copy.deepcopy(self.settings),
            "evaluated_on": self.evaluated_on,
            "alpha": self.alpha.to_dict(),
            "beta": self.beta.to_dict(),
            "claims": [c.to_dict() for c in self.claims],
            "cached": list(self.cached),
            "train_wall_time_s": self.train_wall_time_s,
            "wall_time_s": self.wall_time_s,
            "jax_version": self.jax_version,
        }

    @classmethod
    def from_dict(cls, d: Any, where: str = "data-quality study result") -> DataQualityResult:
        """From a results dict (results.json's content), checked as untrusted input; ValueError with one line naming
        the field when it is not one."""
        exact_keys(d, DATA_QUALITY_KEYS, "the result", where)
        res = cls(
            settings=_settings(d["settings"], where),
            alpha=DataQualityGrid.from_dict(d["alpha"], "alpha", where),
            beta=DataQualityGrid.from_dict(d["beta"], "beta", where),
            claims=_claims(d["claims"], where),
            wall_time_s=number(d["wall_time_s"], "wall_time_s", where),
            jax_version=of_type(d["jax_version"], str, "jax_version", where),
        )
        if of_type(d["evaluated_on"], str, "evaluated_on", where) != res.evaluated_on:
            raise field_error(where, "evaluated_on is not alpha.evaluated_on")
        _copy_agrees(d, "cached", res.cached, where)
        _copy_agrees(d, "train_wall_time_s", res.train_wall_time_s, where)
        return res


# ------------------------------------------------------------------------------------------------------------------
# the prediction experiment (Fig. 4)


@dataclass(frozen=True)
class ModelMetrics(FlatRecord):
    """One model's rollout from t = 30 against the truth: θ1's RMSE over [30, 40] and over the whole rollout, the
    energy's RMSE, the first time |Δθ1| exceeds :data:`THETA_TOL` (``t_error_exceeds``: None if never; results.json's
    key ``t_error_exceeds_0.1``), when the rollout diverged (None if not), and its training force error (mean
    |Δq̈|, and relative rms)."""

    theta1_rmse_30_40: float
    theta1_rmse_30_200: float
    energy_rmse_30_200: float
    t_error_exceeds: float | None = field(metadata={"key": f"t_error_exceeds_{THETA_TOL:g}"})
    diverged_at: float | None
    train_force_error: float
    train_force_rel_error: float


@dataclass(frozen=True)
class EnergyTruth(FlatRecord):
    """The true energy at the split and at the end, and the energy lost in between."""

    energy_t_split: float
    energy_t_end: float
    energy_loss: float


@dataclass(frozen=True)
class LnnEnergyConstancy(FlatRecord):
    """How constant the energy of the LNN-alone rollout is (see :func:`nnphd.paper.predict._lnn_energy_constancy`)."""

    true_energy_loss: float
    truth_window_mean_drift: float
    lnn_true_energy_window_mean_drift: float
    lnn_true_energy_drift_over_truth_drift: float
    lnn_learned_energy_range: float
    lnn_learned_energy_range_on_true_states: float
    lnn_learned_energy_range_ratio: float


@dataclass(frozen=True)
class Decomposition(FlatRecord):
    """NNPhD's learned f_n against the true friction on the training and test states: rms values and relative rms
    error (``what`` says so in words)."""

    what: str
    fn_true_rms_train: float
    fn_learned_rms_train: float
    fn_rel_error_train: float
    fn_true_rms_test: float
    fn_learned_rms_test: float
    fn_rel_error_test: float


@dataclass(frozen=True)
class EnergyBalance(FlatRecord):
    """The NNPhD rollout's energy bookkeeping: dH/dt against the learned dissipated power, and the learned
    dissipation against the true one (``what`` says so in words; NaN where the rollout was not finite)."""

    what: str
    rollout_finite: bool
    dHdt_vs_power_rel_rms: float
    dHdt_vs_power_corr: float
    dHdt_vs_naive_fn_dot_qd_rel_rms: float
    mean_dHdt: float
    mean_power: float
    learned_energy_scale_alpha: float
    learned_vs_true_power_corr: float
    learned_vs_true_power_rel_rms: float
    learned_vs_alpha_true_power_rel_rms: float
    mean_learned_power_over_mean_true_power: float


PREDICTION_KEYS = (
    "experiment",
    "settings",
    "metrics",
    "truth",
    "lnn_energy_constancy",
    "decomposition",
    "energy_balance",
    "claims",
    "jax_version",
    "train_time_s",
    "wall_time_s",
)


def _by_model(v: Any, name: str, where: str) -> dict:
    """An object keyed by the three models, in :data:`MODELS`' order."""
    if list(_object(v, name, where)) != list(MODELS):
        raise field_error(where, f"{name} must have the keys {', '.join(MODELS)} in that order, got {list(v)!r:.80}")
    return v


@dataclass(frozen=True)
class PredictionResult:
    """The prediction experiment (Fig. 4, :func:`nnphd.paper.predict.run_prediction`), typed: per model (``nnphd``,
    ``lnn``, ``blackbox``) its rollout ``metrics`` (:class:`ModelMetrics`) and training time (``train_time_s``); the
    true energy (``truth``), the LNN's energy constancy, NNPhD's f_n against the true friction (``decomposition``),
    the energy balance, the paper's ``claims`` judged, ``settings``, ``wall_time_s``. :meth:`to_dict` is
    results.json's content."""

    experiment: str
    settings: dict
    metrics: dict[str, ModelMetrics]
    truth: EnergyTruth
    lnn_energy_constancy: LnnEnergyConstancy
    decomposition: Decomposition
    energy_balance: EnergyBalance
    claims: tuple[Claim, ...]
    jax_version: str
    train_time_s: dict[str, float]
    wall_time_s: float

    @property
    def all_claims_met(self) -> bool:
        return all(c.met for c in self.claims)

    def to_dict(self) -> dict:
        """results.json's content (a copy: changing it changes nothing here)."""
        return {
            "experiment": self.experiment,
            "settings": copy.deepcopy(self.settings),
            "metrics": {k: m.to_dict() for k, m in self.metrics.items()},
            "truth": self.truth.to_dict(),
            "lnn_energy_constancy": self.lnn_energy_constancy.to_dict(),
            "decomposition": self.decomposition.to_dict(),
            "energy_balance": self.energy_balance.to_dict(),
            "claims": [c.to_dict() for c in self.claims],
            "jax_version": self.jax_version,
            "train_time_s": dict(self.train_time_s),
            "wall_time_s": self.wall_time_s,
        }

    @classmethod
    def from_dict(cls, d: Any, where: str = "prediction result") -> PredictionResult:
        """From a results dict (results.json's content), checked as untrusted input; ValueError with one line naming
        the field when it is not one."""
        exact_keys(d, PREDICTION_KEYS, "the result", where)
        metrics = _by_model(d["metrics"], "metrics", where)
        times = _by_model(d["train_time_s"], "train_time_s", where)
        return cls(
            experiment=of_type(d["experiment"], str, "experiment", where),
            settings=_settings(d["settings"], where),
            metrics={k: ModelMetrics.from_dict(m, f"metrics.{k}", where) for k, m in metrics.items()},
            truth=EnergyTruth.from_dict(d["truth"], "truth", where),
            lnn_energy_constancy=LnnEnergyConstancy.from_dict(d["lnn_energy_constancy"], "lnn_energy_constancy", where),
            decomposition=Decomposition.from_dict(d["decomposition"], "decomposition", where),
            energy_balance=EnergyBalance.from_dict(d["energy_balance"], "energy_balance", where),
            claims=_claims(d["claims"], where),
            jax_version=of_type(d["jax_version"], str, "jax_version", where),
            train_time_s={k: number(t, f"train_time_s.{k}", where) for k, t in times.items()},
            wall_time_s=number(d["wall_time_s"], "wall_time_s", where),
        )
