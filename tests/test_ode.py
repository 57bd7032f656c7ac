"""vmj's default ODE solver: diffrax's Dopri8 with its stages written out."""

import diffrax as dfx
import jax.numpy as jnp
import numpy as np
import pytest

import vmj
from vmj._numerics._ode import dopri8, ode_solve, recording, step_size_controller

MODEL = vmj.VariableMass(5.0, 4900.0, 1.0, 0.5, 2.0, vmj.Coulomb(14.7))
W = 1e-3 * float(MODEL.velocity_scale(0.06))  #: the smoothing velocity of every solve here


def _field(t, y, args):
    return MODEL.vector_field(t, y, W)


def _solve(solver=None, saveat=None, limit=None):
    """From x = -6 cm at rest to t = 0.5 s, rtol 1e-10, atol 1e-12."""
    return ode_solve(
        _field,
        jnp.array([-0.06, 0.0]),
        0.5,
        saveat or dfx.SaveAt(ts=jnp.linspace(0.0, 0.5, 41)),  # dense output between the steps
        rtol=1e-10,
        atol=1e-12,
        max_steps=100_000,
        solver=solver,
        limit=limit,
    )


@pytest.mark.production_compile
def test_dopri8_steps_as_diffrax_dopri8():
    """The same tableau and error estimate as diffrax's `Dopri8`: one step from the same state
    gives the same end and error estimate (to the order of the additions), and a whole solve
    about the same steps and the same solution within its tolerance. (The error estimate is a
    difference of nearly equal sums over 14 stages: summed in another order it moves by about
    1e-8 relative, which moves later steps by as much; measured 157 + 62 steps against
    159 + 62, the solutions 4.6e-9 of each component's scale apart. One step's estimates:
    1.4e-15 of the larger apart on a CPU, 3.4e-12 on an H200 GPU, whose compiler forms the
    sums' multiply-adds otherwise.)"""
    term = dfx.ODETerm(_field)
    y0, t0, t1 = jnp.array([-0.05, 0.002]), 0.0, 4e-4  # (into the tanh layer: a large error)
    steps = []
    for solver in (dopri8(), dfx.Dopri8()):
        state = solver.init(term, t0, t1, y0, None)
        steps.append(solver.step(term, t0, t1, y0, None, state, False)[:2])
    (y1, e1), (y2, e2) = steps
    np.testing.assert_allclose(y1, y2, rtol=0, atol=1e-15 * float(jnp.abs(y2).max()))
    assert float(jnp.abs(e2).max()) > 1e-7
    np.testing.assert_allclose(e1, e2, rtol=0, atol=1e-11 * float(jnp.abs(e2).max()))
    ours, theirs = _solve(dopri8()), _solve(dfx.Dopri8())
    assert ours.result == dfx.RESULTS.successful
    n, m = int(ours.stats["num_steps"]), int(theirs.stats["num_steps"])
    assert n > 100 and abs(n - m) <= 0.03 * m
    scale = np.abs(np.asarray(theirs.ys)).max(axis=0)
    assert np.all(np.abs(np.asarray(ours.ys - theirs.ys)) < 3e-8 * scale)


def test_step_size_controller_takes_the_steps_of_diffraxs_pid_controller():
    """vmj's controller computes diffrax's step factor with `exp` and `log` instead of XLA's
    `power`: the same steps, accepted and rejected, and the same solution to rounding."""

    def solve(controller):
        return dfx.diffeqsolve(
            dfx.ODETerm(_field),
            dfx.Tsit5(),
            0.0,
            0.5,
            None,
            jnp.array([-0.06, 0.0]),
            saveat=dfx.SaveAt(ts=jnp.linspace(0.0, 0.5, 41)),
            stepsize_controller=controller,
            max_steps=100_000,
        )

    ours = solve(step_size_controller(1e-10, 1e-12))
    theirs = solve(dfx.PIDController(rtol=1e-10, atol=1e-12))
    for stat in ("num_accepted_steps", "num_rejected_steps"):
        assert int(ours.stats[stat]) == int(theirs.stats[stat]) > 20
    scale = np.abs(np.asarray(theirs.ys)).max(axis=0)
    assert np.all(np.abs(np.asarray(ours.ys - theirs.ys)) < 1e-12 * scale)


