"""`vmj.decay_trajectory`: the exact motion between the turning points (dense output).

References: the closed form of the linear oscillator with viscous and Coulomb damping within
each half-swing (to 1e-11 of the amplitude); an event-driven SciPy integration's dense output
(to 1e-9 of the amplitude) for the variable-mass model and a sine pendulum with Coulomb and
quadratic drag; the turning points themselves (the motion passes through them with zero
velocity); central finite differences for the gradients
(1e-6 relative).
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy_oscillator import motion, oscillator_turning_points
from scipy_reference import variable_mass_turning_points

import vmj

OM, ZE, XF, A0 = 5.0, 0.01, 0.3, 10.0
TS = np.linspace(0.0, 12.0, 1201)


def linear_reference(seq, a0, ts):
    """Half-swing by half-swing: `x = c + (x_j - c) e^{-zeta om tau} (cos wd tau +
    zeta om / wd sin wd tau)`, `c = -s xF` the equilibrium shifted against the velocity sign `s`."""
    wd = OM * np.sqrt(1 - ZE**2)
    T = np.concatenate([[0.0], np.asarray(seq.times)])
    X = np.concatenate([[-a0], np.asarray(seq.positions)])
    count, stop = int(seq.count), float(seq.stop_time)
    out = np.empty_like(ts)
    for i, t in enumerate(ts):
        j = min(int(np.searchsorted(T, t, "right")) - 1, count)
        if t >= stop:
            out[i] = X[j]
            continue
        c = -XF if X[j] < 0 else XF
        tau = t - T[j]
        out[i] = c + (X[j] - c) * np.exp(-ZE * OM * tau) * (
            np.cos(wd * tau) + ZE * OM / wd * np.sin(wd * tau)
        )
    return out


@pytest.mark.parametrize("solver", [vmj.Exact(), vmj.EnergyBalance()], ids=["exact", "energy"])
def test_linear_oscillator_matches_its_closed_form(solver):
    osc = vmj.Oscillator.linear(OM, ZE, XF)
    seq = vmj.turning_points(osc, A0, 30)
    assert bool(seq.stopped)  # the record covers the stop: times after it are the rest
    traj = vmj.decay_trajectory(osc, A0, TS, 30, solver)
    assert traj.message == vmj.RESULTS.successful.message
    np.testing.assert_allclose(traj.xs, linear_reference(seq, A0, TS), rtol=0, atol=1e-11 * A0)
    after = TS > float(seq.stop_time)
    assert np.all(traj.vs[after] == 0.0)


def test_passes_through_its_turning_points_at_rest():
    model = vmj.VariableMass(5.0, 4900.0, 3.0, 0.2, 2.0, vmj.Coulomb(14.7))
    seq = vmj.turning_points(model, 0.06, 12)
    n = int(seq.count)
    t = np.asarray(seq.times)[:n]
    traj = vmj.decay_trajectory(model, 0.06, t, 12)
    np.testing.assert_allclose(traj.xs, np.asarray(seq.positions)[:n], rtol=0, atol=1e-12)
    scale = 0.06 * np.sqrt(4900.0 / 5.0)
    assert np.max(np.abs(traj.vs)) < 1e-9 * scale


@pytest.mark.parametrize("kind", ["variable-mass", "pendulum"])
def test_agrees_with_an_event_driven_scipy_integration(kind):
    """Against the half-swings' dense output of `solve_ivp` (DOP853, rtol 1e-12), integrated
    half-swing by half-swing with a fixed friction sign (tests/scipy_*.py)."""
    segments = []
    if kind == "variable-mass":
        model, a0 = vmj.VariableMass(5.0, 4900.0, 3.0, 0.0, 2.0, vmj.Coulomb(14.7)), 0.06
        _, x, _ = variable_mass_turning_points(
            5.0, 4900.0, 3.0, 0.0, 2.0, a0, 10, F=14.7, segments=segments
        )
    else:
        a0 = 1.2
        laws = (
            vmj.ViscousDamping(0.003),
            vmj.CoulombDamping(0.002, 0.002),
            vmj.QuadraticDamping(0.05),
        )
        model = vmj.Oscillator(4.0, vmj.SineRestoring(0.05, 0.0), laws)
        _, x = oscillator_turning_points(
            4.0, a0, 10, "sine", zeta=0.003, xF=0.002, cq=0.05, b2=0.05, segments=segments
        )
    ts = np.linspace(-0.1, segments[-1][1], 301)
    traj = vmj.decay_trajectory(model, a0, ts, 12)
    assert traj.message == vmj.RESULTS.successful.message
    np.testing.assert_allclose(traj.xs, motion(segments, a0, ts, x[-1]), rtol=0, atol=1e-9 * a0)


_TS = jnp.linspace(0.05, 6.0, 40)
_P = jnp.array([4.0, 0.02, 0.05, 1.0])


def _weighted_motion(p):
    model = vmj.Oscillator.linear(p[0], p[1], p[2])
    return jnp.sum(jnp.sin(3.0 * _TS) * vmj.decay_trajectory(model, p[3], _TS, 16).xs)


def test_gradients_match_finite_differences():
    """Through the turning points' times and positions (implicit-function derivatives) and
    the half-swing series: reverse mode against central differences."""
    g_rev = jax.grad(_weighted_motion)(_P)
    h = 1e-6 * np.abs(np.asarray(_P))
    fd = [
        (_weighted_motion(_P.at[i].add(h[i])) - _weighted_motion(_P.at[i].add(-h[i]))) / (2 * h[i])
        for i in range(4)
    ]
    np.testing.assert_allclose(g_rev, fd, rtol=1e-6)


@pytest.mark.long  # 12 s more of compiling, with the long runs for CI's time
def test_forward_mode_equals_reverse_mode():
    np.testing.assert_allclose(
        jax.jacfwd(_weighted_motion)(_P), jax.grad(_weighted_motion)(_P), rtol=1e-12
    )


def test_times_past_the_last_turning_point_are_flagged():
    osc = vmj.Oscillator.linear(OM, 0.01, 0.0)  # never stops
    traj = vmj.decay_trajectory(osc, A0, [-1.0, 1.0, 100.0], 10)
    assert int(traj.result) == vmj.RESULTS.beyond_turning_points
    assert "raise n" in traj.message
    assert float(traj.xs[0]) == -A0  # before the release: the release point
    assert np.isfinite(traj.xs[1]) and np.isnan(traj.xs[2])
    with pytest.raises(vmj.SolverError, match="raise n"):
        vmj.decay_trajectory(osc, A0, [100.0], 10, throw=True)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(solver=vmj.Smoothed()), "vmj.Exact"),
        (dict(ts=np.zeros((2, 2))), "ts must be a 1-D array"),
        (dict(ts=[0.0, np.nan]), "ts must be finite"),
        (dict(a0=-1.0), "a0 must be finite and > 0"),
        (dict(n=0), "n must be an integer >= 1"),
    ],
)
def test_bad_input_names_the_parameter(kwargs, match):
    args = dict(model=vmj.Oscillator.linear(OM, ZE, XF), a0=A0, ts=TS, n=10)
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        vmj.decay_trajectory(**args)
