"""The smoothed solver: `sign(v)` replaced by `tanh(v/w)`, the ODE solved with diffrax."""

from __future__ import annotations

from typing import TYPE_CHECKING, ClassVar

import equinox as eqx
import jax.numpy as jnp
from jax import lax
from jaxtyping import Array

from .._checks import _float, _is_traced, check, positive
from .._models._base import AbstractDecayModel, AbstractLimitCycle, AbstractModel
from .._numerics._ode import ode_solve, tsit5
from .._solution import RESULTS, DecaySequence, Trajectory
from ._base import AbstractSolver, unsupported

if TYPE_CHECKING:  # diffrax is imported where a solve is built, so that `import vmj` stays light
    import diffrax as dfx

__all__ = ["Smoothed"]

DEFAULT_SMOOTHING = 1e-4  #: default w as a fraction of the model's velocity scale
CREEP = 20.0  #: |v| below CREEP * w after the last reversal counts as the smoothed model's arrest
EVENT_RTOL = 1e-12  #: Newton's tolerance on the time of a turning point (relative to the horizon)


class Smoothed(AbstractSolver):
    """The smoothed model: `sign(v)` replaced by `tanh(v/w)`, solved as an ODE with diffrax.

    A smoothed model cannot stick: where the exact mass sticks it slows to a creep `|v| ~ w`.
    A swing that ends without reversing (it has not passed `x = 0`) ends where `|v|` falls to
    `20 w`; that is its turning point.

    **Arguments:**

    - `smoothing`: smoothing velocity `w` [m/s] (the model's velocity unit), `> 0`. Default:
      `1e-4` of the motion's velocity scale (`|x0| omega + |v0|`); the turning points then
      agree with the exact solver to about 1e-7 relative. Smaller `w` is closer to the
      non-smooth model and stiffer to integrate.
    - `rtol`: relative tolerance of the step-size controller (default: the model's, 1e-10 for
      the decay models); the absolute tolerance is `rtol` times the motion's length scale.
    - `max_steps`: diffrax step limit (default: the model's), per half-swing for the turning
      points and per saved interval for a trajectory.
    - `ode_solver`: a diffrax solver (default: Tsit5, as `diffrax.Tsit5()` with its stages
      written out, which is faster on CPUs; `Kvaerno5()` for stiff models such as stick-slip).
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
        ok = {
            "turning_points": AbstractDecayModel,
            "simulate": AbstractModel,
            "limit_cycle": AbstractLimitCycle,
        }[task]
        if not isinstance(model, ok):
            raise unsupported(
                self,
                model,
                task.replace("_", " "),
                "see vmj.turning_points, "
                "vmj.simulate and vmj.limit_cycle for the models each solves",
            )
        return model

    # -- settings ----------------------------------------------------------------------------
    def with_defaults(self, model, x0, v0) -> Smoothed:
        """This solver with its smoothing resolved to an array (the default from the motion's
        velocity scale): one compilation for every value of `w`."""
        if self.smoothing is not None:
            return eqx.tree_at(lambda s: s.smoothing, self, _float(self.smoothing))
        scale = model.smoothing_scale(x0, v0)
        if not (_is_traced(scale)) and not bool(jnp.all(scale > 0)):
            raise ValueError(
                "smoothing must be given (> 0 [m/s]) when the motion starts at rest "
                "at x = 0: its default is relative to the initial velocity scale"
            )
        return eqx.tree_at(
            lambda s: s.smoothing,
            self,
            DEFAULT_SMOOTHING * _float(scale),
            is_leaf=lambda x: x is None,
        )

    def _settings(self, model):
        rtol = model.smoothed_rtol if self.rtol is None else self.rtol
        steps = model.smoothed_max_steps if self.max_steps is None else self.max_steps
        import diffrax as dfx

        ode = self.ode_solver
        if ode is None:
            ode = dfx.Kvaerno5() if model.smoothed_stiff else tsit5()
        return rtol, steps, ode

    # -- the one diffrax call ------------------------------------------------------------------
    def solve(self, model, x0, v0, t1, saveat):
        """diffrax solution of the smoothed model from `(x0, v0)` at `t = 0` to `t1`, and its
        status code."""
        import diffrax as dfx

        rtol, steps, ode = self._settings(model)
        w = self.smoothing
        y0 = model.initial_state(x0, v0)
        sol = ode_solve(
            lambda t, y, args: model.vector_field(t, y, w),
            y0,
            t1,
            saveat,
            rtol=rtol,
            atol=rtol * model.length_scale(x0, v0),
            max_steps=steps,
            solver=ode,
        )
        ok = sol.result == dfx.RESULTS.successful
        return sol, jnp.where(ok, RESULTS.successful, RESULTS.solver_failed)

    def simulate(self, model, x0, v0, t1, n_save: int) -> Trajectory:
        """The solution at `n_save` equally spaced times: one solve continued from each saved
        time to the next (the solver's and the step-size controller's states carried over).
        (Saving at `SaveAt(ts=...)` compiles a check on the host, which would keep the program
        out of JAX's persistent compilation cache.)"""
        import diffrax as dfx

        rtol, steps, ode = self._settings(model)
        w = self.smoothing
        ts = jnp.linspace(0.0, t1, n_save)
        y0 = model.initial_state(x0, v0)
        atol = rtol * model.length_scale(x0, v0)
        go_on = dfx.SaveAt(t1=True, solver_state=True, controller_state=True, made_jump=True)

        def piece(t_a, t_b, y, resume):
            sol = ode_solve(
                lambda t, y, args: model.vector_field(t, y, w),
                y,
                t_b,
                go_on,
                rtol=rtol,
                atol=atol,
                max_steps=steps,
                solver=ode,
                t0=t_a,
                resume=resume,
            )
            resume = (sol.solver_state, sol.controller_state, sol.made_jump)
            return sol.ys[-1], resume, sol.result == dfx.RESULTS.successful

        def body(carry, interval):
            y, resume, ok = carry
            y, resume, okay = piece(*interval, y, resume)
            return (y, resume, ok & okay), y

        y1, resume, ok = piece(ts[0], ts[1], y0, None)
        (_, _, ok), ys = lax.scan(body, (y1, resume, ok), (ts[1:-1], ts[2:]))
        ys = jnp.concatenate([y0[None], y1[None], ys])
        code = jnp.where(ok, RESULTS.successful, RESULTS.solver_failed).astype(jnp.int32)
        xs, vs = model.observe(jnp.where(ok, ys, jnp.nan))
        return Trajectory(ts=ts, xs=xs, vs=vs, result=code)

    def turning_points(self, model, a0, n: int) -> DecaySequence:
        """Turning points of the smoothed solution released from rest at `x = -a0`, each
        located by a diffrax event: swing by swing, the solve stops where the velocity in the
        swing's direction falls through zero (a reversal), or, for a swing that has not passed
        `x = 0` (the spring pushes on), where it falls to `CREEP w`: the smoothed model's
        arrest, which creeps on without reversing where the exact mass stops. Event times come
        from Newton's method on the last step's dense output; memory does not grow with the
        number of steps.

        At each turning point the model's stick rule (`model.rest`) decides whether the mass
        stops for good (`stopped`): a smoothed mass only creeps from there (`|v| < CREEP w`),
        which is stiff and is not integrated. A decay that runs into the horizon still
        creeping is `stopped` too."""
        import diffrax as dfx
        import optimistix as optx

        rtol, steps, ode = self._settings(model)
        w = self.smoothing
        slow = CREEP * w
        x0 = -a0 * jnp.ones_like(model.velocity_scale(1.0))
        v0 = jnp.zeros_like(x0)
        t_end = model.horizon(a0, n)
        atol = rtol * model.length_scale(x0, v0)
        newton = optx.Newton(rtol=EVENT_RTOL, atol=EVENT_RTOL * t_end)

        def field(t, y, args):
            return model.vector_field(t, y, w)

        scale = model.velocity_scale(a0)  # (event functions in units of it: Newton's test)

        def swing(t0, y0, s):
            """From the turning point `(t0, y0)`, moving in direction `s`, to the next one (or
            to the horizon): `(reached, okay, t, y)`."""

            def reverses(t, y, args, **kwargs):
                return s * model.observe(y)[1] / scale

            def arrests(t, y, args, **kwargs):
                x, v = model.observe(y)
                return jnp.where(s * x < 0, (s * v - slow) / scale, 1.0)

            event = dfx.Event((reverses, arrests), root_finder=newton, direction=False)
            sol = ode_solve(
                field,
                y0,
                t_end,
                dfx.SaveAt(t1=True),
                rtol=rtol,
                atol=atol,
                max_steps=steps,
                solver=ode,
                t0=t0,
                event=event,
            )
            reached = sol.result == dfx.RESULTS.event_occurred
            okay = reached | (sol.result == dfx.RESULTS.successful)
            return reached, okay, sol.ts[-1], sol.ys[-1]

        def body(carry, _):
            t, y, s, moving, stuck, failed = carry  # (t, y): the last turning point
            reached, okay, t1, y1 = swing(jnp.where(moving, t, t_end), y, s)
            turned = moving & reached
            failed = failed | (moving & jnp.logical_not(okay))
            # where the lane's last swing ended (a turning point, or the horizon)
            t, y = jnp.where(moving, t1, t), jnp.where(moving, y1, y)
            s_next, _, stop = model.rest(t, model.observe(y)[0])
            stuck = stuck | (turned & stop)
            moving = turned & jnp.logical_not(stop)
            carry = (t, y, jnp.where(turned, s_next, s), moving, stuck, failed)
            return carry, (t, model.observe(y)[0], turned)

        y_start = model.initial_state(x0, v0)
        false = jnp.zeros_like(x0, dtype=bool)
        init = (
            jnp.zeros_like(x0),
            y_start,
            jnp.ones_like(x0),
            jnp.logical_not(false),
            false,
            false,
        )
        (_, y_end, _, _, stuck, failed), (times, positions, turned) = lax.scan(
            body, init, None, length=n
        )
        count = jnp.sum(turned.astype(jnp.int32))
        k = jnp.arange(n)
        valid = k < count
        last = jnp.maximum(count - 1, 0)
        times = jnp.where(valid, times, jnp.where(count > 0, times[last], 0.0))
        positions = jnp.where(valid, positions, jnp.where(count > 0, positions[last], x0))
        previous = jnp.concatenate([x0[None], positions[:-1]])
        crossed = valid & (positions * previous < 0)
        creeping = (count < n) & (jnp.abs(model.observe(y_end)[1]) <= slow)
        stopped = stuck | creeping
        incomplete = (count < n) & jnp.logical_not(stopped)
        exhausted = incomplete & (t_end >= 0.998 * model.lifetime())
        code = jnp.where(
            failed,
            RESULTS.solver_failed,
            jnp.where(
                exhausted,
                model.exhausted,
                jnp.where(
                    incomplete,
                    RESULTS.step_limit,
                    jnp.where(stopped, RESULTS.stopped, RESULTS.successful),
                ),
            ),
        )
        code = code.astype(jnp.int32)
        return DecaySequence(
            times=times,
            positions=positions,
            crossed=crossed,
            count=count,
            stopped=code == RESULTS.stopped,
            result=code,
        )
