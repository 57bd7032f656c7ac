"""The pendulum identification model (issue 11): synthetic raw records of every restoring x
dissipation law set, read like a user's file (arrival-time stamps in bursts, sensor offset and
side-dependent gain, noise 0.2 % of the amplitude), must give every parameter within 3 %
(damping within 10 %) and the true law set by BIC; the public record 80P.txt must be explained
(residual lag-1 autocorrelation at least halved against the plain oscillator fit).

The records are simulated once per law set (module fixture) and fitted with `fits.fit_batch`
over the seeds: one compiled solve for every law set.
"""

import collections
import dataclasses
import math
import os
import time
import warnings
from importlib.resources import files

import numpy as np
import pytest

import fits
import vmj
from fits._pendulum import DEGREE, FREE, PENDULUM, named_angle_unit

FS = 259.6  #: the logger's sampling rate [Hz]
RELEASE = 27.0  #: release amplitude of the simulations [deg]
DURATION = 12.0  #: length of the records [s]
SENSOR = {"offset": 4.0, "asym": 0.03}
BASE = {"omega": 21.7, "b2": -0.2}
#: the dissipation law sets and their true values (xF [deg], cq [1/deg])
DISSIPATION = {
    "viscous": {"zeta": 0.008},
    "coulomb": {"xF": 0.15},
    "viscous+coulomb": {"zeta": 0.005, "xF": 0.06},
    "viscous+coulomb+quadratic": {"zeta": 0.003, "xF": 0.04, "cq": 4e-4},
}
MAX_STEPS = 200  #: Levenberg-Marquardt steps per solve
DAMPING = ("zeta", "xF", "cq")  #: within 10 %; every other parameter within 3 %


def oscillator(truth: dict, sine: bool) -> vmj.Oscillator:
    """The true model in radians (`truth` in degrees, as the fit reports it)."""
    law = (vmj.SineRestoring if sine else vmj.PolynomialRestoring)(truth["b2"], 0.0)
    return vmj.Oscillator(
        truth["omega"],
        law,
        (
            vmj.ViscousDamping(truth.get("zeta", 0.0)),
            vmj.CoulombDamping(truth.get("xF", 0.0) * DEGREE),
            vmj.QuadraticDamping(truth.get("cq", 0.0) / DEGREE),
        ),
    )


def simulate(truth: dict, sine: bool):
    """Sample times [s], true angles [deg] sampled at FS from a little before the first turning
    point after the release, and the true turning points `(times [s], angles [deg])`."""
    model = oscillator(truth, sine)
    first = 13  # samples dropped: the record starts during the first half-swing, as 80P.txt
    n = int(DURATION * FS) + first
    with vmj.assume_valid():
        traj = vmj.simulate(model, -RELEASE * DEGREE, 0.0, (n - 1) / FS, n_save=n)
        seq = vmj.turning_points(model, RELEASE * DEGREE, 200, vmj.Exact())
    return (
        np.asarray(traj.ts)[first:],
        np.asarray(traj.xs)[first:] / DEGREE,
        (np.asarray(seq.times), np.asarray(seq.positions) / DEGREE),
    )


def write_raw(path, ts, angles, seed: int):
    """A raw record as the pendulum's serial logger writes it: the sensor's reading with
    noise 0.2 % of the release amplitude, stamped with the time each row ARRIVED at the
    computer (bursts of 15-20 rows 0.5 ms apart after the burst's last sample, then a gap of
    50-60 ms), `HH:MM:SS.mmm`, a coarse elapsed-time column, angles to 0.01 deg."""
    rng = np.random.default_rng(seed)
    reading = SENSOR["offset"] + angles * (1 + SENSOR["asym"] * np.sign(angles))
    reading = reading + rng.normal(0.0, 0.002 * RELEASE, angles.size)
    stamps = np.empty(angles.size)
    i = 0
    while i < angles.size:
        j = min(i + int(rng.integers(15, 21)), angles.size)
        stamps[i:j] = ts[j - 1] + rng.uniform(0.0, 2e-3) + 5e-4 * np.arange(j - i)
        i = j
    stamps = np.maximum.accumulate(stamps) + 16 * 3600.0 + rng.uniform(0, 60)
    lines = ["Timestamp, Time_Elapsed(s), Angle(deg)", "-" * 37]
    for s, y in zip(stamps, reading):
        ms = int(round(s * 1000))
        h, rest = divmod(ms, 3_600_000)
        m, rest = divmod(rest, 60_000)
        elapsed = 0.06 * math.floor((s - stamps[0]) / 0.06)
        lines.append(
            f"{h:02d}:{m:02d}:{rest // 1000:02d}.{rest % 1000:03d}, {elapsed:.3f}, {y:.2f}"
        )
    path.write_text("\n".join(lines) + "\n")


