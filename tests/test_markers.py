"""Camera markers → constraints → generalized coordinates (issue 58): the look-alikes of tests/fixtures/markers.py
(known truth) and the real IBM double pendulum's raw marker tracks (../shared), the reader and the command line."""

from __future__ import annotations

import csv
import os

import numpy as np
import pytest

from nnphd.user.markers import MarkerError, from_columns, marker_columns
from nnphd.user.recording import DataError, load_trajectories
from tests.fixtures.markers import PX_PER_M, make

REAL = os.path.join(os.path.dirname(__file__), "..", "..", "shared", "data", "real")


def _kinds(mm, kind):
    return [c for c in mm.constraints if c.kind == kind]


def _same_up_to_offset(a, b, tol):
    """a = ±b + const to ``tol`` (an angle from the image's +x axis against one from the downward vertical; the
    image's rows grow downwards, so the sense may flip)."""
    return min(np.ptp(a - b), np.ptp(a + b)) < tol


def test_double_pendulum_in_pixels_two_rods_two_angles():
    cam = make("double-pendulum")
    mm = from_columns(cam.columns, fps=cam.fps)
    assert [c.markers for c in _kinds(mm, "fixed")] == [("pivot",)]
    rods = {c.markers: c.value[0] for c in _kinds(mm, "rod")}
    assert set(rods) == {("pivot", "joint"), ("joint", "tip")}
    for k, length in cam.rods.items():
        assert abs(rods[k] - length) < 0.01 * length  # within 1 % of the true length (pixels)
    assert mm.names == ("theta_joint", "theta_tip") and mm.angles == mm.names
    assert mm.dropped == 6 and len(np.unique(mm.traj)) == 1  # six lost frames: rows left out, no cut
    keep = np.isfinite(cam.columns["tip_x"])
    for j in range(2):  # the chosen angles are the true ones (up to the image's axis and sense), to the jitter
        assert _same_up_to_offset(mm.q[:, j], cam.q[keep, j], 0.02)


def test_untracked_pivot_found_within_a_percent_of_the_rod():
    cam = make("double-pendulum-untracked")
    mm = from_columns(cam.columns, fps=cam.fps)
    (piv,) = _kinds(mm, "pivot")
    assert piv.markers == ("pivot", "joint")
    l1 = cam.rods[("pivot", "joint")]
    assert np.linalg.norm(np.asarray(piv.value[:2]) - cam.pivot) < 0.01 * l1
    assert abs(piv.value[2] - l1) < 0.01 * l1
    assert mm.names == ("theta_joint", "theta_tip")
    keep = np.isfinite(cam.columns["tip_x"])
    assert _same_up_to_offset(mm.q[:, 0], cam.q[keep, 0], 0.02)
    assert _same_up_to_offset(mm.q[:, 1], cam.q[keep, 1], 0.02)


def test_cart_on_a_rail_with_a_pendulum():
    cam = make("cart-pendulum")
    mm = from_columns(cam.columns, fps=cam.fps)
    assert [c.markers for c in _kinds(mm, "rail")] == [("cart",)]
    assert [c.markers for c in _kinds(mm, "rod")] == [("cart", "bob")]
    assert [c.kind for c in mm.coordinates] == ["rail", "angle"] and mm.names == ("s_cart", "theta_bob")
    keep = np.isfinite(cam.columns["bob_x"])
    assert _same_up_to_offset(mm.q[:, 0] / PX_PER_M, cam.q[keep, 0], 0.01)  # metres along the rail
    assert _same_up_to_offset(mm.q[:, 1], cam.q[keep, 1], 0.02)


def test_a_spring_is_not_a_rod():
    cam = make("spring-pendulum")
    mm = from_columns(cam.columns, fps=cam.fps)
    assert not _kinds(mm, "rod") and not _kinds(mm, "rough") and not _kinds(mm, "pivot")
    assert [c.markers for c in _kinds(mm, "fixed")] == [("pivot",)]
    assert [c.kind for c in mm.coordinates] == ["free", "free"]
    assert "varies by" in mm.coordinates[0].why  # what is left free is said


