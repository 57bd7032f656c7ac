"""Raw measured signals: the sample clock behind arrival-time stamps, turning points on the
recovered clock, the sensor's offset and asymmetry starting values, amplitude-only records, and
a clear error for every bad input file. NumPy only (no JAX compilation): fast."""

import io
import json
import math
import os

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

import fits
from fits._extract import _noise

HERE = os.path.dirname(__file__)
P80 = os.path.join(HERE, "..", "fits", "data", "80P.txt")
RATE = 259.37  #: synthetic sampling rate [Hz], near the pendulum records'


# -- synthetic records ---------------------------------------------------------------------------
def arrival_stamps(
    n,
    rate,
    seed,
    *,
    drop_rows=(),
    lost_packets=(),
    quantum=1e-3,
    t_start=1000.0,
    jitter=0.3e-3,
    wander=1e-3,
    read=6e-4,
    busy=(),
):
    """A uniform sampler at `rate` whose rows reach the computer in packets (13-21 rows, now and
    then 1-2): the last row of a packet arrives 2 ms + an exponential latency (scale `jitter`)
    + a slow wander after it was sampled, the earlier rows were read `read` apart before it;
    stamps rounded to `quantum`. `drop_rows` and `lost_packets` (whole packets) never arrive.
    `busy`: `(start, length)` pairs [s from the first sample] when the computer stutters: each
    packet is then held up, with probability 0.6, by 5-50 ms (rows never overtake each other).

    Returns `(true sample times, stamps, packet index of every kept row)`."""
    rng = np.random.default_rng(seed)
    s = t_start + np.arange(n) / rate
    stamps = np.empty(n)
    packet = np.empty(n, dtype=int)
    bounds, i = [], 0
    while i < n:
        size = int(rng.integers(13, 22)) if rng.random() > 0.1 else int(rng.integers(1, 3))
        j = min(i + size, n)
        lag = 2e-3 + rng.exponential(jitter) + wander * math.sin(2 * math.pi * s[j - 1] / 10.0)
        stamps[i:j] = s[j - 1] + lag - read * np.arange(j - i)[::-1]
        packet[i:j] = len(bounds)
        bounds.append((i, j))
        i = j
    for start, length in busy:
        for i, j in bounds:
            if t_start + start <= stamps[j - 1] < t_start + start + length and rng.random() < 0.6:
                stamps[i:j] += rng.uniform(5e-3, 50e-3)
        stamps = np.maximum.accumulate(stamps)
    keep = np.ones(n, dtype=bool)
    keep[list(drop_rows)] = False
    for p in lost_packets:
        keep[slice(*bounds[p])] = False
    if quantum:
        stamps = np.round(stamps / quantum) * quantum
    return s[keep], stamps[keep], packet[keep]


