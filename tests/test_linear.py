"""Linear one-degree-of-freedom oscillator: diffrax simulation vs analytic response, the problem
book's worked example 4.1.2/2, the Lagrange-equation paper's example and its erratum, bad input,
CLI."""

import json
import math

import jax
import numpy as np
import pytest
from decimal_linear import derivative as reference_derivative, response as reference_response
from hypothesis import given, settings, strategies as st

import vmj
from vmj.cli import main as cli_main

REL = 1e-8


def _printed(value, printed, decimals):
    """`value` rounds to the printed number at its printed precision."""
    assert round(float(value), decimals) == pytest.approx(printed, abs=1e-12), (value, printed)


CASES = {
    "free-under": (vmj.LinearOscillator(2.0, 0.8, 50.0), 0.03, -0.2, 8.0),
    "free-critical": (vmj.LinearOscillator(1.0, 2.0 * math.sqrt(14.5), 14.5), 0.02, 0.1, 5.0),
    "free-over": (vmj.LinearOscillator(1.0, 20.0, 14.5), 0.02, -0.1, 5.0),
    "free-undamped": (vmj.LinearOscillator(1.0, 0.0, 9.0), 0.01, 0.3, 10.0),
    "force": (vmj.LinearOscillator(1.0, 1.0, 14.5, vmj.HarmonicForce(4.0, 15.0)), 0.0, 0.1, 20.0),
    "force-resonant": (
        vmj.LinearOscillator(1.0, 0.2, 16.0, vmj.HarmonicForce(1.0, 4.0)),
        0.0,
        0.0,
        20.0,
    ),
    "base": (vmj.LinearOscillator(3.0, 2.0, 40.0, vmj.BaseMotion(0.01, 2.5)), 0.02, 0.0, 15.0),
    "force-undamped-resonance": (
        vmj.LinearOscillator(1.0, 0.0, 16.0, vmj.HarmonicForce(1.0, 4.0)),
        0.01,
        0.0,
        20.0,
    ),
}


@pytest.mark.parametrize("name", list(CASES))
def test_simulation_matches_analytic_response(name):
    osc, x0, v0, t1 = CASES[name]
    tr = vmj.simulate(osc, x0, v0, t1, vmj.Smoothed(rtol=1e-12), n_save=801)
    assert int(tr.result) == 0
    x, v = osc.response(tr.ts, x0, v0)
    assert np.max(np.abs(tr.xs - x)) <= REL * np.max(np.abs(x))
    assert np.max(np.abs(tr.vs - v)) <= REL * np.max(np.abs(v))


@settings(max_examples=10)
@given(
    m=st.floats(0.1, 100.0),
    k=st.floats(1.0, 1e5),
    eta=st.floats(0.0, 3.0),
    r=st.floats(0.1, 5.0),
    F0=st.floats(-10.0, 10.0),
    x0=st.floats(0.1, 1.0),
    v0=st.floats(-1.0, 1.0),
)
def test_simulation_matches_analytic_property(m, k, eta, r, F0, x0, v0):
    wc = math.sqrt(k / m)
    osc = vmj.LinearOscillator(m, 2 * eta * math.sqrt(k * m), k, vmj.HarmonicForce(F0, r * wc))
    x0, v0 = x0 * (1 + abs(F0)) / k, v0 * (1 + abs(F0)) / k * wc  # comparable to the forced part
    tr = vmj.simulate(osc, x0, v0, 6 * math.pi / wc, vmj.Smoothed(rtol=1e-12), n_save=801)
    x, v = osc.response(tr.ts, x0, v0)
    assert np.max(np.abs(tr.xs - x)) <= REL * np.max(np.abs(x))
    assert np.max(np.abs(tr.vs - v)) <= REL * np.max(np.abs(v))