def test_a_throw_gets_no_constraint():
    cam = make("throw")
    mm = from_columns(cam.columns, fps=cam.fps)
    assert mm.constraints == () and mm.names == ("ball_x", "ball_y")


def test_markers_on_one_rigid_body_give_one_angle():
    cam = make("rigid-pendulum")
    mm = from_columns(cam.columns, fps=cam.fps)
    assert len(_kinds(mm, "rod")) == 3 and mm.names == ("theta_mid",)
    assert any("rigid body" in a for a in mm.assumed)
    keep = np.isfinite(cam.columns["end_x"])
    assert _same_up_to_offset(mm.q[:, 0], cam.q[keep, 0], 0.03)  # the shorter arm (204 px): 1/400 rad of jitter


def test_a_flexible_rod_is_reported_not_assumed():
    """A rod whose length wanders by 2–3 % (a flexible rod, a slipping string): rough, not a rod; the bob stays free."""
    rng = np.random.default_rng(1)
    t = np.arange(0, 10, 0.01)
    th = 0.8 * np.cos(3 * t)
    r = 300 * (1 + 0.03 * np.sin(0.7 * t))
    cols = {"t": t, "pivot_x": 500 + rng.normal(0, 0.5, t.size), "pivot_y": 500 + rng.normal(0, 0.5, t.size)}
    cols |= {"bob_x": 500 + r * np.sin(th), "bob_y": 500 + r * np.cos(th)}
    mm = from_columns(cols)
    (rough,) = _kinds(mm, "rough")
    assert rough.markers == ("pivot", "bob") and 0.01 < rough.rel < 0.05 and "not assumed" in rough.text()
    assert not _kinds(mm, "rod") and [c.kind for c in mm.coordinates] == ["free", "free"]
    assert mm.note() == (
        "no simple constraint set: pivot – bob keep their distance only to 2% (a flexible rod, a "
        "slipping string?); not assumed: bob left free"
    )
    assert from_columns(make("double-pendulum").columns, fps=200).note() is None


@pytest.mark.skipif(not os.path.isdir(os.path.join(REAL, "ibm_markers")), reason="../shared/data/real not here")
def test_real_double_pendulum_markers_give_the_hand_converted_angles():
    """Run 5 of the IBM double pendulum as the camera gave it (pixels, the pivot marker jittering): the pivot fixed,
    two rods within 1 % of the median marker distances, two angles — those of the hand conversion."""
    ud = load_trajectories(os.path.join(REAL, "ibm_markers", "run5.csv"), fps=400)
    mm = ud.markers
    assert [c.markers for c in _kinds(mm, "fixed")] == [("red",)]
    P = mm.positions
    for a, b in (("red", "green"), ("green", "blue")):
        (rod,) = [c for c in _kinds(mm, "rod") if c.markers == (a, b)]
        med = np.median(np.linalg.norm(P[b] - P[a], axis=1))
        assert abs(rod.value[0] - med) <= 0.01 * med and rod.rel < 0.01
    assert ud.coords == ("theta_green", "theta_blue") and ud.angles == ud.coords
    hand = np.genfromtxt(os.path.join(REAL, "ibm_double_pendulum_runs5-20.csv"), delimiter=",", names=True)
    m = hand["traj"] == 5
    q = ud.trajectories[0].q
    assert np.max(np.abs(q[:, 0] - hand["theta1"][m])) < 1e-5  # the hand file's 6 decimals
    assert np.max(np.abs(q[:, 1] - hand["theta2"][m])) < 1e-5
    assert np.allclose(ud.trajectories[0].t, hand["t"][m] - hand["t"][m][0] + ud.trajectories[0].t[0])


def _write(path, cols: dict):
    names = list(cols)
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(names)
        for i in range(len(cols[names[0]])):
            w.writerow(["" if not np.isfinite(cols[c][i]) else repr(float(cols[c][i])) for c in names])


