"""The Python API: arrays in, a verdict, a law and a fitted model out.

    import numpy as np, nnphd
    data = nnphd.Trajectories([t1, t2], [x1, x2], names=["x"])       # or .from_csv / .from_npz / .from_dataframe
    model = nnphd.NNPhD(seed=0).fit(data)                            # derivatives, λ-sweep, trust checks, the law
    model.verdict_.status, model.confidence_, model.law_             # "detected", 1.0, Law(...) or None
    fc, fn = model.forces(q, qd, t)                                  # the fitted model at any states
    q, qd = model.simulate(q0, qd0, t)                               # roll it out
    model.save("m.npz"); nnphd.load("m.npz")                         # JSON + arrays in one .npz, no pickle

The fitted model is the LNN's conservative acceleration f_c (in the data's units) plus the claimed law as f_n (zero
when no law is claimed — the verdict is not "detected" or no candidate beats zero). Everything runs in float64
inside the calls, without changing the caller's JAX settings (see :func:`nnphd.configure`).
"""

from __future__ import annotations

import json
import os
from collections.abc import Sequence
from dataclasses import asdict, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from nnphd.explain.law import FittedFamily, Law
from nnphd.io.progress import Progress
from nnphd.user.result import ConservativeModel, DetectResult, FittedModel, Status, Verdict, read_report

if TYPE_CHECKING:  # the strategy objects (nnphd.Derivatives, nnphd.LawLibrary) load with the first NNPhD
    from nnphd.user.strategies import Derivatives, LawLibrary

__all__ = ["DetectResult", "Law", "NNPhD", "Status", "Trajectories", "Verdict", "load", "read_report"]


def _x64():
    import jax

    return jax.enable_x64(True)


