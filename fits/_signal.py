"""Raw sampled signals ([`fits.Signal`][]): the time and value columns, arrival-time stamps."""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass, field

import numpy as np

from ._clock import CLOCKS, recover_clock
from ._text import (
    CLOCK,
    MAX_ROWS,
    TIME_NAME,
    TIME_UNIT,
    TIME_UNITS,
    UNIT_SPELLINGS,
    Table,
    column_names,
    fail,
    line_of,
    load_text,
    parse_table,
    read_columns,
    rows_ok,
)


@dataclass(frozen=True)
class Signal:
    """A raw sampled signal.

    **Fields:**

    - `t`: sample times [s] from the file's first sample (non-decreasing; strictly increasing
      where the stamps were kept, rows sharing a stamp averaged; a `window` of
      [`fits.read_signal`][] keeps its samples' times).
    - `y`: the samples [signal units].
    - `source`, `time_name`, `signal_name`: the file and the columns read.
    - `clock`: `"uniform"` if `t` is a uniform clock (recovered or given), `"stamps"` if `t`
      holds the file's stamps.
    - `clock_report`: what was done with the time stamps, a JSON-ready dict (`method`,
      `stamps`, `rate_hz`, `t0`, `jitter_s`, `dropped`, `rows`, `column`, `message`; see
      [`fits.recover_clock`][]).
    - `others`: the names of the file's other columns (neither the time nor the signal).
    """

    t: np.ndarray
    y: np.ndarray
    source: str = ""
    time_name: str = "time"
    signal_name: str = "signal"
    clock: str = "stamps"
    clock_report: dict = field(default_factory=dict)
    others: tuple = ()


# -- raw signals -------------------------------------------------------------------------------
def _pick(spec, header, ncols, what, source):
    if isinstance(spec, (int, np.integer)) or (
        isinstance(spec, str) and spec.strip().lstrip("-").isdigit()
    ):
        i = int(spec)
        if not -ncols <= i < ncols:
            fail(
                source,
                f"missing column: {what} column index {i} out of range "
                f"(the file has {ncols} columns)",
            )
        return i % ncols
    want = spec.strip().lower()
    names = [h.strip().lower() for h in header] if header else []
    for exact in (True, False):
        for i, h in enumerate(names):
            base = re.split(r"[\s(\[]", h, maxsplit=1)[0]
            if (h == want) if exact else (base == want or h.startswith(want)):
                return i
    fail(source, f"missing column: no {what} column named {spec!r} (columns: {header})")


def _time_candidates(tab: Table, yi: int) -> list:
    """Columns that may hold the time: those named like a time, or holding clock times."""
    out = []
    for i in range(tab.ncols):
        if i == yi or i >= len(tab.first):
            continue
        named = tab.header is not None and TIME_NAME.search(tab.header[i].strip())
        if named or CLOCK.match(tab.first[i].strip()):
            out.append(i)
    return out


def unit_of_time(name: str) -> str | None:
    """The unit of a time column named `name` (`TIME_UNITS`' keys) from the end of the name
    (`time_ms`, `t [ms]`, `Time (us)`); `None` where it names none."""
    m = TIME_UNIT.search(name.strip())
    return UNIT_SPELLINGS.get(m.group(1).lower(), "s") if m else None