def truth_of_record(record, truth: dict, turning) -> dict:
    """The true parameters as the record sees them: its `k = 0` is a turning point of the
    simulation (the release of the fitted model), found by its reading; `b2` in the model's
    coordinate (released at `-a0`), whose sign is the record's orientation times the
    simulation's."""
    times, angles = turning
    a = np.abs(angles[:4])
    first = float(record.positions[0]) - SENSOR["offset"]
    first /= 1 + SENSOR["asym"] * np.sign(first)
    j = int(np.argmin(np.abs(a - abs(first))))
    return {**truth, **SENSOR, "a0": float(a[j]), "b2": record.orientation * truth["b2"]}


LAW_SETS = [(sine, label) for sine in (True, False) for label in DISSIPATION]


def label(sine: bool, dissipation: str) -> str:
    return ("sine" if sine else "linear") + ":" + dissipation


class Trajectories(dict):
    """The simulated law sets, each simulated once when first asked for."""

    def __missing__(self, key):
        sine, diss = key
        truth = {**BASE, **DISSIPATION[diss]}
        self[key] = (truth, *simulate(truth, sine))
        return self[key]


@pytest.fixture(scope="module")
def trajectories():
    return Trajectories()


def records_for(trajectories, tmp_path, sine, diss, seeds):
    truth, ts, angles, turning = trajectories[sine, diss]
    recs, truths = [], []
    for seed in seeds:
        path = tmp_path / f"{'sine' if sine else 'linear'}-{diss}-{seed}.txt"
        write_raw(path, ts, angles, seed)
        rec = fits.read_record(path, series=True)
        recs.append(rec)
        truths.append(truth_of_record(rec, truth, turning))
    return recs, truths


def fit_law_set(trajectories, tmp_path, sine, diss, seeds, compare=True):
    recs, truths = records_for(trajectories, tmp_path, sine, diss, seeds)
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        # one record per chunk, the chunks on every core: a vmapped solve runs as many steps
        # as its slowest lane, so records batched together wait for each other (4 seeds: 143
        # s batched, 92 s in chunks of one on 2 cores)
        results = fits.fit_batch(
            recs,
            "pendulum",
            FREE,
            intervals=False,
            max_steps=MAX_STEPS,
            compare=compare,
            chunk_size=1,
        )
    return recs, truths, results, time.perf_counter() - t0


def errors(result, truth) -> dict:
    """Relative errors of the fitted parameters of the chosen law set."""
    out = {}
    for name, value in result.params.items():
        if name in ("offset", "b2", "asym", "a0", "omega", "zeta", "xF", "cq"):
            ref = truth.get(name, 0.0)
            out[name] = abs(value - ref) / abs(ref) if ref else abs(value)
    return out


def test_the_clock_of_a_synthetic_record_is_recovered(trajectories, tmp_path):
    """The generator's stamps are arrival times: the reader recovers the logger's rate."""
    recs, _ = records_for(trajectories, tmp_path, True, "viscous", [0])
    clock = recs[0].clock
    assert clock["stamps"] == "arrival" and clock["method"] == "envelope"
    assert abs(clock["rate_hz"] / FS - 1) < 1e-4


def test_a_record_that_starts_mid_swing_starts_at_its_first_turning_point(trajectories, tmp_path):
    """The records start 13 samples after the release, mid-swing. With seed 6 of the linear
    viscous set the noise makes the first sample a (one-sided) extremum whose local fit puts
    its vertex beyond the next swing; it was taken for a release from rest, and every law set
    then fitted the wrong side (`b2` +0.2 against -0.2, residual sum of squares 100 times
    the others'). The first turning point must be the simulation's first one."""
    _, _, _, (_, angles) = trajectories[False, "viscous"]
    recs, _ = records_for(trajectories, tmp_path, False, "viscous", [0, 6])
    first = SENSOR["offset"] + angles[0] * (1 + SENSOR["asym"] * np.sign(angles[0]))
    for rec in recs:
        assert abs(rec.positions[0] - first) < 0.1, rec.positions[:3]
        assert rec.orientation == recs[0].orientation


