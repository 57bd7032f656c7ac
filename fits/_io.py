"""Reading measured decays: peak-sequence CSV files, raw signals (including the pendulum records
with clock-time stamps), and robust extraction of turning points from a raw signal.

Everything here is NumPy (no JAX): it runs once per file, before the fit.
"""

from __future__ import annotations

import csv
import io
import math
import os
import re
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["Record", "Signal", "read_peaks", "read_signal", "extract_turning_points",
           "record_from_sequence", "read_record"]

_CLOCK = re.compile(r"^(?:(\d+):)?(\d+):(\d+(?:\.\d*)?)$")


@dataclass(frozen=True)
class Signal:
    """A raw sampled signal: `t` [s] (non-decreasing) and `y` [signal units]."""

    t: np.ndarray
    y: np.ndarray
    source: str = ""
    time_name: str = "time"
    signal_name: str = "signal"
    clock: str = "stamps"


@dataclass(frozen=True)
class Record:
    """A measured decay as a sequence of turning points.

    **Fields:**

    - `k`: swing index of each point (`0` is the release, the initial deflection), increasing.
    - `positions`: signed position at each turning point [signal units]; when the source gave
      amplitudes, the sides are reconstructed (release at `-a0`, flips where the swing crossed).
    - `times`: time of each turning point measured from the release [s], or `None`.
    - `centre`: preliminary estimate of the signal's zero (the offset) [signal units].
    - `noise`: noise estimate of the raw signal (extracted records), else `None`.
    - `signal`: the raw [`fits.Signal`][] for extracted records (for figures), else `None`.
    - `time_origin`: absolute time of the release point [s] (times are relative to it).
    """

    k: np.ndarray
    positions: np.ndarray
    times: np.ndarray | None = None
    centre: float = 0.0
    noise: float | None = None
    signal: Signal | None = None
    source: str = ""
    time_origin: float = 0.0
    meta: dict = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.k)

    @property
    def orientation(self) -> float:
        """`+1` if the release point is below the centre (the models release at `-a0`), else `-1`."""
        first = self.positions[0] - self.centre
        parity = -1.0 if int(self.k[0]) % 2 else 1.0
        return 1.0 if first * parity <= 0 else -1.0

    @property
    def amplitudes(self) -> np.ndarray:
        """`|x - centre|` at each turning point."""
        return np.abs(self.positions - self.centre)


def _fail(source: str, message: str):
    raise ValueError(f"{source}: {message}" if source else message)


def _float_cell(text: str, source: str, row: int, column: str) -> float:
    try:
        value = float(text)
    except ValueError:
        _fail(source, f"row {row}, column {column!r}: not a number: {text.strip()!r}")
    if not math.isfinite(value):
        _fail(source, f"row {row}, column {column!r}: {text.strip()!r} is not a finite number "
                      "(NaN and infinity are not allowed)")
    return value


def _text(path_or_text: str) -> tuple[str, str]:
    """(contents, source name) of a path, or of literal text given as `io.StringIO`."""
    if isinstance(path_or_text, io.StringIO):
        return path_or_text.getvalue(), "<text>"
    path = os.fspath(path_or_text)
    if not os.path.exists(path):
        raise ValueError(f"{path}: no such file")
    with open(path, encoding="utf-8-sig") as fh:
        return fh.read(), path


def _check_strictly_increasing(values, source, name):
    bad = np.nonzero(np.diff(values) <= 0)[0]
    if bad.size:
        i = int(bad[0])
        _fail(source, f"{name} must be strictly increasing (row {i + 3} has {values[i + 1]!r} "
                      f"after {values[i]!r})")


