"""Reports and figures of a fit, and the paper's table columns as records."""

from __future__ import annotations

import os
from typing import TYPE_CHECKING

import numpy as np

import vmj

from ._io import record_from_sequence

if TYPE_CHECKING:  # names used in annotations only
    from ._fit import FitResult

__all__ = ["text_report", "plot_fit", "paper_records"]


def _fmt(v) -> str:
    return "nan" if v is None or not np.isfinite(v) else f"{v:.6g}"


def text_report(result: FitResult) -> str:
    """A readable summary of a [`fits.FitResult`][]."""
    lines = [f"model {result.model} (forward {result.forward}, loss {result.loss}, "
             f"optimizer {result.optimizer}), {len(result.record)} turning points"]
    for name, value in result.params.items():
        lines.append(f"  {name:>7} = {_fmt(value):>12} +- {_fmt(result.stderr[name])}")
    if len(result.params) > 1:
        names = list(result.params)
        lines.append("  correlation: " + "; ".join(
            f"{a}/{b} {result.correlation[i][j]:+.3f}" for i, a in enumerate(names)
            for j, b in enumerate(names) if j > i))
    lines.append(f"  converged: {result.converged} after {result.iterations} iterations; "
                 f"rms {_fmt(result.rms)}" + ("" if result.rms_time is None
                                             else f", time rms {_fmt(result.rms_time)} s"))
    dec = result.decrement
    lines.append(f"  decrement method: r = {dec['r']:.6g} per half-swing, zeta = {dec['zeta']:.4g}, "
                 f"xF = {dec['xF']:.4g} +- {dec['stderr_xF']:.2g} (signal units)")
    if result.model_comparison:
        lines.append("  model comparison (lower is better):")
        for k in ("coulomb", "viscous", "both"):
            c = result.model_comparison[k]
            lines.append(f"    {k:>8}: AIC {c['aic']:10.2f}  BIC {c['bic']:10.2f}  "
                         + ", ".join(f"{n}={_fmt(v)}" for n, v in c["params"].items()))
        lines.append(f"    best by AIC: {result.model_comparison['best_aic']}, by BIC: "
                     f"{result.model_comparison['best_bic']}")
    if result.outliers:
        lines.append(f"  outliers (|residual| > 5 robust sd) at k = {result.outliers}")
    lines += [f"  warning: {w}" for w in result.warnings]
    return "\n".join(lines)