def test_reader_recognises_markers_and_lost_frames(tmp_path):
    cam = make("double-pendulum")
    p = tmp_path / "cam.csv"
    _write(p, cam.columns)  # lost frames as empty cells, as trackers write them
    ud = load_trajectories(p, fps=cam.fps)
    assert ud.markers is not None and ud.coords == ("theta_joint", "theta_tip") and ud.n_samples == len(cam.q) - 6
    assert ud.trajectories[0].t[1] == pytest.approx(1 / cam.fps)
    with pytest.raises(DataError, match="frame rate"):  # frames counted, no rate
        load_trajectories(p)
    with pytest.raises(DataError, match="empty"):  # read as coordinates, a lost frame is an empty cell
        load_trajectories(p, markers="none")


@pytest.mark.parametrize(
    "change, message",
    [
        (lambda c: c.pop("tip_y"), "has 'tip_x' but no 'tip_y'"),
        (lambda c: c.__setitem__("joint_x", np.full_like(c["joint_x"], 7.0)), "constant"),
        (lambda c: _swap(c, "joint", "tip", 700), "swap identity at row"),
    ],
)
def test_bad_marker_input_gets_one_line(change, message):
    cam = make("double-pendulum")
    cols = {k: v.copy() for k, v in cam.columns.items()}
    change(cols)
    with pytest.raises(MarkerError, match=message) as e:
        from_columns(cols, fps=cam.fps)
    assert "\n" not in str(e.value)


def _swap(c, a, b, k):
    for ax in ("x", "y"):
        c[f"{a}_{ax}"][k:], c[f"{b}_{ax}"][k:] = c[f"{b}_{ax}"][k:].copy(), c[f"{a}_{ax}"][k:].copy()


def test_marker_columns_named_and_checked():
    names = ["frame", "a_x", "a_y", "b_x", "b_y", "b_z"]
    with pytest.raises(MarkerError, match="differ in their axes"):
        marker_columns(names)
    assert marker_columns(["t", "a_x", "a_y", "b_x", "b_y"], "b") == {"b": ("b_x", "b_y")}
    with pytest.raises(MarkerError, match="'c' has no"):
        marker_columns(["t", "a_x", "a_y"], "c")


