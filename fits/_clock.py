"""The sample clock of a raw signal: what its time stamps mean, and the uniform clock behind them.

A logger's time column is one of three things:

- **genuine uniform stamps**: the sample times of a uniform sampler, with small jitter or
  rounding and perhaps dropped samples (a gap of an integer number of periods);
- **genuine irregular stamps**: true sample times at irregular instants;
- **arrival stamps**: the time each row *arrived* at the computer. A device that samples
  uniformly but sends its buffer in packets gives bursts of rows a fraction of a millisecond
  apart, then a gap as long as the packet took to fill (the public pendulum records: bursts of
  15-20 rows, then 50-60 ms). The stamps then scatter by tens of milliseconds about the true
  sample times, and a turning point timed by them scatters as much.

[`fits.recover_clock`][] tells them apart from the intervals alone and, for arrival stamps, recovers the
uniform clock from the stamps' **lower envelope**. A row cannot have been sampled after it
arrived, so sample `i` was taken at `t0 + m_i / f <= stamp_i`, where `m_i` is its sample number
(`i` plus the samples dropped before it). In each burst the last row (the newest sample in the
packet) arrives soonest after it was taken, so the lowest stamp of each burst, measured from the
line, touches the envelope. The rate `f` is a least-squares line through these touch points
(one per burst, bursts held up far above their neighbours rejected), started from the linear program "the line below every
stamp with the least total gap" (its solution is the edge of the stamps' lower convex hull above
the mean index). `t0` puts the line under every stamp. A dropped sample shifts all later touches
up by one period; such integer steps are detected and the sample numbers corrected.

Everything here is NumPy: it runs once per file.
"""

from __future__ import annotations

import numpy as np

__all__ = ["recover_clock", "CLOCKS"]

CLOCKS = ("auto", "stamps", "uniform")


def _fmt_rate(f: float) -> str:
    return f"{f:.6g} Hz"


