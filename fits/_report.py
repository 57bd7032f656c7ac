"""The figure of a fit, and the paper's table columns as records."""

from __future__ import annotations

import os

import numpy as np

import vmj

from ._extract import extract_turning_points, sample_window
from ._record import record_from_sequence
from ._result import FitResult, _field, _fmt, _short
from ._signal import Signal

__all__ = ["plot_fit", "paper_records"]


def _acf(x: np.ndarray, lags: int) -> np.ndarray:
    """Autocorrelation at lags 1..`lags`, as `fits._stats.diagnostics` defines lag 1 (not
    demeaned: residuals are deviations from the model)."""
    x = np.asarray(x, dtype=float)
    x = x[np.isfinite(x)]
    den = float(np.dot(x, x))
    if den <= 0:
        return np.full(lags, np.nan)
    return np.array(
        [np.dot(x[:-h], x[h:]) / den if h < x.size else np.nan for h in range(1, lags + 1)]
    )


def _panels(result):
    """`(record or None, residuals, per-record parameters, source)` to draw: the first record
    with its data; the further records of a joint fit with their residuals only (a result
    keeps the first record's data)."""
    items = [
        it
        for it in _field(result, "records", [])
        if isinstance(it, dict) and isinstance(it.get("residuals"), dict)
    ]
    first = items[0].get("params", {}) if items else {}
    out = [(result.record, result.residuals, first, result.record.source)]
    out += [
        (None, it["residuals"], it.get("params", {}), it.get("source") or f"record {i + 1}")
        for i, it in enumerate(items[1:])
    ]
    return out


