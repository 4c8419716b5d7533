"""One law from two conservative bases (:func:`nnphd.explain.table.combine_bases`) and the candidate that bars a
weaker law (:func:`nnphd.explain.envelope.blocked_by_disagreement`): the rules on hand-made law tables."""

from __future__ import annotations

import numpy as np
import pytest

from nnphd.explain.envelope import blocked_by_disagreement
from nnphd.explain.families import families
from nnphd.explain.table import LawTable, combine_bases, law_row, preferred, zero_row


def _row(key, beta, ic, significant=True, barred_only_by_disagreement=False, env_dic=None, win_dic=None):
    fam = next(f for f in families(1, ["th"], np.ones(1)) if f.key == key)
    beta = np.asarray(beta, float)
    r = law_row(fam, beta, np.zeros(len(fam.nl_names)), 0.01 * np.ones(len(beta) + len(fam.nl_names)), ["th"], 1.0,
                 "trajectory")  # fmt: skip
    r.ic, r.delta_ic, r.significant = ic, ic, significant
    r.envelope = {
        "agree": significant,
        "distance2": 12.0,
        "eligible_but_agreement": barred_only_by_disagreement,
        "delta_ic": ic if env_dic is None else env_dic,  # the envelope's ΔIC and the windows' (they add up to ic)
        "windows": {"delta_ic": 0.0 if win_dic is None else win_dic},
    }
    return r


def _table(rows, law=None, ties=(), blocked=None):
    zero = zero_row(["th"], 1.0, 10, "trajectory")
    zero.ic = zero.delta_ic = 0.0
    return LawTable([zero, *rows], law, "r", 10.0, 1.0, "f", {}, list(ties), blocked)


def test_a_candidate_the_envelope_clearly_prefers_bars_a_weaker_law_when_only_its_fits_disagree():
    # the 157° encoder pendulum with the library as base: van der Pol claimed, viscous + dry far better on the
    # envelope and no worse on the windows, its two fits 3.4 se apart
    vdp = _row("vanderpol", [-0.6, 0.4], -35.0, env_dic=-30.7, win_dic=-4.35)
    both = _row("linear+coulomb", [0.2, 2.0], -70.0, False, True, env_dic=-65.1, win_dic=-4.9)
    assert blocked_by_disagreement(_table([vdp, both], law=vdp)) is both
    # the envelope's preference within IC_TIE, or the windows worse than the law's: the law stands
    near = _row("linear+coulomb", [0.2, 2.0], -39.0, False, True, env_dic=-33.0, win_dic=-6.0)
    assert blocked_by_disagreement(_table([vdp, near], law=vdp)) is None
    worse_windows = _row("linear+coulomb", [0.2, 2.0], -70.0, False, True, env_dic=-67.0, win_dic=-3.0)
    assert blocked_by_disagreement(_table([vdp, worse_windows], law=vdp)) is None
    # barred for another reason too (a term within 2 se of zero): the law stands
    other = _row("linear+coulomb", [0.2, 2.0], -70.0, False, False, env_dic=-65.1, win_dic=-4.9)
    assert blocked_by_disagreement(_table([vdp, other], law=vdp)) is None
    # a seismometer: a Rayleigh law only the windows prefer (6 IC), its envelope 1.9 ahead: viscous damping stands
    lin = _row("linear", [0.062], -50.2, env_dic=-51.5, win_dic=1.3)
    ray = _row("rayleigh", [-0.087, 17.0], -58.1, False, True, env_dic=-53.4, win_dic=-4.7)
    assert blocked_by_disagreement(_table([lin, ray], law=lin)) is None
    # no law at all: the reference is the zero law (ΔIC 0 on both)
    assert blocked_by_disagreement(_table([both])) is both


def test_both_bases_pointing_to_one_family_claim_it_with_the_first_eligible_fit():
    lib_row = _row("linear", [0.062], -49.0)
    lnn_row = _row("linear", [0.065], -52.0)
    out = combine_bases([("lib", _table([lib_row], law=lib_row)), ("lnn", _table([lnn_row], law=lnn_row))])
    assert out.status == "claimed" and out.law is lib_row and out.ties == []
    assert [b["families"] for b in out.settings["bases"]] == [["linear"], ["linear"]]
    # how many families each base's trajectory-level table fitted rides along (the LNN's funnel is not the home's)
    lnn = _table([lnn_row], law=lnn_row)
    lnn.settings["funnel"] = {"trajectory": 8, "cut": True}
    out = combine_bases([("lib", _table([lib_row], law=lib_row)), ("lnn", lnn)])
    assert [b.get("funnel") for b in out.settings["bases"]] == [None, {"trajectory": 8, "cut": True}]
    # the library's best candidate barred (its two fits disagree), the LNN's windows and envelope agree on it
    barred = _row("linear+coulomb", [0.21, 2.07], -70.0, significant=False, barred_only_by_disagreement=True)
    fit = _row("linear+coulomb", [0.21, 2.06], -68.0)
    out = combine_bases([("lib", _table([barred], blocked=barred)), ("lnn", _table([fit], law=fit))])
    assert out.status == "claimed" and out.law is fit


def test_bases_pointing_to_different_families_tie_and_a_base_without_any_does_not_veto():
    lin = _row("linear", [0.062], -49.0)
    vdp = _row("vanderpol", [-0.07, 3.4], -60.0)
    out = combine_bases([("lib", _table([lin], law=lin)), ("lnn", _table([vdp], law=vdp))])
    assert out.status == "tie" and out.law is lin and out.ties == [vdp]
    assert "depends on the conservative force" in out.reason
    # a barred candidate in one base and another family claimed in the other: a tie, the eligible one first
    barred = _row("linear+coulomb", [0.21, 2.07], -70.0, significant=False, barred_only_by_disagreement=True)
    cq = _row("coulomb+quadratic", [2.6, 0.014], -60.0)
    out = combine_bases([("lib", _table([barred], blocked=barred)), ("lnn", _table([cq], law=cq))])
    assert out.status == "tie" and out.law is cq and out.ties == [barred]
    # no candidate at all with the LNN: the library's law stands
    out = combine_bases([("lib", _table([lin], law=lin)), ("lnn", _table([_row("linear", [0.06], 3.0, False)]))])
    assert out.status == "claimed" and out.law is lin
    # nothing anywhere: no law
    out = combine_bases([("lib", _table([])), ("lnn", _table([]))])
    assert out.status == "none" and preferred(out) == []


@pytest.mark.parametrize("order", [0, 1])
def test_a_tie_inside_one_base_stays_a_tie_whatever_the_order_of_the_bases(order):
    quad = _row("quadratic", [0.0163], -141.0)
    vdp = _row("vanderpol", [-0.025, -0.1], -139.0)
    quad2 = _row("quadratic", [0.0165], -140.0)
    tabs = [("lib", _table([quad, vdp], law=quad, ties=[vdp])), ("lnn", _table([quad2], law=quad2))]
    out = combine_bases(tabs[::-1] if order else tabs)
    assert out.status == "tie" and {out.law.key, *(r.key for r in out.ties)} == {"quadratic", "vanderpol"}