def _clock_text(seconds):
    h = int(seconds // 3600)
    m = int((seconds - 3600 * h) // 60)
    return f"{h:02d}:{m:02d}:{seconds - 3600 * h - 60 * m:06.3f}"


def _regularity(times):
    """Robust scatter of the half-periods about their slow trend [s]: the MAD of successive
    differences of the half-periods, over sqrt(2)."""
    d = np.diff(np.diff(times))
    return 1.4826 * float(np.median(np.abs(d - np.median(d)))) / math.sqrt(2)


# -- the sample clock ----------------------------------------------------------------------------
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_arrival_stamps_give_the_uniform_clock(seed):
    s, stamps, _ = arrival_stamps(8000, RATE, seed)
    t, report = fits.recover_clock(stamps, column="Timestamp")
    assert report["method"] == "envelope" and report["stamps"] == "arrival"
    assert abs(report["rate_hz"] / RATE - 1) < 1e-4
    assert report["dropped"] == 0 and report["rows"] == 8000
    err = (t - s) - np.median(t - s)  # the constant latency is not observable
    assert np.max(np.abs(err)) < 0.25 / RATE
    assert np.all(t <= stamps + 1e-12)  # no row sampled after it arrived
    assert report["t0"] == pytest.approx(t[0])
    assert 0 < report["jitter_s"] < 2e-3
    json.dumps(report)


def test_harsh_latency_no_false_drops():
    """Latency scattered over a whole sample period (exponential, 2 ms): the rate still within
    1e-4 and no dropped samples invented."""
    s, stamps, _ = arrival_stamps(8000, RATE, 5, jitter=2e-3)
    t, report = fits.recover_clock(stamps)
    assert report["dropped"] == 0
    assert abs(report["rate_hz"] / RATE - 1) < 1e-4
    err = (t - s) - np.median(t - s)
    assert np.max(np.abs(err)) < 0.25 / RATE


@pytest.mark.parametrize("seed", [0, 6, 12])
def test_a_busy_computer_is_no_dropped_sample(seed):
    """The computer stutters three times for 0.6 s (most packets held up by 5-50 ms) while the
    latency wanders by +-4 ms (a period): those bursts lie far above the envelope for a while
    and must not look like dropped samples."""
    s, stamps, _ = arrival_stamps(
        8000, RATE, seed, wander=4e-3, busy=((5.0, 0.6), (15.0, 0.6), (25.0, 0.6))
    )
    t, report = fits.recover_clock(stamps)
    assert report["dropped"] == 0
    assert abs(report["rate_hz"] / RATE - 1) < 1e-4
    err = (t - s) - np.median(t - s)
    assert np.max(np.abs(err)) < 0.5 / RATE  # the wander itself is a period wide


@pytest.mark.parametrize("seed", [0, 3])
def test_dropped_samples_and_a_lost_packet(seed):
    s, stamps, packet = arrival_stamps(
        8000, RATE, seed, drop_rows=(1000, 5000, 5001), lost_packets=(200,)
    )
    n_true = int(round((s[-1] - s[0]) * RATE)) + 1
    t, report = fits.recover_clock(stamps)
    assert report["dropped"] == n_true - s.size
    assert abs(report["rate_hz"] / RATE - 1) < 1e-4
    err = (t - s) - np.median(t - s)
    # a row lost inside a packet cannot be placed within it from the stamps: the recovered
    # clock counts it at the start of that packet, so only that packet's earlier rows are off
    gaps = np.nonzero(np.diff(np.round((s - s[0]) * RATE)) > 1)[0] + 1
    suspect = np.isin(packet, packet[gaps])
    assert np.max(np.abs(err[~suspect])) < 0.25 / RATE
    assert np.mean(suspect) < 0.01


@settings(max_examples=15)
@given(rate=st.floats(50.0, 2000.0), seed=st.integers(0, 10_000))
def test_recovered_rate_property(rate, seed):
    """Any rate, any seed: the rate within 1e-4 and every sample time within a quarter period,
    for stamps whose resolution and latency scatter are a tenth of a period and rows read at 6
    times the sampling rate (8000 samples, about 470 packets)."""
    s, stamps, _ = arrival_stamps(
        8000, rate, seed, quantum=0.1 / rate, jitter=0.1 / rate, wander=0.0, read=1 / (6 * rate)
    )
    t, report = fits.recover_clock(stamps)
    assert report["method"] == "envelope"
    assert abs(report["rate_hz"] / rate - 1) < 1e-4
    err = (t - s) - np.median(t - s)
    assert np.max(np.abs(err)) < 0.25 / rate


def test_genuine_uniform_stamps_are_kept():
    rng = np.random.default_rng(1)
    m = np.delete(np.arange(5000.0), [100, 2000, 2001, 2002])  # 4 samples missing
    stamps = 5.0 + m / 333.0 + rng.normal(0, 1e-5, m.size)
    t, report = fits.recover_clock(stamps)
    assert t is None  # kept
    assert report["method"] == "stamps" and report["stamps"] == "uniform"
    assert report["dropped"] == 4 and abs(report["rate_hz"] / 333.0 - 1) < 1e-6
    assert report["jitter_s"] == pytest.approx(1e-5, rel=0.1)
    grid, report = fits.recover_clock(stamps, clock="uniform")
    assert report["method"] == "grid"
    np.testing.assert_allclose(grid, 5.0 + m / 333.0, atol=2e-6)
    grid, report = fits.recover_clock(stamps, rate=333.0)
    assert report["method"] == "rate" and report["dropped"] == 4
    np.testing.assert_allclose(grid, 5.0 + m / 333.0, atol=2e-6)
    # stamps rounded to 1 ms (a quarter of the 3.9 ms period): still uniform
    t, report = fits.recover_clock(np.round(5.0 + m / RATE, 3))
    assert report["stamps"] == "uniform" and report["dropped"] == 4


def test_irregular_stamps_are_kept_or_lined_up_on_request():
    stamps = np.cumsum(np.random.default_rng(2).uniform(0.5e-3, 6e-3, 3000))
    t, report = fits.recover_clock(stamps)
    assert t is None and report["stamps"] == "irregular" and report["jitter_s"] is None
    t, report = fits.recover_clock(stamps, clock="uniform")
    assert report["method"] == "line" and np.allclose(np.diff(t), np.diff(t)[0])
    t, report = fits.recover_clock(stamps, rate=300.0)
    assert report["method"] == "rate" and np.allclose(np.diff(t), 1 / 300.0)
    t, report = fits.recover_clock(None, rate=100.0, rows=5)
    assert report["stamps"] == "none" and np.allclose(t, np.arange(5) / 100.0)


def test_thinned_arrival_stamps_are_irregular_with_a_hint_of_their_clock():
    """Every 10th row of arrival stamps: 1-2 rows of each packet are left, so the stamps no
    longer come in bursts and are kept as irregular; they stay within a few intervals of the
    sampler's clock (a genuinely irregular sampler's wander like a random walk), so the report
    names that clock and how to use it. Irregular intervals (uniform or exponential) get no
    such hint."""
    s, stamps, _ = arrival_stamps(8000, RATE, 7)
    t, report = fits.recover_clock(stamps[::10])
    assert t is None and report["stamps"] == "irregular"
    assert abs(report["uniform_rate_hz"] / (RATE / 10) - 1) < 1e-3
    assert report["uniform_max_s"] < 5 * 10 / RATE and "--rate HZ" in report["message"]
    rng = np.random.default_rng(3)
    for intervals in (rng.uniform(0.5e-3, 6e-3, 3000), rng.exponential(4e-3, 764)):
        _, report = fits.recover_clock(np.cumsum(intervals))
        assert report["stamps"] == "irregular" and "uniform_rate_hz" not in report


def test_given_rate_on_arrival_stamps():
    s, stamps, _ = arrival_stamps(6000, RATE, 4)
    t, report = fits.recover_clock(stamps, rate=RATE)
    assert report["method"] == "rate" and report["rate_hz"] == RATE
    err = (t - s) - np.median(t - s)
    assert np.max(np.abs(err)) < 0.25 / RATE


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"clock": "wall"}, "clock must be one of"),
        ({"rate": -3.0}, "rate must be a positive number"),
        ({"rate": "fast"}, "rate must be a positive number"),
        ({"clock": "stamps", "rate": 100.0}, "cannot be combined"),
    ],
)
def test_clock_argument_errors(kwargs, message):
    with pytest.raises(ValueError, match=message):
        fits.recover_clock(np.arange(10.0), **kwargs)
    with pytest.raises(ValueError, match="no time column"):
        fits.recover_clock(None)