def plot_fit(result: FitResult, path: str | os.PathLike, *, title: str | None = None) -> None:
    """Figure of a fit: the data (and raw signal) with the fitted turning points, the residuals
    (outliers circled), and the decrement diagram `A_{k+1}` against `A_k` with the
    decrement-method line and the fitted model's map."""
    from vmj.plot import pyplot, save

    plt = pyplot()
    rec = result.record
    res = np.asarray(result.residuals["position"])
    fitted = rec.positions + res
    x_axis = rec.times if rec.times is not None else rec.k
    xlabel = "time from the first turning point [s]" if rec.times is not None else "swing k"
    flagged = np.asarray(result.residuals["outlier"], dtype=bool)
    fig, axes = plt.subplots(1, 3, figsize=(16, 4.4), gridspec_kw={"width_ratios": [2.2, 1.4, 1]})
    ax = axes[0]
    if rec.signal is not None:
        s = rec.signal
        ax.plot(s.t - rec.time_origin, s.y, lw=0.5, color="0.6", label="raw signal")
    ax.plot(x_axis, rec.positions, "o", ms=3.5, mfc="none", label="turning points (data)")
    ax.plot(x_axis, fitted, "-", lw=1.0, color="C3", label=f"fit ({result.forward})")
    off = result.params.get("offset", result.fixed.get("offset", 0.0))
    ax.axhline(off, color="k", lw=0.5, ls=":")
    ax.set_xlabel(xlabel)
    ax.set_ylabel("position")
    ax.legend(fontsize=8, loc="upper right")
    ax.set_title(title or f"{result.model} fit: " + ", ".join(
        f"{k}={v:.4g}\u00b1{result.stderr[k]:.2g}" for k, v in result.params.items()), fontsize=9)
    ax = axes[1]
    ax.axhline(0, color="k", lw=0.5)
    ax.plot(x_axis, res, ".-", lw=0.6, ms=4, label="position residual")
    if flagged.any():
        ax.plot(np.asarray(x_axis)[flagged], res[flagged], "o", ms=10, mfc="none", color="r",
                label="flagged outlier")
    ax.set_xlabel(xlabel)
    ax.set_ylabel("fit - data")
    ax.set_title(f"residuals (rms {result.rms:.3g})", fontsize=9)
    ax.legend(fontsize=8)
    ax = axes[2]
    dec = result.decrement
    a_now, a_next = dec["pairs"]
    ax.plot(a_now, a_next, "o", ms=3, mfc="none", label="data pairs")
    grid = np.linspace(0, float(np.max(a_now)) * 1.05, 50)
    ax.plot(grid, dec["slope"] * grid + dec["intercept"], "-", color="C2",
            label=f"decrement method: r={dec['r']:.4f}, xF={dec['xF']:.3g}")
    if result.model == "oscillator":
        p = {**result.fixed, **result.params}
        wd = p["omega"] * np.sqrt(1 - p["zeta"] ** 2)
        r = np.exp(-p["zeta"] * p["omega"] * np.pi / wd)
        ax.plot(grid, r * grid - (1 + r) * p["xF"], "--", color="C3",
                label=f"fitted model: r={r:.4f}, xF={p['xF']:.3g}")
    ax.plot(grid, grid, ":", color="0.5", lw=0.8, label="no loss")
    ax.set_xlabel("amplitude A_k")
    ax.set_ylabel("next amplitude A_{k+1}")
    ax.set_title("decrement diagram", fontsize=9)
    ax.legend(fontsize=7)
    fig.tight_layout()
    save(fig, path)
    plt.close(fig)


def paper_records(table: int | None = None, values: str = "monograph") -> list[dict]:
    """The published columns of the paper's tables as records to fit.

    Each item: `record` (amplitudes in m, the `*` marks as `crossed = 0`, the initial
    deflection `a0 = 0.06 m` as `k = 0`), `given` (`m0`, `c`, `delta`, `eps`, `a0`, `g`),
    `free` (`("FT", "mu")` for tables 1-2, `("f", "mu")` for tables 3-4), `truth`, `table`,
    `notes` (`{k: note}` of the cells with an erratum note).
    """
    if values not in ("monograph", "energy"):
        raise ValueError(f"values must be 'monograph' or 'energy' (got {values!r})")
    cells = vmj.paper_cells(table)
    key = "paper_monograph" if values == "monograph" else "paper_energy"
    columns = {}
    for c in cells:
        columns.setdefault((c["table"], c["friction"], c["delta"], c["mu"], c["eps"]), []).append(c)
    out = []
    for (tab, friction, delta, mu, eps), col in sorted(columns.items()):
        col = sorted(col, key=lambda c: c["k"])
        amps = [vmj.PAPER["a0"]] + [c[f"{key}_cm"] / 100 for c in col]
        crossed = [1] + [0 if c[f"{key}_star"] else 1 for c in col]
        rec = record_from_sequence(amplitudes=amps, crossed=crossed,
                                   k=[0] + [c["k"] for c in col],
                                   source=f"table {tab} mu={mu:g} eps={eps:g} ({values})")
        law = "FT" if friction == "constant" else "f"
        given = {"m0": vmj.PAPER["m0"], "c": vmj.PAPER["c"], "delta": delta, "eps": eps,
                 "a0": vmj.PAPER["a0"], "g": vmj.PAPER["g"]}
        notes = {c["k"]: c["note"] for c in col
                 if c["note"] and (values in c["note"] or "energy" not in c["note"])}
        out.append({"record": rec, "given": given, "free": (law, "mu"),
                    "truth": {law: vmj.PAPER[law], "mu": mu}, "table": tab, "mu": mu, "eps": eps,
                    "delta": delta, "notes": notes})
    return out