def read_stamps(
    tab: Table, candidates: list, names: list, unit: str | None = None
) -> tuple[np.ndarray, str, str]:
    """The time stamps [s] from the finest of the candidate columns (the most distinct values
    among those that parse and never decrease), its name, and a note on the others and on the
    unit: `unit` (`TIME_UNITS`), else the one the column's name ends with, else seconds (clock
    times `HH:MM:SS` are always read as such). Missing stamps are NaN (`_MISSING`)."""
    parsed, first_error = [], None
    for c in candidates:
        try:
            values = read_columns(tab, [c], missing=True)[0]
        except ValueError as err:
            if len(candidates) == 1:
                raise
            first_error = first_error or err
            continue
        there = np.isfinite(values)
        if not np.any(there):
            continue
        if CLOCK.match(tab.first[c].strip()):  # clock stamps through midnight
            values[there] += 86400.0 * np.cumsum(
                np.concatenate([[0.0], np.diff(values[there]) < -43200.0])
            )
        monotone = bool(np.all(np.diff(values[there]) >= 0))
        parsed.append((c, values, monotone, np.unique(values[there]).size))
    if not parsed:
        if first_error is None:
            fail(tab.source, f"the time column {names[candidates[0]]!r} holds no values")
        raise first_error
    usable = [p for p in parsed if p[2]] or parsed[:1]
    ti, stamps = usable[int(np.argmax([p[3] for p in usable]))][:2]  # the first of the finest
    rows = np.flatnonzero(np.isfinite(stamps))
    dt = np.diff(stamps[rows])
    if np.any(dt < 0):
        k = int(np.nonzero(dt < 0)[0][0])
        i, j = int(rows[k]), int(rows[k + 1])
        fail(
            tab.source,
            f"line {line_of(tab, j)}, column {names[ti]!r}: time must be "
            f"non-decreasing (goes back from {stamps[i]:.6g} to {stamps[j]:.6g})",
        )
    if stamps[rows[-1]] <= stamps[rows[0]]:
        fail(tab.source, f"time must increase (column {names[ti]!r} is constant)")
    others = [
        f"{names[c]!r}" + (f" ({d} distinct values)" if ok else " (not monotone)")
        for c, _, ok, d in parsed
        if c != ti
    ]
    note = (
        f"; time column{'s' if len(others) > 1 else ''} {', '.join(others)} ignored"
        if others
        else ""
    )
    if not CLOCK.match(tab.first[ti].strip()):
        named = unit or unit_of_time(names[ti])
        if named not in (None, "s"):
            stamps = stamps * TIME_UNITS[named]
            note += f"; {names[ti]!r} read in {named}"
        there = stamps[np.isfinite(stamps)]
        step = float(np.median(np.diff(there))) if there.size > 1 else 0.0
        if named is None and step >= 1 and np.all(there == np.round(there)):
            # a counter of milliseconds, read as seconds, makes every time 1000 x too long
            note += (
                f"; {names[ti]!r} holds whole numbers {step:g} apart, read as seconds (if "
                f"they are milliseconds, say so: --time-unit ms, time_unit='ms')"
            )
    return stamps, names[ti], note