def plot_fit(
    result: FitResult, path: str | os.PathLike, *, title: str | None = None, lags: int = 20
) -> None:
    """Figure of a fit, written atomically to `path` (format from its extension).

    Panels: the data (turning points; the raw signal when the record has one) with the fitted
    turning points; the decrement diagram (amplitude `A_{k+1}` against `A_k`: data pairs, the
    decrement-method line and the fitted model's map, i.e. its predicted amplitude pairs);
    the position residuals and, when the record has times, the time residuals [s]; and their
    autocorrelation at lags 1-`lags` with the white-noise band `+-1.96/sqrt(n)`.

    **Arguments:** `result` (a [`fits.FitResult`][]), `path` (the file: `.png`, `.pdf`,
    `.svg`), `title` (of the first panel; default: the fitted values), `lags` (the
    autocorrelation's largest lag, in points).
    """
    from vmj.plot import pyplot, save

    plt = pyplot()
    panels = _panels(result)
    has_times = any(res.get("time") is not None for _, res, _, _ in panels)
    fig = plt.figure(figsize=(16, 8.4))
    grid = fig.add_gridspec(2, 3, width_ratios=[2.2, 1.4, 1.1])
    ax_data = fig.add_subplot(grid[0, :2])
    ax_dec = fig.add_subplot(grid[0, 2])
    ax_rx = fig.add_subplot(grid[1, 0] if has_times else grid[1, :2])
    ax_rt = fig.add_subplot(grid[1, 1]) if has_times else None
    ax_acf = fig.add_subplot(grid[1, 2])
    params = {**result.fixed, **result.params}
    off_global = params.get("offset", 0.0)
    a_max = 0.0
    acf_n = {"position": 0, "time": 0}
    joint = len(panels) > 1
    for i, (rec, res, rec_params, source) in enumerate(panels):
        colour = f"C{i % 10}"
        tag = f" ({source or i})" if joint else ""
        off = rec_params.get("offset", off_global)
        rx = np.asarray(res["position"], dtype=float)
        k = np.asarray(res.get("k", np.arange(rx.size)))
        flagged = np.asarray(res.get("outlier", np.zeros(rx.size)), dtype=bool)
        series = "t" in res  # a fit on the whole time series: residuals per sample
        # residuals against time for one record, against the swing for several
        x_res = rec.times if rec is not None and rec.times is not None and not joint else k
        if series:
            x_res = np.asarray(res["t"], dtype=float)
        ax_rx.axhline(0, color="k", lw=0.5)
        ax_rx.plot(x_res, rx, ".-", lw=0.6, ms=4, color=colour, label="position" + tag)
        if flagged.any():
            ax_rx.plot(
                np.asarray(x_res)[flagged],
                rx[flagged],
                "o",
                ms=10,
                mfc="none",
                color="r",
                label="flagged outlier" if i == 0 else None,
            )
        acf_n["position"] += int(np.isfinite(rx).sum())
        ax_acf.plot(
            np.arange(1, lags + 1) + 0.15 * i,
            _acf(rx, lags),
            "o-",
            ms=3,
            lw=0.8,
            color=colour,
            label="position" + tag,
        )
        rt = res.get("time")
        if rt is not None and ax_rt is not None:
            rt = np.asarray(rt, dtype=float)
            ax_rt.axhline(0, color="k", lw=0.5)
            ax_rt.plot(x_res, rt, ".-", lw=0.6, ms=4, color=colour, label="time" + tag)
            rt_used = rt[np.isfinite(rt)]  # NaN: not a datum (a release's time)
            acf_n["time"] += rt_used.size
            ax_acf.plot(
                np.arange(1, lags + 1) + 0.15 * i + 0.3,
                _acf(rt_used, lags),
                "s:",
                ms=3,
                lw=0.8,
                color=colour,
                mfc="none",
                label="time" + tag,
            )
        if rec is None:
            continue
        x_axis = rec.times if rec.times is not None else rec.k
        data = rec.positions if rec.sides_known else rec.amplitudes + off
        if series:
            # the model's reading at the samples, and its turning points for the diagram
            y_fit = sample_window(rec)[1] + rx
            # (broken where samples were left out: a saturated sensor's flat runs)
            gap = np.append(np.diff(x_res) > 2.5 * np.median(np.diff(x_res)), False)
            ax_data.plot(
                np.insert(x_res, np.nonzero(gap)[0] + 1, np.nan),
                np.insert(y_fit, np.nonzero(gap)[0] + 1, np.nan),
                "-",
                lw=0.8,
                color="C3",
                label=f"fit ({result.forward})",
            )
            curve = extract_turning_points(Signal(t=x_res, y=y_fit, clock="uniform"))
            n = min(len(curve), len(rec))
            x_axis, data = x_axis[:n], data[:n]
            fitted = curve.positions[:n]
        else:
            fitted = data + rx  # amplitude-only records: the residual compares amplitudes
        if rec.signal is not None:
            s = rec.signal
            ax_data.plot(s.t - rec.time_origin, s.y, lw=0.5, color="0.6", label="raw signal")
        ax_data.plot(
            x_axis,
            data,
            "o",
            ms=3.5,
            mfc="none",
            color=colour,
            label=("turning points" if rec.sides_known else "amplitudes") + tag,
        )
        if not series:
            ax_data.plot(x_axis, fitted, "-", lw=1.0, color="C3", label=f"fit ({result.forward})")
        ax_data.axhline(off, color="k", lw=0.5, ls=":")
        # decrement diagram: consecutive swings only
        amp_data = np.abs(data - off)
        amp_fit = np.abs(fitted - off)
        nxt = np.flatnonzero(np.diff(rec.k[: data.size]) == 1)
        ax_dec.plot(
            amp_data[nxt],
            amp_data[nxt + 1],
            "o",
            ms=3,
            mfc="none",
            color=colour,
            label="data pairs" + tag,
        )
        order = np.argsort(amp_fit[nxt])
        ax_dec.plot(
            amp_fit[nxt][order],
            amp_fit[nxt + 1][order],
            "-",
            color="C3",
            label="fitted model's map",
        )
        a_max = max(a_max, float(np.max(amp_data)) if amp_data.size else 0.0)
    ax_data.set_xlabel("time from the release [s]" if panels[0][0].times is not None else "swing k")
    ax_data.set_ylabel("position [signal units]")
    ax_data.legend(fontsize=8, loc="upper right")
    stderr = result.stderr
    ax_data.set_title(
        title
        or f"{result.model} fit"
        + (" (first record)" if joint else "")
        + ": "
        + ", ".join(
            f"{k}={_short(v, 5)}\u00b1{_short(stderr.get(k), 2)}" for k, v in result.params.items()
        ),
        fontsize=9,
    )
    xlabel = "swing k" if joint else ax_data.get_xlabel()
    ax_rx.set_xlabel(xlabel)
    ax_rx.set_ylabel("fit - data [signal units]")
    ax_rx.set_title(f"position residuals (rms {_fmt(result.rms)})", fontsize=9)
    ax_rx.legend(fontsize=8)
    if ax_rt is not None:
        ax_rt.set_xlabel(xlabel)
        ax_rt.set_ylabel("fit - data [s]")
        ax_rt.set_title(f"time residuals (rms {_fmt(result.rms_time)} s)", fontsize=9)
    ax_acf.axhline(0, color="k", lw=0.5)
    for kind, shade in (("position", "0.85"), ("time", "0.92")):
        if acf_n[kind]:
            band = 1.96 / np.sqrt(acf_n[kind] / len(panels))
            ax_acf.axhspan(-band, band, color=shade, zorder=0, label=f"{kind}: \u00b11.96/\u221an")
    diag = _field(result, "diagnostics", {})
    ax_acf.set_title(
        "residual autocorrelation"
        + (
            f" (lag-1 {_short(diag.get('lag1'), 3)}, runs p {_short(diag.get('runs_p'), 2)})"
            if diag
            else ""
        ),
        fontsize=9,
    )
    ax_acf.set_xlabel("lag [points]")
    ax_acf.set_ylim(-1.05, 1.05)
    ax_acf.legend(fontsize=7)
    dec = result.decrement
    grid_a = np.linspace(0, a_max * 1.05, 50)
    if dec and "slope" in dec:
        ax_dec.plot(
            grid_a,
            dec["slope"] * grid_a + dec["intercept"],
            "-",
            color="C2",
            lw=0.8,
            label=f"decrement method: r={_fmt(dec['r'])}, xF={_fmt(dec['xF'])}",
        )
    ax_dec.plot(grid_a, grid_a, ":", color="0.5", lw=0.8, label="no loss")
    ax_dec.set_xlabel("amplitude A_k [signal units]")
    ax_dec.set_ylabel(f"next amplitude A_{{k+{dec.get('step', 1) if dec else 1}}}")
    ax_dec.set_title("decrement diagram", fontsize=9)
    ax_dec.legend(fontsize=7)
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
        rec = record_from_sequence(
            amplitudes=amps,
            crossed=crossed,
            k=[0] + [c["k"] for c in col],
            source=f"table {tab} mu={mu:g} eps={eps:g} ({values})",
        )
        law = "FT" if friction == "constant" else "f"
        given = {
            "m0": vmj.PAPER["m0"],
            "c": vmj.PAPER["c"],
            "delta": delta,
            "eps": eps,
            "a0": vmj.PAPER["a0"],
            "g": vmj.PAPER["g"],
        }
        notes = {
            c["k"]: c["note"]
            for c in col
            if c["note"] and (values in c["note"] or "energy" not in c["note"])
        }
        out.append(
            {
                "record": rec,
                "given": given,
                "free": (law, "mu"),
                "truth": {law: vmj.PAPER[law], "mu": mu},
                "table": tab,
                "mu": mu,
                "eps": eps,
                "delta": delta,
                "notes": notes,
            }
        )
    return out