# -- peak sequences ----------------------------------------------------------------------------
def read_peaks(path: str | os.PathLike) -> Record:
    """Read a peak sequence from a CSV file with a header line.

    Columns (names case-insensitive): `k` (swing index, `0` is the initial deflection) and/or
    `time` [s]; `amplitude` (`|x| >= 0`) or `position` (signed `x`); optional `crossed`
    (`0` where the swing did not pass `x = 0`, the tables' `*`; without it successive turning
    points alternate sides). Without `k`, rows are swings `0, 1, 2, ...`; times are then
    measured from the first row.

    Raises `ValueError` for an empty file, missing columns, non-numeric or non-finite cells,
    non-increasing `k` or `time`, and negative amplitudes.
    """
    text, source = _text(path)
    lines = [ln for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
    if not lines:
        _fail(source, "the file is empty")
    reader = csv.reader(lines)
    header = [h.strip().lower() for h in next(reader)]
    body = [row for row in reader]
    if not body:
        _fail(source, "the file has a header but no data rows")
    names = {h: i for i, h in enumerate(header)}
    if "amplitude" not in names and "position" not in names:
        _fail(source, f"missing column: need 'amplitude' or 'position' (found {header})")
    if "k" not in names and "time" not in names:
        _fail(source, f"missing column: need 'k' or 'time' (found {header})")
    wanted = [c for c in ("k", "time", "amplitude", "position", "crossed") if c in names]
    cols = {c: [] for c in wanted}
    for r, row in enumerate(body, start=2):
        if len(row) < len(header):
            _fail(source, f"row {r}: expected {len(header)} cells, found {len(row)}")
        for c in wanted:
            cols[c].append(_float_cell(row[names[c]], source, r, c))
    values = {c: np.asarray(v) for c, v in cols.items()}
    if "k" in values:
        k = values["k"]
        if np.any(k != np.round(k)) or np.any(k < 0):
            _fail(source, "column 'k' must hold integers >= 0")
        k = k.astype(int)
        _check_strictly_increasing(k, source, "k")
    else:
        k = np.arange(len(body))
    times = values.get("time")
    if times is not None:
        _check_strictly_increasing(times, source, "time")
    crossed = values.get("crossed")
    if crossed is not None and not np.all(np.isin(crossed, (0.0, 1.0))):
        _fail(source, "column 'crossed' must hold 0 or 1")
    if "position" in values:
        return record_from_sequence(positions=values["position"], k=k, times=times,
                                    source=source)
    amplitudes = values["amplitude"]
    if np.any(amplitudes < 0):
        _fail(source, "column 'amplitude' must be >= 0 (use a 'position' column for signed values)")
    return record_from_sequence(amplitudes=amplitudes, crossed=crossed, k=k, times=times,
                                source=source)


def record_from_sequence(*, amplitudes: ArrayLike | None = None,
                         positions: ArrayLike | None = None, crossed: ArrayLike | None = None,
                         k: ArrayLike | None = None, times: ArrayLike | None = None,
                         source: str = "") -> Record:
    """A [`fits.Record`][] from arrays: `amplitudes` (`|x|`, with optional `crossed` flags) or signed
    `positions`; swing indices `k` (default `0, 1, ...`) and optional `times` [s]. Times are
    measured from the release: from the `k = 0` row if there is one, else taken as given."""
    if (amplitudes is None) == (positions is None):
        raise ValueError("give exactly one of amplitudes or positions")
    values = np.asarray(amplitudes if positions is None else positions, dtype=float).ravel()
    name = "amplitudes" if positions is None else "positions"
    if values.size == 0:
        _fail(source, f"{name} is empty")
    if not np.all(np.isfinite(values)):
        _fail(source, f"{name} must be finite (NaN and infinity are not allowed)")
    k = np.arange(values.size) if k is None else np.asarray(k).astype(int).ravel()
    if k.shape != values.shape:
        _fail(source, "k and the values must have the same length")
    if np.any(np.diff(k) <= 0) or np.any(k < 0):
        _fail(source, "k must be strictly increasing integers >= 0")
    if positions is None:
        if np.any(values < 0):
            _fail(source, "amplitudes must be >= 0")
        flips = np.ones(int(k[-1]) + 1, dtype=bool)  # swing j (ending at k = j) crossed x = 0
        if crossed is not None:
            crossed = np.asarray(crossed, dtype=float).ravel()
            if crossed.shape != values.shape:
                _fail(source, "crossed and the amplitudes must have the same length")
            flips[k] = crossed.astype(bool)
        flips[0] = False
        side = -np.cumprod(np.where(flips, -1.0, 1.0))
        values = side[k] * values
    origin = 0.0
    if times is not None:
        times = np.asarray(times, dtype=float).ravel()
        if times.shape != values.shape:
            _fail(source, "times and the values must have the same length")
        if not np.all(np.isfinite(times)):
            _fail(source, "times must be finite (NaN and infinity are not allowed)")
        if np.any(np.diff(times) <= 0):
            _fail(source, "times must be strictly increasing")
        if k[0] == 0:
            origin = float(times[0])
            times = times - origin
    return Record(k=k, positions=values, times=times, source=source, time_origin=origin)


# -- raw signals -------------------------------------------------------------------------------
def _parse_time(text: str) -> float | None:
    m = _CLOCK.match(text.strip())
    if m:
        h, mnt, s = m.groups()
        return (int(h) if h else 0) * 3600 + int(mnt) * 60 + float(s)
    return None


def _is_number(text: str) -> bool:
    try:
        float(text)
        return True
    except ValueError:
        return _parse_time(text) is not None


def _pick(spec, header, ncols, default, what, source):
    if spec is None:
        return default
    if isinstance(spec, int) or (isinstance(spec, str) and spec.strip().lstrip("-").isdigit()):
        i = int(spec)
        if not -ncols <= i < ncols:
            _fail(source, f"missing column: {what} column index {i} out of range "
                          f"(the file has {ncols} columns)")
        return i % ncols
    want = spec.strip().lower()
    names = [h.strip().lower() for h in header] if header else []
    for exact in (True, False):
        for i, h in enumerate(names):
            base = re.split(r"[\s(\[]", h, maxsplit=1)[0]
            if (h == want) if exact else (base == want or h.startswith(want)):
                return i
    _fail(source, f"missing column: no {what} column named {spec!r} (columns: {header})")


def read_signal(path: str | os.PathLike, time_col: str | int | None = None,
                signal_col: str | int | None = None, clock: str = "auto") -> Signal:
    """Read a raw signal from a CSV or whitespace-separated text file.

    An optional header line names the columns; lines of dashes and `#` comments are skipped.
    The time column may hold seconds or clock times `HH:MM:SS.mmm` (the pendulum records; a
    wrap past midnight is handled). `time_col`/`signal_col` choose columns by name (a header
    name or its first word, case-insensitive) or by 0-based index; by default the first column
    is the time and the last the signal.

    `clock` says how to use the time stamps: `"stamps"` takes them as the sample times (samples
    sharing a stamp are averaged); `"uniform"` takes the samples as equally spaced in time, at the
    rate of a least-squares line through the stamps; `"auto"` (default) chooses `"uniform"` when
    the stamps come in bursts (median step below half the mean step, with repeated stamps), as
    in the pendulum records, whose stamps are arrival times of buffered samples: there the
    samples are uniform (about 37.5 per half-swing all through the record) while the stamps
    jump by up to 0.1 s, so a stamp-based time base would put +-20 ms of jitter on every
    turning point.

    Raises `ValueError` for an empty file, a missing column, a non-numeric or non-finite cell,
    and time that decreases.
    """
    text, source = _text(path)
    lines = [ln for ln in text.splitlines()
             if ln.strip() and not ln.lstrip().startswith("#") and not set(ln.strip()) <= set("-=")]
    if not lines:
        _fail(source, "the file is empty")
    sep = "," if "," in lines[-1] else None
    split = (lambda ln: [c.strip() for c in ln.split(",")]) if sep else (lambda ln: ln.split())
    header = None
    first = split(lines[0])
    if not all(_is_number(c) for c in first):
        header, lines = first, lines[1:]
    if not lines:
        _fail(source, "the file has a header but no data rows")
    ncols = len(header) if header else len(split(lines[0]))
    ti = _pick(time_col, header, ncols, 0, "time", source)
    yi = _pick(signal_col, header, ncols, ncols - 1, "signal", source)
    if ti == yi:
        _fail(source, "the time and signal columns must differ")
    tname = header[ti] if header else f"column {ti}"
    yname = header[yi] if header else f"column {yi}"
    t = np.empty(len(lines))
    y = np.empty(len(lines))
    offset = 2 if header else 1
    for r, ln in enumerate(lines):
        cells = split(ln)
        if len(cells) <= max(ti, yi):
            _fail(source, f"data line {r + offset}: expected {ncols} cells, found {len(cells)}")
        stamp = _parse_time(cells[ti])
        t[r] = stamp if stamp is not None else _float_cell(cells[ti], source, r + offset, tname)
        y[r] = _float_cell(cells[yi], source, r + offset, yname)
    if ":" in (lines[0].split(",")[ti] if sep else lines[0].split()[ti]):
        # clock stamps: unwrap a pass through midnight
        wraps = np.cumsum(np.concatenate([[0.0], np.diff(t) < -43200.0]))
        t = t + 86400.0 * wraps
    dt = np.diff(t)
    if np.any(dt < 0):
        i = int(np.nonzero(dt < 0)[0][0])
        _fail(source, f"time must be non-decreasing ({tname}: data line {i + offset + 1} goes back "
                      f"from {t[i]:.6g} to {t[i + 1]:.6g})")
    if len(t) < 3:
        _fail(source, "a raw signal needs at least 3 samples")
    if t[-1] <= t[0]:
        _fail(source, f"time must increase ({tname} is constant)")
    if clock not in ("auto", "stamps", "uniform"):
        raise ValueError(f"clock must be 'auto', 'stamps' or 'uniform' (got {clock!r})")
    if clock == "auto":
        bursty = np.median(dt) < 0.5 * np.mean(dt) and np.any(dt == 0)
        clock = "uniform" if bursty else "stamps"
    if clock == "uniform":
        index = np.arange(len(t), dtype=float)
        rate, start = np.polyfit(index, t, 1)
        t = start + rate * index
    else:
        t, inverse = np.unique(t, return_inverse=True)
        y = np.bincount(inverse, weights=y) / np.bincount(inverse)
    return Signal(t=t - t[0], y=y, source=source, time_name=tname, signal_name=yname,
                  clock=clock)


# -- turning points of a raw signal ------------------------------------------------------------
def _noise(t, y) -> float:
    """Robust noise level: MAD of the deviation from linear interpolation between neighbours."""
    if len(y) < 5:
        return 0.0
    h1, h2 = t[1:-1] - t[:-2], t[2:] - t[1:-1]
    interp = (y[:-2] * h2 + y[2:] * h1) / (h1 + h2)
    d = y[1:-1] - interp
    w = np.sqrt(1 + (h1**2 + h2**2) / (h1 + h2) ** 2)  # std of d for white noise of unit std
    return float(1.4826 * np.median(np.abs(d - np.median(d)) / w))


def _despike(y, sigma, threshold):
    """Replace samples far from the running median of 5 (isolated spikes)."""
    if len(y) < 5:
        return y
    pad = np.pad(y, 2, mode="edge")
    windows = np.lib.stride_tricks.sliding_window_view(pad, 5)
    med = np.median(windows, axis=1)
    spread = np.max(windows, axis=1) - np.min(windows, axis=1)
    dev = np.abs(y - med)
    spike = dev > np.maximum(threshold * sigma, 0.5 * (spread - dev))
    spike &= dev > threshold * sigma
    return np.where(spike, med, y)


def _zigzag(y, h):
    """Indices of alternating extrema that the signal leaves by more than `h` (peak detection
    with hysteresis: noise wiggles smaller than `h` are no turning points)."""
    idx = []
    i_max = i_min = 0
    direction = 0  # +1 looking for a max, -1 for a min, 0 undecided
    for i in range(1, len(y)):
        if y[i] > y[i_max]:
            i_max = i
        if y[i] < y[i_min]:
            i_min = i
        if direction >= 0 and y[i_max] - y[i] > h:
            idx.append(i_max)
            direction, i_min = -1, i
        elif direction <= 0 and y[i] - y[i_min] > h:
            idx.append(i_min)
            direction, i_max = 1, i
    return np.asarray(idx, dtype=int)


def _refine(t, y, i, swing, sigma):
    """Time and value of the extremum near sample `i`, by a least-squares parabola through the
    samples within 3 % of the swing (or 3 noise levels) of the extreme value."""
    band = max(0.03 * swing, 3 * sigma)
    lo = i
    while lo > 0 and abs(y[lo - 1] - y[i]) <= band:
        lo -= 1
    hi = i
    while hi < len(y) - 1 and abs(y[hi + 1] - y[i]) <= band:
        hi += 1
    if hi - lo < 3:
        return t[i], y[i]
    tau = t[lo:hi + 1] - t[i]
    scale = max(np.max(np.abs(tau)), 1e-300)
    a2, a1, a0 = np.polyfit(tau / scale, y[lo:hi + 1], 2)
    if a2 == 0 or np.sign(a2) == np.sign(y[i] - np.median(y[lo:hi + 1])):
        return t[i], y[i]
    vertex = -a1 / (2 * a2)
    if not -1 <= vertex <= 1:
        return t[i], y[i]
    return t[i] + vertex * scale, a0 - a1 * a1 / (4 * a2)


def extract_turning_points(signal: Signal, *, hysteresis: float | None = None,
                           min_amplitude: float | None = None) -> Record:
    """Turning points of a raw decaying signal, robust to irregular sampling, noise, a constant
    offset and a few spurious extrema.

    1. the noise level `sigma` is estimated (MAD of the deviation from linear interpolation)
       and isolated spikes (far from the running median of 5 samples) are removed;
    2. extrema are found with hysteresis `h` (default `max(6 sigma, 1e-3 range)`): a turning
       point counts only once the signal has moved back from it by more than `h`;
    3. pairs of extrema much closer in time than the median half-period (spurious wiggles) are
       dropped; each extremum is refined by a parabola through its neighbourhood; leading
       extrema on the same side of the centre as the next one (the mass held or nudged before
       its release) are dropped, so the record starts at the release;
    4. the record ends where the swings fall below `min_amplitude` (default `10 h`).

    The first turning point is the release (`k = 0`); times are measured from it. The
    preliminary offset `centre` is the median of `(x[k-1] + 2 x[k] + x[k+1]) / 4`, which cancels
    the alternation and, to first order, the decay.
    """
    t, y = np.asarray(signal.t, dtype=float), np.asarray(signal.y, dtype=float)
    source = signal.source
    sigma = _noise(t, y)
    y_clean = _despike(y, sigma, 8.0)
    span = float(np.max(y_clean) - np.min(y_clean))
    if span <= 0:
        _fail(source, "the signal is constant: no decay to fit")
    h = float(hysteresis) if hysteresis is not None else max(6 * sigma, 1e-3 * span)
    idx = _zigzag(y_clean, h)
    starts_at_edge = bool(idx.size and idx[0] == 0)
    # spurious wiggles: remove the closest pair while an interval is far below the median
    while idx.size >= 4:
        gaps = np.diff(t[idx])
        j = int(np.argmin(gaps))
        if gaps[j] >= 0.35 * np.median(gaps):
            break
        idx = np.delete(idx, [j, j + 1]) if j + 1 < idx.size else np.delete(idx, j)
    if idx.size < 3:
        _fail(source, f"found only {idx.size} turning points in the signal (hysteresis {h:.3g})")
    swings = np.abs(np.diff(y_clean[idx]))
    swings = np.concatenate([[swings[0]], swings])
    refined = [_refine(t, y_clean, i, s, sigma) for i, s in zip(idx, swings)]
    tk = np.array([r[0] for r in refined])
    xk = np.array([r[1] for r in refined])
    if xk.size >= 5:
        # before the release the mass may be held, or nudged, on the release side: extrema on
        # the same side of the centre as their successor are no swings; the release is the
        # last of them
        c = np.median((xk[1:-2] + 2 * xk[2:-1] + xk[3:]) / 4)
        lead = 0
        while lead + 3 < xk.size and (xk[lead] - c) * (xk[lead + 1] - c) > 0:
            lead += 1
        if lead:
            tk, xk, starts_at_edge = tk[lead:], xk[lead:], False
    if starts_at_edge and xk.size >= 5:
        # an extremum at the first sample is a release from rest only if it is at least as far
        # from the centre as the next one on its side (not a record that starts mid-swing)
        c = np.median((xk[1:-2] + 2 * xk[2:-1] + xk[3:]) / 4)
        if abs(xk[0] - c) < 0.98 * abs(xk[2] - c):
            tk, xk = tk[1:], xk[1:]
    floor = float(min_amplitude) if min_amplitude is not None else 10 * h
    small = np.nonzero(np.abs(np.diff(xk)) < 2 * floor)[0]
    if small.size:
        tk, xk = tk[:small[0] + 1], xk[:small[0] + 1]
    if xk.size < 3:
        _fail(source, "fewer than 3 turning points above the amplitude floor: no decay to fit")
    centre = float(np.median((xk[:-2] + 2 * xk[1:-1] + xk[2:]) / 4))
    origin = float(tk[0])
    return Record(k=np.arange(xk.size), positions=xk, times=tk - origin, centre=centre,
                  noise=sigma, signal=signal, source=source, time_origin=origin,
                  meta={"hysteresis": h})


def read_record(path: str | os.PathLike, *, series: bool = False,
                time_col: str | int | None = None,
                signal_col: str | int | None = None) -> Record:
    """A [`fits.Record`][] from a file: a peak sequence (default) or, with `series=True`, the
    turning points extracted from a raw signal (see [`fits.extract_turning_points`][])."""
    if series:
        return extract_turning_points(read_signal(path, time_col, signal_col))
    if time_col is not None or signal_col is not None:
        raise ValueError("time_col/signal_col apply to raw signals (series=True)")
    return read_peaks(path)
