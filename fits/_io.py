"""Reading measured decays: peak-sequence CSV files, raw signals (including the pendulum records
with arrival-time stamps), and robust extraction of turning points from a raw signal.

Everything here is NumPy (no JAX): it runs once per file, before the fit.
"""

from __future__ import annotations

import dataclasses
import functools
import io
import math
import os
import re
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from vmj.cli._options import LARGEST

from ._clock import CLOCKS, recover_clock

__all__ = [
    "Record",
    "Signal",
    "read_peaks",
    "read_signal",
    "extract_turning_points",
    "record_from_sequence",
    "read_record",
    "read_decays",
    "MAX_ROWS",
    "EDGE_RELEASE",
    "HELD_RELEASE",
    "ROWS_AS_HALF_SWINGS",
    "TIME_UNITS",
]

EDGE_RELEASE = "edge: at the signal's first samples, located from one side (not weighed)"
"""`Record.meta["release"]` of a record whose signal starts at its release."""
HELD_RELEASE = "held: time extrapolated from the first half-swing (not weighed)"
"""`Record.meta["release"]` of a record released from a hold."""
ROWS_AS_HALF_SWINGS = "half-swings"
"""`Record.meta["rows"]` of a peak table of amplitudes without `k`, `cycle` or `crossed`: its
rows were taken as successive half-swings (both sides' peaks in turn), which its numbers cannot
tell from one side's peaks; the fits say so in their warnings."""

MAX_ROWS = 2_000_000
"""Largest number of data rows read by default (about 2 hours at 259 Hz, 33 minutes at 1 kHz):
beyond it a file is refused before it is read, unless `max_rows` is raised or `None`."""

#: a date before a clock time (`2026-11-27`, `2026/11/27`, `27.11.2026`, `11/27/2026`); the
#: date itself is not read: a record's clock times are unwrapped through midnight
_DATE = r"(?:\d{4}[-/.]\d{1,2}[-/.]\d{1,2}|\d{1,2}[-/.]\d{1,2}[-/.]\d{2,4})"
_DATE_PREFIX = re.compile(rf"{_DATE}(?:T|\s+)(?=\d{{1,2}}:)")
#: clock times `[date ]HH:MM:SS.mmm` or `MM:SS.mmm`, 12-hour (`AM`/`PM`) or with a time zone
_CLOCK = re.compile(
    rf"^({_DATE}(?:T|\s+))?(?:(\d+):)?(\d+):(\d+(?:\.\d*)?)\s*([AaPp][Mm])?"
    r"(?:Z|[+-]\d\d:?\d\d)?$"
)
#: clock times as the fast reader takes them (`HH:MM:SS.mmm`, `MM:SS.mmm`)
_PLAIN_CLOCK = re.compile(r"^(?:\d+:)?\d+:\d+(?:\.\d*)?$")
_TIME_NAME = re.compile(
    r"time|stamp|elapsed|zeit|^t$|^t[\s(\[_/]|^sec|[(\[](?:s|ms|us|µs|ns|min)[)\]]", re.IGNORECASE
)


def unit_at_end(spellings: str) -> re.Pattern:
    """The pattern of a unit, one of the `|`-separated regular-expression `spellings`, at the
    end of a column's name (`time_ms`, `t [ms]`, `Time (us)`, `t/min`, `Angle(rad)`, `x in
    deg`); its group 1 is the spelling found."""
    return re.compile(rf"(?:^|[\s_(\[/,-])(?:in\s+)?({spellings})\s*[)\]]?\s*$", re.IGNORECASE)


#: a time column's unit at the end of its name
_TIME_UNIT = unit_at_end("ns|us|µs|μs|usec|ms|msec|s|sec|secs|seconds?|min|minutes?")
TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9, "min": 60.0}
"""Units of a raw signal's time column, in seconds (`read_signal`'s `time_unit`)."""
_UNIT_SPELLINGS = {
    **{unit: unit for unit in TIME_UNITS},
    "µs": "us",
    "μs": "us",
    "usec": "us",
    "msec": "ms",
    "minute": "min",
    "minutes": "min",
}


#: a length unit at the end of a value column's name (`amplitude_mm`, `x [um]`, `Position
#: (in)`), in metres
LENGTH_UNITS = {
    "nm": 1e-9,
    "um": 1e-6,
    "mm": 1e-3,
    "cm": 1e-2,
    "dm": 0.1,
    "m": 1.0,
    "in": 0.0254,
    "ft": 0.3048,
}
_LENGTH_UNIT = unit_at_end("nm|um|µm|μm|mm|cm|dm|m|in|inch|inches|ft|feet|foot")
#: an angle unit at the end of a value column's name (`Angle(deg)`, `theta_rad`)
ANGLE_UNIT = unit_at_end("mrad|rad|radians?|deg|degrees?|°")
_LENGTH_SPELLINGS = {
    "µm": "um",
    "μm": "um",
    "inch": "in",
    "inches": "in",
    "feet": "ft",
    "foot": "ft",
}


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


