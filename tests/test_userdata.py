"""User data files for ``nnphd detect FILE``: loading, validation messages, derivative estimates and their accuracy.

Accuracy is measured on the damped pendulum θ̈ = −sin θ − 0.1 θ̇, θ(0) = 2, θ̇(0) = 0, integrated with DOP853
(rtol 1e-10, atol 1e-12) and sampled at dt = 0.05 on 0…20 s (401 samples), with Gaussian position noise of 0, 0.1 %
and 1 % of std θ.  Errors are RMS over all rows (no trimming) relative to the RMS of the true derivative.  Stated
bounds (about twice the worst of 30 noise seeds measured while writing this):

    noise     q̇ error   q̈ error   (measured here, seed 0: q̇ / q̈)
    0         1e-6      1e-5      3.8e-7 / 2.9e-6
    0.1 %     0.5 %     4 %       0.19 % / 1.5 %
    1 %       2.5 %     12 %      1.0 % / 6.2 %

With trim=True (edge half-windows dropped) the q̈ bounds are 1.5 % and 6 %.  The reported error estimate is within a
factor 3 of the actual error on noisy data, and on noise-free data where the error is interior truncation (trim);
for untrimmed noise-free q̈ it is a conservative upper bound (the ends of this trajectory are quieter than its RMS q⁽⁵⁾).
The noise estimate is within a factor 1.5 of the true σ (the requirement is 2).
"""
import json

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.signal import savgol_filter

import nnphd  # noqa: F401  (enables float64)
from nnphd.userdata import (
    MIN_SAMPLES,
    DataError,
    estimate_derivatives,
    load_trajectories,
    noise_level,
    to_dataset,
)

BOUNDS = {  # relative RMS error bounds (q̇, q̈), untrimmed and trimmed q̈
    0.0: (1e-6, 1e-5, 1e-5),
    1e-3: (5e-3, 4e-2, 1.5e-2),
    1e-2: (2.5e-2, 0.12, 6e-2),
}


def pendulum(theta0=2.0, omega0=0.0, dt=0.05, T=20.0, t=None):
    """Accurate samples of θ̈ = −sin θ − 0.1 θ̇: (t, θ, θ̇, θ̈)."""
    if t is None:
        t = dt * np.arange(int(round(T / dt)) + 1)
    sol = solve_ivp(lambda _, x: [x[1], -np.sin(x[0]) - 0.1 * x[1]], (t[0], t[-1]), [theta0, omega0], t_eval=t,
                    method="DOP853", rtol=1e-10, atol=1e-12)
    th, om = sol.y
    return t, th, om, -np.sin(th) - 0.1 * om


@pytest.fixture(scope="module")
def pend():
    return pendulum()


def rel_err(est, true):
    return float(np.sqrt(np.mean((est - true) ** 2)) / np.sqrt(np.mean(true**2)))


def write_csv(path, names, columns, fmt="%.17g"):
    np.savetxt(path, np.column_stack(columns), delimiter=",", header=",".join(names), comments="", fmt=fmt)
    return path


# ---- derivative accuracy ------------------------------------------------------------------------------------------
@pytest.mark.parametrize("noise", [0.0, 1e-3, 1e-2])
def test_pendulum_derivative_accuracy(pend, noise):
    t, th, om, al = pend
    sigma = noise * th.std()
    y = th + sigma * np.random.default_rng(0).standard_normal(th.size)
    b_qd, b_qdd, b_qdd_trim = BOUNDS[noise]

    est = estimate_derivatives(t, y)
    assert est.method == "savgol" and est.dt == pytest.approx(0.05) and est.keep.all() and est.trimmed == 0
    e_qd, e_qdd = rel_err(est.qd[:, 0], om), rel_err(est.qdd[:, 0], al)
    assert e_qd < b_qd and e_qdd < b_qdd
    rep_qd, rep_qdd = est.qd_err[0] / est.qd_rms[0], est.qdd_err[0] / est.qdd_rms[0]
    assert 1 / 3 < rep_qd / e_qd < 3
    if noise:
        assert 1 / 3 < rep_qdd / e_qdd < 3
        assert 1 / 1.5 < est.noise[0] / sigma < 1.5
        assert est.noise_rel[0] == pytest.approx(est.noise[0] / y.std())
        assert est.window_qdd[0] > 15  # noise widens the window
    else:
        assert 1 <= rep_qdd / e_qdd < 10  # edge bias from the RMS q⁽⁵⁾: an upper bound here
        assert est.noise[0] < 1e-9 and est.window_qd[0] == est.window_qdd[0] == 5

    trimmed = estimate_derivatives(t, y, trim=True)
    k = trimmed.keep
    half = max(trimmed.window_qd[0], trimmed.window_qdd[0]) // 2
    assert k.sum() == t.size - 2 * half and not k[:half].any() and not k[-half:].any() and k[half:-half].all()
    e_trim = rel_err(trimmed.qdd[k, 0], al[k])
    assert e_trim < b_qdd_trim
    assert 1 / 3 < (trimmed.qdd_err[0] / trimmed.qdd_rms[0]) / e_trim < 3


