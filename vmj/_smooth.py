"""The smoothed model: sign(v) replaced by tanh(v/w), solved as an ODE with diffrax."""

from __future__ import annotations

import diffrax as dfx
import jax
import jax.numpy as jnp

from ._solution import RESULTS, DecaySequence, Trajectory

DEFAULT_SMOOTHING = 1e-4  #: default w as a fraction of the velocity scale |x0| sqrt(c/m0) + |v0|
RTOL = 1e-10
MAX_STEPS = 200_000


def default_smoothing(model, x0, v0):
    """Default smoothing velocity w [m/s]: 1e-4 of the motion's velocity scale."""
    return DEFAULT_SMOOTHING * (model.velocity_scale(jnp.abs(x0)) + jnp.abs(v0))


def _solve(model, x0, v0, t1, w, saveat):
    def field(t, y, args):
        x, v = y
        return jnp.stack([v, model.acceleration(t, x, v, jnp.tanh(v / w))])

    scale = jnp.abs(x0) + jnp.abs(v0) / model.velocity_scale(1.0)
    sol = dfx.diffeqsolve(
        dfx.ODETerm(field),
        dfx.Tsit5(),
        t0=0.0,
        t1=t1,
        dt0=None,
        y0=jnp.stack([x0, v0]),
        saveat=saveat,
        stepsize_controller=dfx.PIDController(rtol=RTOL, atol=RTOL * scale),
        max_steps=MAX_STEPS,
        throw=False,
    )
    ok = sol.result == dfx.RESULTS.successful
    return sol, field, jnp.where(ok, RESULTS.successful, RESULTS.solver_failed)


def simulate_smooth(model, x0, v0, t1, w, n_save: int) -> Trajectory:
    ts = jnp.linspace(0.0, t1, n_save)
    sol, _, code = _solve(model, x0, v0, t1, w, dfx.SaveAt(ts=ts))
    ys = jnp.where(code == RESULTS.successful, sol.ys, jnp.nan)
    return Trajectory(ts=ts, xs=ys[:, 0], vs=ys[:, 1], result=code)


def horizon(model, a0, n: int):
    """A time by which n half-swings are over (1.3 times the sum of estimated half-periods),
    kept short of the zero-mass time."""

    def body(m, _):
        half = jnp.pi * jnp.sqrt(jnp.maximum(m, 1e-12) / model.c)
        return m + model.delta * half, half

    _, halves = jax.lax.scan(body, model.m0, None, length=n + 1)
    return jnp.minimum(1.3 * jnp.sum(halves), 0.999 * model.lifetime())


CREEP = 20.0  #: |v| below CREEP * w after the last reversal counts as the smoothed model's arrest


def turning_points_smooth(
    model, a0, n: int, w, grid_per_swing: int = 64, t1=None,
    exhausted_code: int = RESULTS.mass_exhausted,
) -> DecaySequence:
    """Velocity zeros of the smoothed solution released from rest at x = -a0.

    A smoothed model cannot stick: where the exact mass sticks, the smoothed one slows to a
    creep `|v| ~ w` without reversing. Its arrival at `|v| = CREEP * w` after the last reversal
    is reported as the final turning point, and `stopped` is set when the motion is still
    creeping at the end of the horizon. `t1` overrides the variable-mass `horizon`; a solve cut
    short by the model's lifetime reports `exhausted_code`.
    """
    x0 = -a0 * jnp.ones_like(model.velocity_scale(1.0))
    t1 = horizon(model, a0, n) if t1 is None else t1
    sol, field, code = _solve(model, x0, jnp.zeros_like(x0), t1, w, dfx.SaveAt(dense=True))
    ts = jnp.linspace(0.0, t1, grid_per_swing * (n + 1) + 1)
    vs = jax.vmap(sol.evaluate)(ts)[:, 1]
    # a reversal is a sign change of v; the release at t = 0 (v = 0) is not one
    reversal = (vs[:-1] * vs[1:] <= 0) & (ts[:-1] > 0) & (vs[:-1] != 0)
    idx = jnp.nonzero(reversal, size=n, fill_value=-1)[0]
    n_rev = jnp.sum((idx >= 0).astype(jnp.int32))
    t_last = jnp.where(n_rev > 0, ts[jnp.maximum(idx[jnp.maximum(n_rev - 1, 0)], 0)], 0.0)
    slow = CREEP * w
    entry = (jnp.abs(vs[:-1]) > slow) & (jnp.abs(vs[1:]) <= slow) & (ts[:-1] > t_last)
    arrest = jnp.nonzero(entry, size=1, fill_value=-1)[0][0]
    add_arrest = (n_rev < n) & (arrest >= 0)
    idx = jnp.where(jnp.arange(n) == n_rev, jnp.where(add_arrest, arrest, -1), idx)
    level = jnp.where(jnp.arange(n) == n_rev, slow, 0.0)
    valid = idx >= 0
    lo, hi = ts[jnp.maximum(idx, 0)], ts[jnp.maximum(idx, 0) + 1]

    def refine(lo, hi, level):
        sgn = jnp.sign(sol.evaluate(lo)[1])

        def bisect(_, bracket):  # to float64 resolution on the dense interpolant
            lo, hi = bracket
            mid = 0.5 * (lo + hi)
            ahead = sol.evaluate(mid)[1] * sgn > level
            return jnp.where(ahead, mid, lo), jnp.where(ahead, hi, mid)

        lo, hi = jax.lax.fori_loop(0, 50, bisect, (lo, hi))
        t = 0.5 * (lo + hi)
        return t, sol.evaluate(t)[0]

    times, positions = jax.vmap(refine)(lo, hi, level)
    count = jnp.sum(valid.astype(jnp.int32))
    last = jnp.maximum(count - 1, 0)
    times = jnp.where(valid, times, jnp.where(count > 0, times[last], 0.0))
    positions = jnp.where(valid, positions, jnp.where(count > 0, positions[last], x0))
    previous = jnp.concatenate([x0[None], positions[:-1]])
    crossed = valid & (positions * previous < 0)
    creeping = (n_rev < n) & (jnp.abs(vs[-1]) <= slow)
    incomplete = (count < n) & jnp.logical_not(creeping)
    exhausted = incomplete & (t1 >= 0.998 * model.lifetime())
    code = jnp.where(
        code != RESULTS.successful,
        code,
        jnp.where(
            exhausted,
            exhausted_code,
            jnp.where(incomplete, RESULTS.step_limit, jnp.where(creeping, RESULTS.stopped, code)),
        ),
    )
    return DecaySequence(
        times=times,
        positions=positions,
        crossed=crossed,
        count=count,
        stopped=code == RESULTS.stopped,
        result=code,
    )