def _lower_hull(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Indices of the lower convex hull of points with increasing `x` (monotone chain)."""
    hull: list[int] = []
    for i in range(len(x)):
        while len(hull) >= 2:
            a, b = hull[-2], hull[-1]
            if (y[b] - y[a]) * (x[i] - x[a]) >= (y[i] - y[a]) * (x[b] - x[a]):
                hull.pop()
            else:
                break
        hull.append(i)
    return np.asarray(hull)


def _envelope_lp(m: np.ndarray, stamps: np.ndarray, starts: np.ndarray) -> tuple[float, float]:
    """`(t0, period)` of the line `t0 + period m` below every stamp with the least total gap
    `sum(stamp - line)`: a linear program whose optimum is the lower-hull edge over the mean
    of `m`. Only the lowest row of each burst (against the mean step) can be a hull vertex."""
    slope = (stamps[-1] - stamps[0]) / (m[-1] - m[0])
    rows = _touches(stamps, m, starts, stamps[0], slope)
    rows = np.unique(np.concatenate([[0], rows, [len(m) - 1]]))
    hull = rows[_lower_hull(m[rows], stamps[rows])]
    j = int(np.clip(np.searchsorted(m[hull], np.mean(m)), 1, len(hull) - 1))
    a, b = hull[j - 1], hull[j]
    period = (stamps[b] - stamps[a]) / (m[b] - m[a])
    return float(stamps[a] - period * m[a]), float(period)


def _line(m, t, keep=None):
    """Least-squares `(t0, period)` of `t = t0 + period m` over the rows in `keep`."""
    if keep is not None:
        m, t = m[keep], t[keep]
    mc = m - m.mean()
    period = float(mc @ (t - t.mean()) / (mc @ mc))
    return float(t.mean() - period * m.mean()), period


def _mad(x) -> float:
    return 1.4826 * float(np.median(np.abs(x - np.median(x)))) if len(x) else 0.0


def _bursts(stamps: np.ndarray, mean_step: float) -> np.ndarray:
    """Index of the first row of every burst (a new burst after a step longer than the mean)."""
    return np.concatenate([[0], np.nonzero(np.diff(stamps) > mean_step)[0] + 1])


def _touches(stamps, m, starts, t0, period):
    """Row of each burst closest to (least above) the line `t0 + period m`."""
    r = stamps - (t0 + period * m)
    low = np.minimum.reduceat(r, starts)
    burst = np.repeat(np.arange(len(starts)), np.diff(np.append(starts, len(r))))
    hit = np.nonzero(r == low[burst])[0]
    first = np.unique(burst[hit], return_index=True)[1]
    return hit[first]


def _late(b: np.ndarray, window: int = 11) -> np.ndarray:
    """Touches [periods] of bursts held up by a busy computer: more than four robust deviations
    (and at least half a period) above the median of all touches, or above the running median
    of `window` touches (which follows a wandering clock). One-sided: latency only delays."""
    late = b > np.median(b) + max(4 * _mad(b), 0.5)
    if b.size >= window:
        pad = np.pad(b, window // 2, mode="edge")
        r = b - np.median(np.lib.stride_tricks.sliding_window_view(pad, window), axis=1)
        late |= r > max(4 * _mad(r), 0.5)
    return late


def _jump(b: np.ndarray, j: int, width: int) -> tuple[float, float]:
    """Least-absolute-deviation fit of a line with a jump at `j` to the `width` touches on
    either side (iteratively reweighted least squares): `(sum of |residuals|, jump)`. Absolute
    deviations, so a few held-up bursts that slipped through do not make a jump."""
    idx = np.arange(max(0, j - width), min(len(b), j + width))
    design = np.stack([np.ones(idx.size), idx - j, (idx >= j)], axis=1).astype(float)
    weight = np.ones(idx.size)
    for _ in range(20):
        coef = np.linalg.lstsq(design * weight[:, None], b[idx] * weight, rcond=None)[0]
        r = np.abs(b[idx] - design @ coef)
        weight = 1 / np.sqrt(np.maximum(r, 1e-3))
    return float(np.sum(r)), float(coef[2])


def _steps(b: np.ndarray, w: int = 3, width: int = 20) -> np.ndarray:
    """Persistent upward steps of a whole number of periods in the touch residuals `b`
    [periods], as `(j, k)` pairs: `k >= 1` samples dropped between touches `j - 1` and `j`.

    A step is located where `e_j`, the median of the next `w` touches minus that of the
    previous `w`, peaks above both half a period and five times the typical `|e|` (the MAD of
    all `e_j`, most of which straddle no step). Its place (within `w` of the peak) and size are
    those of the best least-absolute-deviation fit of a line with a jump to the `width` touches
    on either side (slow clock wander and a provisional rate tilt the touches; the line takes
    that out); it is accepted if the jump is within 0.35 of a whole number `k >= 1`."""
    n = len(b)
    if n < 2 * w + 2:
        return np.zeros((0, 2), dtype=int)
    med = np.median(np.lib.stride_tricks.sliding_window_view(b, w), axis=1)  # of b[i:i + w]
    e = np.zeros(n)
    e[w : n - w + 1] = med[w:] - med[:-w]
    scale = 1.4826 * float(np.median(np.abs(e[w : n - w + 1])))
    candidates = np.nonzero(e > max(0.5, 5 * scale))[0]
    out = []
    for j in candidates[np.argsort(-e[candidates])]:
        if any(abs(j - j2) <= w for j2, _ in out):
            continue
        fits = [(*_jump(b, j2, width), j2) for j2 in range(max(1, j - w), min(n, j + w + 1))]
        _, k, j = min(fits)
        if round(k) >= 1 and abs(k - round(k)) < 0.35:
            out.append((int(j), int(round(k))))
    return np.asarray(sorted(out), dtype=int).reshape(-1, 2)


def _arrival(stamps, rate, mean_step):
    """Uniform clock behind arrival stamps: `(m, t0, period, jitter, dropped, bursts)`."""
    n = len(stamps)
    m = np.arange(n, dtype=float)
    starts = _bursts(stamps, mean_step)
    if rate is None:
        t0, period = _envelope_lp(m, stamps, starts)
    else:
        t0, period = float(np.min(stamps)), 1.0 / rate
    dropped_at = np.zeros(n)

    def envelope(t0, period):
        touch = _touches(stamps, m, starts, t0, period)
        keep = ~_late((stamps[touch] - (t0 + period * m[touch])) / period)
        if rate is None and keep.sum() >= 3:
            t0, period = _line(m[touch], stamps[touch], keep)
        b = (stamps[touch] - (t0 + period * m[touch])) / period
        return t0, period, b, np.nonzero(keep)[0]

    for _ in range(5):
        t0, period, b, kept = envelope(t0, period)
        new = _steps(b[kept])
        if not len(new):
            break
        for j, k in new:
            dropped_at[starts[kept[j]]] += k  # at the start of the burst after the step
        m = np.arange(n) + np.cumsum(dropped_at)
    else:
        t0, period, b, kept = envelope(t0, period)
    jitter = _mad(b[kept]) * period
    t0 = float(np.min(stamps - period * m))  # the line under every stamp
    return m, t0, period, jitter, int(dropped_at.sum()), len(starts)


def _uniform_grid(stamps, period):
    """Sample numbers of stamps on a uniform grid with gaps of whole periods, refined period,
    `t0` and the largest deviation from the grid; `None` if the stamps are not on such a grid."""
    dt = np.diff(stamps)
    for _ in range(3):
        steps = np.round(dt / period)
        if np.any(steps < 1):
            return None
        m = np.concatenate([[0.0], np.cumsum(steps)])
        t0, period = _line(m, stamps)
    dev = stamps - (t0 + period * m)
    if np.max(np.abs(dev)) >= 0.35 * period:
        return None
    return m, t0, period, dev


def classify(stamps: np.ndarray) -> str:
    """`"arrival"`, `"uniform"` or `"irregular"`: what the stamps are (see the module text).

    Arrival stamps: the median interval is below half the mean interval (most rows share a
    burst) and intervals longer than twice the mean (the gaps between bursts) hold at least half
    of the record's duration: a bimodal distribution of intervals. Uniform stamps: every stamp
    within 0.35 periods of a uniform grid whose gaps are whole periods.
    """
    dt = np.diff(stamps)
    mean = (stamps[-1] - stamps[0]) / len(dt)
    gaps = dt > 2 * mean
    if (
        np.median(dt) < 0.5 * mean
        and np.sum(dt[gaps]) >= 0.5 * (stamps[-1] - stamps[0])
        and np.sum(gaps) >= 3
    ):
        return "arrival"
    positive = dt[dt > 0]
    if positive.size == dt.size and _uniform_grid(stamps, float(np.median(positive))) is not None:
        return "uniform"
    return "irregular"


#: irregular stamps that stay within this many mean intervals of a uniform clock (over at least
#: `_BOUNDED_ROWS` rows) may be a uniform sampler's (`_near_uniform`): a genuinely irregular
#: sampler's stamps wander from any line like a random walk (sqrt(rows) intervals: 10 over 100
#: rows of exponential intervals, 27 over 764)
_BOUNDED = 5.0
_BOUNDED_ROWS = 100


def _near_uniform(dev, rms, period, mean_step, name) -> dict:
    """For irregular stamps kept as they are, `dev` [s] (rms `rms`) from their least-squares
    uniform clock of `period` [s]: if they stay within `_BOUNDED` mean intervals of it, the
    clock (`uniform_rate_hz`) and the stamps' rms and largest distance from it
    (`uniform_rms_s`, `uniform_max_s`) and the message's hint. Such stamps are what arrival
    times become when the rows are thinned (every 10th row of the public pendulum records:
    1-2 rows left of each burst, classified irregular, scattered by 19 ms rms about the
    sampler's true 26 Hz clock), or a jittery timer's true sample times; the stamps alone
    cannot tell which."""
    largest = float(np.max(np.abs(dev)))
    if dev.size < _BOUNDED_ROWS or largest > _BOUNDED * mean_step:
        return {}
    return {
        "uniform_rate_hz": 1.0 / period,
        "uniform_rms_s": rms,
        "uniform_max_s": largest,
        "message": (
            f"{name} are irregular (mean rate {_fmt_rate(1 / mean_step)}) but stay within "
            f"{largest * 1e3:.3g} ms ({rms * 1e3:.2g} ms rms) of a uniform clock at "
            f"{_fmt_rate(1 / period)}: kept; if the device samples uniformly (arrival times "
            f"thinned, a jittery timer's stamps), give its rate (rate=... in Python, --rate HZ "
            "on the command line) to put the samples on its clock"
        ),
    }


def recover_clock(
    stamps,
    *,
    clock: str = "auto",
    rate: float | None = None,
    column: str | None = None,
    rows: int | None = None,
) -> tuple[np.ndarray | None, dict]:
    """The sample times of a raw signal from its time stamps.

    **Arguments:**

    - `stamps`: time stamp of every row [s], non-decreasing; `None` if the file has no time
      column (then `rate` is required).
    - `clock`: `"auto"` (default) recovers the uniform clock behind arrival stamps and keeps
      genuine stamps (uniform or irregular) as they are; `"uniform"` always puts the samples on
      a uniform clock (from the envelope of arrival stamps, the grid of uniform stamps, or a
      least-squares line through irregular ones); `"stamps"` keeps the stamps.
    - `rate`: the sampling rate [Hz], if known: forces a uniform clock at that rate (only its
      start and the dropped samples are taken from the stamps). Not with `clock="stamps"`.
    - `column`: the name of the time column, for the report.
    - `rows`: the number of rows, needed only when `stamps` is `None`.

    **Returns** `(t, report)`: `t` the sample time of every row [s] on the stamps' time base
    (`None` when the stamps are kept, so that the caller may average rows sharing a stamp), and
    `report` a dict: `method` (`"envelope"`: uniform clock recovered from arrival stamps;
    `"grid"`: uniform clock fitted to uniform stamps; `"line"`: a line through irregular stamps;
    `"rate"`: the given rate; `"stamps"`: the stamps kept), `stamps` (what the stamps were
    classified as: `"arrival"`, `"uniform"`, `"irregular"`, or `"none"`), `rate_hz` (the
    sampling rate [Hz]; for irregular stamps the mean rate), `t0` (time of the first sample on
    the clock used [s], stamps' time base), `jitter_s` (scatter of the stamps about the uniform
    clock [s]: of the envelope's touch points for arrival stamps, of all stamps for uniform
    ones; `None` for irregular stamps), `dropped` (samples missing between rows), `rows`,
    `column`, and a one-line `message`. Irregular stamps kept that stay within a few mean
    intervals of a uniform clock (a uniform sampler's, perhaps) add `uniform_rate_hz`,
    `uniform_rms_s` and `uniform_max_s`: that clock's rate [Hz] and the stamps' rms and largest
    distance from it [s]; the message says how to use it.

    Raises `ValueError` for an unknown `clock`, a rate that is not a positive number, a rate
    below the stamps' own (more rows than the rate allows in their time), or a rate given with
    `clock="stamps"`.
    """
    if clock not in CLOCKS:
        raise ValueError(f"clock must be one of {', '.join(map(repr, CLOCKS))} (got {clock!r})")
    if rate is not None:
        try:
            rate = float(rate)
        except (TypeError, ValueError):
            raise ValueError(
                f"rate must be a positive number of samples per second [Hz] (got {rate!r})"
            ) from None
        if not (np.isfinite(rate) and rate > 0):
            raise ValueError(
                f"rate must be a positive number of samples per second [Hz] (got {rate!r})"
            )
        if clock == "stamps":
            raise ValueError(
                "rate=... puts the samples on a uniform clock: it cannot be "
                "combined with clock='stamps'"
            )
    report = {
        "method": None,
        "stamps": "none",
        "rate_hz": None,
        "t0": 0.0,
        "jitter_s": None,
        "dropped": 0,
        "rows": 0,
        "column": column,
        "message": "",
    }
    if stamps is None:
        if rate is None:
            raise ValueError(
                "the signal has no time column: give its sampling rate [Hz] (rate=... in "
                "Python, --rate HZ on the command line)"
            )
        report.update(
            method="rate",
            rate_hz=rate,
            rows=int(rows),
            message=f"no time column: samples at the given {_fmt_rate(rate)}",
        )
        return np.arange(int(rows)) / rate, report
    stamps = np.asarray(stamps, dtype=float)
    n = stamps.size
    report["rows"] = n
    if n < 3 or not stamps[-1] > stamps[0]:
        raise ValueError("the time stamps must span a positive duration over at least 3 rows")
    kind = classify(stamps)
    report["stamps"] = kind
    mean_step = (stamps[-1] - stamps[0]) / (n - 1)
    name = f"{column!r}" if column else "the time stamps"
    if rate is not None and rate * mean_step < 0.95:  # (dropped samples lower the stamps' rate)
        raise ValueError(
            f"the given rate, {rate:g} Hz, is below that of {name} ({1 / mean_step:.4g} Hz: "
            f"{n} rows in {stamps[-1] - stamps[0]:.4g} s), so the rows would not fit in their "
            "time: give the file's sampling rate, or none"
        )

    if kind == "arrival" and clock != "stamps":
        m, t0, period, jitter, dropped, bursts = _arrival(stamps, rate, mean_step)
        t = t0 + period * m
        report.update(
            method="rate" if rate is not None else "envelope",
            rate_hz=1.0 / period,
            t0=t0,
            jitter_s=jitter,
            dropped=dropped,
        )
        lag = stamps - t
        report["message"] = (
            f"{name} are arrival times ({bursts} bursts, median step "
            f"{np.median(np.diff(stamps)) * 1e3:.3g} ms, mean {mean_step * 1e3:.3g} ms): "
            f"uniform clock at {_fmt_rate(1 / period)}"
            + (" (given)" if rate is not None else " from their lower envelope")
            + f", envelope scatter {jitter * 1e3:.2g} ms, arrival lag up to {lag.max() * 1e3:.3g}"
            f" ms, {dropped} dropped samples"
        )
        return t, report

    if kind == "uniform":
        grid = _uniform_grid(stamps, float(np.median(np.diff(stamps))))
        m, t0, period, dev = grid
        dropped = int(m[-1] - (n - 1))
        if rate is not None:
            period = 1.0 / rate
            grid2 = _uniform_grid(stamps, period)
            m = grid2[0] if grid2 is not None else m
            dropped = int(m[-1] - (n - 1))
            t0 = float(np.mean(stamps - period * m))
            dev = stamps - (t0 + period * m)
        jitter = float(np.sqrt(np.mean(dev**2)))
        report.update(rate_hz=1.0 / period, t0=t0, jitter_s=jitter, dropped=dropped)
        what = (
            f"{name} are uniform at {_fmt_rate(1 / period)} (rms deviation "
            f"{jitter * 1e3:.2g} ms, {dropped} dropped samples)"
        )
        if rate is None and clock in ("auto", "stamps"):
            report.update(method="stamps", t0=float(stamps[0]), message=what + ": kept")
            return None, report
        report.update(
            method="rate" if rate is not None else "grid",
            message=what + ": put on the uniform grid",
        )
        return t0 + period * m, report

    # irregular (or arrival stamps kept on request): the uniform clock through them (a rate is
    # never given where they are kept)
    report["rate_hz"] = 1.0 / mean_step
    m = np.arange(n, dtype=float)
    if rate is not None:
        period = 1.0 / rate
        t0 = float(np.mean(stamps - period * m))
    else:
        t0, period = _line(m, stamps)
    dev = stamps - (t0 + period * m)
    rms = float(np.sqrt(np.mean(dev**2)))
    if clock == "stamps" or (clock == "auto" and rate is None):
        what = (
            "are arrival times (bursts), kept as the sample times on request"
            if kind == "arrival"
            else "are irregular"
        )
        report.update(
            method="stamps",
            t0=float(stamps[0]),
            message=f"{name} {what} (mean rate {_fmt_rate(1 / mean_step)}): kept",
        )
        if kind == "irregular":
            report.update(_near_uniform(dev, rms, period, mean_step, name))
        return None, report
    report.update(
        method="rate" if rate is not None else "line",
        rate_hz=1.0 / period,
        t0=t0,
        jitter_s=rms,
        message=f"{name} are irregular; samples taken as equally spaced at "
        f"{_fmt_rate(1 / period)}"
        + (" (given)" if rate is not None else " (least-squares line)")
        + f", rms deviation {rms * 1e3:.3g} ms",
    )
    return t0 + period * m, report
