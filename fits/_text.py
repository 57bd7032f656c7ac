"""Text files as tables: encodings, separators, header lines, columns, units and clock times.

Everything here is NumPy (no JAX): it runs once per file, before the fit.
"""

from __future__ import annotations

import io
import math
import os
import re
from dataclasses import dataclass

import numpy as np

from vmj.cli._options import LARGEST

MAX_ROWS = 2_000_000
"""Largest number of data rows read by default (about 2 hours at 259 Hz, 33 minutes at 1 kHz):
beyond it a file is refused before it is read, unless `max_rows` is raised or `None`."""

#: a date before a clock time (`2026-11-27`, `2026/11/27`, `27.11.2026`, `11/27/2026`); the
#: date itself is not read: a record's clock times are unwrapped through midnight
_DATE = r"(?:\d{4}[-/.]\d{1,2}[-/.]\d{1,2}|\d{1,2}[-/.]\d{1,2}[-/.]\d{2,4})"
_DATE_PREFIX = re.compile(rf"{_DATE}(?:T|\s+)(?=\d{{1,2}}:)")
#: clock times `[date ]HH:MM:SS.mmm` or `MM:SS.mmm`, 12-hour (`AM`/`PM`) or with a time zone
CLOCK = re.compile(
    rf"^({_DATE}(?:T|\s+))?(?:(\d+):)?(\d+):(\d+(?:\.\d*)?)\s*([AaPp][Mm])?"
    r"(?:Z|[+-]\d\d:?\d\d)?$"
)
#: clock times as the fast reader takes them (`HH:MM:SS.mmm`, `MM:SS.mmm`)
_PLAIN_CLOCK = re.compile(r"^(?:\d+:)?\d+:\d+(?:\.\d*)?$")
TIME_NAME = re.compile(
    r"time|stamp|elapsed|zeit|^t$|^t[\s(\[_/]|^sec|[(\[](?:s|ms|us|µs|ns|min)[)\]]", re.IGNORECASE
)


def unit_at_end(spellings: str) -> re.Pattern:
    """The pattern of a unit, one of the `|`-separated regular-expression `spellings`, at the
    end of a column's name (`time_ms`, `t [ms]`, `Time (us)`, `t/min`, `Angle(rad)`, `x in
    deg`); its group 1 is the spelling found."""
    return re.compile(rf"(?:^|[\s_(\[/,-])(?:in\s+)?({spellings})\s*[)\]]?\s*$", re.IGNORECASE)