def test_cli_bad_marker_files_exit_2_with_one_line(tmp_path, capsys):
    from nnphd.cli import main

    cam = make("double-pendulum")
    out = tmp_path / "o"
    bad = {
        "no 'tip_y'": ({k: v for k, v in cam.columns.items() if k != "tip_y"}, ["--fps", "200"]),
        "frame rate": (cam.columns, []),
        "--angles does not apply": (cam.columns, ["--fps", "200", "--angles", "theta_tip"]),
        "--fps is the frame rate of a marker recording": (
            {"t": cam.columns["frame"], "x": cam.q[:, 0]},
            ["--fps", "200"],
        ),  # fmt: skip
    }
    for i, (message, (cols, opts)) in enumerate(bad.items()):
        p = tmp_path / f"cam{i}.csv"
        _write(p, cols)
        assert main(["detect", str(p), *opts, "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert len(err.strip().splitlines()) == 1 and message in err and "Traceback" not in err, err
        assert not out.exists()


def test_api_from_markers_file_and_columns(tmp_path):
    import nnphd

    cam = make("cart-pendulum")
    a = nnphd.Trajectories.from_markers(cam.columns, fps=cam.fps)
    assert a.names == ("s_cart", "theta_bob") and a.angles == ("theta_bob",)
    assert [c["kind"] for c in a.markers["constraints"]] == ["rod", "rail"]
    p = tmp_path / "cam.csv"
    _write(p, cam.columns)
    b = nnphd.Trajectories.from_markers(p, fps=cam.fps)
    assert b.names == a.names and np.allclose(b.arrays()[0][1], a.arrays()[0][1], atol=1e-12)
    assert nnphd.Trajectories(np.arange(20) * 0.1, np.cos(np.arange(20))).markers is None
    with pytest.raises(DataError, match="frame rate"):
        nnphd.Trajectories.from_markers(cam.columns)


@pytest.mark.slow  # two detections end to end (about a minute each): slow tier
def test_law_from_markers_matches_the_law_from_the_true_angle(tmp_path):
    """A damped pendulum filmed (pixels, jitter, rounded positions, the camera turned): the verdict and the law
    found from its markers are those found from its true angle — the same family, γ within both uncertainties —
    and the report says which constraints gave the coordinate."""
    from nnphd.user.detect import detect_file

    cam = make("damped-pendulum")
    marks, true = tmp_path / "marks.csv", tmp_path / "true.csv"
    _write(marks, cam.columns)
    _write(true, {"t": cam.columns["frame"] / cam.fps, "theta": cam.q[:, 0]})
    a = detect_file(marks, tmp_path / "a", sr_time=0, fps=cam.fps)
    b = detect_file(true, tmp_path / "b", angles=("theta",), sr_time=0)
    assert a["status"] == b["status"] == "detected"
    la, lb = a["law"]["law"], b["law"]["law"]
    assert la["law"] == lb["law"] == "linear" and a["law"]["status"] == b["law"]["status"] == "claimed"
    ga, gb = la["params"]["gamma"], lb["params"]["gamma"]
    assert abs(ga - gb) <= 2 * np.hypot(la["stderr"]["gamma"], lb["stderr"]["gamma"])
    assert abs(ga - cam.gamma) < 0.05 * cam.gamma
    assert a["markers"]["coordinates"][0]["name"] == "theta_bob" and (tmp_path / "a" / "markers.png").exists()


def _tracker(path, cam, multi: bool, delim="\t"):
    """The look-alike as Tracker exports it: one track per file (its name, then t x y), or #multi: (the tracks'
    names over their columns, then t x y x y …); an empty cell where a track has no step; velocities beside."""
    t = cam.columns["frame"] / cam.fps
    marks = [k[:-2] for k in cam.columns if k.endswith("_x")]
    cell = lambda v: "" if not np.isfinite(v) else f"{v:.9E}"  # noqa: E731
    with open(path, "w") as f:
        if multi:
            f.write("#multi:\n" + delim + delim.join(f"mass {m}{delim}{delim}" for m in marks) + "\n")
            f.write("t" + "".join(f"{delim}x{delim}y{delim}v_{{x}}" for _ in marks) + "\n")
            for i in range(len(t)):
                f.write(cell(t[i]) + "".join(delim + cell(cam.columns[f"{m}_x"][i]) + delim
                                             + cell(cam.columns[f"{m}_y"][i]) + delim + "1.0" for m in marks) + "\n")  # fmt: skip
        else:
            m = marks[0]
            f.write(f"mass {m}\nt{delim}x{delim}y\n")
            for i in range(len(t)):
                f.write(delim.join([cell(t[i]), cell(cam.columns[f"{m}_x"][i]), cell(cam.columns[f"{m}_y"][i])]) + "\n")


def test_tracker_data_tables_one_track_and_several(tmp_path):
    cam = make("cart-pendulum")
    p = tmp_path / "cart.txt"
    _tracker(p, cam, multi=True)
    ud = load_trajectories(p)
    assert ud.coords == ("s_mass_cart", "theta_mass_bob") and ud.markers.markers == ("mass cart", "mass bob")
    ref = from_columns(cam.columns, fps=cam.fps)
    assert np.allclose(ud.trajectories[0].q, ref.q, atol=1e-6)
    throw = make("throw")
    p1 = tmp_path / "ball.txt"
    _tracker(p1, throw, multi=False, delim=",")
    ud1 = load_trajectories(p1)
    assert ud1.coords == ("mass_ball_x", "mass_ball_y") and ud1.markers.constraints == ()
    (tmp_path / "junk.txt").write_text("hello\nworld\n1,2\n")
    with pytest.raises(DataError, match="not a Tracker data table"):
        load_trajectories(tmp_path / "junk.txt")
    with pytest.raises(DataError, match="read as Tracker's data table"):
        load_trajectories(p, markers="none")