def test_savgol_is_scipy_and_error_model_uses_its_weights():
    """The estimate is scipy's savgol_filter(mode='interp'); the stencils behind the error model reproduce it."""
    from nnphd.userdata import _sg_weights

    t = 0.1 * np.arange(60)
    y = np.sin(t) + 0.01 * np.random.default_rng(1).standard_normal(60)
    for m, d in ((9, 1), (13, 2)):
        ref = savgol_filter(y, m, 4, deriv=d, delta=0.1, mode="interp")
        w_c, w_e = _sg_weights(m, d)
        half = m // 2
        np.testing.assert_allclose(np.correlate(y, w_c, "valid") / 0.1**d, ref[half:-half], rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(w_e @ y[:m] / 0.1**d, ref[:half], rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose((-1) ** d * w_e @ y[::-1][:m] / 0.1**d, ref[::-1][:half], rtol=1e-9, atol=1e-9)


def test_noise_level_on_pure_noise_and_irregular_grid():
    rng = np.random.default_rng(2)
    t = np.sort(rng.uniform(0, 10, 2000))
    y = 0.3 * rng.standard_normal(2000)
    assert noise_level(t, y) == pytest.approx(0.3, rel=0.1)
    assert noise_level(t, y + np.sin(t)) == pytest.approx(0.3, rel=0.1)  # smooth signal does not leak in
    assert noise_level(np.arange(50.0), np.arange(50.0) ** 2) < 1e-9  # polynomials are annihilated


def test_irregular_sampling_uses_the_spline():
    rng = np.random.default_rng(5)
    t, th, om, al = pendulum(t=np.sort(rng.uniform(0.0, 20.0, 401)))
    sigma = 1e-3 * th.std()
    est = estimate_derivatives(t, th + sigma * rng.standard_normal(t.size))
    assert est.method == "spline" and est.dt is None and est.window_qdd == (None,)
    assert 1 / 1.5 < est.noise[0] / sigma < 1.5
    e_qd, e_qdd = rel_err(est.qd[:, 0], om), rel_err(est.qdd[:, 0], al)
    assert e_qd < 1e-2 and e_qdd < 6e-2  # measured 0.3 % and 1.5 %
    assert 1 / 3 < (est.qdd_err[0] / est.qdd_rms[0]) / e_qdd < 3
    with pytest.raises(DataError, match="uniform sampling"):
        estimate_derivatives(t, th, method="savgol")


# ---- files --------------------------------------------------------------------------------------------------------
def test_multiple_trajectories_do_not_mix(tmp_path):
    """Two trajectories with offsets 100 apart, rows interleaved in the file: each is differentiated on its own."""
    t, th_a, om_a, al_a = pendulum(theta0=2.0, T=5.0)
    _, th_b, om_b, al_b = pendulum(theta0=-1.0, omega0=0.5, T=5.0)
    th_b = th_b + 100.0
    n = t.size
    order = np.r_[n + np.arange(20), np.arange(n), n + np.arange(20, n)]  # traj 1 starts, traj 0 sits inside it
    cols = [np.r_[np.zeros(n), np.ones(n)][order], np.r_[t, t][order], np.r_[th_a, th_b][order]]
    path = write_csv(tmp_path / "two.csv", ["traj", "t", "theta"], cols)
    ud = load_trajectories(path)
    assert ud.n_traj == 2 and [tr.id for tr in ud.trajectories] == [1, 0]  # order of first appearance
    ds, info = to_dataset(ud)
    assert len(ds) == 2 * n and info["n_traj"] == 2 and info["trimmed"] == 0
    qdd = {1: ds.qdd[:n, 0], 0: ds.qdd[n:, 0]}
    truth = {1: al_b, 0: al_a}
    for tid in (0, 1):
        edges = np.r_[0:3, n - 3:n]
        np.testing.assert_allclose(qdd[tid][edges], truth[tid][edges], atol=1e-3)  # mixing would give ~1e4
        assert rel_err(qdd[tid], truth[tid]) < 1e-4  # measured 1.7e-5 (101 samples, edges weigh more)
    np.testing.assert_allclose(ds.qd[n:, 0], estimate_derivatives(t, th_a).qd[:, 0], rtol=0, atol=0)
    np.testing.assert_array_equal(ud.trajectories[1].rows, np.arange(20, 20 + n))
    assert [tr["kept"] for tr in info["trajectories"]] == [[0, n], [0, n]]

    ds_t, info_t = to_dataset(ud, trim=True)  # noise-free: windows of 5, two rows off each end
    kept = [tuple(tr["kept"]) for tr in info_t["trajectories"]]
    assert kept == [(2, n - 2), (2, n - 2)] and info_t["trimmed"] == 8 and len(ds_t) == 2 * n - 8
    rows = np.concatenate([tr.rows[a:b] for tr, (a, b) in zip(ud.trajectories, kept)])
    np.testing.assert_array_equal(ds_t.t, cols[1][rows])  # kept ranges -> file rows
    np.testing.assert_array_equal(ds_t.q[:, 0], cols[2][rows])


def test_wrapped_angle_is_unwrapped(tmp_path):
    t, th, om, al = pendulum(theta0=0.0, omega0=3.0, T=20.0)  # goes over the top a few times
    wrapped = np.mod(th + np.pi, 2 * np.pi) - np.pi
    assert np.max(np.abs(np.diff(wrapped))) > np.pi and np.ptp(th) > 4 * np.pi
    path = write_csv(tmp_path / "spin.csv", ["t", "theta"], [t, wrapped])
    ds, info = to_dataset(load_trajectories(path, angles=["theta"]))
    assert info["angles"] == ["theta"]
    np.testing.assert_array_equal(ds.q[:, 0], wrapped)  # q kept as given
    assert rel_err(ds.qd[:, 0], om) < 1e-5 and rel_err(ds.qdd[:, 0], al) < 1e-3  # measured 1.4e-6, 1.8e-4
    ds_raw, _ = to_dataset(load_trajectories(path))  # not declared an angle: the jumps wreck the derivatives
    assert rel_err(ds_raw.qdd[:, 0], al) > 1.0


def test_given_derivatives_are_used_verbatim(tmp_path):
    t = 0.1 * np.arange(40)
    rng = np.random.default_rng(3)
    x, x_dot, x_ddot = np.sin(t), rng.standard_normal(40), rng.standard_normal(40)
    y, y_dot = np.cos(t), -np.sin(t)
    z, c = t**2, np.full(40, 7.0)
    path = write_csv(tmp_path / "given.csv", ["t", "x", "x_dot", "x_ddot", "y", "y_dot", "z", "c"],
                     [t, x, x_dot, x_ddot, y, y_dot, z, c])
    ud = load_trajectories(path)
    assert ud.coords == ("x", "y", "z", "c")
    assert ud.given_qd == (True, True, False, False) and ud.given_qdd == (True, False, False, False)
    ds, info = to_dataset(ud)
    np.testing.assert_array_equal(ds.qd[:, 0], x_dot)
    np.testing.assert_array_equal(ds.qdd[:, 0], x_ddot)
    np.testing.assert_array_equal(ds.qd[:, 1], y_dot)
    np.testing.assert_allclose(ds.qdd[:, 1], -np.cos(t), atol=1e-4)  # from the given y_dot
    np.testing.assert_allclose(ds.qd[:, 2], 2 * t, atol=1e-9)  # estimated: exact for polynomials
    np.testing.assert_allclose(ds.qdd[:, 2], 2.0, atol=1e-7)
    assert not ds.qd[:, 3].any() and not ds.qdd[:, 3].any()  # a constant coordinate is allowed beside moving ones
    pc = info["per_coordinate"]
    assert pc["x"]["qd"]["source"] == pc["x"]["qdd"]["source"] == pc["y"]["qd"]["source"] == "given"
    assert pc["y"]["qdd"]["source"] == "estimated from q_dot" and pc["z"]["qdd"]["source"] == "estimated from q"
    assert pc["x"]["qd"]["error"] is None and pc["y"]["qdd"]["error"] < 1e-4
    assert pc["c"]["noise"] == 0 and pc["c"]["qdd"]["error"] == 0


def test_npz_matches_csv_and_info_is_json(tmp_path):
    t, th, om, al = pendulum(T=10.0)
    noisy = th + 1e-3 * th.std() * np.random.default_rng(4).standard_normal(t.size)
    traj = np.r_[np.zeros(100), np.ones(t.size - 100)]
    cols = {"t": np.r_[t[:100], t[100:]], "traj": traj, "theta": noisy, "x": 0.5 * noisy + t}
    csv_ds, csv_info = to_dataset(load_trajectories(write_csv(tmp_path / "a.csv", list(cols), list(cols.values())),
                                                    angles=("theta",)), trim=True)
    np.savez(tmp_path / "a.npz", **cols)
    npz_ds, npz_info = to_dataset(load_trajectories(tmp_path / "a.npz", angles=("theta",)), trim=True)
    for f in ("q", "qd", "qdd", "t"):
        np.testing.assert_array_equal(getattr(csv_ds, f), getattr(npz_ds, f))
    npz_info.pop("trajectories"), csv_info.pop("trajectories")
    assert csv_info == npz_info
    info = json.loads(json.dumps(csv_info))
    assert info["n_rows"] == t.size and info["n_samples"] == len(csv_ds) == t.size - info["trimmed"] > 0
    assert info["trim"] is True and info["method"] == "savgol" and info["coordinates"] == ["theta", "x"]
    th_info = info["per_coordinate"]["theta"]
    assert 1 / 1.5 < th_info["noise"] / (1e-3 * th.std()) < 1.5
    assert th_info["noise_relative"] == pytest.approx(1e-3, rel=0.5)
    assert 0 < th_info["qdd"]["relative_error"] < 0.05 and th_info["qdd"]["windows"]


# ---- validation ---------------------------------------------------------------------------------------------------
def _csv(header, *rows):
    return header + "\n" + "".join(r + "\n" for r in rows)


TEN = [f"{i},{i * i}" for i in range(10)]  # ten good rows of t,x

BAD_CSV = [  # (file content, angles, substrings of the message)
    ("", (), ["empty", "header"]),
    ("t,x\n", (), ["no data rows"]),
    (_csv("0,1", "1,2"), (), ["line 1 holds numbers", "header"]),
    (_csv("time,x", *TEN), (), ["no 't' column", "time, x"]),
    (_csv("t,x", "0,1", "1,2", "2,abc", "3,4"), (), ["column 'x' row 3 (line 4)", "'abc' is not a number"]),
    (_csv("t,x", "0,1", "1, "), (), ["column 'x' row 2 (line 3)", "is empty"]),
    (_csv("t,x", "0,1", "1,nan", *TEN[2:]), (), ["column 'x' row 2 (line 3)", "nan", "not finite"]),
    (_csv("t,x", "0,1", "1,-inf"), (), ["column 'x' row 2 (line 3)", "inf", "not finite"]),
    (_csv("t,x", *TEN[:4], "2.5,1", *TEN[4:]), (), ["not strictly increasing", "row 5 (line 6)",
                                                  "decreasing time 2.5 after 3.0"]),
    (_csv("t,x", *TEN[:4], "3,1", *TEN[4:]), (), ["not strictly increasing", "row 5 (line 6)", "duplicate time 3.0"]),
    (_csv("traj,t,x", *[f"0,{r}" for r in TEN], "1.5,11,1"), (),
     ["column 'traj' row 11 (line 12)", "1.5 is not an integer"]),
    (_csv("traj,t,x", *[f"0,{r}" for r in TEN], *[f"3,{r}" for r in TEN[:4]]), (),
     ["trajectory 3 has 4 samples", f"at least {MIN_SAMPLES}"]),
    (_csv("traj,t,x", *[f"0,{r}" for r in TEN], "2,0,5"), (),
     ["trajectory 2 has a single sample", "row 11 (line 12)", f"at least {MIN_SAMPLES}"]),
    (_csv("t,x", "0,1"), (), ["single sample", f"at least {MIN_SAMPLES}"]),
    (_csv("t,x,y", *[f"{i},1,-2" for i in range(10)]), (), ["all coordinates are constant", "x, y"]),
    (_csv("t,traj", *[f"{i},0" for i in range(10)]), (), ["no coordinate column"]),
    (_csv("t,x,y_ddot", *[f"{r},0" for r in TEN]), (), ["'y_ddot' has no coordinate column 'y'"]),
    (_csv("t,x,y_dot", *[f"{r},0" for r in TEN]), (), ["'y_dot' has no coordinate column 'y'"]),
    (_csv("t,x", *TEN), ("phi",), ["angle 'phi' is not a coordinate", "coordinates: x"]),
    (_csv("t,x", "0,1", "1,2,3"), (), ["row 2 (line 3) has 3 fields", "header has 2"]),
    (_csv("t,x,x", "0,1,2"), (), ["duplicate column name 'x'"]),
]


@pytest.mark.parametrize("content,angles,expected", BAD_CSV)
def test_bad_csv_raises_one_line_data_error(tmp_path, content, angles, expected):
    path = tmp_path / "bad.csv"
    path.write_text(content)
    with pytest.raises(DataError) as err:
        load_trajectories(path, angles=angles)
    msg = str(err.value)
    assert "\n" not in msg and msg.startswith(str(path))
    for part in expected:
        assert part in msg, (part, msg)
    assert isinstance(err.value, ValueError)


def test_bad_files_and_npz_arrays(tmp_path):
    def raises(path, *parts, angles=()):
        with pytest.raises(DataError) as err:
            load_trajectories(path, angles=angles)
        msg = str(err.value)
        assert "\n" not in msg and all(p in msg for p in parts), (parts, msg)

    raises(tmp_path / "missing.csv", "missing.csv", "file not found")
    raises(tmp_path / "data.txt", "unsupported file type '.txt'", "expected a .csv or .npz")
    raises(tmp_path, "unsupported file type")
    (tmp_path / "dir.csv").mkdir()
    raises(tmp_path / "dir.csv", "is a directory")
    (tmp_path / "bin.csv").write_bytes(b"\xff\xfe\x00t,x\x00\x81")
    raises(tmp_path / "bin.csv", "not a UTF-8 text file")
    (tmp_path / "junk.npz").write_bytes(b"not a zip file")
    raises(tmp_path / "junk.npz", "cannot read as .npz")
    t = np.arange(10.0)
    np.savez(tmp_path / "a.npz", t=t, x=np.ones((10, 2)))
    raises(tmp_path / "a.npz", "array 'x' has shape (10, 2)", "1-D")
    np.savez(tmp_path / "b.npz", t=t, x=np.array(["a"] * 10))
    raises(tmp_path / "b.npz", "array 'x' has dtype", "expected numbers")
    np.savez(tmp_path / "c.npz", t=t, x=np.arange(9.0))
    raises(tmp_path / "c.npz", "array 'x' has 9 values but 't' has 10")
    np.savez(tmp_path / "d.npz", t=t, x=np.r_[t[:4], np.nan, t[5:]])
    raises(tmp_path / "d.npz", "column 'x' index 4", "not finite")
    np.savez(tmp_path / "e.npz", time=t, x=t)
    raises(tmp_path / "e.npz", "no 't' column")
    np.savez(tmp_path / "f.npz")
    raises(tmp_path / "f.npz", "holds no arrays")
    np.savez(tmp_path / "g.npz", t=np.zeros(0), x=np.zeros(0))
    raises(tmp_path / "g.npz", "empty")


def test_short_trajectories_allowed_when_all_derivatives_are_given(tmp_path):
    path = tmp_path / "given.csv"
    path.write_text("traj,t,x,x_dot,x_ddot\n0,0,0,1,0\n0,1,1,1,0\n1,0,5,0,-1\n")
    ds, info = to_dataset(load_trajectories(path))
    np.testing.assert_array_equal(ds.qd[:, 0], [1, 1, 0])
    np.testing.assert_array_equal(ds.qdd[:, 0], [0, 0, -1])
    assert info["method"] == "given" and info["n_samples"] == 3