def test_units_convert_between_degrees_and_radians():
    """The same pendulum in degrees (angle_unit pi/180) and in radians (angle_unit 1) gives the
    same turning points, and both are `vmj.Oscillator.pendulum`'s."""
    deg = {
        "omega": 21.7,
        "zeta": 0.004,
        "xF": 0.05,
        "xS": 0.0,
        "cq": 2e-4,
        "b2": -0.1,
        "b3": 0.02,
        "w": 1.0,
        "a0": 27.0,
        "angle_unit": DEGREE,
    }
    rad = {
        **deg,
        "xF": deg["xF"] * DEGREE,
        "cq": deg["cq"] / DEGREE,
        "a0": deg["a0"] * DEGREE,
        "angle_unit": 1.0,
    }
    with vmj.assume_valid():
        t_deg, x_deg = PENDULUM.predict(deg, 40, "exact")
        t_rad, x_rad = PENDULUM.predict(rad, 40, "exact")
        direct = vmj.turning_points(
            vmj.Oscillator.pendulum(21.7, 0.004, 0.05 * DEGREE, None, 2e-4 / DEGREE, -0.1, 0.02),
            27.0 * DEGREE,
            40,
            vmj.Exact(),
        )
    np.testing.assert_allclose(np.asarray(x_deg) * DEGREE, np.asarray(x_rad), rtol=1e-12)
    np.testing.assert_allclose(np.asarray(t_deg), np.asarray(t_rad), rtol=1e-12)
    np.testing.assert_allclose(np.asarray(x_rad)[1:], np.asarray(direct.positions), rtol=1e-12)


def test_law_sets_share_one_compiled_model():
    """The eight law sets are one space (the restoring law's sine share `w` held at 1 or 0):
    one compiled solve serves the comparison."""
    labels = {v.label for v in PENDULUM.variants}
    assert labels == {label(sine, d) for sine, d in LAW_SETS}
    assert all(v.space is None or v.space == PENDULUM for v in PENDULUM.variants)
    assert {v.hold["w"] for v in PENDULUM.variants} == {0.0, 1.0}
    assert PENDULUM.time_noise == "amplitude"


def one_record_problem(N: int, m: int):
    """A decaying record of `m` turning points with times, and its fit problem padded to `N`
    with every position and time weighed 1 (for the information criteria)."""
    from fits._fit import _Problem

    rec = fits.record_from_sequence(
        positions=[(-1) ** (k + 1) * (10.0 - 0.5 * k) for k in range(m)],
        times=[0.1 * k for k in range(m)],
    )
    on = np.r_[np.ones(m), np.zeros(N - m)]
    return rec, _Problem([rec], [{}], (), (), [None], wx=[on], wt=[on])


def test_bic_counts_a_law_that_ended_on_its_bound():
    """A law set whose extra law went to 0 (its slot held at the bound by the solver) counts
    that parameter: with the sub-model's residuals it is `log n` behind it in BIC, not tied."""
    from fits._fit import _time_precision
    from fits._params import HELD, LOWER
    from fits._result import _information

    N, m = 16, 12
    rec, prob = one_record_problem(N, m)
    r = np.r_[np.full(m, 1.5), np.zeros(N - m), np.full(m, 0.5), np.zeros(N - m)]

    class Job:
        slots = [("zeta", None), ("xF", None), ("cq", None)]
        code = np.array([LOWER, LOWER, HELD])  # cq ran into 0
        out = {"r": r}
        rss = float(r @ r)

    sub = type("Sub", (), {"slots": Job.slots[:2], "code": Job.code[:2], "out": Job.out})
    sub.rss = Job.rss
    big, small = _information(Job, prob, N), _information(sub, prob, N)
    # the residuals' degrees of freedom: the moved slots and the record's clock shift
    assert big["q"] == small["q"] == 2 + 1
    assert big["bic"] - small["bic"] == pytest.approx(math.log(2 * m))
    # the times of smaller extrema weigh less: precision proportional to the amplitude
    tw = _time_precision(PENDULUM, rec, N)
    np.testing.assert_allclose(tw[:m], rec.amplitudes / np.max(rec.amplitudes))


