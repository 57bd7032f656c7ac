"""The smoothed solver: `sign(v)` replaced by `tanh(v/w)`, the ODE solved with diffrax."""

from __future__ import annotations

from typing import ClassVar

import diffrax as dfx
import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array

from .._checks import _float, _is_traced, check, positive
from .._numerics._ode import ode_solve
from .._numerics._roots import bracketed_newton, implicit_step
from .._models._base import AbstractDecayModel, AbstractLimitCycle, AbstractModel
from .._solution import RESULTS, DecaySequence, Trajectory
from ._base import AbstractSolver, unsupported


__all__ = ["Smoothed"]

DEFAULT_SMOOTHING = 1e-4  #: default w as a fraction of the model's velocity scale
CREEP = 20.0  #: |v| below CREEP * w after the last reversal counts as the smoothed model's arrest
GRID_PER_SWING = 64  #: velocity samples per half-swing searched for reversals
ROOT_ITERATIONS = 30  #: safeguarded Newton iterations on the dense interpolant


class Smoothed(AbstractSolver):
    """The smoothed model: `sign(v)` replaced by `tanh(v/w)`, solved as an ODE with diffrax.

    A smoothed model cannot stick: where the exact mass sticks it slows to a creep `|v| ~ w`.
    Its arrival at `|v| = 20 w` after the last reversal is reported as the last turning point.

    **Arguments:**

    - `smoothing`: smoothing velocity `w` [m/s] (the model's velocity unit), `> 0`. Default:
      `1e-4` of the motion's velocity scale (`|x0| omega + |v0|`); the turning points then
      agree with the exact solver to about 1e-7 relative. Smaller `w` is closer to the
      non-smooth model and stiffer to integrate.
    - `rtol`: relative tolerance of the step-size controller (default: the model's, 1e-10 for
      the decay models); the absolute tolerance is `rtol` times the motion's length scale.
    - `max_steps`: diffrax step limit (default: the model's).
    - `ode_solver`: a diffrax solver (default `Tsit5()`, or `Kvaerno5()` for stiff models such
      as stick-slip).
    """

    smoothing: Array | None = None
    rtol: float | None = eqx.field(static=True, default=None)
    max_steps: int | None = eqx.field(static=True, default=None)
    ode_solver: dfx.AbstractSolver | None = eqx.field(static=True, default=None)
    name: ClassVar[str] = "smooth"

    def __check_init__(self):
        if self.smoothing is not None and not _is_traced(self.smoothing):
            check("smoothing", self.smoothing, positive, "> 0 [m/s]")
        if self.rtol is not None:
            check("rtol", self.rtol, positive, "> 0")

    def check(self, model, task):
        ok = {"turning_points": AbstractDecayModel, "simulate": AbstractModel,
              "limit_cycle": AbstractLimitCycle}[task]
        if not isinstance(model, ok):
            raise unsupported(self, model, task.replace("_", " "), "see vmj.turning_points, "
                              "vmj.simulate and vmj.limit_cycle for the models each solves")
        return model

    # -- settings ----------------------------------------------------------------------------
    def with_defaults(self, model, x0, v0) -> "Smoothed":
        """This solver with its smoothing resolved to an array (the default from the motion's
        velocity scale): one compilation for every value of `w`."""
        if self.smoothing is not None:
            return eqx.tree_at(lambda s: s.smoothing, self, _float(self.smoothing))
        scale = model.smoothing_scale(x0, v0)
        if not (_is_traced(scale)) and not bool(jnp.all(scale > 0)):
            raise ValueError("smoothing must be given (> 0 [m/s]) when the motion starts at rest "
                             "at x = 0: its default is relative to the initial velocity scale")
        return eqx.tree_at(lambda s: s.smoothing, self, DEFAULT_SMOOTHING * _float(scale),
                           is_leaf=lambda x: x is None)

    def _settings(self, model):
        rtol = model.smoothed_rtol if self.rtol is None else self.rtol
        steps = model.smoothed_max_steps if self.max_steps is None else self.max_steps
        ode = self.ode_solver
        if ode is None:
            ode = dfx.Kvaerno5() if model.smoothed_stiff else dfx.Tsit5()
        return rtol, steps, ode

    # -- the one diffrax call ------------------------------------------------------------------
    def solve(self, model, x0, v0, t1, saveat):
        """diffrax solution of the smoothed model from `(x0, v0)` at `t = 0` to `t1`, and its
        status code."""
        rtol, steps, ode = self._settings(model)
        w = self.smoothing
        y0 = model.initial_state(x0, v0)
        sol = ode_solve(lambda t, y, args: model.vector_field(t, y, w), y0, t1, saveat,
                        rtol=rtol, atol=rtol * model.length_scale(x0, v0), max_steps=steps,
                        solver=ode)
        ok = sol.result == dfx.RESULTS.successful
        return sol, jnp.where(ok, RESULTS.successful, RESULTS.solver_failed)

    def simulate(self, model, x0, v0, t1, n_save: int) -> Trajectory:
        ts = jnp.linspace(0.0, t1, n_save)
        sol, code = self.solve(model, x0, v0, t1, dfx.SaveAt(ts=ts))
        ys = jnp.where(code == RESULTS.successful, sol.ys, jnp.nan)
        xs, vs = model.observe(ys)
        return Trajectory(ts=ts, xs=xs, vs=vs, result=code)

    def turning_points(self, model, a0, n: int) -> DecaySequence:
        """Velocity zeros of the smoothed solution released from rest at `x = -a0`, located on
        the dense output: reversals (sign changes of `v`) on a grid of `GRID_PER_SWING` samples
        per half-swing, refined by safeguarded Newton on the interpolant. The arrival at
        `|v| = CREEP w` after the last reversal is the smoothed model's arrest, and `stopped` is
        set when the motion is still creeping at the end of the horizon."""
        w = self.smoothing
        x0 = -a0 * jnp.ones_like(model.velocity_scale(1.0))
        t1 = model.horizon(a0, n)
        sol, code = self.solve(model, x0, jnp.zeros_like(x0), t1, dfx.SaveAt(dense=True))
        ts = jnp.linspace(0.0, t1, GRID_PER_SWING * (n + 1) + 1)
        vs = jax.vmap(lambda t: model.observe(sol.evaluate(t))[1])(ts)
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

        def velocity(t):
            return model.observe(sol.evaluate(t))[1]

        def refine(lo, hi, level):
            sgn = jnp.sign(velocity(lo))

            def f(t):  # > 0 before the crossing of the level, <= 0 after it
                return velocity(t) * sgn - level

            def fprime(t):
                return model.observe(sol.derivative(t))[1] * sgn

            both = lambda t: (f(t), fprime(t))  # noqa: E731
            t = bracketed_newton(both, lo, hi, 0.5 * (lo + hi), ROOT_ITERATIONS)
            t = implicit_step(both, t)
            return t, model.observe(sol.evaluate(t))[0]

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
            jnp.where(exhausted, model.exhausted,
                      jnp.where(incomplete, RESULTS.step_limit,
                                jnp.where(creeping, RESULTS.stopped, code))),
        )
        return DecaySequence(times=times, positions=positions, crossed=crossed, count=count,
                             stopped=code == RESULTS.stopped, result=code)