class Trajectories:
    """Trajectories of one system: positions (and optionally velocities/accelerations) against time.

    ``t``: (N,) times with ``traj`` (N,) trajectory ids, or a list of (N_i,) arrays, one per trajectory (lengths
    may differ); ``q``: (N,) / (N, n) likewise, or a list of them. ``names``: the coordinates' names (default
    q1, q2, …); ``angles``: the names that are angles (whole turns allowed); ``qd``/``qdd``: known derivatives, same
    layout as ``q`` (else estimated from the positions). Invalid input raises :class:`nnphd.user.recording.DataError`
    (a ValueError) with a one-line message."""

    def __init__(
        self, t, q, traj=None, *, names: Sequence[str] | None = None, angles: Sequence[str] = (), qd=None, qdd=None
    ):
        from nnphd.user.recording import from_arrays

        self._ud = from_arrays(t, q, traj, names=names, angles=angles, qd=qd, qdd=qdd)

    @classmethod
    def _from_userdata(cls, ud) -> Trajectories:
        self = cls.__new__(cls)
        self._ud = ud
        return self

    @classmethod
    def from_csv(cls, path, angles: Sequence[str] = ()) -> Trajectories:
        """A CSV file (header t, [traj,] coordinates, optional <c>_dot / <c>_ddot; see ``nnphd detect --help``)."""
        from nnphd.user.recording import DataError, load_trajectories

        if os.path.splitext(os.fspath(path))[1].lower() != ".csv":
            raise DataError(f"{path}: expected a .csv file")
        return cls._from_userdata(load_trajectories(path, angles))

    @classmethod
    def from_npz(cls, path, angles: Sequence[str] = ()) -> Trajectories:
        """An .npz file with one 1-D array per CSV column."""
        from nnphd.user.recording import DataError, load_trajectories

        if os.path.splitext(os.fspath(path))[1].lower() != ".npz":
            raise DataError(f"{path}: expected a .npz file")
        return cls._from_userdata(load_trajectories(path, angles))

    @classmethod
    def from_dataframe(cls, df, angles: Sequence[str] = ()) -> Trajectories:
        """A pandas (or any mapping of columns) table with the CSV file's columns."""
        from nnphd.user.recording import from_table

        return cls._from_userdata(from_table(df, angles))

    @classmethod
    def from_markers(cls, source, markers: Sequence[str] | str = "auto", fps: float | None = None) -> Trajectories:
        """A camera's marker positions — a CSV/NPZ file, or a mapping of columns (``t`` or ``frame``, optional
        ``traj``, ``<marker>_x``, ``<marker>_y`` [, ``_z``]; NaN where a frame lost a marker) — turned into
        generalized coordinates: the constraints (fixed points, untracked pivots, rods, rails) found in the tracks
        and the minimal coordinates chosen from them (:mod:`nnphd.user.markers`; :attr:`markers` says which and
        why). ``markers``: "auto" or the markers' names; ``fps``: the frame rate where there is a frame column and
        no t. Invalid input raises :class:`nnphd.user.recording.DataError` with a one-line message."""
        from nnphd.user.recording import from_marker_columns, load_trajectories

        if isinstance(source, (str, os.PathLike)):
            return cls._from_userdata(load_trajectories(source, markers=markers, fps=fps))
        return cls._from_userdata(from_marker_columns(source, markers, fps))

    @property
    def markers(self) -> dict | None:
        """A marker recording's constraints, coordinates and what was assumed (None for coordinates as given)."""
        return None if self._ud.markers is None else self._ud.markers.to_dict()

    @property
    def names(self) -> tuple[str, ...]:
        return self._ud.coords

    @property
    def angles(self) -> tuple[str, ...]:
        return self._ud.angles

    @property
    def n_trajectories(self) -> int:
        return self._ud.n_traj

    @property
    def n_samples(self) -> int:
        return self._ud.n_samples

    def arrays(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """(t, q) of each trajectory, in order: t (N_i,), q (N_i, n) — copies, as read and validated."""
        return [(tr.t.copy(), tr.q.copy()) for tr in self._ud.trajectories]

    def __repr__(self) -> str:
        return (
            f"Trajectories({self.n_trajectories} trajectories, {self.n_samples} samples, coordinates "
            f"{', '.join(self.names)}{'; angles ' + ', '.join(self.angles) if self.angles else ''})"
        )


def _check_run_settings(seed: int, steps: int, n_seeds: int, sr_time: float) -> None:
    """The ranges of the command line's options (:mod:`nnphd.io.limits`), which a saved model's settings must keep
    too: ValueError naming the first one outside."""
    from nnphd.io.limits import MAX_N_SEEDS, MAX_SEED, MAX_SR_TIME, MAX_STEPS

    for name, value, lo, hi in (
        ("seed", seed, 0, MAX_SEED),
        ("steps", steps, 0, MAX_STEPS),
        ("n_seeds", n_seeds, 1, MAX_N_SEEDS),
        ("sr_time", sr_time, 0, MAX_SR_TIME),
    ):
        if not lo <= value <= hi:  # (NaN fails too)
            raise ValueError(f"{name} must be between {lo} and {hi}, got {value!r}")


class NNPhD:
    """The estimator: ``NNPhD(seed=0).fit(data)`` runs what ``nnphd detect`` runs (derivative estimates, the
    λ-sweep, the trust checks, the ranked candidate laws) and keeps the fitted model.

    ``steps``: training steps per model; ``n_seeds``: seeds of the verdict's repeatability; ``derivatives``: how q̇
    and q̈ are estimated, an :class:`nnphd.Derivatives` (method, trim; None: ``Derivatives()``, what ``nnphd detect``
    does); ``library``: which candidate laws are ranked and how, an :class:`nnphd.LawLibrary` (families, your own
    laws, fit; None: ``LawLibrary()``, every family). The older keywords (in ``options``) set the same fields: ``laws`` (your candidate
    laws, SymPy strings, e.g. ``"c*x_dot*abs(x_dot)"``) is ``LawLibrary.laws``, ``law_fit`` ("auto" / "pointwise" /
    "trajectory") ``LawLibrary.fit``, ``trim`` (drop the ends of each trajectory: "auto", True, False)
    ``Derivatives.trim``; one given beside an object that says otherwise is a ValueError. ``sr_time``: seconds of
    genetic symbolic regression for the fallback (0: none); ``field``: the conservative force, "learned" (by the LNN,
    the default), "uniform" (declared: gravity near the ground, or none — for a throw, a fall, a coast-down; the
    verdict and the law then rest on a fit of the positions beside it, and ``forces``/``simulate`` use the fitted
    field) or "vertical" (declared uniform and along the last coordinate, which points up: its size fitted); ``workers``: train the seeds on that many local Dask worker processes (default 1: here; the numbers are
    the same), ``scheduler``: on an existing Dask cluster; further keywords are fields of :class:`nnphd.user.assess.AssessSettings`.

    After ``fit``: ``result_`` (:class:`DetectResult`: everything below, typed), ``verdict_`` (:class:`Verdict`),
    ``status_`` (:class:`Status`), ``confidence_``, ``new_physics_``, ``law_`` (:class:`Law` or None), ``report_``
    (the JSON-ready report dict), ``names_``, ``angles_``.
    """

    def __init__(
        self,
        *,
        seed: int = 0,
        steps: int = 1000,
        n_seeds: int = 2,
        derivatives: Derivatives | None = None,
        library: LawLibrary | None = None,
        sr_time: float = 0.0,
        field: str = "learned",
        **options: Any,
    ):
        from nnphd.user.settings import check_field
        from nnphd.user.strategies import OLD_KEYWORDS, with_old_keywords

        old = {k: options.pop(k) for k in OLD_KEYWORDS if k in options}
        self.derivatives, self.library = with_old_keywords(derivatives, library, **old)
        check_field(field, self.library.fit)
        self.seed, self.steps, self.n_seeds = int(seed), int(steps), int(n_seeds)
        _check_run_settings(self.seed, self.steps, self.n_seeds, float(sr_time))
        # the older names of the objects' fields (save() writes them)
        self.laws, self.law_fit, self.trim = self.library.laws, self.library.fit, self.derivatives.trim
        self.sr_time, self.assess_kw = float(sr_time), options
        self.field = field
        self._model: FittedModel | None = None
        self._fc_jit = None

    # ------------------------------------------------------------------------------------------------ fitting
    def fit(self, data: Trajectories, progress: Progress | None = None) -> NNPhD:
        """Derivatives, the λ-sweep with the trust checks, the law. ``progress(done, total, message)`` (optional) is
        told what runs."""
        from nnphd.user.detect import detect_data

        if not isinstance(data, Trajectories):
            raise TypeError(f"fit expects nnphd.Trajectories, got {type(data).__name__}")
        with _x64():
            result, model = detect_data(
                data._ud,
                None,
                seed=self.seed,
                steps=self.steps,
                sr_time=self.sr_time,
                n_seeds=self.n_seeds,
                progress=progress,
                trim=self.derivatives.trim,
                derivative_method=self.derivatives,
                thin=self.derivatives.thin,
                laws=self.library.laws,
                law_fit=self.library.fit,
                families=self.library.families,
                field=self.field,
                **self.assess_kw,
            )
        self.report_ = result.report
        self._model = model
        self._set_results(result, None if model.law is None else model.law.fitted_family())
        return self

    def _set_results(self, result: DetectResult, fitted: FittedFamily | None) -> None:
        """The results of a fit or a loaded file; ``fitted``: the claimed law's family with its fitted coefficients,
        which the Law (``law_``, ``result_.law`` and the model's ``law``, one object) then predicts with."""
        if fitted is not None:
            if result.law is not None:
                law = replace(result.law, fitted=fitted)
            else:  # a model file whose report names no law but holds one: that law, its formula made here
                from nnphd.explain.table import fitted_law

                law = fitted_law(fitted, self._model.coords)
            result = replace(result, law=law)
        self.result_ = result
        self._model = replace(self._model, law=result.law)  # the model holds the Law, nothing else of the law
        self.verdict_, self.law_ = self.result_.verdict, self.result_.law
        self.status_, self.confidence_, self.new_physics_ = (
            self.verdict_.status,
            self.verdict_.confidence,
            self.verdict_.new_physics,
        )
        self._fc_jit = None  # compiled f_c of the model now held (a refit replaces it)
        m = self._model
        self.names_, self.angles_ = tuple(m.coords), tuple(c for c, a in zip(m.coords, m.angles) if a)

    def _check_fitted(self):
        if self._model is None:
            raise RuntimeError("this NNPhD is not fitted yet: call .fit(data) or nnphd.load(path) first")
        if self._model.conservative is None:
            raise RuntimeError(
                "no model was trained: the data cannot decide (" + "; ".join(self.verdict_.reasons) + ")"
            )

    # ------------------------------------------------------------------------------------------- the model
    def _fc_fn(self):
        """f_c(q, q̇) of the model held, compiled (once per model and shape)."""
        if self._fc_jit is None:
            import jax

            self._fc_jit = jax.jit(self._fc_raw())
        return self._fc_jit

    def _fc_raw(self):
        """f_c(q, q̇) of the model held, as a JAX function (not compiled: :func:`_check_forward` runs it once)."""
        from nnphd.user.assess import conservative_fn

        fld = self._model.field
        if fld is not None:  # a declared uniform field: its fitted acceleration
            import jax.numpy as jnp

            from nnphd.explain.search import field_force

            ang = self._model.angles
            return lambda q, qd: field_force(fld, q, ang, xp=jnp)
        return conservative_fn(self._model.conservative)

    def _states(self, q, qd, t):
        n = len(self.names_)
        q = np.asarray(q, float).reshape(-1, n)
        qd = np.asarray(qd, float).reshape(-1, n)
        if qd.shape != q.shape:
            raise ValueError(f"qd must have the shape of q {q.shape}, got {qd.shape}")
        t = np.zeros(len(q)) if t is None else np.broadcast_to(np.asarray(t, float), (len(q),))
        return q, qd, t

    def forces(self, q, qd, t=None) -> tuple[np.ndarray, np.ndarray]:
        """(f_c, f_n) at states q, qd (N, n) (or (n,)), times t (N,) — in the data's units; f_n is the claimed law
        (zeros without one)."""
        self._check_fitted()
        return self._forces(self._fc_fn(), *self._states(q, qd, t))

    def _forces(self, fc_fn, q, qd, t) -> tuple[np.ndarray, np.ndarray]:
        with _x64():
            fc = np.asarray(fc_fn(q, qd), float)
        law = self.law_
        fn = np.zeros_like(q) if law is None or law.fitted is None else np.asarray(law.predict(q, qd, t), float)
        return fc, fn

    def simulate(self, q0, qd0, t, substeps: int = 4) -> tuple[np.ndarray, np.ndarray]:
        """Roll the fitted model q̈ = f_c + f_n out from (q0, qd0) at t[0] over the evenly spaced times ``t``
        (RK4, ``substeps`` steps per interval). Returns q, q̇ (len(t), n)."""
        import jax
        import jax.numpy as jnp

        from nnphd.engine.data import rk4_scan

        self._check_fitted()
        t = np.asarray(t, float)
        if t.ndim != 1 or len(t) < 2 or not np.all(np.diff(t) > 0):
            raise ValueError("t must be at least two increasing times")
        dt = np.diff(t)
        if np.ptp(dt) > 1e-9 * np.max(np.abs(t)) + 1e-12:
            raise ValueError("t must be evenly spaced")
        n = len(self.names_)
        law, fc = self.law_ if self.law_ is not None and self.law_.fitted is not None else None, self._fc_fn()

        def f(q, qd, tt):
            a = fc(q[None], qd[None])[0]
            if law is not None:
                a = a + law.predict(q[None], qd[None], jnp.reshape(tt, (1,)), xp=jnp)[0]
            return a

        with _x64():
            x0 = jnp.concatenate([jnp.asarray(q0, jnp.float64).reshape(n), jnp.asarray(qd0, jnp.float64).reshape(n)])
            k = int(substeps)
            run = jax.jit(lambda x: rk4_scan(f, x, float(dt[0]) / k, float(t[0]), (len(t) - 1) * k))
            _, qs, qds = run(x0)
            return np.asarray(qs[::k], float), np.asarray(qds[::k], float)

    # ------------------------------------------------------------------------------------------------ output
    def report(self, out) -> Path:
        """Write report.json, report.html and the figures to the folder ``out`` (as ``nnphd detect --out``)."""
        from nnphd.user.report import write_report

        self._check_fitted()
        m = self._model
        if m.data is None:
            raise RuntimeError("a loaded model keeps no data: report() needs the model from fit()")
        write_report(out, self.report_, m)
        return Path(out)

    def figures(self) -> dict:
        """The report's figures as matplotlib Figures (data, L_e(λ), forces, energy trend where computed, the
        amplitude envelope with the leading candidate laws' predictions for one oscillating coordinate)."""
        from nnphd.user import report as rp

        self._check_fitted()
        m = self._model
        if m.data is None:
            raise RuntimeError("a loaded model keeps no data: figures() needs the model from fit()")
        r = self.report_
        coords = list(m.coords)
        figs = {"data": rp.fig_data(m.data, m.traj, coords)}
        e = rp.fig_energy(r["evidence"]["energy_trend"])
        if e is not None:
            figs["energy_trend"] = e
        if r["table"]:
            figs["loss_vs_lambda"] = rp.fig_loss(r["table"])
            figs["forces"] = rp.fig_forces(
                m.data,
                m.traj,
                coords,
                m.fc,
                m.fn,
                r.get("lambda_forces"),
                rp.declared_field(r) is not None,
            )
        env = rp.fig_envelope((r.get("law") or {}).get("envelope"), coords[0])
        if env is not None:
            figs["envelope"] = env
        return figs

    # ------------------------------------------------------------------------------------------ persistence
    def save(self, path) -> Path:
        """Save the fitted model (LNN weights, scaling, the law, the report) to one .npz file — arrays and JSON,
        no pickle; written atomically."""
        import jax

        from nnphd.user.derivatives import METHODS
        from nnphd.user.strategies import family_filter

        self._check_fitted()
        path = Path(path)
        method, keys = self.derivatives.name, [k for k in self.library.families if isinstance(k, str)]
        if path.suffix != ".npz":
            raise ValueError(f"{path}: the model file must end in .npz")
        cons = self._model.conservative
        leaves = jax.tree_util.tree_leaves(cons.lnn)
        sc = cons.scaling
        law = None
        fitted = None if self.law_ is None else self.law_.fitted
        if fitted is not None:
            if fitted.family.spec is None:
                raise ValueError(f"the law family {self.law_.key!r} cannot be saved (no spec)")
            law = {"spec": fitted.family.spec, "beta": fitted.beta.tolist(), "theta": fitted.theta.tolist()}
        meta = {
            "format": "nnphd-model",
            "version": 1,
            "names": list(self.names_),
            "angles": [c in self.angles_ for c in self.names_],
            "cfg": asdict(cons.cfg),
            "scaling": {
                "mu_q": np.asarray(sc.mu_q).tolist(),
                "s_q": np.asarray(sc.s_q).tolist(),
                "t0": float(sc.t0),
                "s_t": float(sc.s_t),
            },
            "law": law,
            "report": self.report_,
            "n_leaves": len(leaves),
            "settings": {
                "seed": self.seed,
                "steps": self.steps,
                "n_seeds": self.n_seeds,
                "laws": list(self.laws),
                "law_fit": self.law_fit,
                "sr_time": self.sr_time,
                "trim": self.trim,
                "field": self.field,
                # the strategy objects' other fields, where not the default (older files have neither)
                # (your own estimator and Family objects are code: the built-in method's name and families' keys)
                **({"derivative_method": method} if method in METHODS and method != "auto" else {}),
                **({"thin": False} if not self.derivatives.thin else {}),
                **({"families": keys} if family_filter(keys) else {}),
            },
        }
        if self._model.field is not None:
            meta["field"] = self._model.field
        from nnphd.io.results import json_default

        arrays = {f"lnn_{i}": np.asarray(x) for i, x in enumerate(leaves)}
        arrays["meta"] = np.array(json.dumps(meta, default=json_default))
        path.parent.mkdir(parents=True, exist_ok=True)
        import io

        from nnphd.io.results import atomic_write_bytes

        buf = io.BytesIO()
        np.savez(buf, **arrays)
        atomic_write_bytes(path, buf.getvalue())
        return path

    def __repr__(self) -> str:
        if self._model is None:
            return f"NNPhD(seed={self.seed}, steps={self.steps}) — not fitted"
        law = "; ".join(f"{k} = {v}" for k, v in self.law_.formula.items()) if self.law_ else "no law"
        return f"NNPhD(seed={self.seed}): {self.status_} (confidence {self.confidence_:.2f}); {law}"


def load(path) -> NNPhD:
    """A model saved by :meth:`NNPhD.save`. The whole file is checked first (:mod:`nnphd.user.modelfile`: bounded
    reading, every field's type and size, the settings within the command line's ranges, the weights' shapes and
    finiteness, the law parsed, never executed), then the model is run once at states of its own scales
    (:func:`_check_forward`: its forces must be finite); a file that is not a valid model raises ValueError with one
    line naming the path and what is wrong."""
    import jax

    from nnphd.user.modelfile import read_model_file
    from nnphd.user.scaling import Scaling
    from nnphd.user.strategies import FAMILIES, Derivatives, LawLibrary

    mf = read_model_file(Path(path))
    meta, cfg = mf.meta, mf.cfg
    with _x64():
        lnn = jax.tree_util.tree_unflatten(mf.treedef, [jax.numpy.asarray(x) for x in mf.leaves])
    s = meta["scaling"]
    sc = Scaling(np.asarray(s["mu_q"], float), np.asarray(s["s_q"], float), float(s["t0"]), float(s["s_t"]))
    st = meta["settings"]
    try:  # a setting the file's types let through that NNPhD refuses (a trim that is none: Derivatives' check)
        model = NNPhD(
            seed=st["seed"],
            steps=st["steps"],
            n_seeds=st["n_seeds"],
            derivatives=Derivatives(
                method=st.get("derivative_method", "auto"), trim=st["trim"], thin=st.get("thin", True)
            ),
            library=LawLibrary(families=st.get("families", FAMILIES), laws=st["laws"], fit=st["law_fit"]),
            sr_time=st["sr_time"],
            field=st.get("field", "learned"),
        )
    except ValueError as e:
        raise ValueError(f"{path}: not a valid nnphd model file: settings: {e}") from None
    fitted = None if mf.family is None else FittedFamily(mf.family, mf.beta, mf.theta)
    names, angles = tuple(meta["names"]), tuple(bool(a) for a in meta["angles"])
    model._model = FittedModel(ConservativeModel(lnn, cfg, None, sc), None, None, None, names, angles, None, None,
                               meta.get("field"))  # fmt: skip
    model.report_ = meta["report"]
    model._set_results(DetectResult.from_dict(meta["report"], f"{path}: report"), fitted)
    _check_forward(model, path)
    return model


PROBE_STATES = ((-1.0, 1.0), (0.0, -1.0), (1.0, 0.5))  # (a, b) of load's forward pass: q = μ_q + a·s_q, q̇ = b·s_q/s_t


def _check_forward(model: NNPhD, path) -> None:
    """One forward pass of a loaded model at states of its own scales (:data:`PROBE_STATES`; t = t₀ + a·s_t): its
    scales, input scales, weights and law coefficients are each finite when checked, but extreme ones together
    (an input_scale of 1e-300, weights of 1e200) make :meth:`NNPhD.forces` return NaN or inf without a word. Such a
    file is refused with one ValueError line, as a file :func:`nnphd.user.modelfile.read_model_file` refuses. (The
    same functions as :meth:`NNPhD.forces`, run op by op, not compiled: ~10 ms once JAX has run those ops in the
    process, where compiling each loaded model's function would cost ~0.5 s on every load.)"""
    from nnphd.io.cache import one_line

    sc = model._model.conservative.scaling
    a, b = np.asarray(PROBE_STATES).T
    with np.errstate(all="ignore"):
        q = np.asarray(sc.mu_q, float) + a[:, None] * np.asarray(sc.s_q, float)
        qd = b[:, None] * np.asarray(sc.s_q, float) / sc.s_t
        t = sc.t0 + a * sc.s_t
    why = None
    if not (np.isfinite(q).all() and np.isfinite(qd).all() and np.isfinite(t).all()):
        why = "its scaling overflows (μ_q ± s_q, s_q/s_t or t₀ ± s_t is not finite)"
    else:
        with np.errstate(all="ignore"):  # (a law computed in numpy: the overflow is the finding, not a warning)
            fc, fn = model._forces(model._fc_raw(), q, qd, t)
        parts = (("the conservative force f_c (the network)", fc), ("the law's force f_n", fn))
        bad = next((what for what, f in parts if not np.isfinite(f).all()), None)
        if bad is not None:
            why = f"{bad} is not finite at states of its own scales (q = μ_q ± s_q, q̇ ~ s_q/s_t)"
    if why is not None:
        raise ValueError(one_line(f"{path}: not a valid nnphd model file: {why}"))
