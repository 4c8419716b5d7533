"""The figures of the λ/p study (Fig. 5) and the data-quality study (Fig. 6); Fig. 4's are in :mod:`nnphd.paper.predict`."""

from __future__ import annotations

import numpy as np

from nnphd.io.results import subplots

_SYS_LABEL = {"ho+mf": "HO+MF", "ho+cg": "HO+CG", "ho+ld": "HO+LD", "ho+cd": "HO+CD", "ho+pf": "HO+PF"}


def _loss_title(l: str) -> str:
    return "MSE" if l == "mse" else f"p = {l}"


def _force_panels(ax_c, ax_n, forces: dict | None, title: str, letters=("", "")):
    if forces is None:  # no λ of force_lambdas was in the grid: nothing was stored to draw
        for ax in (ax_c, ax_n):
            ax.text(0.5, 0.5, f"{title}: no learned forces\n(no λ of force_lambdas in the grid)", ha="center",
                    va="center", fontsize=8, transform=ax.transAxes)  # fmt: skip
            ax.axis("off")
        return
    q, qd = np.asarray(forces["q"]), np.asarray(forces["qd"])
    order = sorted(forces["by_lambda"].values(), key=lambda d: d["lam"])
    import matplotlib

    cmap = matplotlib.colormaps["viridis"]
    for i, d in enumerate(order):
        c = cmap(i / max(1, len(order) - 1))
        ax_c.scatter(q, d["fc"], s=3, color=c, alpha=0.6, label=f"λ={d['lam']:g}")
        ax_n.scatter(qd, d["fn"], s=3, color=c, alpha=0.6, label=f"λ={d['lam']:g}")
    xs = np.linspace(min(q.min(), qd.min()), max(q.max(), qd.max()), 50)
    ax_c.plot(xs, -xs, "r--", lw=1.2, label="truth −q")
    ax_n.plot(xs, -0.5 * xs, "r--", lw=1.2, label="truth −q̇/2")
    ax_c.set_xlabel("q")
    ax_c.set_ylabel(r"$f_c^{NN}$")
    ax_n.set_xlabel(r"$\dot q$")
    ax_n.set_ylabel(r"$f_n^{NN}$")
    # a few points where the learned Lagrangian's mass is nearly singular can be far off: keep the axes on the truth's
    # scale and count what falls outside
    for ax, _x, truth, preds in (
        (ax_c, q, -q, [d["fc"] for d in order]),
        (ax_n, qd, -0.5 * qd, [d["fn"] for d in order]),
    ):
        lim = 2.0 * float(np.max(np.abs(truth))) + 0.5
        n_out = sum(int(np.sum(np.abs(np.asarray(p)) > lim)) for p in preds)
        ax.set_ylim(-lim, lim)
        if n_out:
            ax.text(0.02, 0.02, f"{n_out} points off scale", transform=ax.transAxes, fontsize=7)
    pre = [f"({x}) " if x else "" for x in letters]
    ax_c.set_title(f"{pre[0]}{title}: $f_c^{{NN}}$ vs $q$", fontsize=9)
    ax_n.set_title(f"{pre[1]}{title}: $f_n^{{NN}}$ vs $\\dot q$", fontsize=9)