def read_signal(
    path: str | os.PathLike,
    time_col: str | int | None = None,
    signal_col: str | int | None = None,
    clock: str = "auto",
    *,
    rate: float | None = None,
    time_unit: str | None = None,
    max_rows: int | None = MAX_ROWS,
    window: tuple | None = None,
) -> Signal:
    """Read a raw signal from a CSV (`,`, or `;` with decimal points or commas), tab- or
    whitespace-separated text file (decimal commas there too).

    **Arguments:**

    - `path`: the file. An optional header line names the columns (lines of notes above it
      are passed over, a line of units below it adds the units to the names; lines of dashes
      and `#` comments are skipped); UTF-8 with or without a byte-order mark, UTF-16 with
      one, Windows line ends.
    - `time_col`, `signal_col`: the columns, by name (a header name or its first word,
      case-insensitive) or 0-based index. By default the signal is the last column that is
      not the time and the time the column named like a time (`time`, `timestamp`, `elapsed`, `t`, `... (s)`) or
      holding clock times `HH:MM:SS.mmm`, after a date or not (`2026-11-27T23:59:50.125`,
      `27.11.2026 23:59:50,125`, `11/27/2026 11:59:50.125 PM`, a time zone after it; the date
      is not read, a pass through midnight is unwrapped): of several
      such, the one with the finest resolution (most distinct values), so a quantised
      `Time_Elapsed` column beside the stamps is ignored; else the first column. A file of one
      column has no time: give `rate`.
    - `clock`: `"auto"` (default), `"uniform"` or `"stamps"`: what to do with the stamps, see
      [`fits.recover_clock`][]. With `"auto"`, arrival-time stamps (bursts) are replaced by the
      uniform sampling clock recovered from their lower envelope, and genuine stamps kept.
    - `rate`: the sampling rate [Hz], when known: the samples are put on a uniform clock at
      that rate.
    - `time_unit`: the time column's unit, one of [`fits.TIME_UNITS`][] (`"s"`, `"ms"`,
      `"us"`, `"ns"`, `"min"`); default: the unit its name ends with (`time_ms`, `t [ms]`,
      `Time (us)`), else seconds. Clock times `HH:MM:SS.mmm` are read as such.
    - `max_rows`: refuse files with more data rows than this (estimated from the file size
      before reading; default [`fits.MAX_ROWS`][]); `None` for no limit.
    - `window`: `(start, end)` [s from the file's first sample; `None` for an open end]: only
      the samples within it are kept (one decay of several in a file, a part without a
      disturbance); their times stay on the whole file's clock.

    Rows sharing a stamp are averaged where the stamps are kept (`clock_report` counts them).
    A row whose time or signal
    is missing (an empty cell, `NaN`, `NA`, `N/A`, `null` or `none`: a logger's dropped sample)
    is left out; on a clock made from `rate` the other rows keep their places. The result's
    `clock_report` says what was done.

    Raises `ValueError` naming the file, and the line and column where there is one, for a
    missing, unreadable or binary file, a directory, an empty or header-only file, fewer than
    3 rows with values (in the `window`), a missing column, a non-numeric or infinite cell,
    time that decreases, an unknown `clock` or `time_unit`, a bad `rate` or `window`, and too
    many rows.
    """
    if clock not in CLOCKS:
        raise ValueError(f"clock must be one of {', '.join(map(repr, CLOCKS))} (got {clock!r})")
    lo, hi = _window(window)
    if time_unit is not None and time_unit not in TIME_UNITS:
        raise ValueError(
            f"time_unit must be one of {', '.join(map(repr, TIME_UNITS))} (got {time_unit!r})"
        )
    text, source = load_text(path, max_rows)
    tab = parse_table(text, source)
    header, ncols = tab.header, tab.ncols
    names = column_names(tab)
    if signal_col is not None:
        yi = _pick(signal_col, header, ncols, "signal", source)
    else:  # the last column that is not the time (given, named like one or of clock times)
        times = (
            [_pick(time_col, header, ncols, "time", source)]
            if time_col is not None
            else _time_candidates(tab, None)
        )
        yi = max((i for i in range(ncols) if i not in times), default=ncols - 1)
    if time_col is not None:
        candidates = [_pick(time_col, header, ncols, "time", source)]
        if candidates[0] == yi:
            fail(source, "the time and signal columns must differ")
    elif ncols == 1:
        candidates = []
    else:
        candidates = _time_candidates(tab, yi) or [0 if yi != 0 else 1]
    y = read_columns(tab, [yi], missing=True)[0]
    rows_ok(len(y), source, max_rows, 3, "a raw signal")
    stamps, tname, ignored = (
        read_stamps(tab, candidates, names, time_unit) if candidates else (None, None, "")
    )
    # rows without a value (a logger's dropped samples, `_MISSING`) are left out; by row
    # number they keep their place on a clock made from the rate
    there = np.isfinite(y) if stamps is None else np.isfinite(y) & np.isfinite(stamps)
    gaps = int(np.count_nonzero(~there))
    if gaps:
        rows_ok(int(np.count_nonzero(there)), source, None, 3, "a raw signal with values")
        if stamps is not None:
            y, stamps = y[there], stamps[there]
    try:
        t, report = recover_clock(stamps, clock=clock, rate=rate, column=tname, rows=there.size)
    except ValueError as err:
        fail(source, str(err))
    if gaps and stamps is None:
        t, y = t[there], y[there]
    if gaps:
        first = line_of(tab, int(np.flatnonzero(~there)[0]))
        rows = f"{gaps} row{'s' if gaps > 1 else ''}"
        ignored += f"; {rows} without a value left out (the first: line {first})"
    report["message"] += ignored
    if t is None:  # stamps kept
        t, inverse = np.unique(stamps, return_inverse=True)
        counts = np.bincount(inverse)
        y = np.bincount(inverse, weights=y) / counts
        kind = "stamps"
        shared = counts[counts > 1]
        if shared.size:
            report["message"] += f"; {shared.sum()} rows sharing {shared.size} time stamps averaged"
    else:
        kind = "uniform"
    t = t - t[0]
    if window is not None:
        inside = (t >= lo) & (t <= hi)
        if np.count_nonzero(inside) < 3:
            fail(
                source,
                f"window [{lo:g}, {hi:g}] s holds {np.count_nonzero(inside)} samples (the signal "
                f"spans 0 to {t[-1]:.6g} s from its first sample): at least 3 are needed",
            )
        t, y = t[inside], y[inside]
        report["message"] += f"; the samples from {t[0]:.6g} to {t[-1]:.6g} s kept (window)"
    return Signal(
        t=t,
        y=y,
        source=source,
        time_name=tname or "sample index",
        signal_name=names[yi],
        clock=kind,
        clock_report=report,
        others=tuple(n for i, n in enumerate(names) if i != yi and i not in candidates),
    )


def _window(window) -> tuple:
    """`(start, end)` of `read_signal`'s `window` [s], open ends as infinities."""
    if window is None:
        return -math.inf, math.inf
    try:
        lo, hi = window
        lo = -math.inf if lo is None else float(lo)
        hi = math.inf if hi is None else float(hi)
    except (TypeError, ValueError):
        raise ValueError(
            f"window must be (start, end) in seconds from the first sample (got {window!r})"
        ) from None
    if math.isnan(lo) or math.isnan(hi) or not lo < hi:
        raise ValueError(f"window needs start < end [s] (got {window!r})")
    return lo, hi
