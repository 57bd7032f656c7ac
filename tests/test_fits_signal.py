"""fits: readers and their errors, turning-point extraction from raw signals, the oscillator fit
(synthetic and the measured pendulum record 80P.txt), Adam, batching, and `vmj fit`."""

import dataclasses
import json
import math
import os
import warnings

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import fits
import vmj
from fits._fit import _bucket, _init_weights, _make_job, _problem
from fits._models import SPACES
from fits._params import HELD, derivative
from fits._solve import _Data, _job_arrays, _residual_and_jacobian, _Shape, _values
from vmj.cli import main

HERE = os.path.dirname(__file__)
P80 = os.path.join(HERE, "..", "fits", "data", "80P.txt")
FREE = ("omega", "zeta", "xF", "a0", "offset")


def _oscillator_signal(
    omega, zeta, xF, a0, offset, t_end, seed, n_spikes=3, noise=0.002, per_period=None
):
    """Closed-form piecewise solution sampled irregularly (or `per_period` times per period,
    from a random phase), with noise (`noise` of `a0`), offset and spikes."""
    rng = np.random.default_rng(seed)
    if per_period is None:
        t = np.cumsum(rng.uniform(0.5e-3, 6e-3, int(t_end / 3e-3)))
    else:
        dt = 2 * np.pi / omega / per_period
        t = np.arange(rng.uniform(0, dt), t_end, dt)
    t = t[t < t_end]
    wd = omega * np.sqrt(1 - zeta**2)
    half = np.pi / wd
    x = np.empty_like(t)
    start, xs = 0.0, -a0
    turning = [(0.0, -a0)]
    while start < t_end:
        s = -np.sign(xs)
        if abs(xs) <= xF:
            sel = t >= start
            x[sel] = xs
            break
        sel = (t >= start) & (t < start + half)
        tau = t[sel] - start
        u0 = xs + s * xF
        x[sel] = (
            u0
            * np.exp(-zeta * omega * tau)
            * (np.cos(wd * tau) + zeta * omega / wd * np.sin(wd * tau))
            - s * xF
        )
        xs = -s * xF - np.exp(-zeta * omega * half) * u0
        start += half
        turning.append((start, xs))
    y = x + offset + rng.normal(0, noise * a0, t.size)
    spikes = rng.choice(np.arange(10, t.size - 10), n_spikes, replace=False)
    y[spikes] += 0.3 * a0 * rng.choice([-1, 1], n_spikes)
    return t, y, np.array(turning)


def _true_positions(rec, truth):
    """The true turning points (`_oscillator_signal`'s) nearest in time to `rec`'s."""
    at = rec.times + rec.time_origin
    return truth[[int(np.argmin(np.abs(truth[:, 0] - x))) for x in at], 1]


def _extracted(truth, seeds, **signal):
    """The turning points extracted from `_oscillator_signal(**truth, seed=s, **signal)`
    (without spikes) for each seed `s`."""
    records = []
    for seed in seeds:
        t, y, _ = _oscillator_signal(**truth, seed=seed, **{"n_spikes": 0, **signal})
        records.append(fits.extract_turning_points(fits.Signal(t=t, y=y, clock="stamps")))
    return records


TRUE = {"omega": 20.0, "zeta": 0.01, "xF": 0.05, "a0": 10.0, "offset": 2.0}


@pytest.fixture(scope="module")
def synthetic_signal(tmp_path_factory):
    t, y, turning = _oscillator_signal(**TRUE, t_end=8.0, seed=3)
    path = tmp_path_factory.mktemp("sig") / "signal.csv"
    np.savetxt(path, np.column_stack([t, y]), delimiter=",", header="t,angle", comments="")
    return str(path), turning


@pytest.fixture(scope="module")
def pendulum():
    record = fits.read_record(P80, series=True)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return record, fits.fit(record, "oscillator", FREE)


# -- readers and errors ------------------------------------------------------------------------
def _write(tmp_path, text, name="f.csv"):
    p = tmp_path / name
    p.write_text(text)
    return str(p)


@pytest.mark.parametrize(
    "text, message",
    [
        ("", "empty"),
        ("k,amplitude\n", "no data rows"),
        ("k,value\n0,1\n1,0.5\n", "missing column"),
        ("amplitude\n1\n0.5\n", "missing column"),
        ("k,amplitude\n0,1\n1,abc\n", "not a number"),
        ("k,amplitude\n0,1\n1,nan\n", "not a finite number"),
        ("time,amplitude\n0,1\n0.2,0.8\n0.2,0.6\n", "strictly increasing"),
        ("k,amplitude\n0,1\n1,-0.5\n", ">= 0"),
    ],
)
def test_peak_file_errors(tmp_path, text, message):
    with pytest.raises(ValueError, match=message):
        fits.read_peaks(_write(tmp_path, text))


def test_signal_file_errors(tmp_path):
    with pytest.raises(ValueError, match="empty"):
        fits.read_signal(_write(tmp_path, "\n\n"))
    with pytest.raises(ValueError, match="missing column"):
        fits.read_signal(_write(tmp_path, "t,y\n0,1\n1,2\n2,3\n"), signal_col="angle")
    with pytest.raises(ValueError, match="not a number"):
        fits.read_signal(_write(tmp_path, "t,y\n0,1\n1,x\n2,3\n"))
    with pytest.raises(ValueError, match="non-decreasing"):
        fits.read_signal(_write(tmp_path, "t,y\n0,1\n2,2\n1,3\n"))
    # a rate below the stamps' own: the rows would not fit in their time
    rows = "".join(f"{0.01 * i:.2f},{i % 7}\n" for i in range(50))
    with pytest.raises(ValueError, match=r"the given rate, 50 Hz, is below that of 't' \(100 Hz"):
        fits.read_signal(_write(tmp_path, "t,y\n" + rows), rate=50)
    assert fits.read_signal(_write(tmp_path, "t,y\n" + rows), rate=100).clock == "uniform"
    # a raw-signal option on a table of turning points
    peaks = _write(tmp_path, "k,amplitude\n0,10\n1,9.3\n2,8.62\n3,7.95\n4,7.3\n5,6.67\n")
    with pytest.raises(ValueError, match="a table of turning points, but the raw-signal option"):
        fits.read_record(peaks, rate=100)
    assert len(fits.read_record(peaks)) == 6
    with pytest.raises(ValueError, match="holds text \\('ok'\\); the columns must be numbers"):
        fits.read_record(_write(tmp_path, "k,amplitude,note\n0,10,ok\n1,9.3,ok\n2,8.6,ok\n"))
    with pytest.raises(ValueError, match="beyond the largest magnitude read, 1e"):
        fits.read_record(_write(tmp_path, "k,amplitude\n0,1e300\n1,9e299\n2,8e299\n"))


def test_too_few_points_and_no_decay(tmp_path):
    rec = fits.read_peaks(_write(tmp_path, "k,amplitude\n0,0.06\n1,0.05\n"))
    with pytest.raises(ValueError, match="too few"):
        fits.fit(rec, "variable-mass", ("FT", "mu"), {"m0": 5, "c": 4900})
    grows = fits.read_peaks(_write(tmp_path, "k,amplitude\n0,0.01\n1,0.02\n2,0.03\n3,0.04\n"))
    with pytest.raises(ValueError, match="does not decay"):
        fits.fit(grows, "variable-mass", ("FT", "mu"), {"m0": 5, "c": 4900})
    with pytest.raises(ValueError, match="unknown parameter"):
        fits.fit(grows, "variable-mass", ("T",), {"m0": 5, "c": 4900})
    with pytest.raises(ValueError, match="needs m0"):
        fits.fit(grows, "variable-mass", ("FT",), {"c": 4900})
    with pytest.raises(ValueError, match="mu must be finite"):
        fits.fit(grows, "variable-mass", ("FT",), {"m0": 5, "c": 4900, "mu": -1})


@pytest.mark.parametrize("rate", [0.02, 0.002])
def test_a_growing_signal_is_refused_as_no_free_decay(tmp_path, rate):
    """A self-excited oscillation (swings growing by `rate` of a period's radians, 10 s at
    5 Hz): strong growth leaves its first swings below the amplitude floor, and is named as
    growth, not as too few turning points; weak growth reaches the decay check."""
    t = np.arange(0, 10, 1e-3)
    w = 2 * np.pi * 5
    y = -np.exp(rate * w * t) * np.cos(w * t)
    y += np.random.default_rng(0).normal(0, 0.002, t.size)
    path = _write(tmp_path, "t,x\n" + "\n".join(f"{a:.4f},{b:.6f}" for a, b in zip(t, y)))
    with pytest.raises(ValueError, match="(swings|amplitudes) grow"):  # (the path says growing)
        fits.fit(fits.read_record(path, series=True), "oscillator", ("omega", "zeta", "a0"))


def test_crossed_column_sets_the_sides(tmp_path):
    rec = fits.read_peaks(_write(tmp_path, "k,amplitude,crossed\n0,6,1\n1,5,1\n2,4,1\n3,1,0\n"))
    assert rec.positions.tolist() == [-6, 5, -4, -1]
    rec = fits.read_peaks(_write(tmp_path, "time,position\n0.1,-6\n0.2,5\n0.3,-4\n"))
    assert rec.k.tolist() == [0, 1, 2] and np.allclose(rec.times, [0, 0.1, 0.2])