def test_bic_comparison_does_not_depend_on_how_positions_and_times_are_weighed():
    """Each block (a record's positions, its times) has its own variance in the likelihood, so
    the weight that puts the times on the positions' scale (estimated from one fit's
    residuals) cannot decide between two law sets: scaling one block of both fits' residuals
    leaves their BIC difference unchanged. (With one pooled variance it moved the choice:
    linear records weighed by a misfitting sine law chose a spurious drag in 2 of 10 seeds.)"""
    from fits._params import LOWER
    from fits._result import _information

    N, m = 16, 12
    _, prob = one_record_problem(N, m)
    rng = np.random.default_rng(0)
    rx, rt = rng.normal(size=(2, m)), rng.normal(size=(2, m))
    rx[1] *= 0.9  # the larger law set explains the positions a little better

    def bic_gap(time_scale):
        out = []
        for j, q in ((0, 2), (1, 3)):
            r = np.r_[rx[j], np.zeros(N - m), time_scale * rt[j], np.zeros(N - m)]
            job = type("Job", (), {"slots": [("p", None)] * q, "code": np.full(q, LOWER)})
            job.out, job.rss = {"r": r}, float(r @ r)
            out.append(_information(job, prob, N)["bic"])
        return out[1] - out[0]

    gaps = [bic_gap(s) for s in (1e-3, 1.0, 1e3)]
    np.testing.assert_allclose(gaps, gaps[1], rtol=1e-10)


def within(err: dict) -> bool:
    return all(e < (0.10 if name in DAMPING else 0.03) for name, e in err.items())


@pytest.mark.long  # 30-40 s: with the long runs, for CI's time
def test_synthetic_law_set_is_recovered(trajectories, tmp_path):
    """Default suite: one seed of the richest law set, fitted as that law set alone (one
    compiled model; the comparison of the eight law sets over 50 seeds is the slow test
    below, and `select=True` is tested in tests/test_fits_engine.py)."""
    sine, diss = True, "viscous+coulomb+quadratic"
    _, truths, results, _ = fit_law_set(trajectories, tmp_path, sine, diss, [1], compare=False)
    res, truth = results[0], truths[0]
    assert res.label == label(sine, diss)
    assert res.converged
    assert within(errors(res, truth)), (res.params, truth)


#: seeds of the slow test (the environment variable VMJ_PENDULUM_SEEDS runs fewer)
SEEDS = int(os.environ.get("VMJ_PENDULUM_SEEDS", "50"))


@pytest.mark.long
@pytest.mark.parametrize("sine,diss", LAW_SETS)
def test_law_sets_over_seeds(trajectories, tmp_path, sine, diss):
    """Issue 11's acceptance: over 50 seeded records of each law set the true law set is the
    BIC choice in at least 90 %, and in at least 90 % of them it is chosen AND every parameter
    is within 3 % (damping within 10 %)."""
    _, truths, results, dt = fit_law_set(trajectories, tmp_path, sine, diss, range(SEEDS))
    chosen = [res.label == label(sine, diss) for res in results]
    good = [ok and within(errors(res, truth)) for ok, res, truth in zip(chosen, results, truths)]
    worst = {
        name: max(
            errors(res, truth)[name] for res, truth in zip(results, truths) if name in res.params
        )
        for name in results[0].params
    }
    picks = collections.Counter(res.label for res in results)
    print(
        f"{label(sine, diss)}: BIC choice {sum(chosen)}/{SEEDS} ({dict(picks)}), all "
        f"parameters within tolerance {sum(good)}/{SEEDS}, worst errors {worst}, {dt:.0f} s"
    )
    assert sum(chosen) >= 0.9 * SEEDS
    assert sum(good) >= 0.9 * SEEDS


# -- the public record 80P.txt -------------------------------------------------------------
@pytest.fixture(scope="module")
def record_80p():
    return fits.read_record(files("fits") / "data" / "80P.txt", series=True)


def lag1(r) -> float:
    r = np.asarray(r, dtype=float) - np.mean(r)
    return float(r[1:] @ r[:-1] / (r @ r))


