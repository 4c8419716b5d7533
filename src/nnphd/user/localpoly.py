r"""Local polynomial estimates of q̇ and q̈: Savitzky–Golay on uniform grids and its generalisation to the actual
times, the error model that chooses order and window, and the end rows — items 3 to 5 of the derivative estimation
of :mod:`nnphd.user.derivatives` (the items referred to below are its).

3. **Local polynomial regression** (:func:`local_fit`; Savitzky–Golay generalised): at row i the least-squares
   polynomial of order p in the offsets t_j − t_i over the m samples nearest by index (one-sided at the ends, as
   ``mode='interp'``), differentiated at t_i.  Batched over rows through power sums (only S_k = Σ u_jᵏ and
   Σ u_jˡ(y_j − y_i) touch the samples; weights, ‖w‖² and moments follow from them); on a uniform grid it reproduces
   savgol_filter to ~1e-11.  Orders p = 4 and 6 (ORDERS) and odd windows 5 (7), 7 (9), … growing by ~20 % up to
   min(N, 2001) are tried.  Runtime: 10⁴ rows with windows up to ~300, 0.7–0.9 s (2 busy cores); the window search
   runs on at most 2048 rows and the chosen fits are then evaluated at every row.

4. **Error model and choice.**  Row i's squared error is estimated as σ²‖w_i‖² (noise, from its actual weights)
   plus Σₖ (R_k M_k(w_i))² (Taylor bias, M_k(w) = Σ_j w_j (t_j − t_i)ᵏ/k!, k = p+1, p+2).  The RMS sizes R_k of
   q⁽ᵏ⁾ are measured Richardson-style from the estimates of neighbouring windows a < b over the rows interior to
   both: E[Δ²] = R²⟨ΔM²⟩ + σ²⟨‖w_a‖² − ‖w_b‖²⟩ (‖w_b − w_a‖² = ‖w_a‖² − ‖w_b‖² exactly on any grid, as the larger
   window's least-squares estimate is uncorrelated with its difference to any other unbiased estimate).  A pair
   counts when its excess over the noise term is significant (> 3 standard deviations and > the noise term); R is the
   largest over such pairs; the grid stops once the bias clearly dominates (excess > 10 × noise term) for both
   derivatives.  Per derivative, the (order, window) of least estimated mean squared error over the interior rows of
   the window is used.  Order 6 is dropped when its measured R falls steeply with the window (slope of log R against
   log window < −3 over the first pairs: the signal is not smooth at that scale; measured ≈ −0.8 on the pendulum and
   cart, −2.5…−5.4 on a chaotic double pendulum); when even order 4's R falls faster than −1.5, windows are scored
   over all rows (smaller windows: the bias of mid-sized windows is understated on such signals).

5. **End rows.**  A one-sided fit amplifies noise and bias strongly (q̈ of order 4 at the last row: ‖w‖ ≈ 5× the
   interior's).  The first and last half-window rows whose estimated error is over twice the median choose their own
   order (2, 3, 4, 6) and window (up to 3× the interior one) by σ²‖w_i‖² + 2·bias² (R₃, R₄ measured from order-4
   estimates of q⁽³⁾, q⁽⁴⁾).  The ends stay the least accurate rows (on the pendulum below q̈ at the first and last
   rows is ~0.09, 20× the interior error), and their estimated errors say so.

   **Per-row errors**: ``qd_err_rows``/``qdd_err_rows`` (N, n) are the estimated errors of every row; ``qd_err``/
   ``qdd_err`` their RMS over the kept rows.  ``derive`` returns them as ``row_errors``.  ``trim=True`` drops
   the first and last half-window rows (largest window over coordinates and derivatives) and then chooses windows for
   the interior rows (no end treatment); for the spline, the runs of end rows whose estimated error exceeds twice the
   median.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy.signal import savgol_filter

POLYORDER = 4  # Savitzky–Golay polynomial order
MIN_WINDOW = POLYORDER + 1  # smallest SG window (exact interpolation of 5 points)
MAX_WINDOW = 2001
MIN_SAMPLES = MIN_WINDOW + 2  # two windows (5, 7) are needed to measure the bias
ORDERS = (4, 6)  # polynomial orders tried for the whole trajectory (the end rows may also use 2 and 3)
MIN_DECLINE_HIGH = -3.0  # order 6 is used only where its bias scales nearly as Taylor's (_OrderFits.decline)
ROUGH_DECLINE = -1.5  # order 4 declining faster: a rough signal, windows scored over all rows (see poly_coordinate)


# ---- local polynomial estimates: Savitzky–Golay (uniform) and its generalisation to the actual times ----------------
def _window_grid(n: int, p: int = POLYORDER) -> list[int]:
    """Odd windows p+1 (or p+2), …, growing by ~20 %, up to min(N, MAX_WINDOW)."""
    m_max = min(n if n % 2 else n - 1, MAX_WINDOW)
    grid, m = [], p + 1 if p % 2 == 0 else p + 2
    while m <= m_max:
        grid.append(m)
        nxt = max(m + 2, int(round(m * 1.2)))
        m = nxt if nxt % 2 else nxt + 1
    return grid


def sg_weights(m: int, d: int, p: int = POLYORDER, edges: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
    """SG weights (units of dt⁻ᵈ) of the d-th derivative with window m and order p, as savgol_filter(mode='interp')
    applies them: the centred interior stencil (m,) and the left-edge stencils (half, m) of rows r = 0…half-1, which
    evaluate the polynomial fitted to the first m samples at row r (the right edge mirrors them: reversed, times
    (-1)ᵈ).  edges=False: the interior stencil only (None for the edges)."""
    half = m // 2
    u = (np.arange(m) - half) / half  # window scaled to [-1, 1] for conditioning
    fit = np.linalg.pinv(u[:, None] ** np.arange(p + 1)[None, :])  # (p+1, m): samples -> coefficients
    ks = np.arange(d, p + 1)
    falling = np.array([math.factorial(k) / math.factorial(k - d) for k in ks])
    at = u[: half + 1] if edges else u[half : half + 1]
    rows = at[:, None] ** (ks - d)[None, :] * falling  # d-th derivative of the monomials at rows 0…half
    w = rows @ fit[ks] / half**d
    return (w[half], w[:half]) if edges else (w[0], None)


@lru_cache(maxsize=512)
def _sg_stats(m: int, d: int, p: int = POLYORDER):
    """What the error model needs of window m and order p on a unit grid: the interior stencil w_c, the squared norms
    of the left-edge stencils (half,), and the Taylor bias moments Mₖ = Σ_j w_j o_jᵏ/k! (k = p+1, p+2; offsets o_j
    from the row) of the interior (2,) and of each left-edge row (half, 2); the right edge has the same norms and
    moments up to the sign (-1)ᵈ⁺ᵏ."""
    w_c, w_e = sg_weights(m, d, p)
    half = m // 2
    o = (np.arange(m)[None, :] - np.arange(half + 1)[:, None]).astype(np.float64)  # rows 0…half (half: interior)
    w = np.vstack([w_e, w_c])
    mom = np.stack(
        [
            np.sum(w * o ** (p + 1), axis=1) / math.factorial(p + 1),
            np.sum(w * o ** (p + 2), axis=1) / math.factorial(p + 2),
        ],
        axis=1,
    )
    return w_c, np.sum(w_e**2, axis=1), mom[half], mom[:half]


@lru_cache(maxsize=512)
def _pair_acf_sq(a: int, b: int, d: int, p: int) -> float:
    """Σ acf² of the difference of the uniform interior stencils of windows a < b: the correlation of the filtered
    noise, used for the standard deviation of the Richardson statistic (also on non-uniform grids, approximately)."""
    wa, wb = sg_weights(a, d, p, edges=False)[0], sg_weights(b, d, p, edges=False)[0]
    pad = (b - a) // 2
    dw = wb - np.pad(wa, (pad, pad))
    acf = np.correlate(dw, dw, mode="full") / np.sum(dw**2)
    return float(np.sum(acf**2))


@dataclass
class _Stencil:
    """Results of one window and order p at some rows (sorted indices) for d = 1, 2: the estimates (2, R), the
    squared weight norms ‖w_i‖² (2, R) in time units (noise variance / σ²) and the Taylor moments Mₖ(w_i) (2, R, 2)
    for k = p+1, p+2."""

    rows: np.ndarray
    est: np.ndarray
    ns: np.ndarray
    mom: np.ndarray


def _uniform_stencil(y: np.ndarray, m: int, h: float, p: int = POLYORDER, rows: np.ndarray | None = None) -> _Stencil:
    """Savitzky–Golay (scipy's savgol_filter, mode='interp') with window m, order p on a uniform grid of spacing h,
    at ``rows`` (every row if None)."""
    n = y.shape[0]
    half = m // 2
    rows = np.arange(n) if rows is None else np.asarray(rows)
    R = rows.size
    est, ns, mom = np.empty((2, R)), np.empty((2, R)), np.empty((2, R, 2))
    for d in (1, 2):
        w_c, ns_e, mom_c, mom_e = _sg_stats(m, d, p)
        est[d - 1] = savgol_filter(y, m, p, deriv=d, delta=h, mode="interp")[rows]
        nsd = np.full(n, float(np.sum(w_c**2)))
        nsd[:half], nsd[n - half :] = ns_e, ns_e[::-1]
        md = np.tile(mom_c, (n, 1))
        md[:half] = mom_e
        md[n - half :] = mom_e[::-1] * [(-1.0) ** (d + p + 1), (-1.0) ** (d + p + 2)]
        ns[d - 1] = nsd[rows] / h ** (2 * d)
        mom[d - 1] = md[rows] * [h ** (p + 1 - d), h ** (p + 2 - d)]
    return _Stencil(rows, est, ns, mom)


_CHUNK = 1 << 17  # rows × window elements per batch of the local fits


def local_fit(
    t: np.ndarray,
    y: np.ndarray,
    m: int,
    rows: np.ndarray | None = None,
    degree: int = POLYORDER,
    derivs: Sequence[int] = (1, 2),
    ks: Sequence[int] | None = None,
):
    """Local polynomial regression (Savitzky–Golay generalised to the actual sample times) at ``rows`` (all if None).

    Row i uses the m samples nearest by index (one-sided at the ends, as savgol_filter's mode='interp'): the
    least-squares polynomial of order p = ``degree`` in the offsets t_j − t_i, differentiated at t_i.  Returns, for
    each d in ``derivs``, the estimates (D, R), the squared weight norms ‖w_i‖² (D, R) and the Taylor moments
    Mₖ(w_i) = Σ_j w_ij (t_j − t_i)ᵏ/k! (D, R, K) for k in ``ks`` (default p+1, p+2), in time units.

    Batched over rows, in the window's own scaled time u = (t − centre)/half-span ∈ [−1, 1]: only the power sums
    S_k = Σ_j u_jᵏ (k ≤ 2p+2) and Y_l = Σ_j u_jˡ (y_j − y_i) (l ≤ p) touch the m samples.  The weights are
    w_j = Σ_l z_l u_jˡ with G z = (the d-th derivative of 1, u, …, uᵖ at u_i), G_kl = S_{k+l}; then Σ_j w_j y_j = z·Y,
    ‖w‖² = zᵀGz and Σ_j w_j u_jⁱ = Σ_l z_l S_{l+i}, from which the moments follow binomially.
    """
    n = t.shape[0]
    rows = np.arange(n) if rows is None else np.asarray(rows)
    ks = (degree + 1, degree + 2) if ks is None else tuple(ks)
    half = m // 2
    n_d, p1, top = len(derivs), degree + 1, max(ks)
    est, ns, mom = np.empty((n_d, rows.size)), np.empty((n_d, rows.size)), np.empty((n_d, rows.size, len(ks)))
    ar = np.arange(m)
    hank = np.add.outer(np.arange(p1), np.arange(p1))  # G_kl = S_{k+l}
    hank_m = np.add.outer(np.arange(p1), np.arange(top + 1))  # Σ_j w_j u_jⁱ = Σ_l z_l S_{l+i}
    n_s = max(2 * degree, degree + top) + 1
    chunk = max(1, _CHUNK // m)
    for c0 in range(0, rows.size, chunk):
        sel = slice(c0, min(rows.size, c0 + chunk))
        r = rows[sel]
        idx = np.clip(r - half, 0, n - m)[:, None] + ar
        tt = t[idx]
        centre = 0.5 * (tt[:, 0] + tt[:, -1])
        s = 0.5 * (tt[:, -1] - tt[:, 0])
        u = (tt - centre[:, None]) / s[:, None]
        u0 = (t[r] - centre) / s
        yy = y[idx] - y[r, None]
        sums = np.empty((r.size, n_s))
        ysum = np.empty((r.size, p1))
        sums[:, 0] = m
        ysum[:, 0] = yy.sum(axis=1)
        pw, py = u.copy(), yy * u
        sums[:, 1], ysum[:, 1] = pw.sum(axis=1), py.sum(axis=1)
        for k in range(2, n_s):
            pw *= u
            sums[:, k] = pw.sum(axis=1)
            if k < p1:
                py *= u
                ysum[:, k] = py.sum(axis=1)
        gram = sums[:, hank]
        rhs = np.zeros((r.size, p1, n_d))  # d-th derivative of the monomials uᵏ at u0
        for a, d in enumerate(derivs):
            for k in range(d, p1):
                rhs[:, k, a] = math.factorial(k) / math.factorial(k - d) * u0 ** (k - d)
        z = np.linalg.solve(gram, rhs)  # (rows, p+1, D)
        wu = np.einsum("rla,rli->rai", z, sums[:, hank_m])  # (rows, D, top+1): Σ_j w_j u_jⁱ
        for a, d in enumerate(derivs):
            za = z[:, :, a]
            est[a, sel] = np.einsum("rl,rl->r", za, ysum) / s**d
            ns[a, sel] = np.einsum("rl,rlk,rk->r", za, gram, za) / s ** (2 * d)
            for b, k in enumerate(ks):
                acc = np.zeros(r.size)
                for i in range(k + 1):
                    acc += math.comb(k, i) * (-u0) ** (k - i) * wu[:, a, i]
                mom[a, sel, b] = acc * s ** (k - d) / math.factorial(k)
    return est, ns, mom


def _local_stencil(t: np.ndarray, y: np.ndarray, m: int, p: int = POLYORDER) -> _Stencil:
    """Order-p local polynomial q̇, q̈ with window m at every row, with their weight norms and moments."""
    return _stencil(t, y, m, p, None)


def _stencil(tg: np.ndarray, y: np.ndarray, m: int, p: int, dt: float | None, rows=None) -> _Stencil:
    """Order-p q̇, q̈ with window m: Savitzky–Golay at every row on a uniform grid (dt given), else the local
    polynomial at ``rows`` (all if None)."""
    if dt is not None:
        return _uniform_stencil(y, m, dt, p, rows)
    rows = np.arange(y.shape[0]) if rows is None else rows
    return _Stencil(rows, *local_fit(tg, y, m, rows, p))


@dataclass(frozen=True, eq=False)
class _WindowPair:
    """Two neighbouring windows a < b of one polynomial order and their results ``sa``, ``sb`` at the same rows."""

    a: int
    b: int
    sa: _Stencil
    sb: _Stencil


def _taylor_pair(pair: _WindowPair, d: int, sigma: float, r_lead: float, n: int, p: int = POLYORDER):
    """Richardson measurement of the bias of the order-p estimates (leading order k = p+1 for d=1, p+2 for d=2) from
    the windows a < b of ``pair``: (a, b, excess, ⟨M_a²⟩, ⟨M_b²⟩, ⟨M_a M_b⟩) of the leading moments when significant,
    else None.

    Over the rows interior to both windows, E[Δ²] = R² ⟨ΔMₖ²⟩ + σ² ⟨‖w_a‖² − ‖w_b‖²⟩ (the least-squares estimate of
    the larger window is uncorrelated with its difference to any other unbiased estimate, so ‖w_b − w_a‖² =
    ‖w_a‖² − ‖w_b‖² on any grid); for d = 2 the q⁽ᵖ⁺¹⁾ part r_lead² ⟨ΔM_{p+1}²⟩ (non-zero on non-uniform grids) is
    subtracted first, and R = √(excess/⟨ΔMₖ²⟩) (:func:`_pair_r`).  The pair
    counts only when the excess over the noise term is significant: above 3 standard
    deviations (counting the correlation of filtered noise) and above the noise term itself, which absorbs an
    underestimate of σ by up to 30 %.  Also returns whether the bias dominates clearly (excess > 10 × noise term), i.e.
    longer windows can only be worse.  sa and sb hold the same rows (of a trajectory of n samples).
    """
    a, b, sa, sb = pair.a, pair.b, pair.sa, pair.sb
    hb = b // 2
    n_int = n - 2 * hb
    if n_int < 5:
        return None, False
    sl = (sa.rows >= hb) & (sa.rows < n - hb)
    var = sigma**2 * float(np.mean(np.maximum(sa.ns[d - 1, sl] - sb.ns[d - 1, sl], 0.0)))
    delta = sb.est[d - 1, sl] - sa.est[d - 1, sl]
    dmom = sb.mom[d - 1, sl] - sa.mom[d - 1, sl]
    excess = float(np.mean(delta**2)) - var
    if d == 2:
        excess -= r_lead**2 * float(np.mean(dmom[:, 0] ** 2))
    ma, mb = sa.mom[d - 1, sl, d - 1], sb.mom[d - 1, sl, d - 1]  # the leading order k
    dm2 = float(np.mean((mb - ma) ** 2))
    sd = var * math.sqrt(2.0 * _pair_acf_sq(a, b, d, p) / n_int)
    if excess > max(3.0 * sd, var) and dm2 > 0:
        rec = (a, b, excess, float(np.mean(ma * ma)), float(np.mean(mb * mb)), float(np.mean(ma * mb)))
        return rec, excess > 10.0 * var
    return None, False


def _mse_rows(st: _Stencil, d: int, sigma: float, r: np.ndarray) -> np.ndarray:
    """Estimated squared error of the d-th derivative in every row: σ²‖w_i‖² + Σₖ (Rₖ Mₖ(w_i))² (k = p+1, p+2)."""
    return sigma**2 * st.ns[d - 1] + np.sum((st.mom[d - 1] * r) ** 2, axis=1)


@dataclass
class _OrderFits:
    """The windows tried with one polynomial order, their results at the search rows and the significant Richardson
    pairs (see :func:`_taylor_pair`) for R_{p+1} (from q̇) and R_{p+2} (from q̈)."""

    p: int
    used: list
    stencils: dict
    pairs: tuple

    def __post_init__(self):
        # R per significant pair, by window; R_{p+1}, R_{p+2}: the largest (windows much longer than the signal's
        # time scale saturate and would understate them), 0 where no pair is significant
        self.rj = [[(rec[1], _pair_r(rec)) for rec in pr] for pr in self.pairs]
        self.r = np.array([max((r for _, r in rj), default=0.0) for rj in self.rj])

    def decline(self) -> float | None:
        """How fast the measured R falls with the window over the smallest significant pairs: the least-squares slope
        of log R_b against log b over up to _SCALE_PAIRS pairs, the steeper of q̇ and q̈ (None with fewer than 2).

        Near 0 while the signal is smooth at the window scale (the Taylor bias ∝ m^(k−d) holds); −0.8 on the
        pendulum and the cart below at the windows that matter, −2.5 to −5.4 on broadband motion (a chaotic double
        pendulum), where a pair's excess no longer follows Taylor and the higher order loses to order 4."""
        slopes = []
        for rj in self.rj:
            use = rj[:_SCALE_PAIRS]
            if len(use) >= 2:
                slopes.append(float(np.polyfit(np.log([b for b, _ in use]), np.log([r for _, r in use]), 1)[0]))
        return min(slopes) if slopes else None


_SCALE_PAIRS = 3  # the smallest significant pairs used to judge how R depends on the window


def _pair_r(rec) -> float:
    """R = √(excess/⟨ΔMₖ²⟩) of a significant pair (a, b, excess, ⟨M_a²⟩, ⟨M_b²⟩, ⟨M_a M_b⟩)."""
    _, _, exc, maa, mbb, mab = rec
    return math.sqrt(exc / max(mbb - 2.0 * mab + maa, 1e-300))


_SEARCH_ROWS = 2048  # on non-uniform grids, the window search uses at most this many rows (evenly spread)


_SEARCH_ROWS_UNIFORM = 200_000  # on uniform grids (Savitzky–Golay, cheap), at most this many rows: memory bounded


def _search_rows(n: int, uniform: bool = False) -> np.ndarray | None:
    cap = _SEARCH_ROWS_UNIFORM if uniform else _SEARCH_ROWS
    return None if n <= cap else np.unique(np.linspace(0, n - 1, cap).round().astype(int))


def _grow_windows(tg, y, sigma, dt, p, rows) -> _OrderFits:
    """Order-p fits along the window grid until the bias clearly dominates both derivatives; R_{p+1}, R_{p+2} are the
    largest significant values over the neighbouring pairs (windows much longer than the signal's time scale
    saturate and would understate them), 0 where no pair is significant."""
    n = y.shape[0]
    stencils: dict[int, _Stencil] = {}
    pairs: tuple[list, list] = ([], [])
    strong = [False, False]
    used: list[int] = []
    for m in _window_grid(n, p):
        stencils[m] = _stencil(tg, y, m, p, dt, rows)
        if used:
            a = used[-1]
            r_lead = max((_pair_r(rec) for rec in pairs[0]), default=0.0)
            for d in (1, 2):
                rec, s = _taylor_pair(_WindowPair(a, m, stencils[a], stencils[m]), d, sigma, r_lead, n, p)
                if rec is not None:
                    pairs[d - 1].append(rec)
                strong[d - 1] |= s
        used.append(m)
        if all(strong):
            break
    return _OrderFits(p, used, stencils, pairs)


def poly_coordinate(
    tg: np.ndarray, y: np.ndarray, sigma: float, trim: bool, dt: float | None = None, ends: bool = True
):
    """q̇, q̈ of one coordinate by local polynomials: order (4 or 6) and window chosen per derivative by the estimated
    RMS error over the interior rows of each window.

    tg: the sample times; dt: the spacing when they are uniform (scipy's savgol_filter is then used).  On long
    non-uniform trajectories the search runs on _SEARCH_ROWS rows and the chosen fits are then evaluated at every row.
    Order 6 is dropped when its measured R falls steeply with the window (``decline`` < MIN_DECLINE_HIGH: the signal
    is not smooth at that scale and the order-6 Taylor bias model fails).  Unless ``trim`` (or not ``ends``), the end
    rows then choose their own order and window (:func:`_end_rows`).  Where even order 4's R declines fast
    (< ROUGH_DECLINE: broadband motion), the bias model understates the bias of mid-sized windows, and windows are
    scored over all rows as before the end treatment existed (the one-sided end rows then keep windows small); the same
    when ``ends`` is False.  Returns (qd, qdd, (m1, m2), (p1, p2), err_rows (2, N)).
    """
    n = y.shape[0]
    rows = _search_rows(n, uniform=dt is not None)
    fits = [_grow_windows(tg, y, sigma, dt, p, rows) for p in ORDERS if len(_window_grid(n, p)) >= 2]
    fits = [f for f in fits if f.p == POLYORDER or (f.decline() or 0.0) >= MIN_DECLINE_HIGH]
    interior = trim or (ends and (fits[0].decline() or 0.0) >= ROUGH_DECLINE)
    out, windows, orders, err_rows = [], [], [], []
    for d in (1, 2):
        best = None
        for f in fits:
            for m in f.used:
                st = f.stencils[m]
                mse = _mse_rows(st, d, sigma, f.r)
                half = m // 2
                inner = (st.rows >= half) & (st.rows < n - half)
                score = float(np.mean(mse[inner] if interior else mse))
                if best is None or score < best[0]:
                    best = (score, f, m)
        _, f, m = best
        st = f.stencils[m]
        if st.rows.size < n:
            st = f.stencils[m] = _stencil(tg, y, m, f.p, dt)  # every row
        out.append(st.est[d - 1].copy())
        windows.append(m)
        orders.append(f.p)
        err_rows.append(_mse_rows(st, d, sigma, f.r))
    if ends and not trim:
        r34 = _low_order_sizes(tg, y, sigma, fits[0])
        samples = _Samples(tg, y, sigma)
        for d in (1, 2):
            _end_rows(samples, d, windows[d - 1], fits, r34, out[d - 1], err_rows[d - 1])
    return out[0], out[1], tuple(windows), tuple(orders), np.sqrt(np.array(err_rows))


_R34_ROWS = 512  # interior rows sampled to measure R₃, R₄
_END_LOW_ORDERS = (2, 3)  # lower orders the end rows may also use
_END_MAX_FACTOR = 3.0  # end rows consider windows up to this many times the interior one
_END_BIAS_SAFETY = 2.0  # end rows choose by σ²‖w‖² + this × bias² (their one-sided bias model is the least reliable)


def _low_order_sizes(tg: np.ndarray, y: np.ndarray, sigma: float, fit: _OrderFits) -> np.ndarray:
    """RMS sizes R₃, R₄ of q⁽³⁾, q⁽⁴⁾ (needed for the bias of the order-2 and -3 end fits), inf where not measurable.

    q⁽ᵈ⁾ (d = 3, 4) is estimated by the order-4 local polynomial at up to _R34_ROWS interior rows for every window
    tried; at the window with the least estimated error e² = σ²⟨‖w‖²⟩ + R₅²⟨M₅²⟩ + R₆²⟨M₆²⟩, R_d² = ⟨est²⟩ − e².
    The estimate must stand clearly above its error (⟨est²⟩ > 4 e²), else R_d = inf and the lower orders are not used.
    """
    n = y.shape[0]
    out = np.full(2, np.inf)
    best = [None, None]
    for m in fit.used:
        half = m // 2
        if n - 2 * half < 5:
            continue
        rows = np.unique(np.linspace(half, n - half - 1, min(_R34_ROWS, n - 2 * half)).round().astype(int))
        est, ns, mom = local_fit(tg, y, m, rows, fit.p, (3, 4))
        for a in range(2):
            e2 = sigma**2 * float(np.mean(ns[a])) + float(np.mean(np.sum((mom[a] * fit.r) ** 2, axis=1)))
            if best[a] is None or e2 < best[a][0]:
                best[a] = (e2, float(np.mean(est[a] ** 2)))
    for a in range(2):
        if best[a] is not None and best[a][1] > 4.0 * best[a][0]:
            out[a] = math.sqrt(best[a][1] - best[a][0])
    return out


@dataclass(frozen=True, eq=False)
class _Samples:
    """One coordinate of a trajectory: the sample times ``t``, the values ``y`` and their noise level ``sigma``."""

    t: np.ndarray
    y: np.ndarray
    sigma: float


def _end_rows(samples: _Samples, d, m_star, fits, r34, est, mse):
    """Re-choose order and window in those of the first and last m_star//2 rows whose estimated squared error is
    more than twice the median (modified in place: est, mse).

    A one-sided fit amplifies noise strongly at the ends (order 4, q̈ at the last row: ‖w‖ ≈ 5× the interior's with
    the same window).  Each end row takes, among orders 2, 3 and those of ``fits`` and the windows tried (up to
    3·m_star), the candidate of least estimated squared error σ²‖w_i‖² + Σ (R_k M_k(w_i))² over its two leading
    Taylor orders k = p+1, p+2 (R₃, R₄: ``r34``; R₅…R₈ from the fits of orders 4 and 6 at that window).
    """
    tg, y, sigma = samples.t, samples.y, samples.sigma
    n = y.shape[0]
    e = m_star // 2
    if e == 0:
        return
    rows = np.r_[0:e, n - e : n]
    rows = rows[mse[rows] > 2.0 * np.median(mse)]  # only where the one-sided fit is clearly worse than the interior
    if rows.size == 0:
        return
    best_mse, best_est = mse[rows].copy(), est[rows].copy()
    best_score = best_mse.copy()

    def take(ce, noise, bias2):
        cm = noise + bias2
        score = noise + _END_BIAS_SAFETY * bias2
        better = score < best_score
        best_score[better], best_mse[better], best_est[better] = score[better], cm[better], ce[better]

    for f in fits:
        for m in f.used:
            if m > _END_MAX_FACTOR * m_star:
                break
            st = f.stencils[m]
            r = f.r
            if st.rows.size == n:
                take(st.est[d - 1][rows], sigma**2 * st.ns[d - 1][rows], np.sum((st.mom[d - 1][rows] * r) ** 2, axis=1))
            else:
                ep, nsp, mp = local_fit(tg, y, m, rows, f.p, (d,))
                take(ep[0], sigma**2 * nsp[0], np.sum((mp[0] * r) ** 2, axis=1))
    for p in _END_LOW_ORDERS:
        ks = (p + 1, p + 2)
        for m in fits[0].used:
            if m > _END_MAX_FACTOR * m_star:
                break
            r = np.array([r34[0], r34[1]]) if p == 2 else np.array([r34[1], fits[0].r[0]])
            if not np.all(np.isfinite(r)):
                break
            ep, nsp, mp = local_fit(tg, y, m, rows, p, (d,), ks)
            take(ep[0], sigma**2 * nsp[0], np.sum((mp[0] * r) ** 2, axis=1))
    est[rows], mse[rows] = best_est, best_mse