# -- the public pendulum record ------------------------------------------------------------------
@pytest.fixture(scope="module")
def p80():
    return fits.read_record(P80, series=True), fits.read_record(P80, series=True, clock="stamps")


def test_80P_clock(p80):
    record, stamped = p80
    report = record.clock
    assert report["method"] == "envelope" and report["column"] == "Timestamp"
    assert 259.4 < report["rate_hz"] < 259.8  # measured 259.596 Hz
    assert report["dropped"] == 0 and report["rows"] == 7625
    assert "Time_Elapsed(s)" in report["message"]  # the quantised column, ignored
    json.dumps(report)
    assert stamped.clock["method"] == "stamps"
    # the half-periods: 0.23 ms scatter on the recovered clock, 32 ms on the arrival stamps
    fine, raw = _regularity(record.times), _regularity(stamped.times)
    assert fine < 0.5e-3 and raw > 30 * fine
    assert 0.1440 < np.median(np.diff(record.times)) < 0.1450


def test_80P_quantised_column_alone_gives_the_same_clock(tmp_path):
    """`Time_Elapsed(s)` alone (steps of 51-70 ms, all rows of a burst equal): the envelope of
    this coarse column gives the same clock as the millisecond stamps, within 0.5 period."""
    fine = fits.read_signal(P80)
    coarse = fits.read_signal(P80, time_col="Time_Elapsed(s)")
    assert coarse.clock_report["stamps"] == "arrival" and coarse.clock_report["dropped"] == 0
    assert abs(coarse.clock_report["rate_hz"] / fine.clock_report["rate_hz"] - 1) < 1e-4
    assert np.ptp(coarse.t - fine.t) < 0.5 / fine.clock_report["rate_hz"]


# -- turning points on the recovered clock -------------------------------------------------------
def _decay_file(tmp_path, seed=0, quantum=0.01):
    """A released, viscously damped oscillation (omega 21.8 rad/s, 20 deg, offset 1.5 deg,
    noise 0.04 deg) sampled at RATE with arrival stamps, written like the pendulum records;
    returns the path and the true turning points (times from the release, values)."""
    omega, lam, a0, offset = 21.8, 0.06, 20.0, 1.5
    hold = 0.3
    s, stamps, _ = arrival_stamps(int(12 * RATE), RATE, seed, t_start=57600.0, wander=0.0)
    tau = s - s[0] - hold
    wd = math.sqrt(omega**2 - lam**2)
    x = -a0 * np.exp(-lam * tau) * (np.cos(wd * tau) + lam / wd * np.sin(wd * tau))
    x[tau < 0] = -a0
    rng = np.random.default_rng(seed)
    y = np.round((x + offset + rng.normal(0, 0.04, s.size)) / quantum) * quantum
    k = np.arange(int(11.5 * wd / math.pi))
    truth_t = k * math.pi / wd
    truth_x = offset - a0 * np.exp(-lam * truth_t) * (-1.0) ** k
    path = tmp_path / f"decay{seed}.txt"
    with open(path, "w") as fh:
        fh.write("Timestamp, Angle(deg)\n----------\n")
        fh.write("\n".join(f"{_clock_text(a)}, {b:.2f}" for a, b in zip(stamps, y)))
    return str(path), truth_t, truth_x


