"""A law that adds energy where the record loses it: :func:`nnphd.explain.wholerecord.active_share` and
:func:`nnphd.explain.wholerecord.passivity` on constructed rows, and the verdict's rule
:func:`nnphd.user.rules.unclaim_active` on constructed law tables."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pytest

from nnphd.explain import wholerecord as W
from nnphd.explain.table import LawTable
from nnphd.user.rules import unclaim_active


def test_the_active_share_of_drags_pumps_and_the_encoder_pendulums_law():
    rng = np.random.default_rng(0)
    q = rng.uniform(-2.7, 2.7, (4000, 1))
    v = rng.normal(size=(4000, 1))
    assert W.active_share(-0.4 * v, v) == 0.0  # viscous
    assert W.active_share(-0.1 * np.abs(v) * v - 0.02 * np.tanh(v / 0.01), v) == 0.0  # quadratic + dry
    assert W.active_share(0.3 * v, v) == 1.0  # anti-damping
    # the law once claimed on an encoder pendulum past 90°: 0.53 θ²θ̇ − 0.70 θ̇ pumps wherever |θ| > √(0.70/0.53) = 1.15 rad
    share = W.active_share((0.53 * q**2 - 0.70) * v, v)
    assert share == pytest.approx(np.mean(np.abs(q) > np.sqrt(0.70 / 0.53)), abs=0.01)
    assert share > 0.5
    # a force across the velocity (a magnetic field) does no work
    v2 = rng.normal(size=(100, 2))
    assert W.active_share(np.column_stack([-v2[:, 1], v2[:, 0]]), v2) == 0.0
    assert W.active_share(np.zeros((5, 1)), v[:5]) is None  # a zero force


@dataclass
class _Row:
    key: str
    force: float  # the row's force is force(q, v) = a·(q² − 1)·v + b·v: here simply coefficient on v and q²v
    pump: float = 0.0
    significant: bool = True
    ic: float = 0.0
    k: int = 2
    heldout_mse: float = 1.0
    family: object = "family"
    params: dict = field(default_factory=dict)
    stderr: dict = field(default_factory=dict)

    def predict(self, q, qd, t):
        return self.force * qd + self.pump * q**2 * qd

    @property
    def title(self):
        return self.key


@dataclass
class _Ranked:
    rows: list
    tau: float = 1.0
    settings: dict = field(default_factory=lambda: {"windows": 3, "in_sample": True, "conservative_columns": 3})


def _state(n=3000):
    rng = np.random.default_rng(1)
    return rng.uniform(-2.7, 2.7, (n, 1)), rng.normal(size=(n, 1)), np.arange(n) * 0.01


def _table(law, others):
    return LawTable([law, *others], law, "claimed", 100.0, 1.0, "windows", {})


def _lib(n):
    return LawTable([], None, "", 1.0, 1.0, "", {}, whole_record={"t": np.zeros(n)})


def test_a_passive_law_needs_no_whole_record_fit():
    q, v, t = _state()
    info = W.passivity(_table(_Row("linear", -0.4), []), None, q, v, t)
    assert info == {"law": "linear", "active_share": 0.0, "active": False, "threshold": W.ACTIVE_SHARE_MAX}


@pytest.mark.parametrize(("ic_law", "ic_passive", "margin"), [(0.0, 25.0, 25.0), (0.0, 4.0, 4.0)])
def test_an_active_law_is_compared_with_the_passive_families_over_the_whole_record(
    monkeypatch, ic_law, ic_passive, margin
):
    q, v, t = _state()
    law = _Row("vanderpol", -0.7, pump=0.53)
    rows = [law, _Row("linear", -0.4), _Row("quadratic", -0.1, significant=False), _Row("rayleigh", 0.3)]
    n = len(t)  # τ = 1: n_eff = n, so the IC difference is n·log of the χ²/N ratio
    fits = [("lib", _Ranked([_Row("vanderpol", 0, heldout_mse=np.exp(ic_law / n)),
                             _Row("linear", 0, heldout_mse=np.exp(ic_passive / n))]))]  # fmt: skip
    asked = []
    monkeypatch.setattr(W, "whole_record_fits", lambda ctx, keys: (asked.append(keys), (fits, None))[1])
    info = W.passivity(_table(law, rows[1:]), _lib(n), q, v, t)
    assert asked == [["vanderpol", "linear"]]  # the eligible passive families only (quadratic is not eligible,
    assert info["passive_candidates"] == ["linear"]  # Rayleigh with a = +0.3 pumps everywhere)
    assert info["active"] and info["active_share"] > 0.5
    assert info["margin"] == pytest.approx(margin, abs=1e-6) and info["best_passive"] == "linear"


def _law_dict(info, direction="loses energy"):
    law = {
        "law": {"title": "van der Pol", "key": "vanderpol"},
        "status": "claimed",
        "ties": [],
        "passivity": info,
        "reason": "r",
    }
    res = {"evidence": {"combined": {"direction": direction, "significant": True}}}
    return res, law


def test_an_active_law_on_a_record_losing_energy_is_claimed_only_far_ahead_of_every_passive_family():
    info = {"law": "vanderpol", "active": True, "active_share": 0.62, "margin": 4.0, "best_passive": "linear"}
    law, why = unclaim_active(*_law_dict(info))
    assert why.startswith("no law is claimed: the best candidate, van der Pol, adds energy on 62% of the visited")
    assert "only +4.0 in IC against the best passive family, linear" in why
    assert law["law"] is None and law["candidate_law"]["key"] == "vanderpol" and law["status"] == "none"
    assert law["passivity"] == info and list(law)[-1] == "candidate_law"
    # far enough ahead: kept
    law, why = unclaim_active(*_law_dict({**info, "margin": 12.0}))
    assert why is None and law["law"]["key"] == "vanderpol"
    # no whole-record fit at all: not claimed, and the reason says why
    res, law = _law_dict({"law": "vanderpol", "active": True, "active_share": 0.3, "why": "two coordinates"})
    assert "no fit over the whole record could prefer it (two coordinates)" in unclaim_active(res, law).why


@pytest.mark.parametrize("direction", ["gains energy", "none"])
def test_a_pump_on_a_record_that_does_not_lose_energy_stays_claimed(direction):
    info = {"law": "vanderpol", "active": True, "active_share": 0.62, "margin": -3.0, "best_passive": "linear"}
    law, why = unclaim_active(*_law_dict(info, direction))
    assert why is None and law["law"]["key"] == "vanderpol"


def test_a_force_of_the_state_is_a_force_of_position_on_one_orbit_but_not_on_a_1d_oscillation():
    from nnphd.explain.work import position_explained

    t = np.arange(0.0, 60.0, 0.05)  # ~9.5 periods of 2π
    # a slightly eccentric orbit in the plane: each position comes with one velocity
    q2 = np.column_stack([1.1 * np.cos(t), np.sin(t)])
    v2 = np.column_stack([-1.1 * np.sin(t), np.cos(t)])
    odd = 0.3 * v2 + 0.1 * v2**3  # a "sparse polynomial odd in q̇"
    assert position_explained(odd, q2, t, period=2 * np.pi) > 0.9
    # a 1-D oscillation: each position comes with ±q̇, so a drag (odd in q̇) is no function of position
    q1, v1 = np.cos(t)[:, None], -np.sin(t)[:, None]
    assert position_explained(-0.2 * v1, q1, t, period=2 * np.pi) < 0.2
    assert position_explained(0.2 * (1 - v1**2) * v1, q1, t, period=2 * np.pi) < 0.2
    # ... while a force of position is, in either case
    assert position_explained(-(q1**3), q1, t, period=2 * np.pi) > 0.9


def test_a_law_that_differs_at_the_same_state_on_another_pass_is_no_reproducible_force_of_the_state():
    from nnphd.explain.work import position_explained

    t = np.arange(0.0, 60.0, 0.05)
    q = np.column_stack([1.1 * np.cos(t), np.sin(t)])
    v = np.column_stack([-1.1 * np.sin(t), np.cos(t)])
    x = np.hstack([q, v])
    smooth = 0.3 * v + 0.1 * v**3
    assert position_explained(smooth, x, t, period=2 * np.pi) > 0.9
    # an ill-conditioned fit: its force changes from pass to pass at the same state (here: with the pass number)
    erratic = smooth * np.cos(7.0 * np.floor(t / (2 * np.pi)))[:, None]
    assert position_explained(erratic, x, t, period=2 * np.pi) < 0.5