@pytest.mark.long
def test_80p_residuals_lose_their_structure(record_80p):
    """The pendulum model at least halves the residual lag-1 autocorrelation of the plain
    oscillator fit (issue 11; measured 0.944 -> -0.11 on the positions, 0.946 -> 0.45 pooled
    over the weighted positions and times), with a position RMS below a quarter of it (0.290
    -> 0.0207 deg). The times keep a smooth wander of +-2 ms (not a law: it is not monotonic
    in the amplitude; it mirrors the arrival stamps' envelope, docs/pendulum-fits.md). The
    eight law sets of a 120-point record and the plain fit: about a minute of CPU."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        plain = fits.fit(
            record_80p, "oscillator", ("omega", "zeta", "xF", "a0", "offset"), intervals=False
        )
        pend = fits.fit(record_80p, "pendulum", FREE, intervals=False)
    before, after = lag1(plain.residuals["position"]), lag1(pend.residuals["position"])
    assert before > 0.9
    assert abs(after) <= 0.5 * before
    assert pend.diagnostics["lag1"] <= 0.5 * plain.diagnostics["lag1"]
    assert pend.rms < 0.25 * plain.rms
    assert pend.converged
    assert pend.label.startswith("linear:viscous+coulomb"), pend.model_comparison


def test_a_swing_beyond_pi_radians_is_refused():
    """Angles in radians (`angle_unit` 1) of 10: no pendulum swings so far; the fit says so
    before any computation instead of fitting the sine law to nonsense."""
    k = np.arange(8)
    record = fits.Record(k=k, positions=10.0 * (-1.0) ** (k + 1) * 0.95**k, times=0.5 * k)
    with pytest.raises(ValueError, match="a pendulum swings below pi rad"):
        fits.fit(record, "pendulum", ("omega", "zeta", "a0"), given={"angle_unit": 1.0})


def test_the_angle_unit_is_read_from_the_signal_columns_name(tmp_path):
    """A record in radians whose column says so (`Angle(rad)`) is read in radians without
    `--angle-unit`: the sine law's frequency and its even term come out right. Read as degrees
    (the default before), this record's omega was 4.346 [4.341, 4.350] rad/s for 4.4, and on
    80P.txt in radians `b2` was -13.19 1/rad for -0.230."""
    truth = {"omega": 4.4, "zeta": 0.005, "b2": -0.2}
    model = vmj.Oscillator(
        truth["omega"], vmj.SineRestoring(truth["b2"], 0.0), (vmj.ViscousDamping(truth["zeta"]),)
    )
    ts = np.arange(0.0, 12.0, 1 / 250.0)
    with vmj.assume_valid():
        angle = np.asarray(vmj.decay_trajectory(model, 0.45, ts, 40).xs)
    rng = np.random.default_rng(3)
    reading = 0.02 + angle + rng.normal(0.0, 0.001, ts.size)
    path = tmp_path / "rad.csv"
    np.savetxt(
        path, np.column_stack([ts, reading]), delimiter=",", header="t,Angle(rad)", comments=""
    )
    record = fits.read_record(path, series=True)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = fits.fit(
            record, "pendulum", ("omega", "zeta", "b2", "a0", "offset"), compare=False
        )
    assert result.fixed["angle_unit"] == 1.0
    for name in ("omega", "zeta", "b2"):
        lo, hi = result.intervals[name]
        assert lo <= truth[name] <= hi, (name, result.params[name], lo, hi)
    names = {"theta_deg": DEGREE, "phi [mrad]": 1e-3, "Angle (radians)": 1.0, "angle": DEGREE}
    for name, unit in names.items():
        signal = fits.Signal(t=ts, y=reading, signal_name=name)
        assert named_angle_unit(dataclasses.replace(record, signal=signal)) == unit, name


def test_a_law_set_the_data_do_not_decide_is_said_to_be_undecided(tmp_path):
    """A pendulum with viscous damping and a small Coulomb level (zeta 0.005, xF 0.02 deg)
    under noise of 3 % of its 25 deg swing, sampled at 83 Hz: viscous-only and Coulomb-only
    fit about as well (BIC 8.5 and 12.9), and the chosen viscous set reported zeta 0.0057
    [0.00519, 0.00621], converged and without a warning (on another noise draw the Coulomb set
    won by 1.9 with xF 0.198 [0.182, 0.213] deg, ten times the truth). Now a warning says that
    the law set is not decided (the chosen set's BIC weight 90 %); with noise of 0.05 % the
    set chosen is every law with the drag held at 0, the other mechanisms (the linear law's
    sets) are 110 and more behind, and there is none."""
    truth = {"omega": 4.4, "zeta": 0.005, "xF": 0.02}
    model = vmj.Oscillator(
        truth["omega"],
        vmj.SineRestoring(0.0, 0.0),
        (vmj.ViscousDamping(truth["zeta"]), vmj.CoulombDamping(truth["xF"] * DEGREE)),
    )
    ts = np.arange(0.0, 12.0, 3 / 250.0)
    with vmj.assume_valid():
        angle = np.asarray(vmj.decay_trajectory(model, 25.0 * DEGREE, ts, 40).xs) / DEGREE
    said = {}
    for noise in (0.03, 0.0005):
        rng = np.random.default_rng(13)
        signal = fits.Signal(t=ts, y=1.0 + angle + rng.normal(0.0, noise * 25.0, ts.size))
        record = fits.extract_turning_points(signal)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            result = fits.fit(record, "pendulum", ("omega", "zeta", "xF", "a0", "offset"))
        said[noise] = [w for w in result.warnings if w.startswith("the law set is not decided")]
    assert len(said[0.03]) == 1, said
    assert said[0.0005] == [], said