def test_turning_points_on_the_recovered_clock(tmp_path):
    path, truth_t, truth_x = _decay_file(tmp_path)
    rec = fits.read_record(path, series=True)
    assert rec.clock["method"] == "envelope"
    n = min(len(rec), len(truth_t))
    assert n >= 40
    dt = rec.times[:n] - truth_t[:n]
    assert np.sqrt(np.mean(dt**2)) < 0.3e-3 and np.max(np.abs(dt)) < 1e-3
    assert np.max(np.abs(rec.positions[:n] - truth_x[:n])) < 0.05  # 1.25 noise levels
    assert abs(rec.centre - 1.5) < 0.02
    stamped = fits.read_record(path, series=True, clock="stamps")
    m = min(len(stamped), n)
    assert np.sqrt(np.mean((stamped.times[:m] - truth_t[:m]) ** 2)) > 10 * np.sqrt(np.mean(dt**2))


def test_noise_estimate_on_an_oversampled_signal():
    t = np.arange(0, 20, 1 / RATE)
    clean = 20 * np.exp(-0.05 * t) * np.cos(21.8 * t)
    rng = np.random.default_rng(3)
    assert _noise(t, clean + rng.normal(0, 0.02, t.size)) == pytest.approx(0.02, rel=0.15)
    q = 360 / 4096  # a 12-bit angle encoder, no other noise: most samples repeat their value
    quantised = np.round(clean / q) * q
    assert q / math.sqrt(12) <= _noise(t, quantised) < 1.25 * q / math.sqrt(12)


# -- the sensor: offset and asymmetry starting values --------------------------------------------
def _sensor_record(offset, asym, seed, noise=0.002, a0=20.0, r=0.97, xF=0.02):
    amp = [a0]
    while amp[-1] > 0.5:
        amp.append(r * amp[-1] - (1 + r) * xF)
    amp = np.array(amp[:-1])
    x = np.where(np.arange(amp.size) % 2 == 0, -amp, amp)  # released at -a0
    y = offset + np.where(x > 0, (1 + asym) * x, (1 - asym) * x)
    y = y + np.random.default_rng(seed).normal(0, noise * a0, amp.size)
    return fits.record_from_sequence(positions=y)


@pytest.mark.parametrize("offset, asym", [(2.0, 0.03), (-1.0, -0.05), (0.0, 0.0)])
def test_sensor_start_recovers_offset_and_asym(offset, asym):
    json.dumps(fits.sensor_start(_sensor_record(offset, asym, 0)))
    for seed in range(3):
        est = fits.sensor_start(_sensor_record(offset, asym, seed))
        assert abs(est["asym"] - asym) < 4 * est["asym_stderr"] < 0.006
        assert abs(est["offset"] - offset) < 4 * est["offset_stderr"] < 0.05
    # the standard errors are honest: over 100 seeds the spread matches them within 25 %
    ests = [fits.sensor_start(_sensor_record(offset, asym, s)) for s in range(100)]
    spread = np.std([e["asym"] for e in ests])
    assert spread == pytest.approx(np.mean([e["asym_stderr"] for e in ests]), rel=0.25)


@settings(max_examples=20)
@given(shift=st.floats(-50, 50), scale=st.floats(0.1, 10.0), seed=st.integers(0, 1000))
def test_sensor_start_is_equivariant(shift, scale, seed):
    """Moving the sensor's zero moves the offset, rescaling the reading rescales it; the
    asymmetry (a ratio) changes with neither."""
    rec = _sensor_record(1.0, 0.02, seed)
    moved = fits.record_from_sequence(positions=scale * rec.positions + shift)
    a, b = fits.sensor_start(rec), fits.sensor_start(moved)
    assert b["asym"] == pytest.approx(a["asym"], abs=1e-9)
    assert b["offset"] == pytest.approx(scale * a["offset"] + shift, abs=1e-9 * (1 + abs(shift)))


def test_sensor_start_on_a_signal_and_its_limits(tmp_path):
    path, _, _ = _decay_file(tmp_path, seed=1)
    est = fits.sensor_start(fits.read_signal(path))
    assert abs(est["offset"] - 1.5) < 0.03 and abs(est["asym"]) < 0.005
    few = fits.record_from_sequence(positions=[-10.0, 9.0, -8.1, 7.3])
    est = fits.sensor_start(few)
    assert est["asym"] == 0.0 and "not identifiable" in est["message"]
    with pytest.raises(ValueError, match="amplitudes without sides"):
        fits.sensor_start(fits.record_from_sequence(amplitudes=[10.0, 9.0, 8.1, 7.3]))