def test_response_initial_conditions_and_equation():
    osc = CASES["base"][0]
    x0, v0 = 0.02, -0.3
    x, v = osc.response(0.0, x0, v0)
    assert float(x) == pytest.approx(x0, abs=1e-15) and float(v) == pytest.approx(v0, abs=1e-14)
    # the analytic response satisfies m x'' + c x' + k x = F(t) (x'' by autodiff of v)
    a = jax.vmap(jax.grad(lambda t: osc.response(t, x0, v0)[1]))(np.linspace(0.1, 5, 7))
    ts = np.linspace(0.1, 5, 7)
    xs, vs = osc.response(ts, x0, v0)
    np.testing.assert_allclose(a, osc.acceleration(ts, xs, vs), rtol=1e-10, atol=1e-12)


def test_log_decrement_is_ratio_of_peaks():
    osc = vmj.LinearOscillator(2.0, 0.8, 50.0)
    Td = 2 * np.pi / float(osc.damped_frequency)
    ts = np.array([0.3, 0.3 + Td])
    x, _ = osc.response(ts, 0.03, -0.2)
    assert math.log(float(x[0] / x[1])) == pytest.approx(float(osc.log_decrement), rel=1e-12)
    eta = float(osc.damping_ratio)
    assert float(osc.log_decrement) == pytest.approx(2 * np.pi * eta / np.sqrt(1 - eta**2))


def test_undamped_response_through_resonance():
    """An undamped forcing a rounding away from resonance (`p = sqrt(k/m)` as computed) gave
    x = 0 at every time (the steady part H ~ 1e15 and the free part cancelling it lost every
    digit). Now it matches the exact resonant response (checked against SciPy DOP853 to 2e-12
    of its 8.0 peak), and continues smoothly a little off resonance (secular formula
    `-F0 t cos(p t)/(2 m p)`, detuning 1e-9: phase error p t 1e-9)."""
    ts = np.array([1.0, 2 * np.pi * 10 / np.sqrt(14.5)])

    def x(p):
        osc = vmj.LinearOscillator(1.0, 0.0, 14.5, vmj.HarmonicForce(4.0, p))
        return osc.response(ts, 0.0, 0.0)[0]

    w = np.sqrt(14.5)
    secular = 4.0 / (2 * w**2) * np.sin(w * ts) - 4.0 * ts * np.cos(w * ts) / (2 * w)
    for p in (w, w * (1 + 1e-9), w * (1 - 1e-9)):
        np.testing.assert_allclose(np.asarray(x(p)), secular, rtol=1e-7, atol=1e-12)
    # the derivative in p: central differences (h = 1e-5) agree to 1e-6 relative
    g = np.asarray(jax.jacfwd(x)(w))
    fd = (np.asarray(x(w + 1e-5)) - np.asarray(x(w - 1e-5))) / 2e-5
    np.testing.assert_allclose(g, fd, rtol=1e-6)
    traj = vmj.simulate(
        vmj.LinearOscillator(1.0, 0.0, 14.5, vmj.HarmonicForce(4.0, w)),
        0.0,
        0.0,
        1.0,
        vmj.ClosedForm(),
        n_save=2,
    )
    assert float(traj.xs[-1]) == pytest.approx(float(x(w)[0]), rel=1e-12)


# the response against a 60-digit evaluation (tests/decimal_linear.py: the matrix exponential
# of the system with its forcing, no roots), over damping from none to over-damped and forcing
# frequencies at, a rounding off and near resonance, and away from it
M, K, F0 = 2.0, 50.0, 1.5
W = math.sqrt(K / M)
CRITICAL = 2 * math.sqrt(K * M)
DAMPING = [0.0, 1e-14, 1e-10, 1e-6, 1.0, CRITICAL, 10 * CRITICAL]
RATIOS = [1 - 1e-12, 1.0, 1 + 1e-9, 0.5, 2.0, 1e-3]
TIMES = np.array([-3.0, -0.5, 0.0, 1e-6, 1e-3, 0.37, 3.1, 40.0, 400.0])
EARLY = (TIMES >= 0) & (TIMES <= 1e-3)