def test_peak_columns_by_their_names_first_word(tmp_path):
    """A peak table's columns by the first word of their names, a unit read from the name."""
    rows = "\n0,10\n150,9\n300,8.1\n"
    rec = fits.read_peaks(_write(tmp_path, "Time (ms),Amplitude [mm],Note" + rows))
    assert np.allclose(rec.times, [0, 0.15, 0.3]) and rec.amplitudes.tolist() == [10, 9, 8.1]
    rec = fits.read_peaks(_write(tmp_path, "time_us,peak" + rows))
    assert np.allclose(rec.times, [0, 1.5e-4, 3e-4])
    rec = fits.read_peaks(_write(tmp_path, "t,Position (deg)" + rows))
    assert np.allclose(rec.times, [0, 150, 300]) and rec.positions.tolist() == [10, 9, 8.1]
    with pytest.raises(ValueError, match="both name the amplitude"):
        fits.read_peaks(_write(tmp_path, "k,amplitude,peak\n0,1,1\n1,0.9,0.9\n"))
    # a count of the peaks (half-swings or periods: the name does not say) is no amplitude
    rec = fits.read_peaks(_write(tmp_path, "Peak No.;Time [s];Amplitude [mm]\n1;0;10\n2;0.15;9\n"))
    assert rec.amplitudes.tolist() == [10, 9] and rec.meta["rows"] == fits.ROWS_AS_HALF_SWINGS
    with pytest.raises(ValueError, match="missing column: need 'amplitude'"):
        fits.read_peaks(_write(tmp_path, "k,height\n0,1\n1,0.9\n"))


@pytest.mark.parametrize(
    "name, scale",
    [
        ("Zeit [ms]", 1e-3),
        ("time [ms]", 1e-3),
        ("t (s)", 1.0),
        ("Timestamp", 1.0),
        ("Elapsed (us)", 1e-6),
        ("Peak time [ms]", 1e-3),
    ],
)
def test_peak_tables_read_the_time_column_as_raw_signals_do(tmp_path, name, scale):
    """A peak table's time column is named as a raw signal's may be, its unit honoured (until
    2026-11-28 by its first word only: `Zeit [ms]` was refused, or beside a `k` column dropped
    without a word)."""
    rows = "\n0,10\n150,9\n300,8.1\n"
    assert np.allclose(
        fits.read_peaks(_write(tmp_path, f"{name},amplitude" + rows)).times,
        [0, 150 * scale, 300 * scale],
    )
    rows = "\n0,0,10\n1,150,9\n2,300,8.1\n"
    rec = fits.read_peaks(_write(tmp_path, f"k,{name},amplitude" + rows))
    assert np.allclose(rec.times, [0, 150 * scale, 300 * scale])
    # of several time columns, the finest (a coarse elapsed time beside the stamps)
    rows = "\n0,0,10\n0,150,9\n0.3,300,8.1\n"
    rec = fits.read_peaks(_write(tmp_path, f"Time_Elapsed(s),{name},amplitude" + rows))
    assert np.allclose(rec.times, [0, 150 * scale, 300 * scale])


def test_the_signal_is_the_last_column_that_is_not_the_time(tmp_path):
    """A header `angle,time`: the signal is `angle`, by default and with the time named."""
    t = np.arange(400) * 0.01
    path = tmp_path / "swapped.csv"
    rows = "\n".join(f"{np.cos(6.0 * x):.6f},{x:.2f}" for x in t)
    path.write_text("angle,time\n" + rows + "\n")
    for kw in ({}, {"time_col": "time"}):
        sig = fits.read_signal(str(path), **kw)
        assert (sig.signal_name, sig.time_name) == ("angle", "time")
        np.testing.assert_allclose(sig.y, np.cos(6.0 * t), atol=1e-6)


def test_raw_signal_or_peak_table_decided_from_the_file(tmp_path, capsys):
    """`read_record(path)` (and `vmj fit` without `--series`) reads a raw signal as one: a
    file without a header, without an amplitude or position column, or whose position or
    (oscilloscope-style, signed) amplitude column holds samples of an oscillation (read as
    peaks, 2000 samples would be fitted as 2000 turning points: converged False, lag-1 1.00).
    Peak tables stay peak tables: both sides' signed turning points, amplitudes with a
    sensor offset's alternation, one side's peaks."""
    t, y, _ = _oscillator_signal(9.4, 0.02, 0.002, 0.5, 0.1, 10.0, seed=3, n_spikes=0)
    t, y = t[:2000], y[:2000]
    want = None
    for header in ("time,position", "Time (s),Amplitude (V)", "t,displacement", None):
        body = "\n".join(f"{a:.17g},{b:.17g}" for a, b in zip(t, y))
        path = _write(tmp_path, (f"{header}\n" if header else "") + body)
        rec = fits.read_record(path)
        assert rec.signal is not None, header
        if want is None:
            want = fits.read_record(path, series=True)
        np.testing.assert_array_equal(rec.positions, want.positions)
        np.testing.assert_array_equal(rec.times, want.times)
    with pytest.raises(ValueError, match="samples of a motion, not its turning points"):
        fits.read_peaks(path := _write(tmp_path, "time,position\n" + body, "raw.csv"))
    with pytest.raises(ValueError, match="samples of a motion"):
        fits.read_record(path, series=False)
    # peak tables: the extracted turning points themselves (alternating about the centre)
    rows = "\n".join(f"{a:.17g},{b:.17g}" for a, b in zip(want.times, want.positions))
    rec = fits.read_record(_write(tmp_path, "time,position\n" + rows))
    assert rec.signal is None and np.allclose(rec.positions, want.positions)
    # amplitudes of a decay to 10 % with an offset alternating them (+-0.1 of 1), and one
    # side's peaks as signed positions: cross their median in one band of rows, or once
    k = np.arange(60)
    amp = np.exp(-k / 26) + 0.1 * (-1.0) ** k
    rows = "\n".join(f"{0.33 * i},{a:.17g}" for i, a in zip(k, amp))
    assert fits.read_record(_write(tmp_path, "time,amplitude\n" + rows)).signal is None
    rows = "\n".join(f"{0.67 * i},{a:.17g}" for i, a in zip(k, np.exp(-k / 26)))
    assert fits.read_record(_write(tmp_path, "time,position\n" + rows)).signal is None
    # a peak table whose amplitude column is misnamed: said as a peak table's error too
    with pytest.raises(ValueError, match="as a peak table: missing column: need 'amplitude'"):
        fits.read_record(_write(tmp_path, "time,amp\n0,1\n1,0.8\n2,0.6\n"))
    with pytest.raises(ValueError, match="missing column: need 'amplitude'"):  # a k column
        fits.read_record(_write(tmp_path, "k,amp\n0,1\n1,0.8\n2,0.6\n"))
    # the command line: without --model, the default model's needs and the other models
    assert main(["fit", path]) == 2
    err = capsys.readouterr().err
    assert "the variable-mass model needs m0, c" in err and "--model): oscillator" in err


def test_a_column_without_a_decay_names_the_others(tmp_path):
    """The signal is the last column unless one is named: where that column holds no decay (a
    trigger, a constant, noise), the error names the file's other columns and how to choose
    (the time columns are not among them)."""
    t = np.arange(0, 20, 0.004)
    x = 5 * np.exp(-0.14 * t) * np.cos(7 * t) + 0.3
    for last in (np.where(t > 0.5, 5.0, 0.0), np.full_like(t, 2.5)):
        rows = "\n".join(f"{a:.3f},{a:.2f},{b:.5f},{c:g}" for a, b, c in zip(t, x, last))
        path = _write(tmp_path, "time,elapsed,displacement,trigger\n" + rows)
        with pytest.raises(ValueError, match="no decay|turning points") as err:
            fits.read_record(path)
        assert str(err.value).endswith(
            "(in the column 'trigger'; the file's other column: 'displacement': name the "
            "signal's with --signal-col NAME, signal_col=NAME)"
        )
    assert len(fits.read_record(path, signal_col="displacement")) > 20


#: the one-side peak table's oscillator: omega [rad/s], zeta, xF and a0 [signal units]
CYCLE_TRUTH = 20.0, 0.01, 0.05, 10.0