# -- amplitude-only records ----------------------------------------------------------------------
def test_amplitude_only_records_have_unknown_sides(tmp_path):
    p = tmp_path / "a.csv"
    p.write_text("k,amplitude\n0,6\n1,5\n2,4\n3,1\n")
    rec = fits.read_peaks(str(p))
    assert rec.sides_known is False and rec.crossed is None
    np.testing.assert_array_equal(rec.amplitudes, [6, 5, 4, 1])
    p.write_text("k,amplitude,crossed\n0,6,1\n1,5,1\n2,4,1\n3,1,0\n")
    rec = fits.read_peaks(str(p))
    assert rec.sides_known is True and rec.crossed.tolist() == [True, True, True, False]
    assert rec.positions.tolist() == [-6, 5, -4, -1]
    p.write_text("k,position\n0,-6\n1,5\n2,-4\n3,-1\n")
    rec = fits.read_peaks(str(p))
    assert rec.sides_known is True and rec.crossed is None
    with pytest.raises(ValueError, match="crossed applies to amplitudes"):
        fits.record_from_sequence(positions=[-6.0, 5.0], crossed=[1, 1])


# -- every bad input file ------------------------------------------------------------------------
def _write(tmp_path, content, name="f.csv"):
    p = tmp_path / name
    (p.write_bytes if isinstance(content, bytes) else p.write_text)(content)
    return str(p)


DATE_TIMES = [  # (header, separator, how a datetime is written)
    ("datetime,angle", ",", lambda d: d.isoformat(timespec="milliseconds")),
    ("time,angle", ",", lambda d: d.isoformat(timespec="milliseconds") + "+01:00"),
    ("Zeit;Winkel", ";", lambda d: d.strftime("%d.%m.%Y %H:%M:%S,%f")[:-3]),
    ("Date Time Angle", " ", lambda d: d.strftime("%Y-%m-%d %H:%M:%S.%f")[:-3]),
    (
        "Timestamp\tAngle",
        "\t",
        lambda d: d.strftime("%m/%d/%Y %I:%M:%S.%f")[:-3] + d.strftime(" %p"),
    ),
]