@dataclass(frozen=True)
class Record:
    """A measured decay as a sequence of turning points.

    **Fields:**

    - `k`: swing index of each point (`0` is the release, the initial deflection), increasing.
    - `positions`: signed position at each turning point [signal units]. When the source gave
      amplitudes with a `crossed` column, the sides are reconstructed from it (release at
      `-a0`). When it gave amplitudes only (`sides_known` False), the sides are NOT known: the
      positions then alternate provisionally and only `amplitudes` may be trusted.
    - `times`: time of each turning point measured from the release [s], or `None`.
    - `centre`: preliminary estimate of the signal's zero [signal units]: the median of the
      local centres of successive extrema (see [`fits.sensor_start`][] for offset and asymmetry).
    - `noise`: noise estimate of the raw signal (extracted records) [signal units], else `None`.
    - `signal`: the raw [`fits.Signal`][] for extracted records (for figures), else `None`.
    - `time_origin`: absolute time of the release point [s] (times are relative to it).
    - `sides_known`: `False` for amplitude-only records (`k, amplitude` without sign or
      `crossed`): whether each swing passed the centre is for the model to decide.
    - `crossed`: the source's `crossed` flags (`True` where the swing ending at this point
      passed the centre), or `None` when the source gave none.
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
    sides_known: bool = True
    crossed: np.ndarray | None = None

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

    @property
    def clock(self) -> dict | None:
        """The sample-clock report of the raw signal this record was extracted from (the fit
        JSON's `"clock"`), or `None` for peak records."""
        return None if self.signal is None else dict(self.signal.clock_report)


class _NotPeakTable(ValueError):
    """`read_peaks`' refusal of a file that is no peak table: no header line, no amplitude or
    position column, or values that are samples of a motion (`read_record` reads it as a raw
    signal instead)."""


class _NoDecay(ValueError):
    """A signal that holds no decay to extract (constant, noise, growing): where the file has
    other columns, the message names them."""


def _fail(source: str, message: str, error: type = ValueError):
    raise error(f"{source}: {message}" if source else message)


# -- text files --------------------------------------------------------------------------------
def _decode(data: bytes, source: str) -> str:
    """Text of a file's bytes: UTF-16 with its byte-order mark, else UTF-8 (an optional BOM
    dropped), else Windows-1252; a file with NUL bytes or many control characters is binary."""
    if data[:2] in (b"\xff\xfe", b"\xfe\xff"):
        try:
            return data.decode("utf-16")
        except UnicodeDecodeError:
            _fail(
                source, "not a readable text file (a UTF-16 byte-order mark, then invalid UTF-16)"
            )
    head = data[:65536]
    nul = head.find(b"\x00")
    control = sum(
        head.count(bytes([c])) for c in (*range(1, 9), 14, 15, *range(16, 27), *range(28, 32))
    )
    if nul >= 0 or control > 0.01 * max(len(head), 1):
        where = (
            nul
            if nul >= 0
            else next(i for i, c in enumerate(head) if c < 32 and c not in (9, 10, 11, 12, 13, 27))
        )
        _fail(
            source,
            f"not a text file (binary data at byte {where}): give a CSV or "
            "whitespace-separated text file",
        )
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError:
        return data.decode("cp1252", errors="replace")


_RAISE_LIMIT = (
    "to read it, raise the limit (max_rows=N, or max_rows=None for none; on the command line "
    "--max-rows N or --max-rows none)"
)


#: a file longer than this many lines that is no peak table was not meant as one (the raw
#: signal's errors do not add why it is none)
_PEAK_TABLE_ROWS = 200


@dataclass(frozen=True)
class _Loaded:
    """A file's text as `_text` returned it, for a second reader (`read_record` tries the peak
    table, then the raw signal) without reading the file again."""

    text: str
    source: str


def _text(path_or_text, max_rows: int | None = None) -> tuple[str, str]:
    """(contents with `\\n` line ends, source name) of a path, or of literal text given as
    `io.StringIO`. Refuses a file estimated to hold more than `max_rows` lines."""
    if isinstance(path_or_text, _Loaded):
        return path_or_text.text, path_or_text.source
    if isinstance(path_or_text, io.StringIO):
        text, source = path_or_text.getvalue(), "<text>"
    else:
        try:
            path = os.fspath(path_or_text)
        except TypeError:
            raise ValueError(f"expected a file path, got {type(path_or_text).__name__}") from None
        if os.path.isdir(path):
            raise ValueError(f"{path}: is a directory, not a file")
        if not os.path.exists(path):
            raise ValueError(f"{path}: no such file")
        try:
            size = os.path.getsize(path)
            with open(path, "rb") as fh:
                head = fh.read(65536)
                if max_rows is not None and size > len(head) > 0:
                    estimate = size * max(head.count(b"\n"), 1) / len(head)
                    if estimate > 1.1 * max_rows:
                        _fail(
                            path,
                            f"about {estimate:,.0f} rows ({size / 2**20:.0f} MiB), more "
                            f"than the limit of {max_rows:,} rows: {_RAISE_LIMIT}",
                        )
                data = head + fh.read()
        except OSError as err:
            raise ValueError(f"{path}: cannot be read ({err.strerror or err})") from None
        text, source = _decode(data, path), path
    if "\r" in text:
        text = text.replace("\r\n", "\n").replace("\r", "\n")
    return text, source


def _skip(line: str) -> bool:
    """Blank lines, `#` comments and rules of dashes or equals signs carry no data."""
    s = line.strip()
    return not s or s.startswith("#") or set(s) <= set("-=")


def _parse_time(text: str) -> float | None:
    """Seconds since midnight of a clock time (`_CLOCK`), or `None`."""
    m = _CLOCK.match(text.strip())
    if not m:
        return None
    date, h, mnt, s, half = m.groups()
    if h is None and (date or half):  # `date HH:MM`, `HH:MM PM`: hours and whole minutes
        if "." in s:
            return None
        h, mnt, s = mnt, s, "0"
    hours = int(h) if h else 0
    if half:
        if not 1 <= hours <= 12:
            return None
        hours = hours % 12 + (12 if half.lower() == "pm" else 0)
    return hours * 3600 + int(mnt) * 60 + float(s)


def _is_number(text: str) -> bool:
    try:
        float(text)
        return True
    except ValueError:
        return _parse_time(text) is not None


def _clock_groups(words: list) -> list:
    """Whitespace-separated words grouped into cells: a date and the clock time after it, and
    a clock time and its `AM`/`PM`, are one cell each (`2026-11-27 23:59:50.125 4.1`)."""
    groups = []
    for w in words:
        if groups and (
            (re.fullmatch(_DATE, groups[-1][-1]) and _CLOCK.match(w))
            or (w.lower() in ("am", "pm") and _CLOCK.match(" ".join(groups[-1])))
        ):
            groups[-1].append(w)
        else:
            groups.append([w])
    return groups


def _splitter(sep):
    """Cells of a line: split at `sep` (whitespace if `None`: a date and its clock time stay
    one cell), spaces and double quotes around each cell removed."""
    if sep is None:
        return lambda ln: [" ".join(g) for g in _clock_groups([c.strip('"') for c in ln.split()])]
    return lambda ln: [c.strip().strip('"').strip() for c in ln.split(sep)]


@dataclass
class _Table:
    """A delimited text file: its header, separator, and where the data rows start."""

    text: str
    source: str
    header: list | None
    sep: str | None
    ncols: int
    body: int  # character offset of the first data line
    first_line: int  # its line number (1-based)
    first: list  # its cells


def _data_cells(line: str) -> tuple:
    """`(separator, cells, decimal_comma)` of a line of numbers, or `(separator, None, False)`
    of a line of text. The separators tried: `;` (a comma beside it is a decimal mark), `,`, a
    tab, whitespace (with decimal points, or commas: `0,005 -19,41`)."""
    seps = [c for c in (";", ",", "\t") if c in line] + [None]
    for sep in seps:
        cells = _splitter(sep)(line)
        while len(cells) > 1 and not cells[-1]:  # a trailing separator
            cells.pop()
        if all(c and _is_number(c) for c in cells):
            return sep, cells, False
        if sep != "," and any("," in c for c in cells):
            cells = [c.replace(",", ".") for c in cells]
            if all(c and _is_number(c) for c in cells):
                return sep, cells, True
    return seps[0], None, False


#: a line of units under a header (`s,mm`, `(ms),(V)`, `seconds degrees`): every cell a unit
_UNIT_WORDS = {
    *("s", "ms", "us", "µs", "μs", "ns", "min", "h", "hz", "khz", "-", "%", "°", "counts"),
    *("m", "mm", "cm", "um", "µm", "μm", "nm", "in", "v", "mv", "a", "ma", "deg", "rad", "g"),
    *("n", "kn", "pa", "kpa", "m/s", "mm/s", "m/s^2", "m/s2", "m/s²", "sec", "secs"),
    *("second", "seconds", "degree", "degrees", "volt", "volts", "radian", "radians"),
    *("meter", "meters", "metre", "metres", "millimeter", "millimeters", "millimetre"),
    "millimetres",
}


def _units_line(names: list) -> bool:
    return any(names) and all(
        not n or n.lower() in _UNIT_WORDS or re.fullmatch(r"[(\[][^()\[\]]{0,16}[)\]]", n)
        for n in names
    )


def _header_names(header: str, line: str, sep, cells: list) -> list:
    """The column names of a header line above the data line `line` (split into `cells` at
    `sep`)."""
    hdr = _splitter(sep)(header)
    if sep is None and len(hdr) != len(cells):
        groups = _clock_groups([c.strip('"') for c in line.split()])
        if len(hdr) == sum(map(len, groups)):  # `Date Time Angle`: a name per word
            names = iter(hdr)
            hdr = [" ".join(next(names) for _ in g) for g in groups]
    if sep is None and len(hdr) != len(cells):
        hdr = [h for h in re.split(r"\s{2,}|\t", header.strip()) if h]  # "time (s)"
    while hdr and len(hdr) > len(cells) and not hdr[-1]:
        hdr.pop()
    return hdr


def _table(text: str, source: str, *, need_header: bool = False) -> _Table:
    """Header, separator and first data row of a text table (a header line is optional unless
    `need_header`). Of the lines of text above the data (an instrument's notes, the header,
    units), the header is the last that names as many columns as the data have and is not a
    line of units; where none does, the first. A line of units under the header adds each
    column's unit to its name (`Time` over `(ms)`: `Time (ms)`, read in milliseconds)."""
    pos, no = 0, 0
    texts = []
    while pos < len(text):
        end = text.find("\n", pos)
        end = len(text) if end < 0 else end
        line, start = text[pos:end], pos
        pos, no = end + 1, no + 1
        if _skip(line):
            continue
        sep, cells, comma = _data_cells(line)
        if comma:  # decimal commas (`0,005;-19,41`): every comma of the data is one
            text = text[:start] + text[start:].replace(",", ".")
        if cells is None:
            texts.append(line)
            continue
        if not texts and need_header:
            _fail(
                source,
                f"line {no}: expected a header line naming the columns, found "
                f"numbers: {line.strip()!r}",
                _NotPeakTable,
            )
        hdr = None
        if texts:
            named = [_header_names(t, line, sep, cells) for t in texts]
            fits_data = [
                i for i, h in enumerate(named) if len(h) == len(cells) and not _units_line(h)
            ]
            at = fits_data[-1] if fits_data else 0
            hdr = named[at]
            units = [h for h in named[at + 1 :] if fits_data and len(h) == len(cells)][:1]
            if units:  # (a line of units, as the header is the last line that is not)
                hdr = [  # `Time,Channel A` over `(ms),(V)`: `Time (ms)`
                    f"{n} {u if u[:1] in '([' else f'({u})'}" if u and u != "-" else n
                    for n, u in zip(hdr, units[0])
                ]
        if hdr is not None and len(hdr) < len(cells):
            _fail(
                source,
                f"line {no}: {len(cells)} cells, but the header names only "
                f"{len(hdr)} column{'s' if len(hdr) != 1 else ''}: {hdr}",
            )
        ncols = len(hdr) if hdr else len(cells)
        return _Table(text, source, hdr, sep, ncols, start, no, cells)
    if not texts:
        _fail(source, "the file is empty")
    for line in texts[1:]:  # rows of numbers and words: a column of text
        cells = [c for c in _splitter(_data_cells(line)[0])(line) if c]
        words = [c for c in cells if not _is_number(c)]
        if words and len(words) < len(cells):
            _fail(
                source,
                f"no row of numbers only: {line.strip()!r} holds text ({words[0]!r}); the "
                "columns must be numbers (remove a column of notes)",
            )
    _fail(source, "the file has a header but no data rows")


def _column_names(tab: _Table) -> list:
    return list(tab.header) if tab.header else [f"column {i}" for i in range(tab.ncols)]


#: how a logger writes a sample it did not get (with `missing=True`, NaN in the columns)
_MISSING = {"", "nan", "na", "n/a", "null", "none"}


def _slow_columns(tab: _Table, cols: list, clock_cols: set, missing: bool = False) -> list:
    """Parse the columns `cols` line by line; raises the first problem with its line number
    (with `missing`, a cell of `_MISSING` is NaN)."""
    names = _column_names(tab)
    split = _splitter(tab.sep)
    need = max(cols) + 1
    out = [[] for _ in cols]
    lines = tab.text[tab.body :].split("\n")
    for offset, line in enumerate(lines):
        line = line.split("#", 1)[0]  # an inline comment, as NumPy's parser drops it
        if _skip(line):
            continue
        no = tab.first_line + offset
        cells = split(line)
        if len(cells) < need:
            _fail(tab.source, f"line {no}: expected {tab.ncols} cells, found {len(cells)}")
        for j, c in enumerate(cols):
            cell = cells[c]
            if missing and cell.strip().lower() in _MISSING:
                out[j].append(math.nan)
                continue
            value = _parse_time(cell) if c in clock_cols else None
            if value is None:
                try:
                    value = float(cell)
                except ValueError:
                    what = "empty cell" if not cell.strip() else f"not a number: {cell.strip()!r}"
                    _fail(tab.source, f"line {no}, column {names[c]!r}: {what}")
            if not math.isfinite(value):
                _fail(
                    tab.source,
                    f"line {no}, column {names[c]!r}: {cell.strip()!r} is not a "
                    "finite number (NaN and infinity are not allowed)",
                )
            if abs(value) > LARGEST:
                _fail(
                    tab.source,
                    f"line {no}, column {names[c]!r}: {cell.strip()!r} is beyond the largest "
                    f"magnitude read, {LARGEST:g}: rescale the column",
                )
            out[j].append(value)
    return [np.asarray(v, dtype=float) for v in out]


def _fast_columns(tab: _Table, body: str, first: list, cols: list, missing: bool) -> list:
    """`_columns` by NumPy's parser: `body` (dates removed) with the clock's colons turned
    into separators; `ValueError` where anything does not parse."""
    clock_cols = [c for c in cols if c < len(first) and ":" in first[c]]
    if any(not _PLAIN_CLOCK.match(first[c].strip()) for c in clock_cols):
        raise ValueError("12-hour clock times or time zones")  # read line by line
    parts = [cell.count(":") for cell in first]
    index = np.concatenate([[0], np.cumsum(np.asarray(parts) + 1)])
    if any(parts):
        body = body.replace(":", " " if tab.sep is None or tab.sep == ":" else tab.sep)
    use = []
    for c in cols:
        if c >= len(first):
            raise ValueError("short row")
        use += range(index[c], index[c] + parts[c] + 1)
    data = np.loadtxt(
        io.StringIO(body),
        delimiter=tab.sep,
        usecols=use,
        comments="#",
        quotechar='"',
        ndmin=2,
        dtype=float,
    )
    out, j = [], 0
    for c in cols:
        block = data[:, j : j + parts[c] + 1]
        j += parts[c] + 1
        value = block[:, -1].copy()
        for q in range(1, parts[c] + 1):
            value += block[:, -1 - q] * 60.0**q
        if parts[c] and (np.any(block[:, :-1] < 0) or np.any(block[:, -1] < 0)):
            raise ValueError("negative clock field")
        out.append(value)
    # (NaN is a missing value where those are allowed; infinity never)
    if not all(np.all(~np.isinf(v) if missing else np.isfinite(v)) for v in out):
        raise ValueError("not finite")
    if any(np.any(np.abs(v) > LARGEST) for v in out):
        raise ValueError("too large")
    return out


def _columns(tab: _Table, cols: list, missing: bool = False) -> list:
    """Float arrays of the columns `cols` (clock times `HH:MM:SS.mmm` in seconds, a date
    before them not read; with `missing`, NaN where a cell is empty or says NaN, `_MISSING`).
    Fast path: NumPy's parser (`_fast_columns`), the dates removed (as text where every row
    has the first row's, else by their pattern: a record through midnight); any problem is
    located and reported by the line-by-line parser."""
    body, first = tab.text[tab.body :], tab.first
    dates = {m.group(0) for m in map(_DATE_PREFIX.match, first) if m}
    if dates:
        rows = body.count("\n") + (not body.endswith("\n"))
        if all(body.count(date) == rows for date in dates):  # every row's date the first's
            for date in dates:
                body = body.replace(date, "")
        else:
            body = _DATE_PREFIX.sub("", body)
        first = [_DATE_PREFIX.sub("", c) for c in first]
    try:
        return _fast_columns(tab, body, first, cols, missing)
    except ValueError:
        pass
    clock_cols = {c for c in cols if c < len(tab.first) and _CLOCK.match(tab.first[c].strip())}
    return _slow_columns(tab, cols, clock_cols, missing)


def _rows_ok(n: int, source: str, max_rows: int | None, need: int, what: str):
    if max_rows is not None and n > max_rows:
        _fail(
            source,
            f"{n:,} rows, more than the limit of {max_rows:,} rows: {_RAISE_LIMIT}",
        )
    if n < need:
        _fail(source, f"only {n} data row{'s' if n != 1 else ''}: {what} needs at least {need}")


def _line_of(tab: _Table, row: int) -> int:
    """Line number (1-based) of data row `row` (0-based); for error messages only."""
    for offset, line in enumerate(tab.text[tab.body :].split("\n")):
        if not _skip(line.split("#", 1)[0]):
            if row == 0:
                return tab.first_line + offset
            row -= 1
    return -1


def _strictly_increasing(values, tab: _Table, name: str):
    bad = np.nonzero(np.diff(values) <= 0)[0]
    if bad.size:
        i = int(bad[0])
        _fail(
            tab.source,
            f"line {_line_of(tab, i + 1)}, column {name!r}: must be strictly "
            f"increasing ({values[i + 1]:g} after {values[i]:g})",
        )


# -- peak sequences ----------------------------------------------------------------------------
#: the columns of a peak table by their names' first word (case-insensitive); the time column
#: by the raw signals' rule (`_TIME_NAME`)
_PEAK_ROLES = {
    "k": "k",
    "cycle": "cycle",
    "amplitude": "amplitude",
    "peak": "amplitude",
    "position": "position",
    "crossed": "crossed",
}


#: words after `peak` that make a column a count of the peaks, not their amplitude
_COUNTS = {"no", "nr", "number", "num", "#", "index", "idx", "count", "n"}


def _peak_role(name: str) -> str | None:
    """What a peak table's column holds, from its name: its first word, less a unit
    (`Amplitude [mm]`, `amplitude_mm`, `k`, `cycle`, `crossed`), and the time as a raw
    signal's time column is named (`_TIME_NAME`: `Time (s)`, `time_ms`, `t/min`, `Zeit [ms]`,
    `Timestamp`, `Elapsed (s)`, `Peak time`); `None` for another column, and for a count of
    the peaks (`Peak No.`, `peak #`, `peak_index`: half-swings or periods, the name does not
    say)."""
    words = re.split(r"[\s(\[_/.]+", name.strip().lower())
    if words[0] == "peak" and len(words) > 1 and words[1] in _COUNTS:
        return None
    role = _PEAK_ROLES.get(words[0])
    if (role is None or words[0] == "peak") and _TIME_NAME.search(name.strip()):
        return "time"
    return role


def _samples_of_motion(x) -> str | None:
    """What shows that a peak table's values (rows in order) are samples of an oscillation, not
    its turning points; `None` where nothing does. Both sides' turning points alternate about
    their median (successive rows cross it: gaps of one row); one side's peaks and amplitudes
    cross it where their envelope does (once, or in one band of rows where a sensor offset
    alternates them). Samples cross it twice a period all along the record, rows apart."""
    side = np.sign(x - np.median(x))
    side = side[side != 0]
    cross = np.flatnonzero(side[:-1] != side[1:])
    if cross.size < 6 or np.median(np.diff(cross)) < 2 or cross[-1] - cross[0] < side.size / 2:
        return None
    return (
        f"the values cross their median {cross.size} times in {x.size} rows, "
        f"{np.median(np.diff(cross)):.0f} rows apart"
    )


def read_peaks(path: str | os.PathLike, *, max_rows: int | None = MAX_ROWS) -> Record:
    """Read a peak sequence from a CSV file with a header line.

    Columns, by the first word of their names (case-insensitive), the time column as a raw
    signal's is named (`Time (ms)`, `time_ms`, `Zeit [ms]`, `Timestamp`; a unit at the end of
    its name is read, and times are converted to seconds): `k` (the
    half-swing index, `0` the initial deflection: successive rows of a table of both sides'
    peaks are `k`, `k + 1`) or `cycle` (full periods, for a table of one side's peaks as a
    logarithmic-decrement table lists them: `k = 2 cycle`), and/or `time` (or `t`);
    `amplitude` (or `peak`: `|x| >= 0`) or `position` (signed `x`); optional `crossed` (`0`
    where the swing did not pass `x = 0`, the tables' `*`). Other columns are ignored. Signed
    positions and amplitudes with `crossed` fix the sides; amplitudes alone give a record
    whose sides are unknown (`sides_known` False). Without `k` or `cycle`, rows are
    half-swings `0, 1, 2, ...` (both sides' peaks in turn); times are then measured from the
    first row. One side's peaks read as successive half-swings would give half the frequency
    and twice the damping, and nothing in the numbers tells the two apart: such a table needs
    its `cycle` (an amplitude table without `k`, `cycle` or `crossed` is marked,
    [`fits.ROWS_AS_HALF_SWINGS`][], and its fits warn).

    Raises `ValueError` naming the file (and the line and column where there is one) for a
    missing, unreadable, binary or empty file, a directory, a header without data, a single
    row, missing columns, two columns of one kind, non-numeric, empty or non-finite cells,
    non-increasing `k` or `time`, negative amplitudes, and more than `max_rows` rows.
    """
    text, source = _text(path, max_rows)
    tab = _table(text, source, need_header=True)
    names, times_at = {}, []
    for i, h in enumerate(tab.header):
        role = _peak_role(h)
        if role == "time":  # several: the finest, as a raw signal's (below)
            times_at.append(i)
            continue
        if role in names:
            _fail(
                source,
                f"columns {tab.header[names[role]]!r} and {h!r} both name the {role} "
                f"(found {tab.header})",
            )
        if role is not None:
            names[role] = i
    if "amplitude" not in names and "position" not in names:
        _fail(
            source,
            f"missing column: need 'amplitude' or 'position' (found {tab.header})",
            ValueError if {"k", "cycle", "crossed"} & set(names) else _NotPeakTable,
        )
    if "k" in names and "cycle" in names:
        _fail(source, "give 'k' (half-swings) or 'cycle' (full periods), not both")
    if len(times_at) == 1:
        names["time"] = times_at[0]
    elif times_at:  # (`Timestamp`, `Time_Elapsed(s)`)
        columns = _column_names(tab)
        names["time"] = columns.index(_stamps(tab, times_at, columns)[1])
    wanted = [c for c in ("k", "cycle", "time", "amplitude", "position", "crossed") if c in names]
    values = dict(zip(wanted, _columns(tab, [names[c] for c in wanted])))
    n = len(values[wanted[0]])
    _rows_ok(n, source, max_rows, 2, "a decay")
    label = {c: tab.header[names[c]].strip() for c in wanted}
    value = "position" if "position" in values else "amplitude"
    if not {"k", "cycle", "crossed"} & set(values):  # nothing says the rows are turning points
        samples = _samples_of_motion(values[value])
        if samples:
            _fail(
                source,
                f"column {label[value]!r}: {samples}: these are samples of a motion, not its "
                "turning points: read the file as a raw signal (fits.read_record(path) "
                "decides by itself, or series=True; a 'k' column makes it a peak table)",
                _NotPeakTable,
            )
    if "k" not in names and "cycle" not in names and "time" not in names:
        _fail(source, f"missing column: need 'k', 'cycle' or 'time' (found {tab.header})")

    def check(column, bad, what):
        rows = np.nonzero(bad)[0]
        if rows.size:
            _fail(
                source,
                f"line {_line_of(tab, int(rows[0]))}, column {label[column]!r}: "
                f"{values[column][rows[0]]:g}: {what}",
            )

    index = "k" if "k" in values else "cycle" if "cycle" in values else None
    if index is not None:
        k = values[index]
        check(index, (k != np.round(k)) | (k < 0), f"{index} must hold integers >= 0")
        _strictly_increasing(k, tab, label[index])
        k = k.astype(int) * (2 if index == "cycle" else 1)
    else:
        k = np.arange(n)
    times = values.get("time")
    if times is not None:
        _strictly_increasing(times, tab, label["time"])
        times = times * TIME_UNITS[_time_unit(label["time"]) or "s"]
    crossed = values.get("crossed")
    if crossed is not None:
        check("crossed", ~np.isin(crossed, (0.0, 1.0)), "crossed must hold 0 or 1")
    if "position" in values:
        record = record_from_sequence(positions=values["position"], k=k, times=times, source=source)
        record.meta["value_name"] = label[value]
        return record
    amplitudes = values["amplitude"]
    check(
        "amplitude",
        amplitudes < 0,
        "an amplitude must be >= 0 (use a 'position' column for signed values)",
    )
    record = record_from_sequence(
        amplitudes=amplitudes, crossed=crossed, k=k, times=times, source=source
    )
    record.meta["value_name"] = label[value]
    if index is None and crossed is None:  # nothing says the rows are half-swings
        record.meta["rows"] = ROWS_AS_HALF_SWINGS
    return record


def value_name(record: Record) -> str:
    """The name of the column the record's values were read from (the raw signal's, or the
    peak table's amplitude or position column), `""` where it came from arrays."""
    return (
        record.signal.signal_name
        if record.signal is not None
        else record.meta.get("value_name", "")
    )


def in_metres(record: Record, model: str = "this") -> Record:
    """`record` with its positions in metres, for models whose lengths are SI: where its value
    column's name ends with another length unit (`amplitude_mm`, `x [um]`), the positions, the
    centre, the noise and the raw signal scaled to metres, `meta["length_unit"]` the unit
    converted from; else `record` itself (a name without a unit is read in metres). A column
    named in an angle unit is a `ValueError` naming `model`."""
    name = value_name(record).strip()
    if ANGLE_UNIT.search(name):
        _fail(
            record.source,
            f"the column {name!r} holds an angle, and the {model} model's positions are "
            "lengths [m] (an angle record: --model pendulum, or oscillator in the signal's "
            "units)",
        )
    m = _LENGTH_UNIT.search(name)
    unit = _LENGTH_SPELLINGS.get(m.group(1).lower(), m.group(1).lower()) if m else "m"
    scale = LENGTH_UNITS[unit]
    if scale == 1.0:
        return record
    signal = record.signal
    if signal is not None:
        signal = dataclasses.replace(signal, y=signal.y * scale)
    return dataclasses.replace(
        record,
        positions=record.positions * scale,
        centre=record.centre * scale,
        noise=None if record.noise is None else record.noise * scale,
        signal=signal,
        meta={**record.meta, "length_unit": unit},
    )


def record_from_sequence(
    *,
    amplitudes: ArrayLike | None = None,
    positions: ArrayLike | None = None,
    crossed: ArrayLike | None = None,
    k: ArrayLike | None = None,
    times: ArrayLike | None = None,
    source: str = "",
) -> Record:
    """A [`fits.Record`][] from arrays: signed `positions`, or `amplitudes` (`|x|`) with optional
    `crossed` flags (`1` where the swing ending at that point passed `x = 0`); swing indices `k`
    (default `0, 1, ...`) and optional `times` [s], measured from the `k = 0` row if there is
    one, else taken as given (a fit aligns the record's clock with the model's by a fitted
    shift, so their origin need not be the release).

    Amplitudes without `crossed` give a record with `sides_known = False`: its positions
    alternate provisionally (as if every swing crossed), and a fit must let the model decide
    which swings passed zero."""
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
    sides_known, flags = True, None
    if positions is None:
        if np.any(values < 0):
            _fail(source, "amplitudes must be >= 0")
        flips = np.ones(int(k[-1]) + 1, dtype=bool)  # swing j (ending at k = j) crossed x = 0
        if crossed is not None:
            flags = np.asarray(crossed, dtype=float).ravel()
            if flags.shape != values.shape:
                _fail(source, "crossed and the amplitudes must have the same length")
            if not np.all(np.isin(flags, (0.0, 1.0))):
                _fail(source, "crossed must hold 0 or 1")
            flags = flags.astype(bool)
            flips[k] = flags
        else:
            sides_known = False
        flips[0] = False
        side = -np.cumprod(np.where(flips, -1.0, 1.0))
        values = side[k] * values
    elif crossed is not None:
        raise ValueError("crossed applies to amplitudes (positions carry their sides)")
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
    return Record(
        k=k,
        positions=values,
        times=times,
        source=source,
        time_origin=origin,
        sides_known=sides_known,
        crossed=flags,
    )


# -- raw signals -------------------------------------------------------------------------------
def _pick(spec, header, ncols, what, source):
    if isinstance(spec, (int, np.integer)) or (
        isinstance(spec, str) and spec.strip().lstrip("-").isdigit()
    ):
        i = int(spec)
        if not -ncols <= i < ncols:
            _fail(
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
    _fail(source, f"missing column: no {what} column named {spec!r} (columns: {header})")


def _time_candidates(tab: _Table, yi: int) -> list:
    """Columns that may hold the time: those named like a time, or holding clock times."""
    out = []
    for i in range(tab.ncols):
        if i == yi or i >= len(tab.first):
            continue
        named = tab.header is not None and _TIME_NAME.search(tab.header[i].strip())
        if named or _CLOCK.match(tab.first[i].strip()):
            out.append(i)
    return out


def _time_unit(name: str) -> str | None:
    """The unit of a time column named `name` (`TIME_UNITS`' keys) from the end of the name
    (`time_ms`, `t [ms]`, `Time (us)`); `None` where it names none."""
    m = _TIME_UNIT.search(name.strip())
    return _UNIT_SPELLINGS.get(m.group(1).lower(), "s") if m else None


def _stamps(
    tab: _Table, candidates: list, names: list, unit: str | None = None
) -> tuple[np.ndarray, str, str]:
    """The time stamps [s] from the finest of the candidate columns (the most distinct values
    among those that parse and never decrease), its name, and a note on the others and on the
    unit: `unit` (`TIME_UNITS`), else the one the column's name ends with, else seconds (clock
    times `HH:MM:SS` are always read as such). Missing stamps are NaN (`_MISSING`)."""
    parsed, first_error = [], None
    for c in candidates:
        try:
            values = _columns(tab, [c], missing=True)[0]
        except ValueError as err:
            if len(candidates) == 1:
                raise
            first_error = first_error or err
            continue
        there = np.isfinite(values)
        if not np.any(there):
            continue
        if _CLOCK.match(tab.first[c].strip()):  # clock stamps through midnight
            values[there] += 86400.0 * np.cumsum(
                np.concatenate([[0.0], np.diff(values[there]) < -43200.0])
            )
        monotone = bool(np.all(np.diff(values[there]) >= 0))
        parsed.append((c, values, monotone, np.unique(values[there]).size))
    if not parsed:
        if first_error is None:
            _fail(tab.source, f"the time column {names[candidates[0]]!r} holds no values")
        raise first_error
    usable = [p for p in parsed if p[2]] or parsed[:1]
    ti, stamps = usable[int(np.argmax([p[3] for p in usable]))][:2]  # the first of the finest
    rows = np.flatnonzero(np.isfinite(stamps))
    dt = np.diff(stamps[rows])
    if np.any(dt < 0):
        k = int(np.nonzero(dt < 0)[0][0])
        i, j = int(rows[k]), int(rows[k + 1])
        _fail(
            tab.source,
            f"line {_line_of(tab, j)}, column {names[ti]!r}: time must be "
            f"non-decreasing (goes back from {stamps[i]:.6g} to {stamps[j]:.6g})",
        )
    if stamps[rows[-1]] <= stamps[rows[0]]:
        _fail(tab.source, f"time must increase (column {names[ti]!r} is constant)")
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
    if not _CLOCK.match(tab.first[ti].strip()):
        named = unit or _time_unit(names[ti])
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
    text, source = _text(path, max_rows)
    tab = _table(text, source)
    header, ncols = tab.header, tab.ncols
    names = _column_names(tab)
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
            _fail(source, "the time and signal columns must differ")
    elif ncols == 1:
        candidates = []
    else:
        candidates = _time_candidates(tab, yi) or [0 if yi != 0 else 1]
    y = _columns(tab, [yi], missing=True)[0]
    _rows_ok(len(y), source, max_rows, 3, "a raw signal")
    stamps, tname, ignored = (
        _stamps(tab, candidates, names, time_unit) if candidates else (None, None, "")
    )
    # rows without a value (a logger's dropped samples, `_MISSING`) are left out; by row
    # number they keep their place on a clock made from the rate
    there = np.isfinite(y) if stamps is None else np.isfinite(y) & np.isfinite(stamps)
    gaps = int(np.count_nonzero(~there))
    if gaps:
        _rows_ok(int(np.count_nonzero(there)), source, None, 3, "a raw signal with values")
        if stamps is not None:
            y, stamps = y[there], stamps[there]
    try:
        t, report = recover_clock(stamps, clock=clock, rate=rate, column=tname, rows=there.size)
    except ValueError as err:
        _fail(source, str(err))
    if gaps and stamps is None:
        t, y = t[there], y[there]
    if gaps:
        first = _line_of(tab, int(np.flatnonzero(~there)[0]))
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
            _fail(
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


# -- turning points of a raw signal ------------------------------------------------------------
def _noise(t, y) -> float:
    """Robust noise level of a sampled signal [signal units].

    The smallest of MAD estimates from differences that cancel the smooth signal: the
    deviation from linear interpolation between neighbours in time (any sampling), and the 3rd
    and 4th differences of successive samples (an oversampled oscillation's curvature
    dominates the 2nd differences, not its noise; and where the stamps are wrong, the samples'
    order still holds). Each overestimates where it does not apply, so the smallest is taken.
    Never below the quantisation noise `q / sqrt(12)` of a signal read in steps of `q` (the
    smallest change between samples; the MAD of a signal that mostly repeats its value would
    be zero)."""
    if len(y) < 7:
        return 0.0
    h1, h2 = t[1:-1] - t[:-2], t[2:] - t[1:-1]
    ok = (h1 > 0) & (h2 > 0)
    interp = (y[:-2] * h2 + y[2:] * h1) / np.where(ok, h1 + h2, 1.0)
    d = (y[1:-1] - interp)[ok]
    w = np.sqrt(1 + (h1**2 + h2**2) / (h1 + h2) ** 2)[ok]  # std of d for white noise of unit std
    estimates = [1.4826 * float(np.median(np.abs(d - np.median(d)) / w))] if d.size else []
    for order in (3, 4):
        dk = np.diff(y, order)
        estimates.append(
            1.4826
            * float(np.median(np.abs(dk - np.median(dk))))
            / math.sqrt(math.comb(2 * order, order))
        )
    return max(min(estimates) if estimates else 0.0, _quantum(y) / math.sqrt(12))


def _quantum(y) -> float:
    """The smallest change between successive samples (the step of a quantised signal;
    changes below 1e-12 of the signal's size are rounding)."""
    steps = np.abs(np.diff(y))
    steps = steps[steps > 1e-12 * max(float(np.max(np.abs(y))), 1e-300)]
    return float(np.min(steps)) if steps.size else 0.0


def _despike(t, y, sigma, threshold, keep=None):
    """Replace isolated spikes: a sample farther than `threshold` noise standard deviations
    (`sigma`) from the cubic through its two neighbours on either side (at times `t`) is
    replaced by that cubic's value, unless `keep` (a mask) holds it. A smooth oscillation
    sampled `N` times per period departs from the cubic by about `(2 pi / N)^4 / 6` of its
    amplitude (4e-3 at `N = 16`, 7e-4 at 25), so this is for signals of at least 16 samples
    per period (`_SMOOTH_MIN`). (A running median of 5 samples took a swing's peak for a spike
    below about 30 samples per period: on synthetic records at 25, the extrema 4 times the
    noise off, against 0.6 times without it; on the pendulum records 60, 70 and 90p.txt, 1-10
    peak samples of swings of 30 deg.)"""
    if len(y) < 5:
        return y
    tc, others = t[2:-2], [t[:-4], t[1:-3], t[3:-1], t[4:]]
    values = [y[:-4], y[1:-3], y[3:-1], y[4:]]
    weights = []
    for j, tj in enumerate(others):
        w = np.ones_like(tc)
        for m, tm in enumerate(others):
            if m != j:
                w = w * (tc - tm) / (tj - tm)
        weights.append(w)
    cubic = sum(w * v for w, v in zip(weights, values))
    sd = sigma * np.sqrt(1.0 + sum(w * w for w in weights))
    candidate = np.zeros(y.shape, dtype=bool)
    candidate[2:-2] = np.abs(y[2:-2] - cubic) > threshold * sd
    if keep is not None:
        candidate &= ~keep
    # a spike throws its neighbours' cubics off too (unevenly spaced samples: by more than
    # itself): of the candidates within two samples the spike is the one farthest from the
    # running median of 5
    median = np.median(np.lib.stride_tricks.sliding_window_view(np.pad(y, 2, mode="edge"), 5), 1)
    score = np.where(candidate, np.abs(y - median), -1.0)
    nearby = np.max(np.lib.stride_tricks.sliding_window_view(np.pad(score, 2), 5), axis=1)
    spike = candidate & (score >= nearby)
    out = y.copy()
    out[2:-2][spike[2:-2]] = cubic[spike[2:-2]]
    return out


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


#: how far a faster oscillation's spectral line stands above the noise's median bin
_LINE = 300.0
#: the swing's harmonics that are its shape, not another oscillation (`_faster_period`)
_HARMONICS = 9
#: the weakest faster oscillation taken for one, in amplitude relative to the swing's spectral
#: peak (`_faster_period`): a sinusoid this small moves a turning point by less than 1e-4 of
#: the swing; on a signal without noise (a simulation's output) the swing's higher harmonics
#: stand far above the empty bins around them, at 1e-6 to 3e-5 of its peak
_LINE_FLOOR = 1e-4


def _faster_period(t, y) -> tuple | None:
    """`(samples per period, angular frequency [rad/s])` of an oscillation faster than the
    decay's that rides on it (mains hum, a higher mode of the structure), or `None`. The
    signal less its average over a quarter of its half-swing (from the spectrum's highest
    peak) holds the noise and what is faster; there, above 1.5 times the decay's
    frequency, a spectral line (a local peak `_LINE` times the median of the bins around it:
    white noise's highest bin is some 15 times it) is such an oscillation, away from the
    swing's own harmonics (up to the `_HARMONICS`-th, +-0.15 of the swing's frequency, and
    their skirts: the shape of a pendulum's large swings, not another oscillation) and at
    least `_LINE_FLOOR` of the swing's peak in amplitude (else, on a signal without noise, a
    higher harmonic of a kinked or chirping swing would be taken for one). A decaying higher
    mode whose power is spread over a band is not found."""
    dt = float(np.median(np.diff(t)))
    window = np.hanning(y.size)
    n = 1 << (y.size - 1).bit_length()  # (a fast length: zeros after the data)
    f = np.fft.rfftfreq(n, dt)
    power = np.abs(np.fft.rfft((y - y.mean()) * window, n)) ** 2
    slow = np.flatnonzero(f > 2 / (y.size * dt))  # (not a drift)
    if slow.size < 16:
        return None
    main = slow[np.argmax(power[slow])]  # the swing's bin
    main_half = 1 / (2 * f[main] * dt)  # [samples]
    floor = _LINE_FLOOR**2 * float(power[main])
    rest = y - _smooth(y, max(2, int(main_half // 4)))
    power = np.abs(np.fft.rfft((rest - rest.mean()) * window, n)) ** 2
    ratio = f * (2 * main_half * dt)  # (multiples of the swing's frequency)
    harmonic = (np.round(ratio) <= _HARMONICS) & (np.abs(ratio - np.round(ratio)) < 0.15)
    usable = (ratio > 1.5) & ~harmonic
    lobe = int(math.ceil(2 * n / y.size))  # the window's main lobe [bins]
    peaks = (
        np.flatnonzero(usable[1:-1] & (power[1:-1] >= power[:-2]) & (power[1:-1] >= power[2:])) + 1
    )
    for k in peaks[np.argsort(power[peaks])[::-1][:8]]:
        if k - lobe < 0 or k + lobe >= f.size or not np.all(usable[k - lobe : k + lobe + 1]):
            continue  # (on a harmonic's skirt)
        around = np.r_[max(k - 16 * lobe, 0) : k - lobe, k + lobe + 1 : k + 16 * lobe + 1]
        around = around[around < f.size]
        around = around[usable[around]]
        if around.size >= 4 and power[k] >= max(_LINE * np.median(power[around]), floor):
            break
    else:
        return None
    shift = 0.0
    if 0 < k < f.size - 1 and np.all(power[k - 1 : k + 2] > 0):
        a, b, c = np.log(power[k - 1 : k + 2])
        shift = 0.5 * (a - c) / (a - 2 * b + c) if a - 2 * b + c < 0 else 0.0
    rate = float(f[k] + shift * (f[1] - f[0]))
    return max(2, int(round(1 / (rate * dt)))), 2 * np.pi * rate


def _smooth(y, width: int) -> np.ndarray:
    """`y` averaged twice over `width` samples (a triangle of `2 width - 1`): an oscillation of
    `width` samples per period (and its multiples) removed, a much slower one kept but for
    `1 - sinc(width / P)^2` of its amplitude. Used only to find the turning points."""
    out = y
    for left in (width // 2, (width - 1) // 2):  # (the two passes' shifts cancel)
        padded = np.concatenate([[0.0], np.full(left, out[0]), out, np.full(width, out[-1])])
        sums = np.cumsum(padded)
        out = (sums[width:] - sums[:-width])[: y.size] / width
    return out


def _harmonic_noise(t, y, idx) -> float:
    """Noise level [signal units] of a signal of few samples per period, from the residuals of
    the arcs through the samples within the mean half-period of each extremum `idx` (`c0 +
    c1 cos(w tau) + c2 sin(w tau) + c3 sign(tau) (1 - cos(w tau))`, the last the dry-friction
    kink of `_refine`), each standardised by its leverage; 1.4826 times their median absolute
    value (inf with fewer than 10). The differences of `_noise` see the swings' curvature
    there: at 8 samples per period, a signal without a tail at rest, 0.04 for noise of 1e-4
    (this: 6e-4, the damping within the arcs; 0.033 for noise of 0.02)."""
    if len(idx) < 3:
        return math.inf
    hp = (t[idx[-1]] - t[idx[0]]) / (len(idx) - 1)  # (each interval is a sample period off)
    rate = math.pi / hp
    z = []
    for i in idx:
        lo, hi = np.searchsorted(t, [t[i] - hp, t[i] + hp])
        tau = t[lo:hi] - t[i]
        if tau.size < 6:
            continue
        cos, sin = np.cos(rate * tau), np.sin(rate * tau)
        basis = np.column_stack([np.ones_like(tau), cos, sin, np.sign(tau) * (1.0 - cos)])
        q, _ = np.linalg.qr(basis)
        resid = y[lo:hi] - q @ (q.T @ y[lo:hi])
        leverage = np.sum(q * q, axis=1)
        keep = leverage < 1.0 - 1e-9
        z.extend(resid[keep] / np.sqrt(1.0 - leverage[keep]))
    return 1.4826 * float(np.median(np.abs(z))) if len(z) >= 10 else math.inf


def _local_half_periods(times) -> np.ndarray:
    """Each extremum's local half-period [s]: the median of the 4 nearest intervals between
    the extrema at `times` (robust to a hold before the release)."""
    gaps = np.diff(times)
    return np.array([np.median(gaps[max(0, i - 2) : i + 2]) for i in range(len(times))])


def _samples_per_half_period(idx) -> float:
    """Mean number of samples between the successive extrema at the sample indices `idx`; inf
    with fewer than 3 extrema."""
    return (idx[-1] - idx[0]) / (idx.size - 1) if idx.size >= 3 else math.inf


#: the least samples per half-period of a signal whose turning points are extracted (a
#: sinusoid through the samples near each, `_refine_harmonic`)
_SAMPLES_MIN = 3
#: the least samples per half-period at which the swings are smooth over a few samples: isolated
#: spikes are removed (`_despike`) and the noise is measured from differences (`_noise`); below
#: it from sinusoids through the samples near each extremum (`_harmonic_noise`)
_SMOOTH_MIN = 8
_WINDOW = 0.4  #: half-width of the local fit around an extremum, in local half-periods


def _refine(t, y, i, half, peak, kink=0.0, degree=4, fast=None):
    """Time and value of the extremum near sample `i`: a least-squares polynomial of `degree`
    (a quartic by default; where fewer than `degree + 3` samples fall inside, a sinusoid:
    `_refine_harmonic`) through the samples within `0.4 half` of it, less the dry-friction kink `kink sign(tau)
    (1 - cos(pi tau / half))` about its vertex, the vertex nearest the centre, the window
    re-centred on that vertex twice. `half` is the local
    half-period [s]; `peak` says a maximum is sought (else a minimum). The sample itself is
    kept where the fit has no such vertex inside the window.

    The kink: at a turning point with Coulomb friction the friction force reverses, and the
    motion is an arc of a cosine about the centre shifted by the friction level `xF` on one
    side and by `-xF` on the other: `kink = xF` at a maximum, `-xF` at a minimum [signal
    units] (a record's level, from the decay of its extrema: `_dry_level`). A smooth quartic
    through such a turning point times it late by about `0.07 half xF / a` (`a` the
    amplitude).

    At 37 samples per half-period (the pendulum records) and noise of 0.2 % of the amplitude
    this times an extremum to about 0.2 ms (a twentieth of a sample period) and biases its value
    by less than 1e-3 of the amplitude for a sinusoid; the window is wide enough that quantised
    or flat-topped peaks still show their curvature.

    `fast` [rad/s]: the angular frequency of a faster oscillation on the signal
    (`_faster_period`): a sinusoid at it is fitted with the polynomial (its two terms, a few
    of its periods in the window), so that it does not move the vertex."""
    width = _WINDOW * half
    rate = math.pi / half  # the local angular frequency [rad/s]
    centre, value = t[i], y[i]
    for _ in range(3 if kink else 2):
        lo, hi = np.searchsorted(t, [centre - width, centre + width], side="left")
        lo, hi = max(lo, 0), min(hi + 1, len(t))
        tau = (t[lo:hi] - centre) / width
        inside = np.abs(tau) <= 1.0
        tau, ys = tau[inside], y[lo:hi][inside]
        if tau.size < degree + 3:
            return _refine_harmonic(t, y, i, half, peak, kink)
        bump = np.sign(tau) * (1.0 - np.cos(rate * width * tau))
        design = np.vander(tau, degree + 1)
        if fast is not None:
            phase = fast * width * tau
            design = np.column_stack([design, np.cos(phase), np.sin(phase)])
        c = np.linalg.lstsq(design, ys - kink * bump, rcond=None)[0][: degree + 1]
        slope = np.polyder(c)  # (coefficients highest power first)
        roots = np.roots(slope)
        roots = roots[np.abs(roots.imag) < 1e-9].real
        curv = np.polyval(np.polyder(slope), roots)
        roots = roots[(np.abs(roots) <= 1.0) & ((curv < 0) if peak else (curv > 0))]
        if roots.size == 0:
            return t[i], y[i]
        u = roots[np.argmin(np.abs(roots))]
        value = float(np.polyval(c, u) + kink * np.sign(u) * (1.0 - math.cos(rate * width * u)))
        centre = centre + u * width
    return float(centre), value


def _refine_harmonic(t, y, i, half, peak, kink=0.0):
    """`_refine` where too few samples fall in its window for a quartic (below about 16
    samples per period): a sinusoid at the local rate `w = pi / half`, `c0 + c1 cos(w tau) +
    c2 sin(w tau)`, through the samples within `half / 2` of the extremum (the motion between
    two turning points is such an arc, about a centre shifted by the dry-friction `kink` on
    either side of the vertex, subtracted as in `_refine`; with `0.75 half` neighbouring
    windows shared samples, and zeta's errors over 24 fits at 12 samples per period were 1.35
    of its standard errors), its
    vertex the extremum, the window re-centred on it twice. The sample itself is kept where
    fewer than 3 samples fall inside."""
    rate = math.pi / half
    width = 0.5 * half
    centre, value = t[i], y[i]
    for _ in range(3):
        lo, hi = np.searchsorted(t, [centre - width, centre + width], side="left")
        lo, hi = max(lo, 0), min(hi + 1, len(t))
        tau = t[lo:hi] - centre
        inside = np.abs(tau) <= width
        tau, ys = tau[inside], y[lo:hi][inside]
        if tau.size < 3:
            return t[i], y[i]
        bump = np.sign(tau) * (1.0 - np.cos(rate * tau))
        basis = np.column_stack([np.ones_like(tau), np.cos(rate * tau), np.sin(rate * tau)])
        c0, c1, c2 = np.linalg.lstsq(basis, ys - kink * bump, rcond=None)[0]
        amplitude = math.hypot(c1, c2)
        # c1 cos + c2 sin = amplitude cos(w tau - phi): a maximum at w tau = phi, a minimum at
        # phi + pi, the one nearest the window's centre
        phase = math.atan2(c2, c1) + (0.0 if peak else math.pi)
        u = (phase + math.pi) % (2 * math.pi) - math.pi
        if abs(u) > rate * width:
            return t[i], y[i]
        value = float(c0 + (amplitude if peak else -amplitude))
        centre = centre + u / rate
    return float(centre), value


def _shape_bias(x4, x6, raw, usable) -> np.ndarray:
    """The bias of the quartic's extremum values `x4` where the waveform is not quartic near
    its extrema over the fitting window (a pendulum's swings far from sinusoidal), from their
    difference with sextic fits `x6` through the same samples (unbiased, but noisier: +23 % in
    the values and +70 % in the times, measured on synthetic pendulum records with noise 0.2 %
    of the amplitude), smoothed over the record: `x4 - x6 = s f(a)` for extrema at distance
    `a` from the median centre on side `s`, `f(a) = b1 a + b3 a^3 + b5 a^5` by least squares
    over the `usable` extrema whose fits found a vertex (`raw` the extrema's samples: a fit
    that did not keeps them), the first left out (a hold before the release is no vertex,
    and a release at the signal's start is fitted from one side). Returns the bias to
    subtract (`s f(a)`, not extrapolated beyond the largest amplitude fitted) where `f` is
    significant (somewhere over the record's amplitudes more than 3 standard errors from 0),
    else zeros: where the quartic suffices its values are kept as they are.

    Measured (noise-free synthetic pendulum records, sine law, the extrema above half the
    release): the quartic overstates the amplitudes by 1.5e-3 deg released from 27 deg, 2.8e-3
    from 60 deg and 4.3e-2 from 120 deg (half the scatter of a turning point at 0.2 %
    noise there), a trend in the amplitude that a fit reads as quadratic drag."""
    x4, x6 = np.asarray(x4, dtype=float), np.asarray(x6, dtype=float)
    ok = usable & (x4 != raw) & (x6 != raw) & np.isfinite(x6)
    ok[0] = False  # the first extremum may be a hold before the release, or cut by the start
    out = np.zeros_like(x4)
    if np.count_nonzero(ok) < 12:
        return out
    c = float(np.median(_local_centres(x4))) if x4.size >= 3 else 0.0
    side, a = np.sign(x4 - c), np.abs(x4 - c)
    scale = float(np.max(a[ok]))
    u = np.minimum(a, scale) / scale  # (not extrapolated beyond the extrema fitted)
    basis = np.column_stack([u, u**3, u**5])
    d = (x4 - x6) * side  # the quartic's bias, on each side away from the centre
    coef, *_ = np.linalg.lstsq(basis[ok], d[ok], rcond=None)
    resid = d[ok] - basis[ok] @ coef
    dof = max(np.count_nonzero(ok) - 3, 1)
    cov = np.linalg.pinv(basis[ok].T @ basis[ok]) * float(resid @ resid) / dof
    grid = np.linspace(0.0, 1.0, 21)[1:]
    g = np.column_stack([grid, grid**3, grid**5])
    se = np.sqrt(np.maximum(np.einsum("ij,jk,ik->i", g, cov, g), 0.0))
    if not np.any(np.abs(g @ coef) > 3 * se):
        return out
    return side * (basis @ coef)


def _pendulum_decrements(angle) -> tuple:
    """Shapes of a pendulum's decrements per half-swing at the amplitudes `angle` [rad], each
    relative to the linear oscillator's (1 at small swings), for weak damping (from the energy
    lost over a half-swing, `dA = dE / (omega^2 sin A)`): Coulomb `A / sin A`; viscous
    `2 I1 / (pi A sin A)` with `I1 = int sqrt(2 (cos t - cos A)) dt` over `(-A, A)`; quadratic
    drag `3 (sin A - A cos A) / (A^2 sin A)`. `I1 = 4 k^2 int cos^2 p / sqrt(1 - k^2 sin^2 p)
    dp` over `(-pi/2, pi/2)`, `k = sin(A/2)` (Gauss-Legendre, 24 nodes: within 1e-12 up to 120
    deg, 1e-7 at 170)."""
    A = np.clip(np.asarray(angle, dtype=float), 1e-6, 3.0)
    nodes, weights = np.polynomial.legendre.leggauss(24)
    phi = 0.5 * math.pi * nodes
    k2 = np.sin(0.5 * A)[:, None] ** 2
    inner = np.cos(phi) ** 2 / np.sqrt(1.0 - k2 * np.sin(phi) ** 2)
    I1 = 4 * k2[:, 0] * (0.5 * math.pi) * (inner @ weights)
    s = np.sin(A)
    return A / s, 2 * I1 / (math.pi * A * s), 3 * (s - A * np.cos(A)) / (A * A * s)


def _dry_level(t, x, peak, angle_unit=None, cut=None, tail=None) -> list:
    """The dry-friction level seen at the maxima and at the minima of a decay [signal units],
    from the decay of each side's amplitudes `a` (about the local centre) over a period:
    `a[j] - a[j+1] = 4 xF g_c + c1 a g_v + c2 a^2 g_q` (Coulomb, viscous and quadratic
    decrements at `a[j]`), at least 0; 0 with fewer than 6 extrema on a side, and at most a
    quarter of the median decay over a period (all of the decay dry friction's). For a linear
    restoring law the shapes `g` are 1; for a pendulum's angle (`angle_unit` [rad per signal
    unit] given) they are its own (`_pendulum_decrements`: Coulomb's 2.4 at 120 deg), without
    which the level of a record released from 120 deg came out 3-4 times too large. The first
    extremum is left out (it may be a hold before the release).

    The centre is the least-squares line through the local centres (`_local_centres`) over
    the extrema's times `t` [s]: a sensor's zero that drifts by `d` [signal units/s] lowers
    one side's decrements by `d T` and raises the other's (`T` the period), and about a fixed
    centre took `d T / 4` from the level at the maxima and gave it to the minima (the fit's
    omega 2-4 of its standard errors off: docs/signals.md, "The level under a drifting
    zero"). A side's gain and a drift both move the local centres with time, and the extrema
    alone cannot always tell them apart (the amplitude falls linearly under dry friction
    alone); the fit can, with `asym` and `drift`. A side of fewer than 6 extrema takes the
    level of both sides' decrements per half-swing (`2 xF` each) before the `tail` (the
    extrema beyond the first swing below the floor: where a decay of few swings sticks, the
    noise's at rest); 0 where those are fewer than 5 too.

    `cut` marks extrema a saturated sensor cut off (`_clipped`): they are in the sequence, so
    that the others keep their places, and take part in neither a local centre nor a
    decrement. (Until 2026-11-28 the extrema left were passed on their own: a record clipped
    on both sides keeps a run of one side's extrema, whose "local centres" lay among them,
    and the level came out 0: the turning points were timed up to 1.1 ms late, the fit's
    omega 6 standard errors off.)"""
    t, x, peak = np.asarray(t, float)[1:], np.asarray(x, float)[1:], np.asarray(peak)[1:]
    cut = np.zeros(x.size, dtype=bool) if cut is None else np.asarray(cut, dtype=bool)[1:]
    c = np.zeros_like(x)
    whole = ~(cut[:-2] | cut[1:-1] | cut[2:])  # successive extrema, none cut off
    if np.count_nonzero(whole) >= 3:  # (a line through at least 3 local centres)
        c = np.polyval(np.polyfit(t[1:-1][whole], _local_centres(x)[whole], 1), t)

    def level(use, step):
        """The level from the decrements between the extrema `use` `step` half-swings apart
        (2: a side's, 4 xF each; 1: both sides', 2 xF each); None with fewer than 5."""
        j = np.nonzero(use & ~cut)[0]
        a = np.abs(x[j] - c[j])
        pair = np.diff(j) == step
        if np.count_nonzero(pair) < 5:
            return None
        d = (a[:-1] - a[1:])[pair]
        mid = (0.5 * (a[:-1] + a[1:]))[pair]  # (the loss rate at the pair's middle)
        shapes = np.ones((3, d.size))
        if angle_unit is not None:
            shapes = np.array(_pendulum_decrements(mid * angle_unit))
        A = np.column_stack([shapes[0], mid * shapes[1], mid**2 * shapes[2]])
        got = float(np.linalg.lstsq(A, d, rcond=None)[0][0]) / (2 * step)
        return min(max(got, 0.0), max(float(np.median(d / shapes[0])), 0.0) / (2 * step))

    # a side of fewer than 6 extrema: both sides' level (a decay that sticks after a few
    # swings; 0 until 2026-11-28: dry friction of 8 % of a0, 7 turning points, their times
    # 1-14 ms late and the fit's omega 19.92 [19.85, 19.995] for 20)
    out = [level(peak, 2), level(~peak, 2)]
    if None in out:
        both = level(np.ones(x.size, dtype=bool) if tail is None else ~np.asarray(tail)[1:], 1)
        out = [both if v is None else v for v in out]
    return [0.0 if v is None else v for v in out]


def _decays(y, idx, h, starts_at_edge: bool) -> list:
    """The free decays among a signal's extrema `idx` (hysteresis `h`): a swing more than 1.5
    times the one before it (and 2 h) was excited anew, by a tap, a pluck or a release (the
    first swing of a decay started at rest from the centre is half the next one: its start is
    no turning point). Returns `(a, b, largest swing)` per decay, its extrema `idx[a:b]`; a
    decay's first extremum much nearer the centre than the next (where the excitation found
    the mass at rest) is left out. A partial first swing at the signal's first sample
    (`starts_at_edge`) is left to the extraction's own edge rule."""
    s = np.abs(np.diff(y[idx]))
    starts = [0] + [
        j
        for j in range(1, s.size)
        if s[j] > 1.5 * s[j - 1] + 2 * h and not (starts_at_edge and j == 1)
    ]
    out = []
    for a, b in zip(starts, starts[1:] + [idx.size]):
        if 0 < a and b - a >= 4:
            centre = float(np.median(_local_centres(y[idx[a + 1 : b]])))
            if abs(y[idx[a]] - centre) < 0.5 * abs(y[idx[a + 1]] - centre):
                a += 1
        out.append((a, b, float(np.max(s[a : b - 1])) if b - a >= 2 else 0.0))
    return out


def _local_centres(x):
    """Local centre of each interior extremum: `(x[k-1] + 2 x[k] + x[k+1]) / 4`, which cancels
    the alternation and, to first order, the decay."""
    x = np.asarray(x, dtype=float)
    return (x[:-2] + 2 * x[1:-1] + x[2:]) / 4


def _clipped(t, y, idx, peak, half):
    """Which extrema `idx` (samples of `y`; `peak`: maxima) a saturated sensor cut off, and
    the levels it clipped at: `(mask, {"max": level or None, "min": level or None})`.

    A side (the maxima, or the minima) is clipped when at least two of its extrema sit on
    a flat run of samples equal to the signal's extreme value that lasts more than three
    times as long as an unclipped sinusoidal extremum of that amplitude stays within one
    quantisation step of its vertex, and more than 2.5 sample intervals. A decay reaches its
    extreme value once (at the release, or over a hold before it); a sensor at the end of its
    range reads the same value at every swing beyond it. Every extremum of a clipped side at
    the level is then cut off: its true value lies beyond."""
    quantum = _quantum(y)
    dt = float(np.median(np.diff(t)))
    centre = float(np.median(y))
    mask = np.zeros(idx.size, dtype=bool)
    levels = {"max": None, "min": None}
    for name, side, level in (("max", peak, float(np.max(y))), ("min", ~peak, float(np.min(y)))):
        at = y == level
        amplitude = max(abs(level - centre), 1e-300)
        # an unclipped vertex of amplitude a stays within q of it for (2 h / pi) sqrt(2 q / a)
        long_runs, touching = 0, []
        for j in np.nonzero(side)[0]:
            i = int(idx[j])
            if not at[i]:
                continue
            touching.append(j)
            lo, hi = i, i
            while lo > 0 and at[lo - 1]:
                lo -= 1
            while hi + 1 < y.size and at[hi + 1]:
                hi += 1
            natural = 2 * half[j] / math.pi * math.sqrt(2 * quantum / amplitude)
            long_runs += bool(t[hi] - t[lo] > max(3 * natural, 2.5 * dt))
        if long_runs >= 2:
            mask[touching] = True
            levels[name] = level
    return mask, levels


def _maxima(y, idx) -> np.ndarray:
    """Which of the alternating extrema `y[idx]` are maxima."""
    peak = np.empty(idx.size, dtype=bool)
    peak[:-1] = y[idx[:-1]] > y[idx[1:]]
    peak[-1] = not peak[-2]
    return peak


def _near_clipping(t, y, idx):
    """The samples at a saturated sensor's levels (`_clipped`, judged at the raw signal's
    extrema `idx`) and the two on either side of each: the corners of a flat run depart from
    the cubic through their neighbours like spikes, and replaced they would hide the run."""
    near = np.zeros(y.shape, dtype=bool)
    if idx.size < 3:
        return near
    _, levels = _clipped(t, y, idx, _maxima(y, idx), _local_half_periods(t[idx]))
    for level in levels.values():
        if level is not None:
            near |= y == level
    at = near.copy()
    for shift in (1, 2):
        near[shift:] |= at[:-shift]
        near[:-shift] |= at[shift:]
    return near


def _naming_other_columns(extract):
    """`extract(signal, ...)` (`extract_turning_points`, `_every_decay`), whose failure to find
    a decay names the file's other columns (the signal is the last column unless one is named:
    a trigger or a second sensor may be last)."""

    @functools.wraps(extract)
    def named(signal: Signal, *args, **kwargs):
        try:
            return extract(signal, *args, **kwargs)
        except _NoDecay as err:
            if not signal.others:
                raise
            others = ", ".join(map(repr, signal.others))
            raise ValueError(
                f"{err} (in the column {signal.signal_name!r}; the file's other "
                f"column{'s' if len(signal.others) > 1 else ''}: {others}: name the signal's "
                "with --signal-col NAME, signal_col=NAME)"
            ) from None

    return named


@_naming_other_columns
def extract_turning_points(
    signal: Signal,
    *,
    hysteresis: float | None = None,
    min_amplitude: float | None = None,
    angle_unit: float | None = None,
    decay: int | None = None,
) -> Record:
    """Turning points of a raw decaying signal, robust to irregular sampling, noise,
    quantisation, a constant offset and a few spurious extrema.

    1. the noise level `sigma` is estimated (MAD of differences that cancel the smooth signal,
       at least the quantisation noise) and isolated spikes (far from the cubic through their
       neighbours, `_despike`) are removed; a signal of fewer than 16 samples per period is
       not despiked and its noise is measured from sinusoids through the samples near each
       extremum (`_harmonic_noise`), and one of fewer than 6 is refused;
    2. extrema are found with hysteresis `h` (default `max(6 sigma, 1e-3 range)`): a turning
       point counts only once the signal has moved back from it by more than `h`; a swing
       more than 1.5 times the one before it starts a new free decay (`_decays`: a tap, a
       pluck or a release, after a quiet lead-in or during another decay), and the decay of
       the largest swing is kept, or the `decay`-th (0-based, in time order) where it is
       given (`meta["decays"]`: where each starts, the one taken and its index, where there
       are several; [`fits.read_decays`][] reads every one). An oscillation faster than the
       decay's riding on it (mains hum: a spectral line, `_faster_period`) is averaged out
       of the signal they are found on, and fitted beside the local polynomial that locates
       each (`meta["faster"]`: its period [s] and amplitude);
    3. pairs of extrema much closer in time than the median half-period (spurious wiggles) are
       dropped; each extremum is refined by a local quartic over +-0.4 local half-periods
       (sub-sample time and value; a sinusoid over +-0.5 where fewer than 7 samples fall
       inside, `_refine_harmonic`), bent by the dry-friction level that the extrema's decay
       shows (at a turning point the friction force reverses: the curvature steps), less the
       quartic's bias where the record shows one (`_shape_bias`: a pendulum's large swings
       are not quartic over the window); leading
       extrema on the same side of the centre as the next one (the mass held or nudged before
       its release) are dropped, so the record starts at the release;
    4. the record ends where the swings fall below `min_amplitude` (default `10 h`); where
       that floor would cut the decay short (swings down to 90 noise sd above a fifth of the
       largest), at 16 or more samples per half-swing, the turning points are found on the
       signal averaged over a quarter of a half-swing, its noise and so `h` lower by
       `sqrt(2 / (3 width))` (`width` the samples averaged; `meta["averaged"]` [s]), and
       located on the samples as above;
    5. extrema cut off by a saturated sensor (flat runs at the signal's extreme value at two
       or more swings, `_clipped`) are left out of the record (their `k` skipped; positions
       and times), of the dry-friction level and of the centre; `meta["clipped"]` holds the
       levels (`{"max": ..., "min": ...}`, `None` for a side not clipped), and a fit on the
       whole time series leaves out the samples at those levels.

    The first turning point is the release (`k = 0`); times are measured from it. `centre` is
    the median local centre `(x[k-1] + 2 x[k] + x[k+1]) / 4`. A release from a hold (the first
    half-swing more than 10 % longer or shorter than the second: the first extremum is then a
    flat stretch, not a sharp turning point) is timed one half-swing before the end of the
    first swing, at the hold's level; `meta` says so (`"release"`: `HELD_RELEASE`, the fits do
    not weigh its time), as it does of a release at the signal's first samples
    (`EDGE_RELEASE`: located from one side only, the fits weigh neither its position nor its
    time), and holds the `hysteresis`, the `min_amplitude`, the `angle_unit` and the
    dry-friction `kink` levels of the maxima and the minima [signal units].

    `angle_unit` [rad per signal unit]: the signal is a pendulum's angle; the dry-friction
    level is then measured with a pendulum's decrements (`_dry_level`). The fits of a model
    with an angle unit (the pendulum) extract a record again with theirs.
    The signal's clock report is `record.clock`.
    """
    return _extract(signal, _find(signal, hysteresis), min_amplitude, angle_unit, decay)


class _Found(NamedTuple):
    """What `_find` found on a signal, before any one decay is taken."""

    t: np.ndarray
    y_clean: np.ndarray  # despiked
    y_found: np.ndarray  # where the turning points were found (averaged, or `y_clean`)
    idx: np.ndarray  # the turning points' samples
    h: float  # the hysteresis
    starts_at_edge: bool
    sigma: float  # the noise of `y_found`
    per_half: float  # samples per half-swing
    width: int | None  # samples averaged over (`y_found`)
    fast: tuple | None  # (amplitude, angular frequency [rad/s]) of a faster oscillation


def _find(signal: Signal, hysteresis) -> _Found:
    """Steps 1 and 2 of `extract_turning_points` on the whole signal: its noise, spikes,
    faster oscillation and turning points (every decay's: `read_decays` takes each of them
    from one `_find`)."""
    t, y = np.asarray(signal.t, dtype=float), np.asarray(signal.y, dtype=float)
    source = signal.source
    sigma = _noise(t, y)
    span = float(np.max(y) - np.min(y))
    if span <= 0:
        _fail(source, "the signal is constant: no decay to fit", _NoDecay)
    # the extrema at the noise's hysteresis (a given `hysteresis` applies to the turning points
    # only): how many samples a swing spans, and whether the signal is too noisy for them
    fast, rate = _faster_period(t, y) or (None, None)
    if fast:  # the turning points are found on the signal without it, refined on the signal
        smoothed = _smooth(y, fast)
        fast_amp = float(np.sqrt(2) * np.std(y - smoothed))
        sigma_found = _noise(t, smoothed)
        first = _zigzag(smoothed, max(6 * sigma_found, 1e-3 * span))
    else:
        first = _zigzag(y, max(6 * sigma, 1e-3 * span))
    per_half = _samples_per_half_period(first)
    if per_half < _SAMPLES_MIN:
        _fail(
            source,
            f"about {2 * per_half:.3g} samples per period: at least {2 * _SAMPLES_MIN} are needed "
            f"to locate the turning points",
            _NoDecay,
        )
    if per_half >= _SMOOTH_MIN:  # spikes are told from the swings (`_despike`)
        y_clean = _despike(t, y, sigma, 8.0, keep=_near_clipping(t, y, first))
    else:  # the differences of `_noise` see the swings: their residuals from sinusoids
        y_clean = y
        sigma = min(sigma, _harmonic_noise(t, y, first))
    width = fast  # samples averaged over in the signal the turning points are found on
    if fast:
        sigma = sigma_found
    elif (
        per_half >= 2 * _SMOOTH_MIN
        and first.size >= 2
        and 90 * sigma > 0.2 * float(np.max(np.abs(np.diff(y_clean[first]))))
    ):
        # the noise floor (swings down to 1.5 x 10 h = 90 sigma) would cut the decay short
        # (above a fifth of its largest swing): found on the signal averaged over a quarter of
        # a half-swing, whose noise is sqrt(2 / (3 width)) of the samples' (located on the
        # samples, over +-0.4 half-swings, as ever)
        width = int(per_half // 4)
        sigma *= math.sqrt(2 / (3 * width))
    h = (
        float(hysteresis)
        if hysteresis is not None
        else max(6 * sigma, 1e-3 * float(np.max(y_clean) - np.min(y_clean)))
    )
    y_found = _smooth(y_clean, width) if width else y_clean  # (where they are found)
    idx = _zigzag(y_found, h)
    starts_at_edge = bool(idx.size and idx[0] == 0)
    # spurious wiggles: remove the closest pair while an interval is far below the median
    while idx.size >= 4:
        gaps = np.diff(t[idx])
        j = int(np.argmin(gaps))
        if gaps[j] >= 0.35 * np.median(gaps):
            break
        idx = np.delete(idx, [j, j + 1]) if j + 1 < idx.size else np.delete(idx, j)
    if idx.size < 3:
        _fail(
            source,
            f"found only {idx.size} turning points in the signal (hysteresis {h:.3g})",
            _NoDecay,
        )
    return _Found(
        t,
        y_clean,
        y_found,
        idx,
        h,
        starts_at_edge,
        sigma,
        per_half,
        width,
        (fast_amp, rate) if fast else None,
    )


def _extract(signal: Signal, found: _Found, min_amplitude, angle_unit, decay) -> Record:
    """Steps 2-6 of `extract_turning_points` for one decay of what `_find` found."""
    t, y_clean, y_found, idx, h, starts_at_edge, sigma, per_half, width, fast = found
    rate = fast[1] if fast else None
    source = signal.source
    floor = float(min_amplitude) if min_amplitude is not None else 10 * h
    decays = _decays(y_found, idx, h, starts_at_edge)
    decays = [d for d in decays if d[2] >= 2 * floor] or decays  # (none: refused below)
    if decay is None:
        decay = max(range(len(decays)), key=lambda i: decays[i][2])  # of the largest swing
    elif not 0 <= decay < len(decays):
        _fail(
            source,
            f"decay {decay} asked for, but the signal holds {len(decays)} free "
            f"decay{'s' if len(decays) > 1 else ''} (numbered from 0 in time order)",
        )
    a, b = decays[decay][:2]
    others = [float(t[idx[d[0]]]) for d in decays]
    if a > 0:
        starts_at_edge = False
    idx = idx[a:b]
    if idx.size < 3:
        _fail(source, f"decay {decay} of the signal holds only {idx.size} turning points")
    swings = np.abs(np.diff(y_found[idx]))
    small = np.nonzero(swings[int(np.argmax(swings)) :] < 1.5 * floor)[0] + int(np.argmax(swings))
    if small.size and small[0] + 3 < idx.size:  # the tail far below the floor: not refined
        idx = idx[: small[0] + 3]
    half = _local_half_periods(t[idx])
    peak = _maxima(y_clean, idx)
    clipped, clip_levels = _clipped(t, y_clean, idx, peak, half)

    def refine(kinks, degree=4):  # every extremum, (time, value) rows
        return np.array(
            [
                _refine(t, y_clean, i, hp, pk, kinks[0] if pk else -kinks[1], degree, rate)
                for i, hp, pk in zip(idx, half, peak)
            ]
        )

    # a dry-friction level bends every turning point (`_refine`): measured from the decay of
    # the extrema refined without it, then each extremum refined again with it
    refined = refine((0.0, 0.0))
    tail = np.zeros(idx.size, dtype=bool)  # beyond a swing below the floor (cut below)
    small = np.nonzero(np.abs(np.diff(refined[:, 1])) < 2 * floor)[0]
    tail[small[0] + 1 if small.size else idx.size :] = True
    kinks = _dry_level(refined[:, 0], refined[:, 1], peak, angle_unit, clipped, tail)
    if max(kinks) > 0:
        refined = refine(kinks)
    if per_half < _SMOOTH_MIN:
        # the samples' intervals are up to a sample period off (15 % of a half-period at 7
        # samples per period), and a sinusoid's vertex moves with its rate: once more with
        # the half-periods of the refined extrema
        half = _local_half_periods(refined[:, 0])
        refined = refine(kinks)
    tk, xk = refined[:, 0], refined[:, 1]
    xk = xk - _shape_bias(xk, refine(kinks, 6)[:, 1], y_clean[idx], ~clipped)
    # the first extremum's window reaches before the first sample: located from one side only
    one_sided = bool(tk[0] - t[0] < _WINDOW * half[0])
    if xk.size >= 5:
        # before the release the mass may be held, or nudged, on the release side: extrema on
        # the same side of the centre as their successor are no swings; the release is the
        # last of them
        c = np.median(_local_centres(xk[1:]))
        lead = 0
        while lead + 3 < xk.size and (xk[lead] - c) * (xk[lead + 1] - c) > 0:
            lead += 1
        if lead:
            tk, xk, starts_at_edge, one_sided = tk[lead:], xk[lead:], False, False
            clipped = clipped[lead:]
    if starts_at_edge and xk.size >= 5:
        # an extremum at the first sample is a release from rest only if it is at least as far
        # from the centre as the next one on its side (not a record that starts mid-swing).
        # Judged by the first sample itself: the local fit of an extremum at the edge is
        # one-sided, and for a record that starts mid-swing its vertex may lie far beyond the
        # data, beyond even the next swing
        # (a first sample at a saturated sensor's level is at the extremum it cut off, which
        # lies beyond the level; the vertex fitted to the next one's flat run may lie beyond it)
        c = np.median(_local_centres(xk[1:]))
        if not clipped[0] and abs(y_clean[0] - c) < 0.98 * abs(xk[2] - c):
            tk, xk, one_sided, clipped = tk[1:], xk[1:], False, clipped[1:]
    meta = {"hysteresis": h, "min_amplitude": floor, "angle_unit": angle_unit, "kink": kinks}
    if fast:
        meta["faster"] = {"period": 2 * np.pi / rate, "amplitude": fast[0]}
    elif width:
        meta["averaged"] = float(width * np.median(np.diff(t)))
    if len(others) > 1:  # several free decays: where each starts, and the one taken
        meta["decays"] = {"starts": others, "taken": others[decay], "index": decay}
    if one_sided:
        # released at (or just after) the first sample: its extremum is located from one side,
        # biased towards the centre (by 0.020 of a0 = 1 noise sd on average, 20 synthetic
        # signals sampled 0.5-6 ms apart), and timed late (1.5 ms); the fits weigh neither
        meta["release"] = EDGE_RELEASE
    if xk.size >= 4 and abs((tk[1] - tk[0]) - (tk[2] - tk[1])) > 0.1 * (tk[2] - tk[1]):
        # released from a hold: the first extremum is no sharp turning point, its time is
        # anywhere in the hold. The release is one half-swing before the first swing's end;
        # the position is the hold level just before it
        tk[0] = tk[1] - (tk[2] - tk[1])
        held = (t >= tk[0] - 0.2 * (tk[2] - tk[1])) & (t <= tk[0])
        if np.any(held):
            xk[0] = float(np.median(y_clean[held]))
        meta["release"] = HELD_RELEASE
    small = np.nonzero(np.abs(np.diff(xk)) < 2 * floor)[0]
    if small.size:
        tk, xk, clipped = tk[: small[0] + 1], xk[: small[0] + 1], clipped[: small[0] + 1]
    if xk.size < 3:
        early = float(np.median(swings[: max(3, swings.size // 4)]))
        if int(np.argmax(swings)) >= swings.size - 3 and swings.max() > 2 * early:
            # the largest swing at the end: the swings below the floor are the record's start
            _fail(
                source,
                f"the swings grow (peak to peak about {early:.3g} over the record's first quarter, "
                f"{swings.max():.3g} at its end): not a free decay (a driven or self-excited "
                f"motion?)",
                _NoDecay,
            )
        _fail(
            source,
            "fewer than 3 turning points above the amplitude floor: no decay to fit",
            _NoDecay,
        )
    centres = _local_centres(xk)
    whole = ~(clipped[:-2] | clipped[1:-1] | clipped[2:])
    centre = float(np.median(centres[whole] if np.any(whole) else centres))
    origin = float(tk[0])
    if np.any(clipped):
        meta["clipped"] = clip_levels
        if np.count_nonzero(~clipped) < 3:
            levels = ", ".join(f"{v:.6g}" for v in clip_levels.values() if v is not None)
            _fail(
                source,
                f"the signal is clipped at {levels} (a saturated sensor): fewer than 3 "
                f"turning points are not cut off",
            )
    keep = ~clipped
    return Record(
        k=np.arange(xk.size)[keep],
        positions=xk[keep],
        times=(tk - origin)[keep],
        centre=centre,
        noise=sigma,
        signal=signal,
        source=source,
        time_origin=origin,
        meta=meta,
    )


def sample_window(record: Record) -> tuple[np.ndarray, np.ndarray]:
    """`(t [s] from the release, samples)` of an extracted record's raw signal from its release
    to its last turning point, less the samples at a saturated sensor's levels
    (`meta["clipped"]`) and less a faster oscillation found on it (`meta["faster"]`: its
    least-squares sinusoid over the whole signal, as mains hum is): the data of a fit on the
    whole time series."""
    t = np.asarray(record.signal.t, dtype=float) - record.time_origin
    y = np.asarray(record.signal.y, dtype=float)
    faster = record.meta.get("faster")
    if faster:  # a stationary faster oscillation (mains hum): its least-squares sinusoid
        width = max(2, int(round(faster["period"] / np.median(np.diff(t)))))
        phase = 2 * np.pi * t / faster["period"]
        basis = np.column_stack([np.cos(phase), np.sin(phase)])
        y = y - basis @ np.linalg.lstsq(basis, y - _smooth(y, width), rcond=None)[0]
    keep = (t >= 0) & (t <= record.times[-1])
    for level in record.meta.get("clipped", {}).values():
        if level is not None:  # samples at a saturated sensor's level are no measurements
            keep &= y != level
    return t[keep], y[keep]


def read_record(
    path: str | os.PathLike,
    *,
    series: bool | None = None,
    time_col: str | int | None = None,
    signal_col: str | int | None = None,
    clock: str = "auto",
    rate: float | None = None,
    time_unit: str | None = None,
    max_rows: int | None = MAX_ROWS,
    angle_unit: float | None = None,
    window: tuple | None = None,
    decay: int | None = None,
) -> Record:
    """A [`fits.Record`][] from a file: a peak sequence ([`fits.read_peaks`][]) or the turning
    points extracted from a raw signal ([`fits.read_signal`][] for `time_col`, `signal_col`,
    `clock`, `rate`, `time_unit`, `window`, and [`fits.extract_turning_points`][] for `decay`).

    `series`: `True` for a raw signal, `False` for a peak table, `None` (default) to decide
    from the file: a raw signal where one of the raw signal's arguments is given, or where the
    file is no peak table (no header line, no amplitude or position column, or values that
    cross their median all along the file, rows apart, as samples of an oscillation do;
    a peak table's rows alternate about it or follow its envelope), else a peak table.
    """
    raw = dict(
        time_col=time_col,
        signal_col=signal_col,
        rate=rate,
        time_unit=time_unit,
        window=window,
        decay=decay,
    )
    raw_given = any(v is not None for v in raw.values()) or clock != "auto"
    not_peaks = None
    if series is None and not raw_given:
        path = _Loaded(*_text(path, max_rows))
        try:
            return read_peaks(path, max_rows=max_rows)
        except _NotPeakTable as err:
            not_peaks = str(err).removeprefix(f"{path.source}: ")
    if series or series is None:
        try:
            return extract_turning_points(
                read_signal(
                    path,
                    time_col,
                    signal_col,
                    clock,
                    rate=rate,
                    time_unit=time_unit,
                    max_rows=max_rows,
                    window=window,
                ),
                angle_unit=angle_unit,
                decay=decay,
            )
        except ValueError as err:
            if series is None and raw_given and _reads_as_peaks(path, max_rows):
                named = [n for n, v in raw.items() if v is not None]
                _peaks_with_raw_options(path, named, clock)
            if not_peaks is None or path.text.count("\n") > _PEAK_TABLE_ROWS:
                raise
            raise ValueError(
                f"{err} (read as a raw signal; as a peak table: {not_peaks})"
            ) from None
    if raw_given:
        raise ValueError(
            "time_col, signal_col, clock, rate, time_unit, window and decay apply to raw "
            "signals (series=True)"
        )
    return read_peaks(path, max_rows=max_rows)


def _peaks_with_raw_options(path, named: list, clock: str = "auto"):
    """Raise the error for a peak table read with the raw-signal options `named` (and `clock`
    where it is not `"auto"`)."""
    named = [n for n in named if n != "clock"] + (["clock"] if clock != "auto" else [])
    flags = ", ".join("--" + n.replace("_", "-") for n in named)
    several = len(named) > 1
    source = path.source if isinstance(path, _Loaded) else os.fspath(path)
    raise ValueError(
        f"{source}: a table of turning points, but the raw-signal option"
        f"{'s' if several else ''} {', '.join(named)} ({flags} on the command line) "
        f"{'were' if several else 'was'} given: leave {'them' if several else 'it'}"
        " out to read the table"
    ) from None


def _reads_as_peaks(path, max_rows) -> bool:
    """Whether `path` reads as a peak table (`read_peaks` without an error)."""
    try:
        read_peaks(path, max_rows=max_rows)
    except (ValueError, _NotPeakTable):
        return False
    return True


def read_decays(path: str | os.PathLike, **kwargs) -> list:
    """Every free decay of a raw signal (repeated taps or releases in one file), one
    [`fits.Record`][] each, in time order: fitted together with shared parameters
    (`fits.fit(records, ..., shared=("omega", "zeta", "xF"))`), each keeps its own release
    amplitude and offset. `kwargs` as [`fits.read_record`][]'s for raw signals (not
    `series`, not `decay`)."""
    for name in ("series", "decay"):
        if name in kwargs:
            raise ValueError(f"read_decays reads raw signals, every decay: no {name}=")
    angle_unit = kwargs.pop("angle_unit", None)
    try:
        return _every_decay(read_signal(path, **kwargs), angle_unit)
    except ValueError:
        if _reads_as_peaks(path, kwargs.get("max_rows", MAX_ROWS)):
            named = [n for n, v in kwargs.items() if v is not None and n != "max_rows"]
            _peaks_with_raw_options(path, ["decay", *named], kwargs.get("clock", "auto"))
        raise


@_naming_other_columns
def _every_decay(signal: Signal, angle_unit) -> list:
    """`extract_turning_points` of every decay of `signal`, the signal searched once."""
    found = _find(signal, None)
    first = _extract(signal, found, None, angle_unit, None)
    decays = first.meta.get("decays")
    if decays is None:
        return [first]
    return [
        first if i == decays["index"] else _extract(signal, found, None, angle_unit, i)
        for i in range(len(decays["starts"]))
    ]
