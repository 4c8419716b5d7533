"""How the seeds' statuses combine (:func:`nnphd.user.rules.combine_seeds`): agreement, a disagreement of well-fitted
models ("inconclusive"), and an "inconclusive" that is an optimisation failure another seed shows the data do not
cause (discounted) — the rules on hand-made per-seed results."""

import pytest

from nnphd.user.rules import UNDERFIT_RATIO, combine_seeds, corroborates, underfit_against


def _seed(k, status, cons, free=0.12, z=(0.1, 0.0), agreement=0.9):
    return {
        "seed": k,
        "status": status,
        "reason": f"reason {k}",
        "agreement": agreement,
        "gap": {"conservative_train": cons, "free_train": free, "gap_train": cons / free, "large": cons / free >= 2},
        "trajectory_evidence": {
            "z_energy": z[0],
            "z_shooting": z[1],
            "significant": status == "detected",
            "direction": "loses energy" if z[0] > 0 else "gains energy",
        },
    }


def test_agreeing_seeds_keep_their_status_and_bootstrap_confidence():
    status, new, conf, reasons = combine_seeds([_seed(0, "none", 0.07, agreement=0.8), _seed(1, "none", 0.08)])
    assert (status, new) == ("none", False)
    assert conf == pytest.approx(0.85)
    assert reasons == ["seed 0: reason 0", "seed 1: reason 1"]


def test_an_underfit_inconclusive_seed_is_discounted_when_another_fits():
    # the numbers of the eccentric Kepler case (seed_robustness): 0.070 (×0.58 the free model) vs 0.295 (×2.4)
    good, bad = _seed(1, "none", 0.070, free=0.121), _seed(2, "inconclusive", 0.295, free=0.122)
    status, new, conf, reasons = combine_seeds([good, bad])
    assert (status, new) == ("none", False)
    assert conf == pytest.approx(0.45)  # the discounted seed counts against the confidence: 0.9 / 2
    assert reasons[0].startswith("seed 2 is discounted") and "x4.2 seed 1's" in reasons[0]
    assert reasons[1:] == ["seed 1: reason 1", "seed 2: reason 2"]
    # the order of the seeds does not matter
    assert combine_seeds([bad, good])[:2] == ("none", False)


def test_a_detection_by_the_well_fitted_seed_stands_against_an_underfit_one():
    status, new, _, reasons = combine_seeds([_seed(0, "detected", 0.05, z=(9.0, 7.0)), _seed(1, "inconclusive", 0.3)])
    assert (status, new) == ("detected", True)
    assert reasons[0].startswith("seed 1 is discounted")


@pytest.mark.parametrize(
    "bad",
    [
        _seed(2, "inconclusive", 0.295, z=(3.5, 0.0)),  # the under-fit seed holds evidence of its own (z ≥ Z_BOTH)
        _seed(2, "inconclusive", 0.13, free=0.06),  # under-fits (×2.2 the free model) but < UNDERFIT_RATIO × 0.070
        _seed(2, "detected", 0.295),  # a detection is never discounted, however poor the fit
        _seed(2, "inconclusive", 0.2, free=0.5),  # it does not under-fit (gap < 2): a disagreement of the evidence
    ],
)
def test_a_disagreement_of_well_fitted_models_or_of_evidence_stays_inconclusive(bad):
    good = _seed(1, "none", 0.070, free=0.121)
    assert 0.13 < UNDERFIT_RATIO * 0.070 < 0.295  # the cases above sit on either side of the threshold
    assert underfit_against(bad, [good, bad]) is None
    status, new, conf, reasons = combine_seeds([good, bad])
    assert status == "inconclusive"
    assert reasons[0].startswith("seeds disagree")
    # the larger share of seeds on one side of detected / not detected; the best call is the majority
    assert (conf, new) == ((0.5, False) if bad["status"] == "detected" else (1.0, False))


def test_no_seed_is_discounted_when_none_fits_as_well_as_a_free_model():
    a, b = _seed(0, "none", 0.20, free=0.09), _seed(1, "inconclusive", 0.9, free=0.1)  # both gaps ≥ 2
    assert underfit_against(b, [a, b]) is None
    assert combine_seeds([a, b])[0] == "inconclusive"


def test_three_seeds_one_discounted_two_agree_and_two_disagreeing_stay_inconclusive():
    seeds = [_seed(0, "none", 0.07), _seed(1, "none", 0.06), _seed(2, "inconclusive", 0.3)]
    status, _, conf, reasons = combine_seeds(seeds)
    assert status == "none" and conf == pytest.approx(0.6)
    assert sum(r.startswith("seed 2 is discounted") for r in reasons) == 1
    seeds[1] = _seed(1, "detected", 0.06, z=(8.0, 6.0))
    assert combine_seeds(seeds)[0] == "inconclusive"