def test_step_size_limit_shortens_steps_and_keeps_the_solution():
    """A `limit` on the next step (here 1 ms; the free steps reach 1.5 ms) makes the
    controller's steps no longer than it, more of them, and the same solution within the
    solve's tolerance."""
    every = dfx.SaveAt(steps=True)
    free, held = _solve(saveat=every), _solve(saveat=every, limit=lambda *_: jnp.asarray(1e-3))

    def accepted(sol):  # (the steps' ends, and the state at the last)
        n = int(sol.stats["num_accepted_steps"])
        return np.asarray(sol.ts)[:n], np.asarray(sol.ys)[n - 1]

    (ts_free, end_free), (ts_held, end_held) = accepted(free), accepted(held)
    assert np.diff(ts_free).max() > 1.4e-3 and np.diff(ts_held).max() <= 1e-3 * (1 + 1e-12)
    assert ts_held.size > ts_free.size
    np.testing.assert_allclose(end_held, end_free, rtol=0, atol=1e-8 * np.abs(end_free).max())


def test_recording_keeps_the_accepted_steps_and_stays_put_when_done():
    """A memo carried through the solve sees every accepted step and no rejected one; from the
    step where `record` says done, the state stays where that step ended."""

    def record(t0, t1, y1, interpolation, memo):
        steps, t_done, y_done = memo
        done = t1 >= 0.2
        first = done & (t_done < 0)
        # the step's dense output ends at the step's end (to rounding)
        y_end = interpolation.at_fraction(jnp.ones_like(t1))
        memo = (steps + 1, jnp.where(first, t1, t_done), jnp.where(first, y_end, y_done))
        return memo, done

    plain = _solve(dopri8(), dfx.SaveAt(t1=True))
    memo = (jnp.array(0), jnp.array(-1.0), jnp.zeros(2))
    sol = _solve(recording(dopri8(), record, memo), dfx.SaveAt(t1=True, solver_state=True))
    steps, t_done, y_done = sol.solver_state[1]
    assert sol.result == dfx.RESULTS.successful and 0.2 <= float(t_done) < 0.5
    # the accepted steps up to t_done, and a few free of error to t1 afterwards
    ts = _solve(dopri8(), dfx.SaveAt(steps=True)).ts
    assert int(steps) == int(np.sum(np.asarray(ts) <= float(t_done)))
    assert int(sol.stats["num_accepted_steps"]) <= int(steps) + 8
    assert int(plain.stats["num_accepted_steps"]) > int(steps) + 20
    # (to rounding: 5.1e-13 relative on an H200 GPU)
    np.testing.assert_allclose(np.asarray(sol.ys[-1]), np.asarray(y_done), rtol=1e-12)


def test_dense_output_and_its_derivative_are_diffrax_dopri8s():
    """vmj's Dopri8 dense output (its weights multiplied out into a polynomial of degree 6)
    and its time derivative against diffrax's `Dopri8` interpolation on the same step: to
    1e-13."""
    term = dfx.ODETerm(_field)
    y0, t0, t1 = jnp.array([-0.06, 0.0]), 0.0, 0.01
    ours, theirs = dopri8(), dfx.Dopri8()
    *_, dense, _, _ = ours.step(term, t0, t1, y0, None, ours.init(term, t0, t1, y0, None), False)
    *_, dense_d, _, _ = theirs.step(
        term, t0, t1, y0, None, theirs.init(term, t0, t1, y0, None), False
    )
    a = ours.interpolation_cls(t0=t0, t1=t1, **dense)
    b = theirs.interpolation_cls(t0=t0, t1=t1, **dense_d)
    for t in np.linspace(t0, t1, 7):
        scale = np.abs(np.asarray(b.evaluate(t1))) + 1e-3
        np.testing.assert_allclose(a.evaluate(t), b.evaluate(t), rtol=0, atol=1e-13 * scale.max())
        d, e = np.asarray(a.derivative(t)), np.asarray(b.derivative(t))
        np.testing.assert_allclose(d, e, rtol=0, atol=1e-11 * np.abs(e).max())