def _sup_error(x, ref):
    return float(np.max(np.abs(np.asarray(x) - ref)) / np.max(np.abs(ref)))


@pytest.mark.parametrize("c", DAMPING, ids=lambda c: f"c={c:g}")
def test_response_against_60_digit_reference(c):
    """The forced response near resonance lost digits with light damping: the steady part
    `Q/(k - m p^2 + i c p)` and the free part that cancels it at t = 0 were summed, 1.3e-4 off
    at c = 1e-14 (3e-8 at c = 1e-10, 1.5e-9 at 1e-6); over-damped (10 times critical) it was
    NaN at t = 400 s (`e^{-bt} cosh(d t)`: 0 times inf). Now one formula (divided differences
    of `exp(z t)` over the roots and `i p`) holds everywhere.

    Tolerance: 2e-12 of the trajectory's largest value. The response's own conditioning is
    the rounding of the phase, `eps omega t` = 4.4e-13 at t = 400 s (`omega t` = 2000); the
    largest error measured is 2.0e-13. From rest, the early values (t <= 1e-3 s, down to
    x = 6e-19 m) to 1e-12 each, relative: the early form is a Taylor series. Negative times
    (the motion before t = 0) were taken as early, their Taylor series far outside its range
    (-6562 for 0.0567 at t = -3 s); forcing 1000 times slower than the natural frequency
    costs about `omega_c/p` roundings (1.3e-15 measured)."""
    for r in RATIOS:
        p = W * r
        for forcing, Qr, Qi in [
            (vmj.HarmonicForce(F0, p), F0, 0.0),
            (vmj.BaseMotion(0.01, p), 0.01 * K, 0.01 * c * p),
        ]:
            osc = vmj.LinearOscillator(M, c, K, forcing)
            for x0, v0 in [(0.0, 0.0), (0.01, -0.2)]:
                x, v = osc.response(TIMES, x0, v0)
                xr, vr = map(np.array, reference_response(M, c, K, Qr, Qi, p, x0, v0, TIMES))
                case = (r, type(forcing).__name__, x0)
                assert _sup_error(x, xr) <= 2e-12, case
                assert _sup_error(v, vr) <= 2e-12, case
                if x0 == 0.0:
                    early = np.abs(np.asarray(x)[EARLY][1:] - xr[EARLY][1:])
                    assert np.all(early <= 1e-12 * np.abs(xr[EARLY][1:])), case


@pytest.mark.parametrize("c", [0.0, 1e-10, 1.0, CRITICAL, 10 * CRITICAL], ids=lambda c: f"c={c:g}")
def test_response_derivatives_against_60_digit_reference(c):
    """`jax.jacrev` of the response in `(c, p, k)`, finite at undamped resonance and at
    critical damping, against central differences of step 1e-22 in 60-digit arithmetic.
    Tolerance 1e-11 of the largest derivative over the times (measured: 1.2e-13 at most);
    `jax.vmap` over the parameters gives the same values (to rounding: 1e-14)."""
    ts = TIMES[5:8]  # 0.37, 3.1, 40 s

    def x(theta):
        c, p, k = theta[0], theta[1], theta[2]
        osc = vmj.LinearOscillator(M, c, k, vmj.HarmonicForce(F0, p))
        return osc.response(ts, 0.01, -0.2)[0]

    thetas = np.array([[c, W * r, K] for r in RATIOS])
    jacobians = np.asarray(jax.vmap(jax.jacrev(x))(thetas))
    values = np.asarray(jax.vmap(x)(thetas))
    for theta, jac, value in zip(thetas, jacobians, values):
        np.testing.assert_allclose(value, np.asarray(x(theta)), rtol=1e-14)
        assert np.all(np.isfinite(jac))
        for j, name in enumerate("cpk"):
            ref = np.array(reference_derivative(name, M, c, K, F0, 0.0, theta[1], 0.01, -0.2, ts))
            assert _sup_error(jac[:, j], ref) <= 1e-11, (theta[1] / W, name)


