"""Figures (matplotlib, imported when a figure is drawn, never by `import vmj`).

`vmj.plot.pyplot()` gives matplotlib's pyplot on the non-interactive Agg backend, and
`vmj.plot.save(fig, path)` writes a figure atomically (a temporary file, then a rename), so that
a full disk or a killed process never leaves a truncated PNG.
"""

from __future__ import annotations

import os
from types import ModuleType
from typing import TYPE_CHECKING

import numpy as np

from ._files import replacing
from ._solution import RESULTS

if TYPE_CHECKING:  # names used in annotations only
    from matplotlib.figure import Figure

    from ._sweep import SweepResult

__all__ = [
    "pyplot",
    "save",
    "plot_table",
    "plot_swings",
    "plot_energy_error",
    "plot_sensitivity",
    "per",
]


def pyplot() -> ModuleType:
    """matplotlib's pyplot on the Agg backend (no display needed)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def save(fig: Figure, path: str | os.PathLike) -> None:
    """Write `fig` to `path` (format from the extension, PNG without one) atomically. The
    directory must exist: nothing is created or renamed silently."""
    with replacing(path) as tmp:
        fig.savefig(tmp, dpi=120, bbox_inches="tight", format=_format(path))


def _format(path: str) -> str:
    return os.path.splitext(path)[1].lstrip(".").lower() or "png"


def plot_table(table: int, rows: list[dict], path: str) -> None:
    """Amplitude against swing number for each column of a paper table."""
    plt = pyplot()
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


# -- sweeps over (eps, mu, delta) of the variable-mass model ------------------------------------
def _panels(result):
    """(delta values or [None], an index function) for one panel per delta."""
    dims = list(result.dims)
    if dims[:2] != ["eps", "mu"] or len(dims) > 3 or (len(dims) == 3 and dims[2] != "delta"):
        raise ValueError(
            "the sweep figures need axes eps, mu and optionally delta, in this order "
            f"(got {', '.join(dims)})"
        )
    if len(dims) == 2:
        return [None], lambda a, j: a
    return list(result.coords["delta"]), lambda a, j: a[:, :, j]


def _boundary(ax, eps, mu, delta):
    """The paper's boundary delta (1 - 2 eps) = 2 mu in the (eps, mu) plane."""
    if delta is None or delta == 0:
        return
    e = np.linspace(eps.min(), eps.max(), 200)
    m = delta * (1 - 2 * e) / 2
    keep = (m >= mu.min()) & (m <= mu.max())
    if keep.any():
        ax.plot(e[keep], m[keep], "w-", lw=2.5)
        ax.plot(e[keep], m[keep], "k--", lw=1.2, label=r"$\delta(1-2\varepsilon)=2\mu$")
        ax.legend(loc="upper right", fontsize=7)


def _edges(x):
    x = np.asarray(x, dtype=float)
    if x.size == 1:
        return np.array([x[0] - 0.5, x[0] + 0.5])
    mid = (x[1:] + x[:-1]) / 2
    return np.concatenate([[2 * x[0] - mid[0]], mid, [2 * x[-1] - mid[-1]]])