def _cycle_table() -> str:
    """A logarithmic-decrement table (`cycle,time,amplitude` rows): the negative peaks of the
    exact oscillator `CYCLE_TRUTH` one per period, amplitudes to 0.002 and times to 0.2 ms."""
    omega, zeta, xF, a0 = CYCLE_TRUTH
    half = np.pi / (omega * np.sqrt(1 - zeta**2))
    r = np.exp(-zeta * omega * half)
    x, rows = -a0, []
    for k in range(40):  # the exact half-swing map
        if k % 2 == 0:
            rows.append((k // 2, k * half, -x))
        x = np.sign(x) * xF * (1 + r) - r * x
    rng = np.random.default_rng(0)
    return "".join(
        f"{c},{t + rng.normal(0, 2e-4):.6f},{a + rng.normal(0, 2e-3):.5f}\n" for c, t, a in rows
    )


def test_one_sides_peaks_by_cycle(tmp_path):
    """The table of `_cycle_table`: with its `cycle` column (`k = 2 cycle`) the fit recovers the
    parameters; read as successive half-swings the same numbers would give omega 10 and twice
    zeta and xF, and a record whose rows nothing numbers says so in its warnings."""
    omega, zeta, xF, a0 = CYCLE_TRUTH
    r = np.exp(-zeta * np.pi / np.sqrt(1 - zeta**2))
    table = _cycle_table()
    rec = fits.read_peaks(_write(tmp_path, "cycle,time,amplitude\n" + table))
    assert rec.k.tolist() == list(range(0, 40, 2)) and "rows" not in rec.meta
    dec = fits.decrement(rec)
    assert dec["step"] == 2 and abs(dec["r"] / r - 1) < 1e-3 and abs(dec["xF"] / xF - 1) < 0.05
    got = fits.fit(rec, "oscillator", ("omega", "zeta", "xF", "a0"), compare=False)
    assert got.converged
    assert abs(got.params["omega"] / omega - 1) < 1e-4
    assert abs(got.params["zeta"] / zeta - 1) < 0.01
    assert abs(got.params["xF"] / xF - 1) < 0.01
    plain = "\n".join(line.split(",", 1)[1] for line in table.splitlines())
    rows_only = fits.read_peaks(_write(tmp_path, "time,amplitude\n" + plain + "\n"))
    assert rows_only.meta["rows"] == fits.ROWS_AS_HALF_SWINGS
    with pytest.raises(ValueError, match="not both"):
        fits.read_peaks(_write(tmp_path, "k,cycle,amplitude\n0,0,1\n2,1,0.9\n"))


def test_the_command_line_fits_no_offset_to_one_sides_peaks(tmp_path, capsys):
    """An offset shifts every peak of one side alike, which the decay takes as dry friction
    (`xF - o (1 - r)/(1 + r)`): with both free the fit is rank-deficient ("offset is not
    identified", not converged). `vmj fit` leaves offset out of its default parameters for
    such a record and says so; the others are recovered as in `test_one_sides_peaks_by_cycle`.
    A name given with `--set` leaves the default parameters too (held at that value)."""
    path = _write(tmp_path, "cycle,time,amplitude\n" + _cycle_table())
    assert main(["fit", path, "--model", "oscillator", "--json"]) == 0
    out, err = capsys.readouterr()
    got = json.loads(out)
    assert "offset not fitted: the record holds one side's peaks only" in err
    assert sorted(got["params"]) == ["a0", "omega", "xF", "zeta"] and got["converged"]
    for name, truth in zip(("omega", "zeta", "xF", "a0"), CYCLE_TRUTH):
        assert abs(got["params"][name] / truth - 1) < 0.01, name
    assert main(["fit", path, "--model", "oscillator", "--json", "--set", "xF=0.05"]) == 0
    got = json.loads(capsys.readouterr().out)
    assert sorted(got["params"]) == ["a0", "omega", "zeta"] and got["converged"]
    assert abs(got["params"]["zeta"] / CYCLE_TRUTH[1] - 1) < 0.01


def test_the_command_line_fits_no_offset_to_amplitudes(tmp_path, capsys):
    """An amplitude table (`k,amplitude`: distances from the centre, both sides' peaks) is
    compared with the model's `|y|`, which no offset changes: `vmj fit`'s default set fitted
    it anyway, and the fit of the commonest peak table was "offset is not identified by these
    data", rank-deficient and not converged. It leaves offset out, says so, and converges."""
    omega, zeta, xF, a0 = CYCLE_TRUTH
    half = np.pi / (omega * np.sqrt(1 - zeta**2))
    r = np.exp(-zeta * omega * half)
    x, rows, rng = -a0, [], np.random.default_rng(1)
    for k in range(30):  # the exact half-swing map
        rows.append(f"{k},{abs(x) + rng.normal(0, 2e-3):.5f}\n")
        x = np.sign(x) * xF * (1 + r) - r * x
    path = _write(tmp_path, "k,amplitude\n" + "".join(rows))
    assert main(["fit", path, "--model", "oscillator", "--json"]) == 0
    out, err = capsys.readouterr()
    got = json.loads(out)
    assert "offset not fitted: the record holds amplitudes only" in err
    assert sorted(got["params"]) == ["a0", "xF", "zeta"] and got["converged"]
    for name, truth in zip(("zeta", "xF", "a0"), CYCLE_TRUTH[1:]):
        lo, hi = got["intervals"][name]
        assert lo < truth < hi, name


def test_the_command_line_reads_the_encodings_the_reader_reads(tmp_path, capsys):
    """`vmj fit` judged a FILE's encoding itself and refused all but UTF-8 ("not a UTF-8 text
    file"), though `fits.read_record` reads Windows-1252 (a spreadsheet's `Weg [\u00b5m]` with
    decimal commas) and UTF-16 with a byte-order mark: the content is now the reader's."""
    t, y, _ = _oscillator_signal(**TRUE, t_end=3.0, seed=3, n_spikes=0)
    rows = "".join(f"{a:.6f};{b:.6f}\n".replace(".", ",") for a, b in zip(t, y))
    for encoding in ("cp1252", "utf-16"):
        path = tmp_path / f"{encoding}.csv"
        path.write_bytes(("Zeit [s];Weg [\u00b5m]\n" + rows).encode(encoding))
        assert main(["fit", str(path), "--model", "oscillator", "--json"]) == 0, encoding
        got = json.loads(capsys.readouterr().out)
        assert abs(got["params"]["omega"] / TRUE["omega"] - 1) < 1e-3, encoding


def test_rows_without_a_value_are_left_out(tmp_path):
    """A logger's dropped samples (an empty cell, NaN, NA, null): the rows are left out and
    said so; the record is the one of the same file without those rows. On a clock made from
    the rate, each row keeps its place."""
    lines = open(P80).read().splitlines()
    rng = np.random.default_rng(0)
    gone = set(rng.choice(np.arange(2, len(lines)), 30, replace=False).tolist())
    spellings = ["", "NaN", "nan", "NA", "null"]
    holed = [
        line if i not in gone else line.rsplit(", ", 1)[0] + ", " + spellings[i % 5]
        for i, line in enumerate(lines)
    ]
    (tmp_path / "holed.txt").write_text("\n".join(holed) + "\n")
    (tmp_path / "cut.txt").write_text(
        "\n".join(line for i, line in enumerate(lines) if i not in gone) + "\n"
    )
    a, b = (fits.read_signal(str(tmp_path / f)) for f in ("holed.txt", "cut.txt"))
    assert np.array_equal(a.t, b.t) and np.array_equal(a.y, b.y)
    first = min(gone) + 1
    assert (
        f"30 rows without a value left out (the first: line {first})" in a.clock_report["message"]
    )
    y = np.sin(np.arange(400) / 10.0)
    cells = [f"{v:.6f}" if i % 37 else "NaN" for i, v in enumerate(y)]  # (a blank: no row)
    (tmp_path / "one.csv").write_text("x\n" + "\n".join(cells) + "\n")
    sig = fits.read_signal(str(tmp_path / "one.csv"), rate=100.0)
    kept = np.arange(400) % 37 != 0
    np.testing.assert_allclose(sig.t, (np.arange(400)[kept] - 1) / 100.0)  # from the first
    np.testing.assert_allclose(sig.y, np.round(y[kept], 6))
    # rows sharing a stamp: averaged, and the report says how many (5 rows at 2 stamps)
    t = np.repeat(np.arange(40.0), [3 if i == 4 else 2 if i == 9 else 1 for i in range(40)])
    rows = "\n".join(f"{a:g},{i}" for i, a in enumerate(t))
    sig = fits.read_signal(_write(tmp_path, "t,y\n" + rows + "\n"), clock="stamps")
    assert sig.t.size == 40 and sig.y[4] == 5.0 and sig.y[9] == 11.5
    assert "5 rows sharing 2 time stamps averaged" in sig.clock_report["message"]
    with pytest.raises(ValueError, match="not a number"):  # other words stay errors
        fits.read_signal(_write(tmp_path, "t,y\n0,1\n1,missing\n2,3\n3,4\n"))


def test_pendulum_format_and_clock(tmp_path):
    sig = fits.read_signal(P80)
    assert sig.time_name == "Timestamp" and sig.signal_name == "Angle(deg)"
    assert sig.clock == "uniform"  # bursty arrival stamps: samples taken as equally spaced
    assert 29.0 < sig.t[-1] < 29.7 and sig.t.size == 7625
    stamps = fits.read_signal(P80, clock="stamps")
    assert stamps.t.size < sig.t.size  # repeated stamps averaged, and said so
    assert "time stamps averaged" in stamps.clock_report["message"]
    assert "averaged" not in sig.clock_report["message"]
    with pytest.raises(ValueError, match="clock"):
        fits.read_signal(P80, clock="wall")


# -- extraction and the oscillator fit ---------------------------------------------------------
def test_extraction_is_robust(synthetic_signal):
    path, turning = synthetic_signal
    rec = fits.read_record(path, series=True, signal_col="angle")
    n = min(len(rec), len(turning))
    # every turning point well above the noise is found (the tail below the floor is dropped)
    assert len(rec) >= np.sum(np.abs(turning[:, 1]) > 1.5)
    # spikes rejected, offset kept: turning points within noise of the truth
    err = rec.positions[:n] - (turning[:n, 1] + TRUE["offset"])
    assert np.max(np.abs(err)) < 0.01 * TRUE["a0"]
    assert np.max(np.abs(rec.times[:n] - turning[:n, 0])) < 3e-3
    assert abs(rec.centre - TRUE["offset"]) < 0.2


@pytest.mark.parametrize("per_period", [6.5, 7.9, 10.0, 25.0])
def test_turning_points_of_a_signal_of_few_samples_per_period(per_period):
    """Below about 16 samples per period too few samples lie near an extremum for a quartic: a
    sinusoid at the local rate is fitted through them (`_refine_harmonic`), the noise is
    measured from such arcs, and spikes are removed only from 16 samples per period (a running
    median of 5 took peaks for spikes at 25; the cubic test of `_despike` does not). Noisy
    signals without a tail at rest: the turning points within 3 noise sd of the truth in value
    (measured: at most 1.3-1.8 sd at 6.5-25 samples per period; before, "no decay to fit" at
    6.5 and 7.9, the noise overestimated 3-6 times at 10-12, and an RMS of 2.5-3.1 sd at 10-25,
    at most 4-10 sd), the times within a hundredth of a half-period after a constant shift (the
    clock's, which the fits align)."""
    true = {**TRUE, "xF": 0.05, "zeta": 0.003}
    t, y, turning = _oscillator_signal(
        **true, t_end=6.0, seed=5, n_spikes=0, noise=0.002, per_period=per_period
    )
    rec = fits.extract_turning_points(fits.Signal(t=t, y=y, clock="stamps"))
    half = np.pi / true["omega"]
    k = np.round((rec.times + rec.time_origin) / half).astype(int)
    assert len(rec) >= 20 and np.all(np.diff(k) >= 1)
    err = rec.positions - (turning[k, 1] + true["offset"])
    assert np.max(np.abs(err[1:])) < 3 * 0.002 * true["a0"], err
    dt = rec.times + rec.time_origin - turning[k, 0]
    assert np.max(np.abs(dt[1:] - np.median(dt[1:]))) < 0.01 * half


def test_signals_of_few_samples_per_period_fit_with_honest_intervals():
    """Ten noisy signals at 7 samples per period: every fit converges and the 95 % intervals of
    omega, zeta and xF hold the truth in at least 8 of 10 (measured over 24 seeds at 6.5-16
    samples per period: 22-24 of 24 for each; before, at 7 and 9 samples per period the
    extraction's errors made the fits' standard errors 3-7 times too large, at 10-16 xF was
    biased by half a standard error, and 4-8 fits of 24 did not converge)."""
    truth = {**TRUE, "zeta": 0.005}
    records = _extracted(truth, range(400, 410), t_end=6.0, per_period=7.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        results = fits.fit_batch(records, "oscillator", FREE, compare=False)
    assert all(r.converged for r in results)
    for name in ("omega", "zeta", "xF"):
        inside = sum(r.intervals[name][0] <= truth[name] <= r.intervals[name][1] for r in results)
        assert inside >= 8, (name, inside)


def test_a_record_of_six_turning_points_weighs_its_blocks_by_their_degrees_of_freedom():
    """60 noisy signals of 6 turning points (5 positions fitted with 4 parameters beside the
    frequency): each block's noise scale is re-estimated from its residuals with the degrees
    of freedom the fit took from it (`fits._fit._block_scale`). Taken as they were, the
    positions' few residuals weighed them too heavily against the times, and of the 45 fits
    reported converged the intervals of zeta, xF, a0 and offset held the truth in 32-34 only
    (now 43-45 of 48)."""
    half = math.pi / TRUE["omega"]
    records = _extracted(TRUE, range(100, 160), t_end=5.3 * half, per_period=25.0)
    assert all(len(rec) == 6 for rec in records)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        results = fits.fit_batch(records, "oscillator", FREE, compare=False)
    converged = [r for r in results if r.converged]
    assert len(converged) >= 40
    for name in FREE:
        inside = sum(r.intervals[name][0] <= TRUE[name] <= r.intervals[name][1] for r in converged)
        assert inside >= 0.85 * len(converged), (name, inside, len(converged))


def test_a_drifting_zero_moves_the_turning_points_of_the_reading():
    """The reading `offset + drift t + y(t)` turns where `drift + y' = 0`, off the model's
    velocity zero by `-drift / y''` (here about 2e-4 s, alternating with the swing). Compared
    at the velocity zero, the times' residuals alternated (lag-1 -0.84, RMS 2.0e-4 s, and "the
    model does not explain the data"); at the reading's turning points they are noise (the
    fit's lag-1 -0.07, RMS 4.1e-5 s; without drift 2.7e-5 s), and omega's standard error 1.5e-4 -> 2.6e-5.
    omega was then still 3.3 of its standard errors off: the extraction's dry-friction level
    was measured about a fixed centre (`_dry_level`; docs/signals.md, "The level under a
    drifting zero"); about the drifting centre, 1.3."""
    drift = 0.05 * TRUE["a0"] / 8.0  # [signal units / s]
    t, y, _ = _oscillator_signal(
        **TRUE, t_end=8.0, seed=11, n_spikes=0, noise=2e-4, per_period=400.0
    )
    rec = fits.extract_turning_points(fits.Signal(t=t, y=y + drift * t, clock="stamps"))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = fits.fit(rec, "oscillator", FREE + ("drift",), compare=False)
    times = np.asarray(r.residuals["time"], float)
    times = times[np.isfinite(times)]
    assert np.sqrt(np.mean(times**2)) < 1e-4
    # (the fit's own lag-1, of the residuals weighed by their noise: the last few small
    # swings' times are noisier by up to 20 x and alternate by chance)
    assert abs(r.diagnostics["lag1"]) < 0.3 and not any("does not explain" in w for w in r.warnings)
    assert r.stderr["omega"] < 5e-5
    assert abs(r.params["omega"] - TRUE["omega"]) < 2 * r.stderr["omega"]
    # the dry-friction level at both sides, about the drifting centre
    kinks = np.asarray(rec.meta["kink"])
    assert np.all(np.abs(kinks / TRUE["xF"] - 1) < 0.04), kinks


def test_a_drifting_sensor_zero_is_fitted():
    """A sensor whose zero drifts by 3 % of a0 over the record (a strain gauge warming up):
    fitted without `drift` the model does not explain the data (flagged, its standard errors
    widened for it) and the warnings say that the residuals' shared part drifts (fit drift);
    with it the fit is clean and every parameter's interval holds the truth
    (three seeds measured: the drift within 1.4 of its standard errors, 1-3 % of its value).
    A record without times cannot have it fitted."""
    drift = 0.03 * TRUE["a0"] / 8.0  # [signal units / s]
    t, y, _ = _oscillator_signal(**TRUE, t_end=8.0, seed=11, n_spikes=0, per_period=40.0)
    rec = fits.extract_turning_points(fits.Signal(t=t, y=y + drift * t, clock="stamps"))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        plain = fits.fit(rec, "oscillator", FREE, compare=False)
        r = fits.fit(rec, "oscillator", FREE + ("drift",), compare=False)
    assert any(w.startswith("the model does not explain the data") for w in plain.warnings)
    (hint,) = [w for w in plain.warnings if "the sensor's zero may drift; fit drift" in w]
    assert hint.startswith("the residuals' mean over successive turning points drifts")
    assert abs(float(hint.split("a line of ")[1].split(" ")[0]) / drift - 1) < 0.05
    assert r.converged and not any("does not explain" in w or "drift" in w for w in r.warnings)
    truth = {**TRUE, "offset": TRUE["offset"] + drift * rec.time_origin, "drift": drift}
    for name, value in truth.items():
        lo, hi = r.intervals[name]
        assert lo <= value <= hi, (name, value, (lo, hi))
    assert abs(r.params["drift"] - drift) < 3 * r.stderr["drift"]
    assert r.units["drift"] == "signal/s"
    amplitudes = fits.record_from_sequence(positions=rec.positions)
    with pytest.raises(ValueError, match="drift can only be fitted from a record with times"):
        fits.fit(amplitudes, "oscillator", ("zeta", "xF", "a0", "drift"), {"omega": 20.0})


def test_sensor_hints_follow_the_residuals_shared_part():
    """`_sensor_hints` on residuals whose mean over successive turning points grows with the
    time (a drifting zero), follows the amplitude (sides that differ), or is noise; and not for
    a parameter the fit had."""
    from fits._models import SPACES
    from fits._result import _sensor_hints

    k = np.arange(40)
    times, amp = 0.16 * k, 5.0 * 0.97**k
    rec = fits.record_from_sequence(positions=amp * (-1.0) ** (k + 1), times=times)
    rng = np.random.default_rng(2)
    noise = 0.002 * rng.normal(size=k.size)
    side = (-1.0) ** k * 0.01  # what the sides do not share
    space = SPACES["oscillator"]

    def hints(shared, free=FREE):
        return _sensor_hints(
            [rec], [{"residuals": {"position": shared + side + noise}}], space, free
        )

    (drift,) = hints(-0.01 * times)
    assert "drifts with time" in drift and "fit drift" in drift
    assert abs(float(drift.split("a line of ")[1].split(" ")[0]) - 0.01) < 5e-4
    (asym,) = hints(0.02 * amp)
    assert "follows the amplitude" in asym and "fit asym" in asym
    assert hints(0.0 * times) == [] and hints(-0.01 * times, FREE + ("drift",)) == []


@pytest.mark.parametrize(
    "per_period, hum, spikes",
    [(200, 0.01, 0), (200, 0.05, 0), (60, 0.01, 3)],  # hum of a0; 60: 2.3 samples per hum period
)
def test_mains_hum_on_the_signal(per_period, hum, spikes):
    """50 Hz hum on a decay of 1.9 Hz (12 rad/s): found by its spectral line, the turning points
    are found on the signal averaged over its period and located with a 50 Hz sinusoid fitted
    beside the local polynomial. The extrema's errors are the clean signal's (rms within 1.6 x:
    0.05 % of a0 against 0.05 %, 0.12 against 0.08 % at 2.3 samples per hum period); before, the hum's own extrema were taken for turning points (36 "free
    decays", zeta 0.002 for 0.004) or, sampled at 2.3 per hum period, taken for noise (3
    turning points above the floor)."""
    t, y, truth = _oscillator_signal(
        12.0, 0.004, 0.01, 2.0, 0.0, 40.0, seed=5, n_spikes=spikes, per_period=per_period
    )
    hummed = y + hum * 2.0 * np.sin(2 * np.pi * 50 * t + 0.3)
    errors = []
    for signal in (hummed, y):
        rec = fits.extract_turning_points(fits.Signal(t=t, y=signal, clock="uniform"))
        want = _true_positions(rec, truth)
        big = np.abs(want) > 0.2
        errors.append(np.sqrt(np.mean((rec.positions - want)[big] ** 2)))
        if signal is hummed:
            assert abs(rec.meta["faster"]["period"] / 0.02 - 1) < 1e-4
            assert abs(rec.meta["faster"]["amplitude"] / (2 * hum) - 1) < 0.2
            hum_record = rec
        else:
            assert "faster" not in rec.meta
    assert errors[0] < 1.6 * errors[1], errors
    if hum == 0.05:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            r = fits.fit(hum_record, "oscillator", FREE, compare=False)
        for name, value in {"omega": 12.0, "zeta": 0.004, "xF": 0.01}.items():
            lo, hi = r.intervals[name]
            assert lo <= value <= hi, (name, value, (lo, hi))
        assert any("a faster oscillation rides on the signal (50 Hz" in w for w in r.warnings)
        # the samples of a fit on the whole time series: less the hum's sinusoid
        from fits._extract import sample_window

        ts, ys = sample_window(hum_record)
        clean = np.interp(ts + hum_record.time_origin, t, y)
        assert np.sqrt(np.mean((ys - clean) ** 2)) < 0.03 * hum * 2.0


@pytest.mark.parametrize("per_period", [30, 100])
def test_a_signal_without_noise_has_no_faster_oscillation(per_period):
    """A simulation's output, without noise (dry friction only, so the swing is kinked where it
    turns): its 11th harmonic stood far above the empty bins around it and was reported as "a
    faster oscillation" of 14.3 Hz and 1.7 % of a0 (measured, at 30 to 400 samples per period);
    its amplitude is 1.6e-5 of the swing's peak, below `_LINE_FLOOR`. Hum of 1e-3 of a0 on the
    same signal is still found (17.3 Hz: below half the sampling rate at 30 per period)."""
    t, y, truth = _oscillator_signal(
        2 * np.pi * 1.3,
        0.0,
        0.001,
        0.1,
        0.01,
        15.0,
        0,
        n_spikes=0,
        noise=0.0,
        per_period=per_period,
    )
    rec = fits.extract_turning_points(fits.Signal(t=t, y=y, clock="stamps"))
    assert "faster" not in rec.meta
    hummed = y + 1e-4 * np.sin(2 * np.pi * 17.3 * t)
    rec = fits.extract_turning_points(fits.Signal(t=t, y=hummed, clock="stamps"))
    assert abs(rec.meta["faster"]["period"] * 17.3 - 1) < 1e-3


def test_thinned_arrival_stamps_warn_and_name_the_clock(tmp_path):
    """Every 10th row of 80P.txt: its arrival stamps, thinned, no longer come in bursts and are
    kept as irregular; they scatter by 19 ms rms about the sampler's 26 Hz clock, 13 % of a
    half-swing. The fit says so and names the rate; given that rate, the warning goes."""
    lines = open(P80).read().splitlines()
    path = tmp_path / "thinned.txt"
    path.write_text("\n".join(lines[:2] + lines[2::10]) + "\n")
    rec = fits.read_record(path, series=True)
    rate = rec.clock["uniform_rate_hz"]
    assert abs(rate - 25.96) < 0.01

    def warned(record):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            r = fits.fit(record, "oscillator", FREE, compare=False, intervals=False)
        return any("time stamps are irregular and scatter by" in w for w in r.warnings)

    assert warned(rec)
    assert not warned(fits.read_record(path, series=True, rate=rate))


def test_a_noisy_signal_is_averaged_to_find_its_turning_points():
    """Noise of 2 % of a0 at 200 samples per period: the noise floor (swings down to 90 noise
    sd) would have cut the decay above its start (refused: "fewer than 3 turning points above
    the amplitude floor"); the turning points are found on the signal averaged over a quarter
    of a half-swing (its noise 0.16 of the samples') and located on the samples: 52 turning
    points, their RMS error 0.3 noise sd. (Fits of 12 seeds, measured: every fit converged,
    every 95 % interval of omega, zeta and xF held the truth, z-scores' spread 0.69-1.04.)"""
    t, y, truth = _oscillator_signal(
        12.0, 0.004, 0.01, 2.0, 0.0, 40.0, seed=5, n_spikes=0, per_period=200, noise=0.02
    )
    rec = fits.extract_turning_points(fits.Signal(t=t, y=y, clock="uniform"))
    assert len(rec) >= 40 and rec.meta["averaged"] > 0
    assert np.sqrt(np.mean((rec.positions - _true_positions(rec, truth)) ** 2)) < 0.4 * 0.02 * 2.0
    # extracted again with the record's hysteresis (a model with an angle unit: the
    # pendulum's fits) it is averaged alike (it was refused: "about 4.4 samples per period")
    from fits._fit import _extracted_for, _space

    again = _extracted_for(_space("pendulum"), rec, {})
    direct = fits.extract_turning_points(rec.signal, angle_unit=math.radians(1.0))
    np.testing.assert_array_equal(again.times, direct.times)
    assert again.meta["averaged"] == rec.meta["averaged"]


def test_a_signal_of_too_few_samples_per_period_is_refused():
    t, y, _ = _oscillator_signal(**TRUE, t_end=6.0, seed=1, n_spikes=0, per_period=4.0)
    with pytest.raises(ValueError, match="about 4 samples per period: at least 6 are needed"):
        fits.extract_turning_points(fits.Signal(t=t, y=y))


def test_dry_friction_turning_points_are_timed_without_the_kink_bias():
    """At a turning point with Coulomb friction the friction force reverses and the curvature
    steps (the motion is a cosine about `+xF` on one side, `-xF` on the other); a smooth local
    fit times such an extremum late, the more the smaller it is (measured before the kink was
    modelled: up to 0.5 ms at 2 deg with `xF = 0.15` deg, the amplitude-weighted times biased
    enough to choose a spurious drag law). The extraction measures the level from the decay of
    the extrema and refines each extremum with it: closed-form motion of a linear oscillator
    with Coulomb friction, noise-free, irregular sampling."""
    true = {"omega": 21.7, "zeta": 0.0, "xF": 0.15, "a0": 27.0, "offset": 0.0}
    t, y, turning = _oscillator_signal(**true, t_end=12.0, seed=1, n_spikes=0, noise=0.0)
    rec = fits.extract_turning_points(fits.Signal(t, y))
    j = int(np.argmin(np.abs(turning[:, 0] - rec.time_origin)))
    n = min(len(rec), len(turning) - j)
    assert n > 60
    np.testing.assert_allclose(rec.meta["kink"], true["xF"], rtol=0.03)
    # every swing after the release (timed from the record's edge) within 0.03 ms (the smooth
    # fit alone: 0.05 ms at 27 deg, 0.6 ms at 2 deg), the values within 0.2 % of a0
    times = rec.times[:n] + rec.time_origin
    np.testing.assert_allclose(times[1:], turning[j + 1 : j + n, 0], atol=3e-5)
    np.testing.assert_allclose(rec.positions[:n], turning[j : j + n, 1], atol=2e-3 * true["a0"])


def test_a_decay_that_sticks_after_a_few_swings_is_timed_with_its_dry_friction():
    """Dry friction of 6 % of a0: 8 turning points, then the mass sticks. With fewer than 6
    extrema a side the dry-friction level was taken as 0, and the kink it bends every turning
    point with was left out: the turning points came out 0.6-2.4 ms late, later at each swing
    (over 20 such signals sampled at 500 Hz, the fit's omega 1.7 standard errors low on
    average, its interval holding 20 in 12 of 20; now 19). Both sides' decrements per
    half-swing give the level now."""
    truth = {"omega": 20.0, "zeta": 0.001, "xF": 0.6, "a0": 10.0, "offset": 2.0}
    for seed in range(2):
        t, y, turning = _oscillator_signal(**truth, t_end=3.0, seed=seed, n_spikes=0, per_period=60)
        rec = fits.extract_turning_points(fits.Signal(t=t, y=y, clock="stamps"))
        assert len(rec) == 8 and np.array_equal(rec.k, np.arange(8))
        assert np.allclose(rec.meta["kink"], truth["xF"], rtol=0.1), rec.meta["kink"]
        late = rec.times[1:-1] + rec.time_origin - turning[1:7, 0]  # (the release at the edge,
        assert np.max(np.abs(late)) < 5e-4, late  # the stop in the rest that follows)


def test_hold_before_the_release_is_not_a_swing(synthetic_signal, tmp_path):
    """A record that starts with the mass held near the release point, nudged a little further
    out and then let go: the extraction starts at the release, not at the hold."""
    path, turning = synthetic_signal
    t, y = np.loadtxt(path, delimiter=",", skiprows=1).T
    rng = np.random.default_rng(7)
    t_hold = np.arange(-0.6, 0.0, 2e-3)
    y0 = turning[0, 1] + TRUE["offset"]
    nudge = -0.04 * TRUE["a0"] * np.clip((t_hold + 0.3) / 0.3, 0, 1) ** 2  # further from centre
    y_hold = y0 + 0.03 * TRUE["a0"] + nudge + rng.normal(0, 0.002 * TRUE["a0"], t_hold.size)
    held = tmp_path / "held.csv"
    np.savetxt(
        held,
        np.column_stack([np.concatenate([t_hold, t]), np.concatenate([y_hold, y])]),
        delimiter=",",
        header="t,angle",
        comments="",
    )
    rec = fits.read_record(str(held), series=True)
    plain = fits.read_record(path, series=True)
    n = min(len(rec), len(plain))
    assert n > 20
    np.testing.assert_allclose(rec.positions[1:n], plain.positions[1:n], atol=0.01 * TRUE["a0"])
    assert abs(rec.positions[0] - plain.positions[0]) < 0.05 * TRUE["a0"]
    assert np.sign(rec.positions[0] - rec.centre) != np.sign(rec.positions[1] - rec.centre)


def test_oscillator_fit_of_a_raw_signal(synthetic_signal):
    path, _ = synthetic_signal
    rec = fits.read_record(path, series=True)
    r = fits.fit(rec, "oscillator", FREE)
    assert r.converged
    assert abs(r.params["zeta"] / TRUE["zeta"] - 1) < 0.05
    assert abs(r.params["xF"] / TRUE["xF"] - 1) < 0.15
    assert abs(r.params["omega"] / TRUE["omega"] - 1) < 1e-3
    assert abs(r.params["offset"] - TRUE["offset"]) < 0.02
    for name in ("zeta", "xF", "a0", "offset"):  # (omega: extraction timing bias ~3e-4)
        assert abs(r.params[name] - TRUE[name]) < 5 * r.stderr[name], name
    assert r.model_comparison["best_bic"] == "both"
    # the decrement method is the start and the comparison: close, but the fit is better
    assert abs(r.decrement["zeta"] / TRUE["zeta"] - 1) < 0.2


def test_outliers_are_judged_in_units_of_each_times_precision():
    """An extremum of a small swing is timed worse (`noise / (a omega^2)`): its time residual is
    judged against its own precision, not the record's large swings'. Ten raw signals without
    spikes: no turning point flagged (before, the robust scale of the unweighted time residuals
    flagged 1-4 small swings' times in 5 of the 10). A time 5 ms off (about 25 of its standard
    deviations) at a large swing still is."""
    records = _extracted(TRUE, range(200, 210), t_end=6.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        results = fits.fit_batch(records, "oscillator", FREE, compare=False, intervals=False)
    assert [r.outliers for r in results] == [[]] * 10
    rec = records[0]
    times = rec.times.copy()
    times[3] += 0.005
    bad = dataclasses.replace(rec, times=times)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = fits.fit(bad, "oscillator", FREE, compare=False, intervals=False)
    assert r.outliers == [int(rec.k[3])]


def _taps(path, taps, t_end=10.0, seed=5):
    """Viscous free decays (5 Hz, zeta 0.01) excited from the centre by taps `(time [s],
    amplitude)` after a quiet lead-in, offset 0.1, noise 0.002, sampled at 1 kHz."""
    rng = np.random.default_rng(seed)
    w, zeta = 2 * np.pi * 5.0, 0.01
    t = np.arange(0, t_end, 1e-3)
    y = 0.1 + rng.normal(0, 0.002, t.size)
    for t0, amplitude in taps:
        tau = np.maximum(t - t0, 0.0)
        y += (
            (t >= t0) * amplitude * np.exp(-zeta * w * tau) * np.sin(w * np.sqrt(1 - zeta**2) * tau)
        )
    np.savetxt(path, np.column_stack([t, y]), delimiter=",", header="time,x", comments="")
    return w, zeta


def test_a_decay_excited_from_rest_after_a_quiet_lead_in(tmp_path):
    """A tap or pluck from the centre recorded with a quiet pre-trigger: the first swing, from
    the centre, is half the next and no turning point; the record starts at the first peak
    (before 2026-11-27: refused, "fewer than 3 turning points above the amplitude floor", the
    quiet samples' extrema taken for the decay's end), as was a mass pulled aside and held
    after such a lead-in. Several taps in one file: the decay of the largest swing is fitted
    and the fit says where the others start."""
    w, zeta = _taps(tmp_path / "tap.csv", [(1.0, 1.0)])
    rec = fits.read_record(str(tmp_path / "tap.csv"), series=True)
    quarter = np.pi / 2 / w
    assert abs(rec.time_origin - (1.0 + quarter)) < 2e-3 and "decays" not in rec.meta
    assert abs(rec.positions[0] - 0.1 - np.exp(-zeta * w * quarter)) < 0.01
    r = fits.fit(rec, "oscillator", ("omega", "zeta", "a0", "offset"), compare=False)
    assert r.converged and abs(r.params["omega"] / w - 1) < 1e-4
    assert abs(r.params["zeta"] / zeta - 1) < 0.01
    _taps(tmp_path / "taps.csv", [(1.0, 1.0), (11.0, 1.5), (21.0, 0.8)], t_end=30.0)
    rec = fits.read_record(str(tmp_path / "taps.csv"), series=True)
    starts = rec.meta["decays"]["starts"]
    assert np.allclose(starts, [1.05, 11.05, 21.05], atol=3e-3)
    assert rec.meta["decays"]["taken"] == starts[1]  # (a sample's time; the origin refined)
    assert abs(rec.time_origin - starts[1]) < 2e-3
    with pytest.warns(UserWarning, match="holds 3 free decays"):
        r = fits.fit(rec, "oscillator", ("omega", "zeta", "a0", "offset"), compare=False)
    assert any("decay 1 fitted" in msg for msg in r.warnings)
    assert abs(r.params["zeta"] / zeta - 1) < 0.01
    # quiet, then pulled aside over 1 s, held for 1 s and released at 3 s: the release is
    # the hold (refused before, as the tap was)
    t = np.arange(0, 12, 1e-3)
    held = np.where(t < 3, np.clip(t - 1, 0, 1), 0.0)
    tau = np.maximum(t - 3, 0)
    wd = w * np.sqrt(1 - zeta**2)
    decay = np.exp(-zeta * w * tau) * (np.cos(wd * tau) + zeta * w / wd * np.sin(wd * tau))
    y = np.where(t < 3, held, decay) + 0.2 + np.random.default_rng(2).normal(0, 0.002, t.size)
    np.savetxt(tmp_path / "hold.csv", np.column_stack([t, y]), delimiter=",", header="t,x")
    rec = fits.read_record(str(tmp_path / "hold.csv"), series=True)
    assert rec.meta["release"] == fits.HELD_RELEASE and abs(rec.time_origin - 3.0) < 2e-3
    assert abs(rec.positions[0] - 1.2) < 0.01 and "decays" not in rec.meta
    # every decay, in time order, fitted jointly with shared omega and zeta; or one by index
    path = str(tmp_path / "taps.csv")
    every = fits.read_decays(path)
    assert [d.meta["decays"]["index"] for d in every] == [0, 1, 2]
    assert np.allclose([d.time_origin for d in every], starts, atol=2e-3)
    assert fits.read_record(path, series=True, decay=2).time_origin == every[2].time_origin
    joint = fits.fit(
        every,
        "oscillator",
        ("omega", "zeta", "a0", "offset"),
        shared=("omega", "zeta"),
        compare=False,
        intervals=False,
    )
    assert joint.converged and abs(joint.params["zeta"] / zeta - 1) < 0.003
    assert not any("free decays" in msg for msg in joint.warnings)  # none left out
    with pytest.raises(ValueError, match="decay 3 asked for, but the signal holds 3 free"):
        fits.read_record(path, series=True, decay=3)
    # another decay by a window [s from the first sample]; its times stay on the file's clock
    rec = fits.read_record(str(tmp_path / "taps.csv"), series=True, window=(20.0, None))
    assert "decays" not in rec.meta and abs(rec.time_origin - starts[2]) < 2e-3
    with pytest.raises(ValueError, match=r"window \[40, inf\] s holds 0 samples"):
        fits.read_record(str(tmp_path / "taps.csv"), series=True, window=(40.0, None))
    with pytest.raises(ValueError, match="start < end"):
        fits.read_signal(str(tmp_path / "taps.csv"), window=(5.0, 3.0))
    with pytest.raises(ValueError, match="apply to raw signals"):
        fits.read_record(str(tmp_path / "taps.csv"), series=False, window=(5.0, 9.0))


def test_a_clipped_signal_leaves_its_cut_off_extrema_out(synthetic_signal, tmp_path):
    """A saturated sensor: the synthetic record clipped at 70 % of its release amplitude above
    the centre and 60 % below. The extrema on the flat tops are no turning points (read, they
    were taken at the clipping level: the fit found Coulomb friction where there is mostly
    viscous damping); they are left out (their `k` skipped), the fit of the rest recovers the
    parameters as the unclipped record's does and says what was left out. Unclipped records,
    also with a hold at their extreme value before the release, are not marked."""
    path, turning = synthetic_signal
    t, y = np.loadtxt(path, delimiter=",", skiprows=1).T
    hi, lo = TRUE["offset"] + 0.7 * TRUE["a0"], TRUE["offset"] - 0.6 * TRUE["a0"]
    clipped = tmp_path / "clipped.csv"
    np.savetxt(
        clipped,
        np.column_stack([t, np.clip(y, lo, hi)]),
        delimiter=",",
        header="t,angle",
        comments="",
    )
    rec = fits.read_record(str(clipped), series=True)
    assert rec.meta["clipped"] == {"max": hi, "min": lo}
    # left out: exactly the extrema whose true value lies beyond a level (the first 9 and
    # the 11th; the 10th, 8.75 against the level 9, is kept)
    truth = turning[: rec.k[-1] + 1, 1] + TRUE["offset"]
    beyond = np.nonzero((truth > hi) | (truth < lo))[0]
    assert beyond.size == 10 and set(rec.k).isdisjoint(beyond)
    assert len(rec) == rec.k[-1] + 1 - beyond.size
    assert np.all((rec.positions < hi) & (rec.positions > lo))
    plain = fits.read_record(path, series=True)
    assert "clipped" not in plain.meta
    r = fits.fit(rec, "oscillator", FREE)
    assert r.converged and any("clipped at" in w for w in r.warnings)
    assert abs(r.params["zeta"] / TRUE["zeta"] - 1) < 0.05
    assert abs(r.params["xF"] / TRUE["xF"] - 1) < 0.25
    assert abs(r.params["omega"] / TRUE["omega"] - 1) < 1e-3
    assert abs(r.params["a0"] / TRUE["a0"] - 1) < 0.01
    # a hold at the extreme value before the release is one flat run: not clipping
    t_hold = np.arange(-0.5, 0.0, 2e-3)
    y0 = float(np.min(y[:20]))
    held = tmp_path / "held.csv"
    np.savetxt(
        held,
        np.column_stack([np.concatenate([t_hold, t]), np.concatenate([0 * t_hold + y0, y])]),
        delimiter=",",
        header="t,angle",
        comments="",
    )
    assert "clipped" not in fits.read_record(str(held), series=True).meta


def test_a_record_clipped_from_its_release_keeps_its_swing_count(synthetic_signal, tmp_path):
    """The synthetic record clipped at 30 % of its release amplitude above the centre and 70 %
    below: the release at the first sample is on the lower level, and the quartic through the
    next flat run puts its vertex beyond the level, so the release was taken for a record
    starting mid-swing and dropped: every `k` one short, the fit's `a0` that of the first
    swing (9.59 [9.53, 9.65] for 10). And the dry-friction level was measured from the
    extrema left on their own (a run of minima: "local centres" among them), 0 for 0.05, and
    the turning points timed by up to 1.1 ms late (at 500 Hz). Over 20 seeds the intervals of
    `a0` held the truth in 0 and 20 of 20 before and after, `omega`'s in 18 and 17."""
    path, turning = synthetic_signal
    t, y = np.loadtxt(path, delimiter=",", skiprows=1).T
    clipped = tmp_path / "clipped.csv"
    np.savetxt(
        clipped, np.column_stack([t, np.clip(y, -5.0, 5.0)]), delimiter=",", header="t,angle"
    )
    rec = fits.read_record(str(clipped), series=True)
    assert rec.meta["clipped"] == {"max": 5.0, "min": -5.0} and rec.k[0] == 10
    at = rec.times + rec.time_origin
    assert np.array_equal(rec.k, [np.argmin(np.abs(turning[:, 0] - x)) for x in at])
    assert np.allclose(rec.meta["kink"], TRUE["xF"], rtol=0.3)
    r = fits.fit(rec, "oscillator", FREE)
    assert r.converged
    for name in ("omega", "a0"):
        lo, hi = r.intervals[name]
        assert lo < TRUE[name] < hi, name


def test_a_clipped_record_with_quantisation_noise_is_seen_as_clipped(tmp_path):
    """80P.txt clipped at +18 and -12 deg (its swings reach +32 and -22): its noise is the
    encoder's step (0.023 deg), so the corners of each flat run depart from the cubic through
    their neighbours by hundreds of noise levels, and the despiking replaced them as spikes,
    which hid the runs (the fit then took the flat tops for turning points: position residuals'
    lag-1 autocorrelation -0.70, 11 outliers). The runs are now kept: the cut-off extrema are
    left out, and the others are the unclipped record's (same turning points, same swing
    numbers to within one fixed shift)."""
    lines = open(P80).read().splitlines()
    rows = [line.split(", ") for line in lines[2:]]
    clipped = tmp_path / "clipped.txt"
    clipped.write_text(
        "\n".join(
            lines[:2] + [f"{a}, {b}, {min(max(float(c), -12.0), 18.0):.2f}" for a, b, c in rows]
        )
        + "\n"
    )
    rec = fits.read_record(str(clipped), series=True)
    plain = fits.read_record(P80, series=True)
    assert rec.meta["clipped"] == {"max": 18.0, "min": -12.0}
    assert np.all((rec.positions > -12.0) & (rec.positions < 18.0))
    t_rec, t_plain = rec.times + rec.time_origin, plain.times + plain.time_origin
    j = np.array([np.argmin(np.abs(t_plain - x)) for x in t_rec])
    same = np.abs(t_rec - t_plain[j]) < 1e-3  # the clipped record goes on longer: lower floor
    assert same.sum() >= 80
    assert np.max(np.abs(rec.positions - plain.positions[j])[same]) < 0.01
    assert np.unique((rec.k - j)[same]).size == 1


def test_the_quartics_bias_at_a_pendulums_large_swings_is_removed(synthetic_signal, monkeypatch):
    """A pendulum swinging at 120 deg is far from sinusoidal: the local quartic through the
    samples near an extremum overstates its amplitude (by about 0.05 deg here), a trend in the
    amplitude that a fit reads as quadratic drag. The extraction measures the bias from sextic
    fits through the same samples, smoothed over the record, and removes it where it is
    significant. Reference: the exact frictionless pendulum, `theta = 2 arcsin(k sn(omega t +
    K, k))`, `k = sin(A / 2)` (scipy.special.ellipj), sampled at 259.6 Hz, noise-free. Where no
    bias shows (the noisy synthetic record of the tests, swings of at most 10 units), the
    values are the quartic's, unchanged."""
    from scipy.special import ellipj, ellipk

    import fits._extract as io

    amplitude, omega = 120.0, 21.7
    k = math.sin(math.radians(amplitude) / 2)
    t = np.arange(0.0, 6.0, 1 / 259.6)
    sn = ellipj(omega * t + ellipk(k * k), k * k)[0]
    theta = np.degrees(2 * np.arcsin(k * sn))
    rec = fits.extract_turning_points(fits.Signal(t=t, y=theta))
    inner = np.abs(rec.positions[1:-1])  # (the first and last extrema are cut by the edges)
    assert inner.size > 20
    np.testing.assert_allclose(inner, amplitude, atol=0.01)
    monkeypatch.setattr(io, "_shape_bias", lambda x4, *_: np.zeros_like(x4))
    quartic = np.abs(fits.extract_turning_points(fits.Signal(t=t, y=theta)).positions[1:-1])
    assert np.max(np.abs(quartic - amplitude)) > 0.03  # (what is removed)
    path, _ = synthetic_signal
    plain = fits.read_record(path, series=True).positions
    monkeypatch.undo()
    np.testing.assert_array_equal(fits.read_record(path, series=True).positions, plain)


def _pendulum(zeta=0.0, xF=0.0, cq=0.0):
    """The sine-law pendulum at 21.7 rad/s [rad, s]."""
    laws = (vmj.ViscousDamping(zeta), vmj.CoulombDamping(xF), vmj.QuadraticDamping(cq))
    return vmj.Oscillator(21.7, vmj.SineRestoring(0.0, 0.0), laws)


def test_a_pendulums_decrements_against_the_exact_solver():
    """The shapes of a pendulum's Coulomb, viscous and quadratic-drag decrements per
    half-swing (`fits._extract._pendulum_decrements`, relative to the linear oscillator's `2 xF`,
    `pi zeta A`, `4 cq A^2 / 3`) against the exact solver's half-swings from 120 and 60 deg
    (each law alone, weak: the shapes are first order in the damping), at the half-swing's
    mean amplitude: within 1e-6 (2.418 for Coulomb at 120 deg)."""
    from fits._extract import _pendulum_decrements

    for a0 in (120.0, 60.0):
        for i, (law, linear) in enumerate(
            (
                (dict(xF=1e-4), lambda A: 2e-4),
                (dict(zeta=1e-4), lambda A: math.pi * 1e-4 * A),
                (dict(cq=1e-4), lambda A: 4 / 3 * 1e-4 * A * A),
            )
        ):
            seq = vmj.turning_points(_pendulum(**law), math.radians(a0), 4, vmj.Exact())
            a = np.abs(np.concatenate([[math.radians(a0)], np.asarray(seq.positions)]))
            mid = 0.5 * (a[:-1] + a[1:])
            got = (a[:-1] - a[1:]) / linear(mid)
            np.testing.assert_allclose(_pendulum_decrements(mid)[i], got, rtol=1e-6)


def test_the_dry_friction_level_of_a_pendulums_large_swings():
    """The extraction's dry-friction level (which bends every turning point, `_refine`) on the
    exact pendulum (sine law, zeta 0.005, xF 0.06 deg) released from 120 deg, noise-free: from
    the linear oscillator's decrements it comes out 0.40 and 0.38 deg, 6-7 times too large,
    and times the extrema early (a trend in the times that the fits read as quadratic drag:
    the drag law chosen on synthetic records from 120 deg); from the pendulum's
    (`angle_unit`) 0.056 and 0.057 deg. The fits of the pendulum model extract such a record
    again with its angle unit (`fits._fit._extracted_for`)."""
    from fits._fit import _extracted_for, _space

    n = int(8 * 259.6)
    with vmj.assume_valid():
        traj = vmj.simulate(
            _pendulum(0.005, math.radians(0.06)), -math.radians(120), 0.0, (n - 1) / 259.6, n_save=n
        )
    signal = fits.Signal(t=np.asarray(traj.ts), y=np.degrees(np.asarray(traj.xs)))
    linear = fits.extract_turning_points(signal)
    assert min(linear.meta["kink"]) > 0.3
    rec = fits.extract_turning_points(signal, angle_unit=math.radians(1.0))
    np.testing.assert_allclose(rec.meta["kink"], 0.06, rtol=0.1)
    again = _extracted_for(_space("pendulum"), linear, {})
    assert again.meta["kink"] == rec.meta["kink"]
    np.testing.assert_array_equal(again.times, rec.times)
    assert _extracted_for(_space("pendulum"), rec, {}) is rec
    assert _extracted_for(_space("oscillator"), linear, {}) is linear


@pytest.mark.long  # 20-25 s: with the long runs, for CI's time
def test_batched_equals_single_and_adam_agrees(synthetic_signal):
    path, _ = synthetic_signal
    rec = fits.read_record(path, series=True)
    peaks = fits.record_from_sequence(positions=rec.positions[:40], times=rec.times[:40])
    peaks = fits.Record(k=peaks.k, positions=peaks.positions, times=peaks.times, centre=rec.centre)
    free = ("zeta", "xF", "a0", "offset")
    given = {"omega": float(np.pi / np.median(np.diff(rec.times)))}
    one = fits.fit(peaks, "oscillator", free, given, compare=False, intervals=False)
    both = fits.fit_batch([peaks, peaks], "oscillator", free, given, compare=False, intervals=False)
    for name in free:
        assert both[0].params[name] == pytest.approx(one.params[name], rel=1e-8)
        assert both[1].params[name] == pytest.approx(one.params[name], rel=1e-8)
    adam = fits.fit(
        peaks,
        "oscillator",
        free,
        given,
        compare=False,
        optimizer="adam",
        loss="huber",
        intervals=False,
    )
    assert abs(adam.params["zeta"] / one.params["zeta"] - 1) < 0.05
    assert abs(adam.params["xF"] - one.params["xF"]) < 3 * one.stderr["xF"]


def test_pendulum_80P_end_to_end(pendulum):
    record, r = pendulum
    assert 100 <= len(record) <= 160
    assert r.converged
    assert 21.5 < r.params["omega"] < 22.0  # the source repository reports ~21.8 rad/s
    for name in ("zeta", "xF"):
        assert 0 < r.stderr[name] < r.params[name]
    assert 0.003 < r.params["zeta"] < 0.012
    comp = r.model_comparison
    assert set(comp) >= {"coulomb", "viscous", "both"}
    assert comp["best_aic"] == "both" and comp["coulomb"]["aic"] > comp["viscous"]["aic"]


def test_cli_json_shape_and_errors(tmp_path, capsys):
    path = _write(
        tmp_path,
        "k,amplitude\n"
        + "\n".join(
            f"{k},{a}" for k, a in enumerate([10.0, 9.3, 8.62, 7.95, 7.3, 6.67, 6.05, 5.45])
        ),
    )
    assert (
        main(
            [
                "fit",
                path,
                "--model",
                "oscillator",
                "--fit",
                "zeta,xF",
                "--set",
                "a0=10,offset=0",
                "--json",
            ]
        )
        == 0
    )
    out = json.loads(capsys.readouterr().out)
    assert list(out) == [
        "model",
        "params",
        "stderr",
        "stderr_gn",
        "intervals",
        "correlation",
        "converged",
        "iterations",
        "rms",
        "diagnostics",
        "model_comparison",
        "residuals_of",
        "units",
    ]
    assert set(out["params"]) == {"zeta", "xF"} and out["converged"] is True
    assert len(out["correlation"]) == 2
    assert main(["fit", _write(tmp_path, "", "e.csv"), "--model", "oscillator"]) == 2
    assert "vmj: error:" in capsys.readouterr().err
    assert main(["fit", path, "--model", "oscillator", "--set", "zeta"]) == 2


def test_energy_forward_model_agrees_with_the_exact_one(pendulum):
    """The closed-form energy-balance recurrence as forward model (`forward="energy"`): for
    constant mass it differs from the exact half-swing map only at second order in zeta."""
    record, exact = pendulum
    r = fits.fit(record, "oscillator", FREE, forward="energy", compare=False)
    assert r.converged
    assert abs(r.params["zeta"] / exact.params["zeta"] - 1) < 0.02
    assert abs(r.params["omega"] / exact.params["omega"] - 1) < 1e-4
    assert abs(r.params["xF"] - exact.params["xF"]) < 3 * exact.stderr["xF"]


def _held(d, slot, value):
    """`d` with slot `slot` held at `value` (no longer moved by p)."""
    return eqx.tree_at(
        lambda z: (z.code, z.held), d, (d.code.at[slot].set(HELD), d.held.at[slot].set(value))
    )


def test_fit_jacobian_matches_finite_differences(synthetic_signal):
    """The materialised Jacobian handed to the solvers (custom_jvp) against central differences,
    and the tangent the solvers see, J (dtheta/dp) dp."""
    path, _ = synthetic_signal
    rec = fits.read_record(path, series=True)
    space = SPACES["oscillator"]
    start = {"omega": 20.1, "zeta": 0.011, "xF": 0.04, "a0": 9.9, "offset": 1.9}
    prob = _problem(space, [rec], [start], FREE, ())
    job = _make_job(0, prob, space, "both", FREE, {}, {}, True)
    N = _bucket(len(rec))
    _init_weights(prob, N, space)
    arrays = _job_arrays(job, prob, _Shape(N, len(FREE), _bucket(int(rec.k[-1])), 1, {}))
    p = jnp.asarray(arrays.pop("p"))
    d = _Data(**{k: jnp.asarray(v) for k, v in arrays.items()})
    n = _bucket(int(rec.k[-1]))
    r, J = _residual_and_jacobian(space, "exact", n, p, d)
    values = _values(d, p)
    for i in range(len(FREE)):
        h = 1e-6 * max(abs(float(values[i])), 1e-3)
        up = _residual_and_jacobian(space, "exact", n, p, _held(d, i, values[i] + h))[0]
        dn = _residual_and_jacobian(space, "exact", n, p, _held(d, i, values[i] - h))[0]
        np.testing.assert_allclose(
            np.asarray(J[:, i]),
            np.asarray((up - dn) / (2 * h)),
            rtol=1e-5,
            atol=1e-6 * float(jnp.max(jnp.abs(J[:, i]))),
        )
    dp = jnp.ones_like(p)
    _, (tangent, _) = jax.jvp(
        lambda q: _residual_and_jacobian(space, "exact", n, q, d), (p,), (dp,)
    )
    np.testing.assert_allclose(
        np.asarray(tangent), np.asarray(J @ (derivative(d.code, d.lo, d.hi, d.scale, p) * dp))
    )


def test_identifiability_warning(synthetic_signal):
    """Six noisy turning points cannot separate a small Coulomb band from viscous damping."""
    path, _ = synthetic_signal
    rec = fits.read_record(path, series=True)
    short = fits.Record(k=rec.k[:6], positions=rec.positions[:6], centre=rec.centre)
    with pytest.warns(UserWarning, match="identifiable"):
        r = fits.fit(short, "oscillator", ("zeta", "xF", "a0", "offset"), compare=False)
    assert any("zeta and xF" in w for w in r.warnings)


def test_critical_damping_is_refused(pendulum):
    record, _ = pendulum
    with pytest.raises(ValueError, match=r"zeta must be finite and in \[0, 1\)"):
        fits.fit(record, "oscillator", ("omega", "xF", "a0", "offset"), {"zeta": 1.0})


def test_a_raw_signal_in_millimetres_is_scaled_to_metres_for_the_si_models(tmp_path):
    """`fits._record.in_metres` (what a fit of an SI model reads, `fits._fit._problem`): a raw
    signal whose column is `x_mm` becomes the same record in metres, positions, centre, noise
    and samples alike, the unit named in its meta; a column without a unit (or in m) is left
    as it is; one named in an angle unit is refused."""
    from fits._record import in_metres

    t, x, _ = _oscillator_signal(20.0, 0.01, 0.5, 10.0, 1.0, 8.0, seed=3, n_spikes=0)
    for name, unit, scale in (
        ("x_mm", "mm", 1e-3),
        ("x (um)", "um", 1e-6),
        ("x [m]", None, 1.0),
        ("x", None, 1.0),
    ):
        text = f"time,{name}\n" + "".join(f"{a:.6f},{b:.6f}\n" for a, b in zip(t, x))
        rec = fits.read_record(_write(tmp_path, text), series=True)
        si = in_metres(rec)
        assert si.meta.get("length_unit") == unit
        np.testing.assert_allclose(si.positions, rec.positions * scale)
        np.testing.assert_allclose(si.signal.y, rec.signal.y * scale)
        assert si.centre == pytest.approx(rec.centre * scale) and si.noise == pytest.approx(
            rec.noise * scale
        )
        np.testing.assert_array_equal(si.times, rec.times)
    text = "time,theta_deg\n" + "".join(f"{a:.6f},{b:.6f}\n" for a, b in zip(t, x))
    with pytest.raises(ValueError, match="'theta_deg' holds an angle, and the rope model's"):
        in_metres(fits.read_record(_write(tmp_path, text), series=True), "rope")


def test_an_oscillation_held_before_the_release_is_warned_of(tmp_path):
    """A free decay (`_oscillator_signal`) after 2 s of a steady oscillation of its release
    amplitude (a shaker switched off; at 20 rad/s about 13 half-swings): the amplitudes fall
    faster after the release than before, which no free decay does, and the oscillator fit
    says so, naming a turning point within two windows of the release. The decay alone gives
    no such warning."""
    from fits._result import _steepening

    omega, a0 = 20.0, 10.0
    t, y, _ = _oscillator_signal(omega, 0.01, 0.05, a0, 0.5, 10.0, seed=4, n_spikes=0)
    lead = np.arange(-2.0, 0.0, 2e-3)
    held = (
        0.5
        + a0 * np.cos(omega * lead + np.pi)
        + np.random.default_rng(5).normal(0, 0.02, lead.size)
    )
    free = _write(tmp_path, "time,x\n" + "".join(f"{a:.6f},{b:.6f}\n" for a, b in zip(t, y)))
    both = "".join(f"{a + 2.0:.6f},{b:.6f}\n" for a, b in zip(np.r_[lead, t], np.r_[held, y]))
    forced = _write(tmp_path, "time,x\n" + both, "forced.csv")
    assert _steepening(fits.read_record(free, series=True)) is None
    rec = fits.read_record(forced, series=True)
    message = _steepening(rec)
    assert message is not None and "fall faster after turning point k = " in message
    k = int(message.split("k = ")[1].split()[0])
    release = int(np.argmin(np.abs(rec.times + rec.time_origin - 2.0)))
    assert abs(k - int(rec.k[release])) <= 2 * max(4, 2 * (len(rec) // 16))
    got = fits.fit(rec, "oscillator", ("omega", "zeta", "xF", "a0", "offset"), compare=False)
    assert any(w == message for w in got.warnings)