@pytest.mark.parametrize("header, sep, write", DATE_TIMES)
def test_date_and_time_stamps(tmp_path, header, sep, write):
    """A logger's date and clock time in one cell (ISO 8601 with `T` or a space, a time zone,
    `DD.MM.YYYY` with a decimal comma, `MM/DD/YYYY` with `AM`/`PM`; whitespace-separated, a
    date and its time as two words and two header names): read as the clock times they are,
    through midnight (the date itself is not read). Before, each was "a header but no data
    rows"."""
    import datetime

    t = np.arange(0, 20, 0.004)
    y = np.round(5 * np.exp(-0.14 * t) * np.cos(7 * t) + 0.3, 5)
    start = datetime.datetime(2026, 11, 27, 23, 59, 50)
    lines = [
        f"{write(start + datetime.timedelta(seconds=float(a)))}{sep}{b:.5f}".replace(
            ".", "," if sep == ";" else "."
        )
        for a, b in zip(t, y)
    ]
    sig = fits.read_signal(_write(tmp_path, header + "\n" + "\n".join(lines) + "\n"))
    np.testing.assert_allclose(sig.t, t, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(sig.y, y)
    assert sig.time_name == ("Date Time" if sep == " " else header.split(sep)[0])


@pytest.mark.parametrize(
    "above, time_name, signal_name",
    [  # an instrument's notes above the header, units under it
        (
            "Instrument: DAQ 3000\nSample rate: 250 Hz\n\nTime (s),Displacement (mm)\n",
            "Time (s)",
            "Displacement (mm)",
        ),
        ("Title,Decay test 4\nChannels,1\nTime,Ch1\ns,mm\n", "Time (s)", "Ch1 (mm)"),
        ("Title,Decay test 4\nTime,Ch1\n(ms),(V)\n", "Time (ms)", "Ch1 (V)"),
        ("t,x\nseconds,degrees\n", "t (seconds)", "x (degrees)"),
    ],
)
def test_header_below_notes_and_above_units(tmp_path, above, time_name, signal_name):
    """The header is the last line of text above the data that names as many columns as they
    have and is not a line of units (before: the first line of text, so that notes above it
    were an error, "the header names only 1 columns", or the columns' names); a line of units
    under it adds them to the names, and a time unit there is read (before: milliseconds under
    `Time` were read as seconds, `omega` 1000 times too small)."""
    t = np.arange(0, 2, 0.004)
    body = "\n".join(f"{a:.3f},{b:.5f}" for a, b in zip(t, np.sin(7 * t)))
    sig = fits.read_signal(_write(tmp_path, above + body + "\n"))
    assert (sig.time_name, sig.signal_name) == (time_name, signal_name)
    np.testing.assert_allclose(sig.t, t * (1e-3 if "(ms)" in above else 1), atol=1e-12)


def test_clock_times():
    from fits._text import _parse_time

    for text, seconds in [
        ("12:00:01.5", 43201.5),
        ("01:02", 62.0),  # minutes and seconds
        ("2026-11-27 23:59", 86340.0),  # with a date: hours and minutes
        ("2026/11/27T07:08:09.25Z", 25689.25),
        ("11/27/2026 12:00:00.5 AM", 0.5),
        ("12:30 PM", 45000.0),
        ("13:00:00 PM", None),
        ("1.2.3", None),
    ]:
        assert _parse_time(text) == seconds, text


BAD_SIGNALS = [
    ("", "the file is empty"),
    ("\n\n# only a comment\n", "the file is empty"),
    (b"\x00\x01\x02\x03PK\x03\x04" * 50, r"not a text file \(binary data at byte 0\)"),
    ("t,angle\n", "a header but no data rows"),
    ("t,angle\n0,1\n", "only 1 data row: a raw signal needs at least 3"),
    ("t,angle\n0,1\n0.1,2\n0.2,abc\n", r"line 4, column 'angle': not a number: 'abc'"),
    # a missing value leaves its row out (a logger's dropped sample); infinity is an error
    (
        "t,angle\n0,1\n0.1,nan\n0.2,3\n",
        "only 2 data rows: a raw signal with values needs at least 3",
    ),
    ("t,angle\n0,1\n0.1,\n0.2,3\n", "only 2 data rows: a raw signal with values needs at least 3"),
    ("t,angle\n0,1\n0.1,inf\n0.2,3\n", r"line 3, column 'angle': 'inf' is not a finite number"),
    ("t,angle\n0,1\n,2\n0.2,3\n", "only 2 data rows: a raw signal with values needs at least 3"),
    ("t,angle\n0,1\n0.1\n0.2,3\n", r"line 3: expected 2 cells, found 1"),
    ("t,angle\n0,1\n0.2,2\n0.1,3\n", r"line 4, column 't': time must be non-decreasing"),
    ("t,angle\n# note\n0,1\n\n0.2,2\n0.1,3\n", r"line 6, column 't': time must be"),
    ("t,angle\n0,1\n0,2\n0,3\n", r"time must increase \(column 't' is constant\)"),
]


@pytest.mark.parametrize("content, message", BAD_SIGNALS)
def test_bad_signal_files(tmp_path, content, message):
    path = _write(tmp_path, content)
    with pytest.raises(ValueError, match=message) as err:
        fits.read_signal(path)
    assert str(err.value).startswith(path + ": ")


BAD_PEAKS = [
    ("", "the file is empty"),
    ("k,amplitude\n", "a header but no data rows"),
    ("0,1\n1,0.5\n", r"line 1: expected a header line"),
    ("k,amplitude\n0,1\n", "only 1 data row: a decay needs at least 2"),
    ("k,amplitude\n0,1\n1,x\n", r"line 3, column 'amplitude': not a number: 'x'"),
    ("k,amplitude\n0,1\n1,inf\n", r"line 3, column 'amplitude': 'inf' is not a finite"),
    ("k,amplitude\n0,1\n1,-0.5\n", r"line 3, column 'amplitude': -0.5: an amplitude must be >= 0"),
    ("k,amplitude\n0,1\n1.5,0.5\n", r"line 3, column 'k': 1.5: k must hold integers"),
    ("k,amplitude\n0,1\n2,0.5\n# c\n2,0.4\n", r"line 5, column 'k': must be strictly increasing"),
    ("k,amplitude,crossed\n0,1,1\n1,0.5,2\n", r"line 3, column 'crossed': 2: crossed must hold"),
    ("k,value\n0,1\n1,0.5\n", "missing column"),
]


@pytest.mark.parametrize("content, message", BAD_PEAKS)
def test_bad_peak_files(tmp_path, content, message):
    path = _write(tmp_path, content)
    with pytest.raises(ValueError, match=message) as err:
        fits.read_peaks(path)
    assert str(err.value).startswith(path + ": ")


def test_missing_file_and_directory(tmp_path):
    for reader in (fits.read_peaks, fits.read_signal):
        with pytest.raises(ValueError, match="no such file"):
            reader(str(tmp_path / "absent.csv"))
        with pytest.raises(ValueError, match="is a directory, not a file"):
            reader(str(tmp_path))
    with pytest.raises(ValueError, match="missing column: no signal column named 'angle'"):
        fits.read_signal(_write(tmp_path, "t,y\n0,1\n1,2\n2,3\n"), signal_col="angle")
    with pytest.raises(ValueError, match="column index 5 out of range"):
        fits.read_signal(_write(tmp_path, "t,y\n0,1\n1,2\n2,3\n"), time_col=5)


def test_encodings_and_line_ends_are_read(tmp_path):
    text = "time (s),angle\n0,1\n0.1,2.5\n0.2,-1\n"
    plain = fits.read_signal(_write(tmp_path, text, "plain.csv"))
    for name, data in [
        ("bom.csv", b"\xef\xbb\xbf" + text.encode()),
        ("crlf.csv", text.replace("\n", "\r\n").encode()),
        ("cr.csv", text.replace("\n", "\r").encode()),
        ("utf16.csv", text.encode("utf-16")),
        ("latin1.csv", text.replace("angle", "angle (\xb0)").encode("cp1252")),
    ]:
        sig = fits.read_signal(_write(tmp_path, data, name))
        np.testing.assert_array_equal(sig.y, plain.y)
        np.testing.assert_array_equal(sig.t, plain.t)
        assert sig.time_name == "time (s)"
    # semicolons, tabs and whitespace; a units line under the header
    for sep in (";", "\t", "  "):
        sig = fits.read_signal(_write(tmp_path, text.replace(",", sep), "sep.txt"))
        np.testing.assert_array_equal(sig.y, plain.y)
    sig = fits.read_signal(_write(tmp_path, "t,angle\ns,deg\n0,1\n0.1,2.5\n0.2,-1\n"))
    np.testing.assert_array_equal(sig.y, plain.y)
    # spreadsheet exports: quoted cells, a trailing separator
    sig = fits.read_signal(_write(tmp_path, '"t","angle"\n"0","1"\n"0.1","2.5"\n"0.2","-1"\n'))
    np.testing.assert_array_equal(sig.y, plain.y)
    sig = fits.read_signal(_write(tmp_path, "t,angle,\n0,1,\n0.1,2.5,\n0.2,-1,\n"))
    np.testing.assert_array_equal(sig.y, plain.y)


def test_decimal_commas(tmp_path):
    """A spreadsheet export with `;` between the cells and decimal commas (and the same with
    tabs or spaces) reads as the file with decimal points."""
    plain = fits.read_signal(_write(tmp_path, "t,angle\n0,1.5\n0.1,-2.25\n0.2,1e-3\n"))
    for sep in (";", "\t", " "):
        text = f"Zeit{sep}Winkel\n0{sep}1,5\n0,1{sep}-2,25\n0,2{sep}1e-3\n"
        sig = fits.read_signal(_write(tmp_path, text, "comma.txt"))
        np.testing.assert_array_equal(sig.y, plain.y)
        np.testing.assert_array_equal(sig.t, plain.t)
    # decimal points with semicolons are unchanged
    sig = fits.read_signal(_write(tmp_path, "t;angle\n0;1.5\n0.1;-2.25\n0.2;1e-3\n"))
    np.testing.assert_array_equal(sig.y, plain.y)


def test_time_unit_from_the_header_or_given(tmp_path):
    """A time column in milliseconds, microseconds or minutes is read in seconds: from the
    unit its name ends with, or from `time_unit`; the clock report says so."""
    from fits._cli import TIME_UNITS

    assert TIME_UNITS == tuple(fits.TIME_UNITS)  # the command line's choices
    for name, scale in (
        ("time_ms", 1e-3),
        ("t [ms]", 1e-3),
        ("Time (us)", 1e-6),
        ("time in ms", 1e-3),
        ("t/min", 60.0),
        ("Time_Elapsed(s)", 1.0),
        ("time", 1.0),
    ):
        text = f"{name},x\n0,1\n5,2\n10,-1\n"
        sig = fits.read_signal(_write(tmp_path, text, "unit.csv"))
        np.testing.assert_allclose(sig.t, np.array([0.0, 5.0, 10.0]) * scale)
        assert ("read in" in sig.clock_report["message"]) == (scale != 1.0), name
        # whole numbers a second or more apart in a column that names no unit: said
        hint = "holds whole numbers 5 apart, read as seconds (if they are milliseconds"
        assert (hint in sig.clock_report["message"]) == (name == "time"), name
    sig = fits.read_signal(_write(tmp_path, "t,x\n0,1\n5,2\n10,-1\n"), time_unit="ms")
    np.testing.assert_allclose(sig.t, [0.0, 0.005, 0.01])
    assert "whole numbers" not in sig.clock_report["message"]
    with pytest.raises(ValueError, match="time_unit must be one of 's', 'ms'"):
        fits.read_signal(_write(tmp_path, "t,x\n0,1\n5,2\n10,-1\n"), time_unit="hours")


def test_the_time_column_is_chosen(tmp_path):
    """Of the columns named like a time, the finest that never decreases; without a header the
    first column."""
    t = np.arange(200) / 100.0
    rows = np.column_stack([np.floor(t * 4) / 4, t, 10 - t, np.sin(7 * t)])
    path = tmp_path / "cols.csv"
    np.savetxt(path, rows, delimiter=",", header="elapsed (s),time,time left,x", comments="")
    sig = fits.read_signal(str(path))
    assert sig.time_name == "time" and sig.signal_name == "x"
    assert "'elapsed (s)' (8 distinct values)" in sig.clock_report["message"]
    assert "'time left' (not monotone)" in sig.clock_report["message"]
    np.savetxt(path, rows[:, [1, 0, 3]], delimiter=",")
    sig = fits.read_signal(str(path))
    assert sig.time_name == "column 0" and np.allclose(sig.t, t)


def test_one_column_signal_needs_a_rate(tmp_path):
    path = _write(tmp_path, "angle\n1\n2\n3\n2\n")
    with pytest.raises(
        ValueError, match=r"no time column: give its sampling rate \[Hz\] \(rate=\.\.\. in Python"
    ):
        fits.read_signal(path)
    sig = fits.read_signal(path, rate=50.0)
    np.testing.assert_allclose(sig.t, np.arange(4) / 50.0)
    assert sig.clock_report["method"] == "rate"


def test_row_limit(tmp_path):
    rows = 30_000
    t = np.arange(rows) / 1000.0
    path = tmp_path / "long.csv"
    np.savetxt(path, np.column_stack([t, np.sin(20 * t)]), delimiter=",", header="t,y", comments="")
    with pytest.raises(
        ValueError,
        match=r"about 3\d,\d{3} rows .*more than the limit of "
        r"10,000 rows: to read it, raise the limit \(max_rows=N",
    ):
        fits.read_signal(str(path), max_rows=10_000)  # estimated from the size, not read
    with pytest.raises(ValueError, match=r"30,000 rows, more than the limit of 29,000"):
        fits.read_signal(str(path), max_rows=29_000)  # within the estimate's margin: counted
    assert fits.read_signal(str(path), max_rows=None).t.size == rows
    from fits._cli import MAX_ROWS

    assert fits.MAX_ROWS == MAX_ROWS == 2_000_000  # the command line's default


def test_row_limit_on_the_command_line(tmp_path, capsys):
    """`vmj fit --max-rows`: the limit named in the command line's spelling, and checked."""
    from vmj.cli import main

    path = tmp_path / "long.csv"
    t = np.arange(3000) / 1000.0
    np.savetxt(path, np.column_stack([t, np.sin(20 * t)]), delimiter=",", header="t,y", comments="")
    args = ["fit", str(path), "--series", "--model", "oscillator"]
    assert main([*args, "--max-rows", "1000"]) == 2
    assert "--max-rows N or --max-rows none" in capsys.readouterr().err
    for bad in ("0", "-5", "many"):
        with pytest.raises(SystemExit):
            main([*args, "--max-rows", bad])
        assert "--max-rows: must be an integer >= 1 or 'none'" in capsys.readouterr().err


def test_window_and_decay_on_the_command_line(tmp_path, capsys):
    """`vmj fit --window START:END` and `--decay N|all`: checked by the parser; either makes
    the file a raw signal."""
    from vmj.cli import main

    path = tmp_path / "x.csv"
    t = np.arange(3000) / 1000.0
    np.savetxt(path, np.column_stack([t, np.sin(20 * t)]), delimiter=",", header="t,y", comments="")
    args = ["fit", str(path), "--model", "oscillator"]
    for bad, message in (
        ("5", "must be START:END"),
        ("a:b", "must be START:END"),
        ("5:3", "START < END"),
    ):
        with pytest.raises(SystemExit):
            main([*args, "--series", "--window", bad])
        assert message in capsys.readouterr().err
    assert main([*args, "--window", "9:"]) == 2  # a raw signal: --window says so
    assert "window [9, inf] s holds 0 samples" in capsys.readouterr().err
    # --decay N|all, likewise
    for bad in ("-1", "some"):
        with pytest.raises(SystemExit):
            main([*args, "--series", "--decay", bad])
        assert "--decay: must be an integer >= 0 or 'all'" in capsys.readouterr().err
    assert main([*args, "--decay", "4"]) == 2
    assert "decay 4 asked for, but the signal holds 1 free decay" in capsys.readouterr().err


@pytest.mark.long  # 12 s of writing and reading, with the long runs for CI's time
def test_a_million_rows(tmp_path):
    """A million rows of clock-stamped arrival data: read and put on the recovered clock in a
    few seconds (NumPy's parser; the line-by-line one only locates errors)."""
    import time

    n = 1_000_000
    s, stamps, _ = arrival_stamps(n, RATE, 9, t_start=50_000.0)
    y = 20 * np.exp(-0.01 * (s - s[0])) * np.cos(21.8 * (s - s[0]))
    path = tmp_path / "big.txt"
    with open(path, "w") as fh:
        fh.write("Timestamp, Angle(deg)\n")
        fh.write("\n".join(f"{_clock_text(a)}, {b:.3f}" for a, b in zip(stamps, y)))
    start = time.perf_counter()
    sig = fits.read_signal(str(path))
    elapsed = time.perf_counter() - start
    assert sig.t.size == n and abs(sig.clock_report["rate_hz"] / RATE - 1) < 1e-5
    assert elapsed < 30  # about 2 s on one core
    rec = fits.extract_turning_points(sig)
    assert len(rec) > 1000


def test_stringio_and_read_record_arguments(tmp_path):
    sig = fits.read_signal(io.StringIO("t,y\n0,1\n0.5,2\n1,3\n"))
    assert sig.source == "<text>" and sig.t.tolist() == [0.0, 0.5, 1.0]
    with pytest.raises(ValueError, match="apply to raw signals"):
        fits.read_record(P80, series=False, rate=100.0)