#: a time column's unit at the end of its name
TIME_UNIT = unit_at_end("ns|us|µs|μs|usec|ms|msec|s|sec|secs|seconds?|min|minutes?")
TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9, "min": 60.0}
"""Units of a raw signal's time column, in seconds (`read_signal`'s `time_unit`)."""
UNIT_SPELLINGS = {
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
LENGTH_UNIT = unit_at_end("nm|um|µm|μm|mm|cm|dm|m|in|inch|inches|ft|feet|foot")
#: an angle unit at the end of a value column's name (`Angle(deg)`, `theta_rad`)
ANGLE_UNIT = unit_at_end("mrad|rad|radians?|deg|degrees?|°")
LENGTH_SPELLINGS = {
    "µm": "um",
    "μm": "um",
    "inch": "in",
    "inches": "in",
    "feet": "ft",
    "foot": "ft",
}


class NotPeakTable(ValueError):
    """`read_peaks`' refusal of a file that is no peak table: no header line, no amplitude or
    position column, or values that are samples of a motion (`read_record` reads it as a raw
    signal instead)."""


def fail(source: str, message: str, error: type = ValueError):
    raise error(f"{source}: {message}" if source else message)


# -- text files --------------------------------------------------------------------------------
def _decode(data: bytes, source: str) -> str:
    """Text of a file's bytes: UTF-16 with its byte-order mark, else UTF-8 (an optional BOM
    dropped), else Windows-1252; a file with NUL bytes or many control characters is binary."""
    if data[:2] in (b"\xff\xfe", b"\xfe\xff"):
        try:
            return data.decode("utf-16")
        except UnicodeDecodeError:
            fail(source, "not a readable text file (a UTF-16 byte-order mark, then invalid UTF-16)")
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
        fail(
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
PEAK_TABLE_ROWS = 200


@dataclass(frozen=True)
class Loaded:
    """A file's text as `load_text` returned it, for a second reader (`read_record` tries the peak
    table, then the raw signal) without reading the file again."""

    text: str
    source: str


def load_text(path_or_text, max_rows: int | None = None) -> tuple[str, str]:
    """(contents with `\\n` line ends, source name) of a path, or of literal text given as
    `io.StringIO`. Refuses a file estimated to hold more than `max_rows` lines."""
    if isinstance(path_or_text, Loaded):
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
                        fail(
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
    """Seconds since midnight of a clock time (`CLOCK`), or `None`."""
    m = CLOCK.match(text.strip())
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
            (re.fullmatch(_DATE, groups[-1][-1]) and CLOCK.match(w))
            or (w.lower() in ("am", "pm") and CLOCK.match(" ".join(groups[-1])))
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
class Table:
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


def parse_table(text: str, source: str, *, need_header: bool = False) -> Table:
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
            fail(
                source,
                f"line {no}: expected a header line naming the columns, found "
                f"numbers: {line.strip()!r}",
                NotPeakTable,
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
            fail(
                source,
                f"line {no}: {len(cells)} cells, but the header names only "
                f"{len(hdr)} column{'s' if len(hdr) != 1 else ''}: {hdr}",
            )
        ncols = len(hdr) if hdr else len(cells)
        return Table(text, source, hdr, sep, ncols, start, no, cells)
    if not texts:
        fail(source, "the file is empty")
    for line in texts[1:]:  # rows of numbers and words: a column of text
        cells = [c for c in _splitter(_data_cells(line)[0])(line) if c]
        words = [c for c in cells if not _is_number(c)]
        if words and len(words) < len(cells):
            fail(
                source,
                f"no row of numbers only: {line.strip()!r} holds text ({words[0]!r}); the "
                "columns must be numbers (remove a column of notes)",
            )
    fail(source, "the file has a header but no data rows")


def column_names(tab: Table) -> list:
    return list(tab.header) if tab.header else [f"column {i}" for i in range(tab.ncols)]


#: how a logger writes a sample it did not get (with `missing=True`, NaN in the columns)
_MISSING = {"", "nan", "na", "n/a", "null", "none"}


def _slow_columns(tab: Table, cols: list, clock_cols: set, missing: bool = False) -> list:
    """Parse the columns `cols` line by line; raises the first problem with its line number
    (with `missing`, a cell of `_MISSING` is NaN)."""
    names = column_names(tab)
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
            fail(tab.source, f"line {no}: expected {tab.ncols} cells, found {len(cells)}")
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
                    fail(tab.source, f"line {no}, column {names[c]!r}: {what}")
            if not math.isfinite(value):
                fail(
                    tab.source,
                    f"line {no}, column {names[c]!r}: {cell.strip()!r} is not a "
                    "finite number (NaN and infinity are not allowed)",
                )
            if abs(value) > LARGEST:
                fail(
                    tab.source,
                    f"line {no}, column {names[c]!r}: {cell.strip()!r} is beyond the largest "
                    f"magnitude read, {LARGEST:g}: rescale the column",
                )
            out[j].append(value)
    return [np.asarray(v, dtype=float) for v in out]


def _fast_columns(tab: Table, body: str, first: list, cols: list, missing: bool) -> list:
    """`read_columns` by NumPy's parser: `body` (dates removed) with the clock's colons turned
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


def read_columns(tab: Table, cols: list, missing: bool = False) -> list:
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
    clock_cols = {c for c in cols if c < len(tab.first) and CLOCK.match(tab.first[c].strip())}
    return _slow_columns(tab, cols, clock_cols, missing)


def rows_ok(n: int, source: str, max_rows: int | None, need: int, what: str):
    if max_rows is not None and n > max_rows:
        fail(
            source,
            f"{n:,} rows, more than the limit of {max_rows:,} rows: {_RAISE_LIMIT}",
        )
    if n < need:
        fail(source, f"only {n} data row{'s' if n != 1 else ''}: {what} needs at least {need}")


def line_of(tab: Table, row: int) -> int:
    """Line number (1-based) of data row `row` (0-based); for error messages only."""
    for offset, line in enumerate(tab.text[tab.body :].split("\n")):
        if not _skip(line.split("#", 1)[0]):
            if row == 0:
                return tab.first_line + offset
            row -= 1
    return -1


def strictly_increasing(values, tab: Table, name: str):
    bad = np.nonzero(np.diff(values) <= 0)[0]
    if bad.size:
        i = int(bad[0])
        fail(
            tab.source,
            f"line {line_of(tab, i + 1)}, column {name!r}: must be strictly "
            f"increasing ({values[i + 1]:g} after {values[i]:g})",
        )