def test_amplification_and_phase():
    osc = vmj.LinearOscillator(1.0, 0.4, 25.0, vmj.HarmonicForce(2.0, 5.0))  # at resonance
    eta = float(osc.damping_ratio)
    D, beta = osc.forced_response()
    assert float(beta) == pytest.approx(np.pi / 2, abs=1e-14)
    assert float(osc.amplification()) == pytest.approx(1 / (2 * eta))
    assert float(D) == pytest.approx(2.0 / 25.0 * float(osc.amplification()), rel=1e-14)
    assert float(osc.amplification(1e-9)) == pytest.approx(1.0)
    # undamped resonance: no steady state, the response grows like t (no NaN)
    und = vmj.LinearOscillator(1.0, 0.0, 16.0, vmj.HarmonicForce(1.0, 4.0))
    assert float(und.forced_response()[0]) == np.inf
    x, _ = und.response(np.array([10.0, 10.0 + np.pi / 2]), 0.0, 0.0)
    assert np.all(np.isfinite(x))
    assert float(und.response(2 * np.pi * 10, 0.0, 0.0)[0]) == pytest.approx(
        -1.0 / (2 * 4.0) * 2 * np.pi * 10, rel=1e-10
    )
    # ... and its free part is defined: A sin(w t + alpha) - t cos(p t)/(2 m p) is the response
    ts = np.linspace(0.0, 7.0, 29)
    A, alpha = und.transient(0.01, 0.3)
    x, _ = und.response(ts, 0.01, 0.3)
    np.testing.assert_allclose(
        float(A) * np.sin(4.0 * ts + float(alpha)) - ts * np.cos(4.0 * ts) / 8.0, x, atol=1e-15
    )
    assert np.isnan(float(und.settling_time(0.01, 0.3)))  # no steady state to settle to
    # undamped off resonance: the transient never decays (inf) or is below from the start (0)
    off = vmj.LinearOscillator(1.0, 0.0, 16.0, vmj.HarmonicForce(1.0, 3.0))
    assert float(off.settling_time(0.0, 0.0)) == np.inf
    assert float(off.settling_time(0.0, 0.0, fraction=0.9)) == 0.0
    # the peak of the amplification curve is at r = sqrt(1 - 2 eta^2)
    r = np.linspace(0.9, 1.05, 30001)
    amp = np.asarray(osc.amplification(r * 5.0))
    assert r[np.argmax(amp)] == pytest.approx(np.sqrt(1 - 2 * eta**2), abs=1e-5)
    # base motion: |X/Y0| = sqrt(1 + (2 eta r)^2) * amplification
    base = vmj.LinearOscillator(1.0, 0.4, 25.0, vmj.BaseMotion(0.01, 7.0))
    Db, _ = base.forced_response()
    rb = 7.0 / 5.0
    assert float(Db) / 0.01 == pytest.approx(
        np.sqrt(1 + (2 * eta * rb) ** 2) * float(base.amplification()), rel=1e-13
    )


def test_problem_book_example_4_1_2_2():
    # m = 100 kg, k3 = 4.7e5 N/m, c3 = 5.49e3 N s/m, V0 = 0.7 m/s, X0 = -2e-3 m
    osc = vmj.LinearOscillator(100.0, 5.49e3, 4.7e5)
    _printed(osc.natural_frequency, 68.6, 1)
    _printed(osc.damping_ratio, 0.4, 1)
    _printed(osc.damped_frequency, 62.8, 1)
    A, _ = osc.free_amplitude(-2e-3, 0.7)
    _printed(A * 1e3, 10.5, 1)  # A = 10.5e-3 m
    # with a quarter of the platform's 50 kg: m3 = 112.5 kg
    osc = vmj.LinearOscillator(112.5, 5.49e3, 4.7e5)
    _printed(osc.natural_frequency, 64.6, 1)
    _printed(osc.damping_ratio, 0.38, 2)
    # the book multiplies its rounded 64.6 and 0.38: 64.6 sqrt(1 - 0.38^2) = 59.75 -> 59.8
    _printed(
        osc.natural_frequency * math.sqrt(1 - round(float(osc.damping_ratio), 2) ** 2), 59.8, 1
    )
    assert float(osc.damped_frequency) == pytest.approx(59.8, abs=0.06)
    A, _ = osc.free_amplitude(-2e-3, 0.7)
    _printed(A * 1e3, 11.0, 0)  # A = 11e-3 m


