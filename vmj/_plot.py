"""matplotlib figures (imported lazily by the CLI and the examples)."""

from __future__ import annotations

import os


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def save(fig, path: str) -> None:
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    fig.savefig(path, dpi=120, bbox_inches="tight")


def plot_table(table: int, rows: list[dict], path: str) -> None:
    """Amplitude against swing number for each column of a paper table."""
    plt = _pyplot()
    columns = sorted({(r["mu"], r["eps"]) for r in rows})
    fig, axes = plt.subplots(1, len(columns), figsize=(4 * len(columns), 3.6), sharey=True)
    for ax, (mu, eps) in zip(axes, columns):
        col = sorted((r for r in rows if (r["mu"], r["eps"]) == (mu, eps)), key=lambda r: r["k"])
        k = [r["k"] for r in col]
        ax.plot(k, [r["paper_energy_cm"] for r in col], "o", mfc="none", label="paper (energy)")
        ax.plot(k, [r["paper_monograph_cm"] for r in col], "s", mfc="none", label="monograph")
        ax.plot(k, [r["exact_cm"] for r in col], "-", lw=1.5, label="vmj exact")
        ax.plot(k, [r["energy_cm"] for r in col], "--", lw=1, label="vmj energy balance")
        for r in col:
            if r["note"]:
                ax.annotate("!", (r["k"], r["paper_monograph_cm"]), color="red")
        ax.set_title(f"table {table}: mu={mu:g} kg/s, eps={eps:g}")
        ax.set_xlabel("swing k")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("amplitude |x_k| [cm]")
    axes[0].legend(fontsize=8)
    save(fig, path)
    plt.close(fig)