def test_an_inconclusive_seed_whose_weaker_evidence_points_the_same_way_backs_a_detection():
    # the camera look-alike of a damped chaotic double pendulum (seed_robustness, --seed 0): seed 0's learned energy
    # decays at z = 4.6 (probe −1.2: not a contradiction), seed 1's at z = 7.4 (probe 0.7)
    weak, strong = _seed(0, "inconclusive", 0.1, z=(4.6, -1.2)), _seed(1, "detected", 0.1, z=(7.4, 0.7), agreement=0.8)
    status, new, conf, reasons = combine_seeds([weak, strong])
    assert (status, new) == ("detected", True)
    assert conf == pytest.approx(0.4)  # the inconclusive seed counts against the confidence: 0.8 / 2
    assert reasons[0] == (
        'seed 0\'s "inconclusive" is weaker evidence of the same loss of energy (energy trend z = 4.6, shooting '
        "probe z = -1.2), not a contradiction: seed 1's detection stands"
    )
    assert combine_seeds([strong, weak])[:2] == ("detected", True)


@pytest.mark.parametrize(
    "weak",
    [
        _seed(0, "inconclusive", 0.1, z=(4.6, -2.5)),  # the probe contradicts it (|z| ≥ Z_CONTRA, other sign)
        _seed(0, "inconclusive", 0.1, z=(2.5, 1.0)),  # nothing reaches Z_BOTH: no evidence either way
        _seed(0, "inconclusive", 0.1, z=(-4.6, 0.0)),  # the energy grows: the other direction
        _seed(0, "none", 0.1, z=(0.5, 0.2)),  # "none" contradicts a detection
    ],
)
def test_a_seed_that_does_not_back_the_detection_keeps_them_inconclusive(weak):
    strong = _seed(1, "detected", 0.1, z=(7.4, 0.7))
    assert corroborates(weak, strong) is None
    status, _, _, reasons = combine_seeds([weak, strong])
    assert status == "inconclusive" and reasons[0].startswith("seeds disagree")


def test_a_detection_by_the_clock_is_not_backed_by_record_level_evidence():
    clock = _seed(1, "detected", 0.1, z=(0.3, 0.1))
    clock["trajectory_evidence"]["significant"] = False  # detected by the clock test, not along the record
    weak = _seed(0, "inconclusive", 0.1, z=(4.6, 0.0))
    assert corroborates(weak, clock) is None
    assert combine_seeds([weak, clock])[0] == "inconclusive"


def _law_dict(share):
    return {"law": {"title": "power-law drag −k (|q̇|²)^m q̇"}, "status": "claimed", "ties": [], "reason": "r",
            "against_velocity": share, "candidates": []}  # fmt: skip


def _res(direction="loses energy", significant=True):
    return {"evidence": {"combined": {"direction": direction, "significant": significant}}}


def test_a_law_that_pumps_energy_into_a_record_that_loses_it_is_not_claimed():
    from nnphd.user.rules import unclaim_against_evidence

    law, why = unclaim_against_evidence(_res(), _law_dict(-1.0))  # a thrust along the velocity (the camera case)
    assert why and "adds energy (-100% of its force against the velocity) where the record loses energy" in why
    assert law["law"] is None and law["candidate_law"]["title"].startswith("power-law") and law["status"] == "none"
    assert list(law)[-2:] == ["against_velocity", "candidate_law"] and law["against_velocity"] == -1.0
    assert law["reason"] == why
    # the mirror case: a drag claimed on a record that gains energy
    law, why = unclaim_against_evidence(_res("gains energy"), _law_dict(0.9))
    assert "takes energy" in why and law["law"] is None


@pytest.mark.parametrize(
    "share, res",
    [
        (1.0, _res()),  # a drag on a record that loses energy: the law stands
        (-0.4, _res()),  # mostly across the velocity (a share above −0.5): not clearly against the evidence
        (-1.0, _res(significant=False)),  # no record-level evidence to contradict (detected by the clock, say)
        (-1.0, _res(direction="none")),
        (None, _res()),  # the share could not be computed (nothing moves)
    ],
)
def test_a_law_consistent_with_or_untested_by_the_evidence_stands(share, res):
    from nnphd.user.rules import unclaim_against_evidence

    law, why = unclaim_against_evidence(res, _law_dict(share))
    assert why is None
    assert law["law"] == {"title": "power-law drag −k (|q̇|²)^m q̇"} and law["status"] == "claimed"


def test_detections_of_opposite_signs_are_no_agreement():
    # a geodetic satellite orbit (laser ranging, one day): seed 0's learned energy decays at z = 428, seed 1's grows at z = −68
    seeds = [_seed(0, "detected", 0.05, z=(428.0, 0.2)), _seed(1, "detected", 0.05, z=(-68.0, -0.1))]
    status, new, conf, reasons = combine_seeds(seeds)
    assert (status, new) == ("inconclusive", False)
    assert conf == pytest.approx(0.5)
    assert reasons[0].startswith("seeds disagree on the sign of the energy change")
    assert "seed 0: the record loses energy" in reasons[0] and "seed 1: the record gains energy" in reasons[0]
    # the same sign twice is an agreement
    same = [_seed(0, "detected", 0.05, z=(428.0, 0.2)), _seed(1, "detected", 0.05, z=(68.0, 0.1))]
    assert combine_seeds(same)[:2] == ("detected", True)