def test_lagrange_paper_example_and_erratum():
    # phi'' + phi' + 14.5 phi = 4 sin 15t, phi(0) = 0, phi'(0) = 0.1
    osc = vmj.LinearOscillator(1.0, 1.0, 14.5, vmj.HarmonicForce(4.0, 15.0))
    _printed(osc.decay_rate, 0.5, 1)
    _printed(osc.natural_frequency, 3.8, 1)
    # the paper prints k* = 3.78; sqrt(14.5 - 0.25) = 3.7749 (it rounded k = 3.8 first)
    assert float(osc.damped_frequency) == pytest.approx(3.78, abs=0.006)
    D, beta = osc.forced_response()
    _printed(D, 0.019, 3)
    _printed(math.tan(float(beta)), -0.071, 3)
    # the paper takes beta = arctan(-0.071) (principal branch); its transient A and settling time
    beta_paper = math.atan(math.tan(float(beta)))
    A_paper, alpha_paper = osc.free_amplitude(
        -float(D) * math.sin(-beta_paper), 0.1 - float(D) * 15 * math.cos(-beta_paper)
    )
    _printed(A_paper, 0.049, 3)
    _printed(math.log(100 * float(A_paper) / float(D)) / 0.5, 11.1, 1)

    # erratum: the printed law (23) violates phi(0) = 0 ...
    def law23(t):
        return 0.049 * np.exp(-0.5 * t) * np.sin(3.78 * t + 0.028) + 0.019 * np.sin(15 * t + 0.071)

    assert abs(law23(0.0)) > 2e-3
    # ... and the lag is beta = pi - 0.071 (p > k), so the forced term is -0.019 sin(15t + 0.071)
    assert float(beta) == pytest.approx(np.pi - 0.0712, abs=1e-3)
    A, alpha = osc.transient(0.0, 0.1)
    assert float(A) == pytest.approx(0.1018, abs=1e-4)
    assert float(alpha) == pytest.approx(0.0132, abs=1e-4)

    def corrected(t):
        return 0.1018 * np.exp(-0.5 * t) * np.sin(3.775 * t + 0.0132) - 0.018954 * np.sin(
            15 * t + 0.0712
        )

    tr = vmj.simulate(osc, 0.0, 0.1, 12.0, vmj.Smoothed(rtol=1e-12), n_save=801)
    assert np.max(np.abs(corrected(np.asarray(tr.ts)) - tr.xs)) < 2e-4
    assert np.max(np.abs(law23(np.asarray(tr.ts)) - tr.xs)) > 0.02
    assert float(osc.settling_time(0.0, 0.1)) == pytest.approx(12.57, abs=0.01)