def _grid_of_panels(n_panels):
    plt = pyplot()
    cols = min(n_panels, 4)
    rows = -(-n_panels // cols)
    fig, axes = plt.subplots(
        rows,
        cols,
        figsize=(3.6 * cols, 3.2 * rows),
        squeeze=False,
        sharex=True,
        sharey=True,
        constrained_layout=True,
    )
    for ax in axes.flat[n_panels:]:
        ax.set_visible(False)
    return plt, fig, list(axes.flat)


def plot_swings(result: SweepResult, path: str, title: str = "") -> None:
    """Number of swings until the mass sticks over (eps, mu), one panel per delta, with the
    paper's boundary `delta (1 - 2 eps) = 2 mu` (below it, `mu` large, the motion decays even
    without dry friction). `result.values` is a [`vmj.DecaySequence`][] over a grid."""
    deltas, at = _panels(result)
    seq = result.values
    n = np.shape(seq.positions)[-1]
    eps, mu = result.coords["eps"], result.coords["mu"]
    plt, fig, axes = _grid_of_panels(len(deltas))
    lowest = int(max(1, np.min(np.where(np.asarray(seq.stopped), np.asarray(seq.count), n))))
    cmap = plt.get_cmap("viridis", n - lowest + 1).with_extremes(over="lightgrey")
    mesh = None
    for j, (ax, d) in enumerate(zip(axes, deltas)):
        count = at(np.asarray(seq.count), j).astype(float)
        stopped = at(np.asarray(seq.stopped), j)
        failed = RESULTS.failed(at(np.asarray(seq.result), j))
        shown = np.where(stopped, count, n + 1.0)  # still moving after n swings: "over"
        mesh = ax.pcolormesh(
            _edges(eps),
            _edges(mu),
            shown.T,
            cmap=cmap,
            vmin=lowest - 0.5,
            vmax=n + 0.5,
            shading="flat",
        )
        if failed.any():
            ie, im = np.nonzero(failed)
            ax.plot(eps[ie], mu[im], "rx", ms=4, label="mass exhausted")
        _boundary(ax, eps, mu, d)
        ax.set_title(title + (f"delta = {d:g} kg/s" if d is not None else ""), fontsize=9)
        ax.set_xlabel("eps [-]")
        ax.set_ylabel("mu [kg/s]")
    bar = fig.colorbar(mesh, ax=list(axes)[: len(deltas)], extend="max", shrink=0.9)
    bar.set_label(f"swings until the mass sticks (grey: still moving after {n})")
    save(fig, path)
    plt.close(fig)


def plot_energy_error(exact: SweepResult, energy: SweepResult, a0: float, path: str) -> None:
    """Largest difference over the swings between the energy-balance amplitudes and the exact
    ones, relative to `a0`, over (eps, mu) for each delta (log scale)."""
    deltas, at = _panels(exact)
    eps, mu = exact.coords["eps"], exact.coords["mu"]
    err = (
        np.max(
            np.abs(
                np.abs(np.asarray(energy.values.positions))
                - np.abs(np.asarray(exact.values.positions))
            ),
            axis=-1,
        )
        / a0
    )
    plt, fig, axes = _grid_of_panels(len(deltas))
    from matplotlib.colors import LogNorm

    norm = LogNorm(
        vmin=max(float(np.nanmin(err[err > 0])) if (err > 0).any() else 1e-6, 1e-6),
        vmax=max(float(np.nanmax(err)), 1e-5),
    )
    mesh = None
    for j, (ax, d) in enumerate(zip(axes, deltas)):
        e = np.maximum(at(err, j), norm.vmin)
        mesh = ax.pcolormesh(_edges(eps), _edges(mu), e.T, norm=norm, cmap="magma", shading="flat")
        cs = ax.contour(eps, mu, e.T, levels=[1e-3, 1e-2], colors=["w", "c"], linewidths=1)
        ax.clabel(cs, fmt={1e-3: "0.1 %", 1e-2: "1 %"}, fontsize=7)
        _boundary(ax, eps, mu, d)
        ax.set_title(f"delta = {d:g} kg/s" if d is not None else "", fontsize=9)
        ax.set_xlabel("eps [-]")
        ax.set_ylabel("mu [kg/s]")
    bar = fig.colorbar(mesh, ax=list(axes)[: len(deltas)], shrink=0.9)
    bar.set_label("max_k | a_k(energy balance) - a_k(exact) | / a0")
    save(fig, path)
    plt.close(fig)


def plot_sensitivity(data: dict, path: str) -> None:
    """Derivatives of the turning points against `k`, one column per parameter: `d|x_k|/dp`
    (top) and `dt_k/dp` (bottom). `data` is the JSON object of `vmj sensitivity` (keys `wrt`,
    `units`, `d_amplitudes`, `d_times`)."""
    plt = pyplot()
    wrt = data["wrt"]
    fig, axes = plt.subplots(
        2,
        len(wrt),
        figsize=(3.4 * len(wrt), 5.2),
        squeeze=False,
        sharex=True,
        constrained_layout=True,
    )
    for j, name in enumerate(wrt):
        unit = data["units"][name]
        for i, (key, label) in enumerate(
            (
                ("d_amplitudes", f"d|x_k|/d{name} [{per('m', unit)}]"),
                ("d_times", f"dt_k/d{name} [{per('s', unit)}]"),
            )
        ):
            values = data[key][name]
            ax = axes[i][j]
            ax.plot(range(1, len(values) + 1), values, "o-", ms=3, lw=1)
            ax.axhline(0.0, color="grey", lw=0.5)
            ax.set_ylabel(label, fontsize=8)
            ax.grid(alpha=0.3)
        axes[1][j].set_xlabel("turning point k")
    fig.suptitle(
        f"{data['model']} ({data['method']}): sensitivities of the turning points", fontsize=9
    )
    save(fig, path)
    plt.close(fig)


def per(unit: str, of: str) -> str:
    """The unit `unit` per `of`: `m/N`, `m/(kg/s)`, `m` per a dimensionless `-`."""
    if of in ("-", ""):
        return unit
    return f"{unit}/({of})" if ("/" in of or " " in of) else f"{unit}/{of}"
