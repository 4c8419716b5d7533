"""Camera marker tracks → constraints → generalized coordinates (issue 58).

A camera user has the image positions of a few markers (a pivot, a joint, a bob, a cart), frame by frame, in pixels,
with dropped frames and a pixel of jitter: columns ``<marker>_x``, ``<marker>_y`` (and ``_z``), with ``t`` — or a
``frame`` column and the frame rate — and optionally ``traj``. This module finds the holonomic constraints the
markers keep, each tested against the tracking noise and against the marker's own motion, and chooses minimal
generalized coordinates from them:

- **fixed**: a marker whose positions scatter by less than :data:`FIXED_REL` of the scene's motion (a pivot);
- **pivot (untracked)**: the common centre of a moving marker's circular arcs, when it keeps its distance to a point
  that is not tracked (its circle fitted; the radius within :data:`ROD_REL`);
- **rod**: a pair of markers at a constant distance (within :data:`ROD_REL` of the distance, and the distance
  varying by less than :data:`ROD_VS_FREE` of their relative motion); a pair that holds only to :data:`ROUGH_REL`
  (a flexible rod, a slipping string, a spring) is reported as *rough* and not assumed;
- **rail**: a moving marker on a straight line (its scatter across the line within :data:`ROD_REL` of its travel);
- what is left is **free**.

Coordinates: from the fixed points outwards, a marker held by a rod to one placed point gets the rod's angle
(``theta_<marker>``, from the image's +x axis, unwrapped through whole turns); a marker held by rods to two placed
points is part of a rigid body and gets none; a marker on a rail its position along it (``s_<marker>``); a free marker
its own x, y (from the first fixed point, if any). Gravity's direction is not assumed: the learned Lagrangian finds
it. Nothing here is evaluated: names are matched against a pattern and numbers parsed by the reader.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

FIXED_REL = 0.02  # a marker scattering by less than this share of the scene's motion (rms) is fixed
ROD_REL = 0.01  # a distance constant to this share of itself is a rod (an arc's radius: an untracked pivot)
ROD_VS_FREE = 0.05  # ... and varying by less than this share of the pair's relative motion (rms)
ROUGH_REL = 0.05  # up to this share: a rough constraint (flexible rod, slipping string): reported, not assumed
MIN_ARC_DEG = 30.0  # an untracked pivot needs arcs spanning at least this angle about it
GAP_STEPS = 10.0  # a gap of more frames than this starts a new trajectory
SWAP_FACTOR = 5.0  # a frame-to-frame step this many times the 99th percentile of steps, undone by a swap: a swap
AXES = ("x", "y", "z")
_MARKER = re.compile(r"^(?P<m>[A-Za-z][A-Za-z0-9]*(?:[_ .-][A-Za-z0-9]+)*?)_(?P<a>[xyzXYZ])$")


class MarkerError(ValueError):
    """A marker recording that cannot be read as one: one line naming what was wrong and what was expected."""


@dataclass(frozen=True)
class Constraint:
    """One constraint found in the tracks: ``kind`` (fixed, pivot, rod, rail, rough), the ``markers`` it holds,
    ``value`` (a rod's length, a fixed point or an untracked pivot's position, a rail's direction), ``scatter`` (rms,
    in the recording's units), ``rel`` (scatter against the value or the travel), ``noise_ratio`` (scatter against
    the tracking noise) and ``vs_free`` (scatter against the same quantity's spread without the constraint: how much
    better than free; 0 best)."""

    kind: str
    markers: tuple[str, ...]
    value: tuple[float, ...]
    scatter: float
    rel: float
    noise_ratio: float
    vs_free: float

    def to_dict(self) -> dict:
        return {
            "kind": self.kind,
            "markers": list(self.markers),
            "value": [float(v) for v in self.value],
            "scatter": float(self.scatter),
            "rel": float(self.rel),
            "noise_ratio": float(self.noise_ratio),
            "vs_free": float(self.vs_free),
            "text": self.text(),
        }

    def text(self) -> str:
        m = " – ".join(self.markers)
        if self.kind == "fixed":
            return f"{m} is fixed (scatter {self.scatter:.3g}, {100 * self.rel:.2g}% of the motion)"
        if self.kind == "pivot":
            return (
                f"{self.markers[1]} turns about an untracked pivot at ({', '.join(f'{v:.4g}' for v in self.value[:-1])}),"
                f" radius {self.value[-1]:.4g} ± {self.scatter:.2g} ({100 * self.rel:.2g}%)"
            )
        if self.kind == "rod":
            return (
                f"rod {m}: length {self.value[0]:.4g} ± {self.scatter:.2g} ({100 * self.rel:.2g}%, "
                f"{self.noise_ratio:.1f}× the tracking noise; the distance varies {self.vs_free:.2g}× as much as "
                "the pair's relative motion)"
            )
        if self.kind == "rail":
            return f"{m} runs on a straight line (scatter across it {self.scatter:.3g}, {100 * self.rel:.2g}% of its travel)"
        return (
            f"{m}: distance {self.value[0]:.4g} ± {self.scatter:.2g} ({100 * self.rel:.2g}%) — roughly constant, "
            "not assumed (a flexible rod, a slipping string or a spring?)"
        )


@dataclass(frozen=True)
class Coordinate:
    """A generalized coordinate: its ``name``, ``kind`` (angle, rail, free), the ``marker`` it places, the point it
    is measured from (``anchor``) and ``why``."""

    name: str
    kind: str
    marker: str
    anchor: str | None
    why: str

    def to_dict(self) -> dict:
        return {"name": self.name, "kind": self.kind, "marker": self.marker, "anchor": self.anchor, "why": self.why}


@dataclass(frozen=True)
class MarkerModel:
    """The constraints and coordinates of a marker recording: ``markers`` (names), ``dim`` (2 or 3), ``noise`` per
    marker (rms), ``constraints``, ``coordinates``, ``assumed`` (what was assumed, in words), ``dropped`` (rows left
    out: a marker missing), ``t``, ``q`` (N, n) the coordinates, ``traj`` (N,) their trajectories (a gap in the
    frames starts a new one), and the tracks ``positions`` (marker → (N, dim), for the picture)."""

    markers: tuple[str, ...]
    dim: int
    noise: dict
    constraints: tuple[Constraint, ...]
    coordinates: tuple[Coordinate, ...]
    assumed: tuple[str, ...]
    dropped: int
    t: np.ndarray
    q: np.ndarray
    traj: np.ndarray
    positions: dict = field(repr=False)
    anchors: dict = field(repr=False, default_factory=dict)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(c.name for c in self.coordinates)

    @property
    def angles(self) -> tuple[str, ...]:
        return tuple(c.name for c in self.coordinates if c.kind == "angle")

    def to_dict(self) -> dict:
        return {
            "markers": list(self.markers),
            "dim": self.dim,
            "noise": {k: float(v) for k, v in self.noise.items()},
            "constraints": [c.to_dict() for c in self.constraints],
            "coordinates": [c.to_dict() for c in self.coordinates],
            "assumed": list(self.assumed),
            "dropped_rows": int(self.dropped),
            "summary": self.summary(),
            "note": self.note(),
        }

    def note(self) -> str | None:
        """One line when the markers admit no simple constraint set — a constraint that holds only roughly, or
        several markers and nothing holding them — saying what was found instead; else None."""
        rough = [c for c in self.constraints if c.kind == "rough"]
        free = sorted({c.marker for c in self.coordinates if c.kind == "free"})
        if rough:
            r = rough[0]
            return (
                f"no simple constraint set: {' – '.join(r.markers)} keep their distance only to {100 * r.rel:.2g}% "
                f"(a flexible rod, a slipping string?); not assumed: {', '.join(free) or 'its markers'} left free"
            )
        if len(free) > 1 and not any(c.kind in ("rod", "pivot", "rail") for c in self.constraints):
            return f"no constraint holds the markers {', '.join(free)}: each is left free (x, y)"
        return None

    def summary(self) -> str:
        held = [c for c in self.constraints if c.kind != "rough"]
        kinds = ", ".join(f"{sum(c.kind == k for c in held)} {k}" for k in ("fixed", "pivot", "rod", "rail")
                          if any(c.kind == k for c in held))  # fmt: skip
        return f"{len(self.markers)} markers; constraints: {kinds or 'none'}; coordinates: " + ", ".join(
            f"{c.name} ({c.kind})" for c in self.coordinates
        )


# ---- reading ------------------------------------------------------------------------------------------------------
def marker_columns(names: Sequence[str], markers: Sequence[str] | str = "auto") -> dict[str, tuple[str, ...]]:
    """The marker columns among ``names``: marker → its axis columns (x, y[, z]). ``markers``: "auto" (every column
    named ``<marker>_x``/``_y``/``_z``) or the markers' names. One-line :class:`MarkerError` when a marker lacks an
    axis, the markers differ in their axes, a named marker has no columns, or fewer than one marker is found."""
    found: dict[str, dict[str, str]] = {}
    for c in names:
        m = _MARKER.match(c)
        if m and c not in ("t", "frame", "traj"):
            found.setdefault(m["m"], {})[m["a"].lower()] = c
    if isinstance(markers, str) and markers != "auto":
        markers = [x.strip() for x in markers.split(",")]
    if not isinstance(markers, str):
        missing = [m for m in markers if m not in found]
        if missing or not markers or len(set(markers)) != len(markers):
            raise MarkerError(
                f"marker {_name(missing[0]) if missing else '(none)'} has no <marker>_x, <marker>_y columns; "
                f"expected markers among: {', '.join(_name(m) for m in found) or '(none found)'}"
            )
        found = {m: found[m] for m in markers}
    if not found:
        raise MarkerError("no marker columns (<marker>_x, <marker>_y, optionally <marker>_z) found")
    dims = set()
    for m, axes in found.items():
        have = [a for a in AXES if a in axes]
        need = list(AXES[: max(2, len(have))]) if "z" not in axes else list(AXES)
        lack = [a for a in need if a not in axes]
        if lack:
            raise MarkerError(
                f"marker {_name(m)} has {', '.join(_name(axes[a]) for a in have)} but no {_name(m + '_' + lack[0])}:"
                " expected one column per axis (x, y, and z for 3-D)"
            )
        dims.add(len(need))
    if len(dims) > 1:
        raise MarkerError("the markers differ in their axes: expected all 2-D (x, y) or all 3-D (x, y, z)")
    d = dims.pop()
    return {m: tuple(axes[a] for a in AXES[:d]) for m, axes in found.items()}


def _name(s: str, n: int = 40) -> str:
    s = str(s)
    return repr(s if len(s) <= n else s[: n - 1] + "…")


def _ident(marker: str) -> str:
    """A marker's name as part of a coordinate's name (Tracker's "mass A" → "mass_A")."""
    return re.sub(r"[^A-Za-z0-9_]", "_", marker)


def marker_times(columns: dict, fps: float | None) -> np.ndarray:
    """The times of a marker recording: its ``t`` column, or its ``frame`` column / ``fps``. One-line error when
    neither is usable."""
    if "t" in columns:
        if fps is not None and "frame" in columns:
            raise MarkerError("the file has both t and frame columns and --fps was given: give one clock (drop --fps)")
        return np.asarray(columns["t"], float)
    if "frame" not in columns:
        raise MarkerError("a marker recording needs a t column, or a frame column and the frame rate (--fps)")
    if fps is None:
        raise MarkerError("the file counts frames (a frame column, no t): give the frame rate, e.g. --fps 400")
    if not (np.isfinite(fps) and fps > 0):
        raise MarkerError(f"--fps must be a positive number of frames per second, got {fps!r}")
    return np.asarray(columns["frame"], float) / float(fps)


# ---- the tracks ---------------------------------------------------------------------------------------------------
def tracking_noise(p: np.ndarray) -> float:
    """The tracking noise of one marker's positions (N, d): the rms per axis of its second differences / √6 (white
    noise ε gives Δ²ε of variance 6σ²), by the median absolute deviation (robust to the motion's own curvature at
    high frame rates and to a few glitches)."""
    d2 = np.diff(p, 2, axis=0)
    d2 = d2[np.all(np.isfinite(d2), axis=1)]
    if len(d2) < 3:
        return float("nan")
    mad = np.median(np.abs(d2 - np.median(d2, axis=0)), axis=0) / 0.6745
    return float(np.sqrt(np.mean(mad**2)) / np.sqrt(6.0))


def _check_tracks(P: dict[str, np.ndarray]) -> None:
    """A constant coordinate column, or two markers that swap identity between frames: one-line error."""
    for m, p in P.items():
        for j in range(p.shape[1]):
            col = p[:, j][np.isfinite(p[:, j])]
            if col.size and np.ptp(col) == 0:
                # a fixed marker still jitters; a column without a single change is no track
                raise MarkerError(
                    f"marker {_name(m)}: its {AXES[j]} column is constant ({col[0]:g} in every frame): expected a "
                    "tracked position (a fixed marker still jitters by the tracking noise)"
                )
    names = list(P)
    steps = {m: np.linalg.norm(np.diff(P[m], axis=0), axis=1) for m in names}
    for i, a in enumerate(names):
        for b in names[i + 1 :]:
            pa, pb = P[a], P[b]
            same = steps[a] + steps[b]
            swap = np.linalg.norm(pb[1:] - pa[:-1], axis=1) + np.linalg.norm(pa[1:] - pb[:-1], axis=1)
            ok = np.isfinite(same) & np.isfinite(swap)
            if not ok.any():
                continue
            typical = np.percentile(same[ok], 99)
            bad = ok & (same > SWAP_FACTOR * max(typical, 1e-300)) & (swap < 0.5 * same)
            if bad.any():
                k = int(np.flatnonzero(bad)[0]) + 1
                raise MarkerError(
                    f"markers {_name(a)} and {_name(b)} swap identity at row {k + 1} (each jumps to where the other "
                    "was): expected each marker tracked as the same point in every frame — fix the tracking there"
                )


def _fit_circle(p: np.ndarray) -> tuple[np.ndarray, float] | None:
    """The circle (sphere in 3-D) through positions p (N, d), by linear least squares (|p|² = 2c·p + k), or None."""
    A = np.concatenate([2 * p, np.ones((len(p), 1))], axis=1)
    b = np.sum(p * p, axis=1)
    sol, *_ = np.linalg.lstsq(A, b, rcond=None)
    c = sol[:-1]
    r2 = sol[-1] + c @ c
    if not np.isfinite(r2) or r2 <= 0:
        return None
    return c, float(np.sqrt(r2))


def _arc_span_deg(p: np.ndarray, c: np.ndarray) -> float:
    """How many degrees of a circle about c the positions p cover (2-D: the largest gap's complement; 3-D: the
    largest angle between a position and the mean direction, doubled)."""
    v = p - c
    if p.shape[1] == 2:
        a = np.sort(np.mod(np.arctan2(v[:, 1], v[:, 0]), 2 * np.pi))
        gaps = np.diff(np.concatenate([a, a[:1] + 2 * np.pi]))
        return float(np.degrees(2 * np.pi - gaps.max()))
    u = v / np.linalg.norm(v, axis=1, keepdims=True)
    m = u.mean(0)
    m = m / max(np.linalg.norm(m), 1e-300)
    return float(2 * np.degrees(np.arccos(np.clip(u @ m, -1, 1)).max()))


def analyse(t: np.ndarray, P: dict[str, np.ndarray], traj: np.ndarray | None = None) -> MarkerModel:
    """The constraints and generalized coordinates of marker tracks ``P`` (marker → (N, d) positions; NaN where a
    frame lost the marker) at times ``t`` (N,), trajectories ``traj`` (N,) or one. A row that lost a marker is left
    out, and a trajectory is cut where many frames are missing (a gap of more than GAP_STEPS steps). One-line
    :class:`MarkerError` when the tracks cannot be used (a constant column, a swap, too few rows) or when no
    coordinate can be chosen."""
    markers = tuple(P)
    d = next(iter(P.values())).shape[1]
    t = np.asarray(t, float)
    traj = np.zeros(len(t), np.int64) if traj is None else np.asarray(traj)
    ok = np.isfinite(t) & np.all([np.all(np.isfinite(P[m]), axis=1) for m in markers], axis=0)
    if ok.sum() < 20:
        raise MarkerError(f"only {int(ok.sum())} frames have every marker: expected at least 20")
    t, traj = t[ok], traj[ok]
    P = {m: np.asarray(P[m], float)[ok] for m in markers}
    _check_tracks(P)
    traj = _split_at_gaps(t, traj)
    tracks = _Tracks(P, {m: tracking_noise(P[m]) for m in markers})
    constraints, fixed = tracks.fixed()
    if len(fixed) == len(markers):
        raise MarkerError("no marker moves (every one scatters by less than 2% of the others): nothing to model")
    rods: dict[frozenset, float] = {}
    constraints += tracks.pairs(fixed, rods)
    anchors = {m: tracks.centre[m] for m in fixed}
    constraints += tracks.untracked_pivots(fixed, rods, anchors)
    on_rails, rails = tracks.rails(fixed, rods, anchors)
    constraints += on_rails
    coords, q_cols, assumed = _choose(markers, fixed, anchors, rods, rails, P, tracks.centre, traj, d)
    if not coords:
        raise MarkerError("no generalized coordinate could be chosen from the markers")
    return MarkerModel(
        markers=markers,
        dim=d,
        noise=tracks.noise,
        constraints=tuple(constraints),
        coordinates=tuple(coords),
        assumed=tuple(assumed),
        dropped=int((~ok).sum()),
        t=t,
        q=np.stack(q_cols, axis=1),
        traj=traj,
        positions=P,
        anchors={k: np.asarray(v, float) for k, v in anchors.items()},
    )


class _Tracks:
    """The tracks of one recording and the tests of each kind of constraint on them (:func:`analyse`)."""

    def __init__(self, P: dict[str, np.ndarray], noise: dict[str, float]):
        self.P, self.noise = P, noise
        self.markers = tuple(P)
        self.centre = {m: np.median(p, axis=0) for m, p in P.items()}
        self.spread = {m: float(np.sqrt(np.mean(np.sum((p - self.centre[m]) ** 2, axis=1)))) for m, p in P.items()}
        self.scene = max(self.spread.values())

    def _noise_ratio(self, scatter: float, *markers: str) -> float:
        return scatter / max(float(np.sqrt(sum(self.noise[m] ** 2 for m in markers))), 1e-300)

    def fixed(self) -> tuple[list[Constraint], list[str]]:
        """The markers that scatter by less than FIXED_REL of the scene's motion."""
        fixed = [m for m in self.markers if self.spread[m] <= FIXED_REL * self.scene]
        out = [
            Constraint(
                "fixed",
                (m,),
                tuple(self.centre[m]),
                self.spread[m],
                self.spread[m] / self.scene,
                self._noise_ratio(self.spread[m], m),
                self.spread[m] / self.scene,
            )  # fmt: skip
            for m in fixed
        ]
        return out, fixed

    def pairs(self, fixed: list[str], rods: dict) -> list[Constraint]:
        """Rods (and rough ones) between pairs of markers, not both fixed; the rods' lengths into ``rods``."""
        out = []
        for i, a in enumerate(self.markers):
            for b in self.markers[i + 1 :]:
                if a in fixed and b in fixed:
                    continue
                rel_v = self.P[b] - self.P[a]
                dist = np.linalg.norm(rel_v, axis=1)
                length, sc = float(np.median(dist)), float(np.std(dist))
                rel = sc / max(length, 1e-300)
                vs_free = sc / max(float(np.sqrt(np.mean(np.sum((rel_v - rel_v.mean(0)) ** 2, axis=1)))), 1e-300)
                if rel <= ROD_REL and vs_free <= ROD_VS_FREE:
                    out.append(Constraint("rod", (a, b), (length,), sc, rel, self._noise_ratio(sc, a, b), vs_free))
                    rods[frozenset((a, b))] = length
                elif rel <= ROUGH_REL and vs_free <= 4 * ROD_VS_FREE:
                    out.append(Constraint("rough", (a, b), (length,), sc, rel, self._noise_ratio(sc, a, b), vs_free))
        return out

    def untracked_pivots(self, fixed: list[str], rods: dict, anchors: dict) -> list[Constraint]:
        """A moving marker with no rod to a fixed point, on a circle about a point nobody tracks (its arcs spanning
        MIN_ARC_DEG, the radius constant to ROD_REL): an untracked pivot, shared by markers whose centres agree to
        ROD_REL of the radius; the radii into ``rods``, the pivots into ``anchors``."""
        out, pivots = [], []
        for m in self.markers:
            if m in fixed or any(frozenset((m, f)) in rods for f in fixed):
                continue
            fit = _fit_circle(self.P[m])
            if fit is None:
                continue
            c, r = fit
            sc = float(np.std(np.linalg.norm(self.P[m] - c, axis=1)))
            far = r > 20 * max(self.spread[m], 1e-300)  # a nearly straight track: no pivot in view
            if sc > ROD_REL * r or far or _arc_span_deg(self.P[m], c) < MIN_ARC_DEG:
                continue
            name = next((p for p, pc, pr in pivots if np.linalg.norm(pc - c) <= ROD_REL * max(r, pr)), None)
            if name is None:
                name = "pivot" if not pivots and "pivot" not in self.markers else f"pivot{len(pivots) + 1}"
                pivots.append((name, c, r))
                anchors[name] = c
            out.append(Constraint("pivot", (name, m), (*c, r), sc, sc / r, self._noise_ratio(sc, m),
                                  sc / max(self.spread[m], 1e-300)))  # fmt: skip
            rods[frozenset((name, m))] = r
        return out

    def rails(self, fixed: list[str], rods: dict, anchors: dict) -> tuple[list[Constraint], dict]:
        """A moving marker held by no rod to a fixed point or pivot (``anchors``) whose scatter across its principal
        line is within ROD_REL of its travel along it (a cart — a pendulum may hang from it); (the constraints, the
        lines' directions by marker)."""
        out, rails = [], {}
        for m in self.markers:
            if m in fixed or any(frozenset((m, a)) in rods for a in anchors):
                continue
            x = self.P[m] - self.P[m].mean(0)
            _, sv, vt = np.linalg.svd(x, full_matrices=False)
            along = sv[0] / np.sqrt(len(x))
            across = float(np.sqrt(np.sum(sv[1:] ** 2) / len(x)))
            if along > 0 and across <= ROD_REL * along:
                rails[m] = vt[0]
                out.append(Constraint("rail", (m,), tuple(vt[0]), across, across / along,
                                      self._noise_ratio(across, m), across / along))  # fmt: skip
        return out, rails


def _split_at_gaps(t: np.ndarray, traj: np.ndarray) -> np.ndarray:
    """Trajectory ids with a new trajectory wherever many frames are missing (a step over GAP_STEPS median steps;
    a few lost frames are a short gap the derivative estimates bridge)."""
    out = np.zeros(len(t), np.int64)
    out[1:] = np.cumsum(traj[1:] != traj[:-1])  # a new id wherever the file's trajectory changes
    new = out.copy()
    shift = 0
    for tid in np.unique(out):
        idx = np.flatnonzero(out == tid)
        dt = np.diff(t[idx])
        if len(dt) == 0:
            new[idx] = tid + shift
            continue
        cuts = np.concatenate([[0], np.cumsum(dt > GAP_STEPS * np.median(dt))])
        new[idx] = tid + shift + cuts
        shift += int(cuts[-1])
    return new


def _unwrapped_angle(v: np.ndarray, traj: np.ndarray) -> np.ndarray:
    """atan2 of the 2-D vectors v (N, 2), unwrapped within each trajectory (whole turns kept)."""
    a = np.arctan2(v[:, 1], v[:, 0])
    out = np.empty_like(a)
    for tid in np.unique(traj):
        idx = np.flatnonzero(traj == tid)
        out[idx] = np.unwrap(a[idx])
    return out


def _choose(markers, fixed, anchors, rods, rails, P, centre, traj, d):
    """Minimal coordinates: from the fixed points (tracked or not) outwards along the rods, then the rails, then free
    markers; returns (coordinates, their columns, what was assumed)."""
    coords: list[Coordinate] = []
    cols: list[np.ndarray] = []
    assumed: list[str] = []
    pos = {**{m: P[m] for m in markers}, **{a: np.broadcast_to(c, P[markers[0]].shape) for a, c in anchors.items()
                                            if a not in P}}  # fmt: skip
    placed = set(fixed) | {a for a in anchors if a not in P}
    todo = [m for m in markers if m not in placed]
    origin = next(iter(anchors.values()), None)

    def rods_to_placed(m):
        return [p for p in sorted(placed, key=lambda x: (x not in fixed, x)) if frozenset((m, p)) in rods]

    while todo:
        progress = False
        for m in list(todo):
            held = rods_to_placed(m)
            if len(held) >= 2:
                coords_note = f"held by rods to {', '.join(held)}: a point of a rigid body, no coordinate of its own"
                assumed.append(f"{m}: {coords_note}")
                todo.remove(m)
                placed.add(m)
                progress = True
            elif len(held) == 1:
                p = held[0]
                if d == 3:  # a spherical pendulum: two angles
                    v = pos[m] - pos[p]
                    r = np.linalg.norm(v, axis=1)
                    cols += [_unwrapped_angle(v[:, :2], traj), np.arccos(np.clip(v[:, 2] / r, -1, 1))]
                    coords += [Coordinate(f"phi_{_ident(m)}", "angle", m, p, f"rod {p}–{m}: azimuth"),
                               Coordinate(f"psi_{_ident(m)}", "angle", m, p, f"rod {p}–{m}: polar angle from +z")]  # fmt: skip
                else:
                    cols.append(_unwrapped_angle(pos[m] - pos[p], traj))
                    coords.append(Coordinate(f"theta_{_ident(m)}", "angle", m, p, f"rod {p}–{m} of constant length"))
                todo.remove(m)
                placed.add(m)
                progress = True
        if progress:
            continue
        # nothing holds any of them to a placed point: a rail first, else the marker with the most rods (the others
        # hang from it), free
        m = max(todo, key=lambda x: (x in rails, sum(x in k for k in rods), -todo.index(x)))
        todo.remove(m)
        placed.add(m)
        if m in rails:
            cols.append((P[m] - centre[m]) @ rails[m])
            coords.append(Coordinate(f"s_{_ident(m)}", "rail", m, None, "on a straight line: the position along it"))
        else:
            o = origin if origin is not None else np.zeros(d)
            why = "no constraint holds it"
            if origin is not None:  # how far from a rod it is: a spring's length, a thrown ball's flight
                r = np.linalg.norm(P[m] - o, axis=1)
                why += (
                    f" (its distance to the fixed point varies by {100 * np.std(r) / max(np.median(r), 1e-300):.3g}%)"
                )
            for j in range(d):
                cols.append(P[m][:, j] - o[j])
                coords.append(Coordinate(f"{_ident(m)}_{AXES[j]}", "free", m, None, why))
    if any(c.kind == "angle" for c in coords):
        assumed.append(
            "angles are measured from the image's +x axis (gravity's direction is not assumed: the learned "
            "Lagrangian finds it); rods are taken rigid at their median length"
        )
    return coords, cols, assumed


def from_columns(
    columns: dict[str, np.ndarray], markers: Sequence[str] | str = "auto", fps: float | None = None
) -> MarkerModel:
    """A marker recording read as columns (``t`` or ``frame``, optional ``traj``, ``<marker>_x``/``_y``[/``_z``];
    NaN where a frame lost a marker) → its :class:`MarkerModel`. Columns other than these are refused."""
    mc = marker_columns(list(columns), markers)
    used = {c for cols in mc.values() for c in cols} | {"t", "frame", "traj"}
    other = [c for c in columns if c not in used]
    if other and markers == "auto":
        raise MarkerError(
            f"column {_name(other[0])} is neither t, frame, traj nor a marker axis (<marker>_x, _y, _z): expected "
            "marker columns only (or name the markers with --markers)"
        )
    t = marker_times(columns, fps)
    P = {m: np.stack([np.asarray(columns[c], float) for c in cols], axis=1) for m, cols in mc.items()}
    traj = columns.get("traj")
    return analyse(t, P, None if traj is None else np.asarray(traj))


def looks_like_markers(names: Sequence[str]) -> bool:
    """Whether a table's columns read as a marker recording: every column but ``t``, ``frame`` and ``traj`` named
    ``<marker>_<axis>`` (x, y, z), of at least two markers or with a ``frame`` column (an incomplete marker is
    then refused by :func:`marker_columns`, with its name)."""
    rest = [c for c in names if c not in ("t", "frame", "traj")]
    found = [_MARKER.match(c) for c in rest]
    if not rest or not all(found):
        return False
    return len({m["m"] for m in found}) >= 2 or "frame" in names