@pytest.mark.parametrize(
    "make,name",
    [
        (lambda: vmj.LinearOscillator(0.0, 1.0, 1.0), "m"),
        (lambda: vmj.LinearOscillator(-1.0, 1.0, 1.0), "m"),
        (lambda: vmj.LinearOscillator(1.0, -0.1, 1.0), "c"),
        (lambda: vmj.LinearOscillator(1.0, 1.0, 0.0), "k"),
        (lambda: vmj.LinearOscillator(float("nan"), 1.0, 1.0), "m"),
        (lambda: vmj.HarmonicForce(1.0, 0.0), "p"),
        (lambda: vmj.HarmonicForce(float("nan"), 1.0), "F0"),
        (lambda: vmj.BaseMotion(0.01, -2.0), "p"),
        (lambda: vmj.LinearOscillator(1.0, 1.0, 1.0, forcing=3.0), "forcing"),
        (
            lambda: vmj.simulate(
                vmj.LinearOscillator(1.0, 1.0, 1.0), 0.0, 1.0, 0.0, vmj.Smoothed(rtol=1e-12)
            ),
            "t1",
        ),
    ],
)
def test_bad_input(make, name):
    with pytest.raises(ValueError, match=name):
        make()


def test_free_amplitude_needs_underdamping():
    # concrete values: a ValueError (it was equinox's runtime error, its reason mid-message)
    with pytest.raises(ValueError, match=r"under-damped .* \(got eta = 2\.6"):
        vmj.LinearOscillator(1.0, 20.0, 14.5).free_amplitude(0.01, 0.0)
    with pytest.raises(ValueError, match="under-damped"):
        vmj.LinearOscillator(1.0, 20.0, 14.5).settling_time(0.01, 0.0)
    with pytest.raises(Exception, match="under-damped"):  # traced: at run time
        jax.jit(lambda c: vmj.LinearOscillator(1.0, c, 14.5).free_amplitude(0.01, 0.0))(20.0)


def _cli_json(capsys, argv):
    assert cli_main(argv) == 0
    return json.loads(capsys.readouterr().out)


KEYS = [
    "natural_frequency",
    "damped_frequency",
    "damping_ratio",
    "log_decrement",
    "free_amplitude",
    "free_phase",
    "forced_amplitude",
    "forced_phase",
]


def test_cli_json(capsys):
    out = _cli_json(
        capsys,
        [
            "linear",
            "--m",
            "100",
            "--c",
            "5.49e3",
            "--k",
            "4.7e5",
            "--x0=-2e-3",
            "--v0",
            "0.7",
            "--json",
        ],
    )
    assert list(out) == KEYS
    assert out["free_amplitude"] == pytest.approx(10.46e-3, abs=1e-5)
    assert out["forced_amplitude"] is None and out["forced_phase"] is None
    out = _cli_json(
        capsys,
        [
            "linear",
            "--m",
            "1",
            "--c",
            "1",
            "--k",
            "14.5",
            "--v0",
            "0.1",
            "--F0",
            "4",
            "--p",
            "15",
            "--json",
        ],
    )
    assert list(out) == KEYS
    assert out["forced_amplitude"] == pytest.approx(0.018954, abs=1e-6)
    assert out["forced_phase"] == pytest.approx(np.pi - 0.0712, abs=1e-3)
    out = _cli_json(capsys, ["linear", "--m", "1", "--c", "10", "--k", "1", "--json"])
    assert out["damped_frequency"] is None and out["log_decrement"] is None


@pytest.mark.parametrize("c,says", [("2", "critically damped (eta = 1)"), ("10", "over-damped")])
def test_cli_text_says_why_a_non_oscillating_response_is_n_a(capsys, c, says):
    """The text printed `n/a` for the damped frequency, decrement and free amplitude of an
    oscillator with eta >= 1 without saying why."""
    assert cli_main(["linear", "--m", "1", "--c", c, "--k", "1", "--x0", "1"]) == 0
    out = capsys.readouterr().out
    assert "A = n/a" in out and says in out and "does not oscillate" in out


@pytest.mark.parametrize(
    "argv",
    [
        ["--m", "0", "--c", "1", "--k", "1"],
        ["--m", "1", "--c", "-1", "--k", "1"],
        ["--m", "1", "--c", "1", "--k", "1", "--F0", "1"],
    ],
)
def test_cli_bad_input_exit_2(capsys, argv):
    assert cli_main(["linear", *argv]) == 2
    assert capsys.readouterr().err.startswith("vmj: error:")