def plot_fig5(result: dict):
    """Fig. 5 analogue: (a–d) L_e(λ) per loss, five systems each; (e, f) HO+LD learned f_c vs q and f_n vs q̇ for
    p = 1 (first loss) at several λ; (g, h) HO+LD m_c(λ) and m_n(λ) for every loss."""
    labels = result["settings"]["ps"]
    ncol = max(4, len(labels))
    fig, axes = subplots(2, ncol, figsize=(4.0 * ncol, 7.6))
    letters = "abcdefghijklmnop"
    for j in range(ncol):
        ax = axes[0, j]
        if j >= len(labels):
            ax.axis("off")
            continue
        l = labels[j]
        for i, (s, by_p) in enumerate(result["curves"].items()):
            rows = by_p[l]
            ax.plot(
                [r["lam"] for r in rows],
                [max(r["L_e"], 1e-9) for r in rows],
                "o-",
                ms=3,
                color=f"C{i}",
                label=_SYS_LABEL.get(s, s),
            )
        ax.axvline(1.0, color="k", lw=0.8, ls=":")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel(r"$\lambda$")
        ax.set_ylabel(r"$L_e$ (test)" + (" (mean square)" if l == "mse" else ""))
        ax.set_title(f"({letters[j]}) {_loss_title(l)}", fontsize=10)
        if j == 0:
            ax.legend(fontsize=7)
    al = result.get("alignment")
    row2 = axes[1]
    if al is None:
        for ax in row2:
            ax.axis("off")
    else:
        l0 = labels[0]
        _force_panels(
            row2[0], row2[1], al["forces"][l0], f"HO+LD {_loss_title(l0)}", (letters[ncol], letters[ncol + 1])
        )
        if row2[0].get_legend_handles_labels()[0]:
            row2[0].legend(fontsize=6, markerscale=3)
        for j, key in ((2, "m_c"), (3, "m_n")):
            ax = row2[j]
            for i, l in enumerate(labels):
                rows = al["by_p"][l]
                ax.plot(
                    [r["lam"] for r in rows],
                    [max(r[key], 1e-9) for r in rows],
                    "o-",
                    ms=3,
                    color=f"C{i}",
                    label=_loss_title(l),
                )
            ax.axvline(1.0, color="k", lw=0.8, ls=":")
            ax.axhline(result["settings"]["align_tol"], color="gray", lw=0.8, ls="--")
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.set_xlabel(r"$\lambda$")
            ax.set_ylabel(f"${key[0]}_{key[2]}$")
            ax.set_title(f"({letters[ncol + j]}) HO+LD misalignment ${key[0]}_{key[2]}$", fontsize=10)
            ax.legend(fontsize=7)
        for ax in row2[4:]:
            ax.axis("off")
    fig.tight_layout()
    return fig


def plot_fig5_forces(result: dict):
    """HO+LD learned f_c (vs q) and f_n (vs q̇) on test points at several λ, one row per loss, truth dashed."""
    al = result["alignment"]
    labels = result["settings"]["ps"]
    fig, axes = subplots(len(labels), 2, figsize=(8.5, 3.2 * len(labels)), squeeze=False)
    for i, l in enumerate(labels):
        _force_panels(axes[i, 0], axes[i, 1], al["forces"][l], f"HO+LD {_loss_title(l)}")
    if axes[0, 0].get_legend_handles_labels()[0]:
        axes[0, 0].legend(fontsize=6, markerscale=3)
    fig.tight_layout()
    return fig


def plot_fig6(result: dict):
    """Fig. 6 analogue: (a) L_e(α) of HO+CD at λ=10; (b) m_c(β), m_n(β) of HO+LD at λ=0.5."""
    fig, (a, b) = subplots(1, 2, figsize=(10, 4))
    rows = result["alpha"]["table"]
    x = [r["alpha"] for r in rows]
    a.plot(x, [max(r["L_e"], 1e-9) for r in rows], "o-", label="test, same α")
    a.plot(x, [max(r["L_e_train"], 1e-9) for r in rows], "s--", ms=3, alpha=0.7, label="training set")
    a.plot(x, [max(r["L_e_full"], 1e-9) for r in rows], "^:", ms=3, alpha=0.6, color="gray", label="full Gaussian")
    a.axvline(0.5, color="k", lw=0.8, ls=":")
    a.set_yscale("log")
    a.set_xlabel(r"pie coverage $\alpha$")
    a.set_ylabel(r"$L_e$ (p=1)")
    a.set_title(rf"(a) HO+CD, $\lambda$={result['settings']['lam_alpha']:g}: incomplete coverage", fontsize=10)
    a.legend(fontsize=7)
    rows = result["beta"]["table"]
    x = [r["beta"] for r in rows]
    b.plot(x, [r["m_c"] for r in rows], "o-", label=r"$m_c$")
    b.plot(x, [r["m_n"] for r in rows], "s-", label=r"$m_n$")
    b.plot(x, [r["m_c_full"] for r in rows], "o:", ms=3, alpha=0.6, color="C0", label=r"$m_c$ on balanced data")
    b.plot(x, [r["m_n_full"] for r in rows], "s:", ms=3, alpha=0.6, color="C1", label=r"$m_n$ on balanced data")
    b.axvline(0.5, color="k", lw=0.8, ls=":")
    b.set_xlabel(r"fraction $\beta$ of samples with $\dot q > 0$")
    b.set_ylabel("misalignment")
    b.set_title(rf"(b) HO+LD, $\lambda$={result['settings']['lam_beta']:g}: imbalanced data", fontsize=10)
    b.legend(fontsize=7)
    fig.tight_layout()
    return fig
