"""Records unlike the constructed ones, end to end through ``detect`` (slow: tens of seconds each): a Rayleigh oscillator
reaching its limit cycle gets its law; two filmed throws with frame-to-frame correlated tracking noise, their field
declared vertical, are "detected" with a drag that fits to the noise; a LAGEOS-like satellite's day under J2 (a
conservative record smooth to 10⁻⁹) is not "detected" (it was, at confidence 0.99)."""

from __future__ import annotations

import pytest

from nnphd.user.detect import detect_data
from nnphd.user.recording import load_trajectories
from tests.fixtures import unlike

pytestmark = pytest.mark.slow  # run by `python3 dev.py test --slow` (and by CI)


def _detect(rec, tmp_path, **kw):
    path = tmp_path / f"{rec.name}.csv"
    rec.write_csv(path)
    return detect_data(load_trajectories(path, rec.angles), None, seed=0, sr_time=0, **kw)[0].report


def test_a_limit_cycle_gets_its_law(tmp_path):
    rec = unlike.make("limit-cycle")
    rep = _detect(rec, tmp_path)
    law = rep["law"]
    assert rep["status"] == "detected", rep["reasons"][:2]
    assert law["status"] == "claimed" and law["law"]["law"] == "rayleigh", law.get("reason")
    for p, v in rec.truth["coefficients"].items():
        assert law["law"]["params"][p] == pytest.approx(v, rel=0.05), law["law"]["params"]


def test_a_filmed_throw_with_correlated_tracking_noise_is_detected_with_a_drag_that_fits_to_the_noise(tmp_path):
    rec = unlike.make("throw-video")
    rep = _detect(rec, tmp_path, field="vertical")
    law = rep["law"]
    assert rep["status"] == "detected", rep["reasons"][:2]
    assert law["noise"]["used"] == "smooth curve" and law["noise"]["chi2_scale"] > 1.5
    lead = law.get("law") or {}
    assert lead.get("law") == "quadratic", law.get("reason")  # claimed, or leading a tie
    assert lead["params"]["c"] == pytest.approx(rec.truth["coefficients"]["c"], rel=0.35)
    assert "χ²/N against the noise a low-degree curve through each arc leaves" in rep["reasons"][0]


def test_a_satellites_precise_conservative_orbit_is_not_detected(tmp_path):
    from nnphd.astro.controls import records

    c = records(["satellite-j2-inertial"])[0]
    path = tmp_path / "sat.csv"
    c.write_csv(path)
    rep = detect_data(load_trajectories(path), None, seed=0, sr_time=0)[0].report
    assert rep["status"] != "detected", rep["reasons"][:2]
    assert rep["law"].get("law") is None
    per = rep["checks"]["per_seed"]
    assert all(s["trajectory_evidence"]["within_fit_error"] for s in per)  # the |z| ≥ 88 trends do not count
