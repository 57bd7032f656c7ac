"""The smoothed solver: `sign(v)` replaced by `tanh(v/w)`, the ODE solved with diffrax."""

from __future__ import annotations

from typing import TYPE_CHECKING, ClassVar

import equinox as eqx
import equinox.internal as eqxi
import jax
import jax.numpy as jnp
from jax import lax
from jaxtyping import Array

from .._checks import _float, _is_traced, check, check_int, instance_of, positive
from .._models._base import AbstractDecayModel, AbstractLimitCycle, AbstractModel
from .._numerics._ode import dopri8, ode_solve, recording
from .._numerics._roots import bracketed_newton, implicit_step
from .._numerics._scan import release_point, zeros_of_lanes
from .._solution import RESULTS, DecaySequence, Trajectory
from ._base import AbstractSolver, unsupported

if TYPE_CHECKING:  # diffrax is imported where a solve is built, so that `import vmj` stays light
    import diffrax as dfx

__all__ = ["Smoothed"]

DEFAULT_SMOOTHING = 1e-4  #: default w as a fraction of the model's velocity scale
CREEP = 20.0  #: |v| below CREEP * w after the last reversal counts as the smoothed model's arrest


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
      the decay models); the absolute tolerance is `rtol` times the motion's scale in each
      state component's unit (`model.state_scale`: its length scale for the position, its
      velocity scale for the velocity).
    - `max_steps`: diffrax step limit (default: the model's), per half-swing for the turning
      points (`n` of them: one solve of at most `n * max_steps` steps) and per saved interval
      for a trajectory.
    - `ode_solver`: a diffrax solver (default: Dopri8, as `diffrax.Dopri8()` with its stages
      written out, which is faster on CPUs; `Kvaerno5()` for stiff models such as stick-slip).

    - `derivatives`: the mode the solve is differentiated in (diffrax's adjoint): `"reverse"`
      (default; diffrax's checkpointed `RecursiveCheckpointAdjoint`): `jax.grad`,
      `jax.jacrev`, `vmj.sensitivity(..., mode="reverse")`; `"forward"` (`diffrax.ForwardMode`):
      `jax.jvp`, `jax.jacfwd`, `mode="forward"`. Each works only in its mode: JAX refuses
      forward mode through the default ("can't apply forward-mode autodiff (jvp) to a
      custom_vjp function") and reverse mode through `"forward"` (its loops have no reverse),
      as [`vmj.Exact`][]`(derivatives="forward")`. Forward mode is the cheaper for a few
      parameters and many outputs: the 8 smoothed turning points of a variable-mass model
      against `mu` and `F_T`, one warm jitted Jacobian, 1.4 ms forward against 13 ms reverse,
      compiled in 19 s against 37 s (one after the other, the 2-core machine); `vmj
      sensitivity --method smooth` runs in forward mode.
    """

    smoothing: Array | None = None
    rtol: float | None = eqx.field(static=True, default=None)
    max_steps: int | None = eqx.field(static=True, default=None)
    ode_solver: dfx.AbstractSolver | None = eqx.field(static=True, default=None)
    derivatives: str = eqx.field(static=True, default="reverse")
    name: ClassVar[str] = "smooth"

    def __check_init__(self):
        if self.smoothing is not None and not _is_traced(self.smoothing):
            check("smoothing", self.smoothing, positive, "> 0 [m/s]")
        if self.rtol is not None:
            check("rtol", self.rtol, positive, "> 0")
        if self.max_steps is not None:
            check_int("max_steps", self.max_steps, 1)
        if self.derivatives not in ("reverse", "forward"):
            raise ValueError(
                f"derivatives must be 'reverse' or 'forward' (got {self.derivatives!r})"
            )

    def check(self, model, task):
        ok = {
            "turning_points": AbstractDecayModel,
            "simulate": AbstractModel,
            "limit_cycle": AbstractLimitCycle,
        }[task]
        if not instance_of(model, ok):
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
            ode = dfx.Kvaerno5() if model.smoothed_stiff else dopri8()
        return rtol, steps, ode

    def _adjoint(self):
        """diffrax's adjoint for `derivatives` (`None`: diffrax's default)."""
        import diffrax as dfx

        return dfx.ForwardMode() if self.derivatives == "forward" else None

    # -- the one diffrax call ------------------------------------------------------------------
    def solve(self, model, x0, v0, t1, saveat):
        """The smoothed model's states (`model.initial_state`'s form) at `saveat`'s times of a
        solve from `(x0, v0)` at `t = 0` to `t1`, and its status code."""
        import diffrax as dfx

        rtol, steps, ode = self._settings(model)
        y0, field, unpack = _components(model, x0, v0, self.smoothing)
        sol = ode_solve(
            field,
            y0,
            t1,
            saveat,
            rtol=rtol,
            atol=rtol,
            max_steps=steps,
            solver=ode,
            adjoint=self._adjoint(),
        )
        ok = sol.result == dfx.RESULTS.successful
        return unpack(sol.ys), jnp.where(ok, RESULTS.successful, RESULTS.solver_failed)

    def simulate(self, model, x0, v0, t1, n_save: int) -> Trajectory:
        """The solution at `n_save` equally spaced times: one solve continued from each saved
        time to the next (the solver's and the step-size controller's states carried over).
        (Saving at `SaveAt(ts=...)` compiles a check on the host, which would keep the program
        out of JAX's persistent compilation cache.)"""
        import diffrax as dfx

        rtol, steps, ode = self._settings(model)
        ts = jnp.linspace(0.0, t1, n_save)
        y0, field, unpack = _components(model, x0, v0, self.smoothing)
        go_on = dfx.SaveAt(t1=True, solver_state=True, controller_state=True, made_jump=True)

        def piece(t_a, t_b, y, resume):
            sol = ode_solve(
                field,
                y,
                t_b,
                go_on,
                rtol=rtol,
                atol=rtol,
                max_steps=steps,
                solver=ode,
                t0=t_a,
                resume=resume,
                adjoint=self._adjoint(),
            )
            resume = (sol.solver_state, sol.controller_state, sol.made_jump)
            return tuple(c[-1] for c in sol.ys), resume, sol.result == dfx.RESULTS.successful

        def body(carry, interval):
            y, resume, ok = carry
            y, resume, okay = piece(*interval, y, resume)
            return (y, resume, ok & okay), y

        y1, resume, ok = piece(ts[0], ts[1], y0, None)
        (_, _, ok), ys = lax.scan(body, (y1, resume, ok), (ts[1:-1], ts[2:]))
        ys = unpack([jnp.concatenate([a[None], b[None], c]) for a, b, c in zip(y0, y1, ys)])
        code = jnp.where(ok, RESULTS.successful, RESULTS.solver_failed).astype(jnp.int32)
        xs, vs = model.observe(jnp.where(ok, ys, jnp.nan))
        return Trajectory(ts=ts, xs=xs, vs=vs, result=code)

    def turning_points(self, model, a0, n: int) -> DecaySequence:
        """Turning points of the smoothed solution released from rest at `x = -a0`, found in
        one solve to the horizon: after each step, the velocity in the swing's direction
        falling through zero is a turning point (a reversal), and, for a swing that has not
        passed `x = 0` (the spring pushes on), so is its falling to `CREEP w` (the smoothed
        model's arrest, which creeps on without reversing where the exact mass stops). Its
        time comes from Newton's method on the step's dense output; the solve goes on with the
        next swing, each lane of a `vmap`ped batch by itself. Memory does not grow with the
        number of steps.

        The arrest counts only where the exact mass would stop (`_stops`): an over-damped mass
        slows through `CREEP w` on its way to rest without a velocity zero; while it creeps on
        from there, its velocity's sign changes (of roundoff size) are no reversals either.

        At each turning point the model's stick rule (`model.rest`) decides whether the mass
        stops for good (`stopped`): a smoothed mass only creeps from there (`|v| < CREEP w`),
        which is stiff and is not integrated. So does a mass that the spring only just moved
        on, which creeps off without ever exceeding `CREEP w`, once the stick rule holds
        where it creeps."""
        import diffrax as dfx

        rtol, steps, ode = self._settings(model)
        w = self.smoothing
        slow = CREEP * w
        x0 = release_point(model, a0, w)
        zero = v0 = zeros_of_lanes(x0)  # (also the solve's start time)
        t_end = model.horizon(a0, n)
        y_start, field, unpack = _components(model, x0, v0, w)
        scale = model.velocity_scale(a0)  # (event functions in units of it)
        slots = jnp.arange(n).reshape((n,) + (1,) * x0.ndim)

        def events(s, x, v):
            """The reversal's and the arrest's event functions of a swing in direction `s`."""
            return s * v / scale, jnp.where(s * x < 0, (s * v - slow) / scale, 1.0)

        def record(t0, t1, y1, interpolation, memo):
            s, count, times, positions, (rev0, arr0), stuck, crept, slowed = memo
            x1, v1 = model.observe(unpack(y1))
            rev1, arr1 = events(s, x1, v1)
            # (falls through zero, as diffrax's events; not while the mass creeps on after a
            # slowing down that was no arrest: an over-damped mass creeping to rest reversed
            # at x ~ 1e-15 of a0 = 0.1, below the solve's absolute tolerance, four times)
            reverses = (rev0 > 0) & (rev1 <= 0) & jnp.logical_not(slowed)
            # (the speed falling through `CREEP w`: not the arrest's event function jumping from
            # its placeholder where a creeping mass crosses `x = 0`, whose located "turning
            # point", with no root in the step, was at x = 5e37)
            arrests = (arr0 > 0) & (arr1 <= 0) & (rev0 > slow / scale)
            arrests = arrests & jnp.logical_not(reverses)
            lift = jnp.where(reverses, 0.0, slow / scale)
            t, x = _turning_point(
                interpolation,
                t0,
                t1,
                lambda y: s * model.observe(unpack(y))[1] / scale - lift,
                jnp.where(reverses, rev0, arr0),
                jnp.where(reverses, rev1, arr1),
                lambda y: model.observe(unpack(y))[0],
                reverses | arrests,
            )
            # a slowing down is an arrest only where the exact mass comes to a stop: not the
            # approach of an over-damped mass (with or without dry friction) to its rest
            stops = _stops(model, s, t, x, slow)
            passed = arrests & jnp.logical_not(stops)
            arrests = arrests & stops
            turned = reverses | arrests
            s_next, _, stop = model.rest(t, x)
            here = turned & (slots == count)  # (a select, not a scatter)
            times = jnp.where(here, t, times)
            positions = jnp.where(here, x, positions)
            count = count + turned.astype(count.dtype)
            s = jnp.where(turned, s_next, s)
            stuck = stuck | (turned & stop)
            # a mass that has crept (`|v| <= CREEP w`) since its last turning point, and is
            # where the stick rule holds, has stopped: the smoothed arrest of a mass that the
            # spring only just moved on, which would creep on, stiffly, to the horizon
            creeping = jnp.abs(v1) <= slow
            crept = turned | (crept & creeping)
            arrested = crept & creeping & model.rest(t1, x1)[2]
            stuck = stuck | (arrested & (count < n))
            slowed = (slowed | passed) & creeping & jnp.logical_not(turned)
            memo = (s, count, times, positions, events(s, x1, v1), stuck, crept, slowed)
            return memo, (turned & (stop | (count >= n))) | arrested

        def approach(t0, t1, y0, y1):
            """The longest step after one that ended with speed `|v|` falling at `|a|` (the
            velocity's mean slope over that step): `max(0.9 (|v| - 5 w), 0.4 (|v| + w)) / |a|`,
            to just outside the `tanh` layer in one step, within it 0.4 of the time to the
            velocity's zero. (diffrax's controller grows a step by up to 10 after one of small
            error; towards a reversal that overshot into the layer and was rejected: the ten
            turning points of delta = eps = mu = 0, 436 steps, 169 rejected, against 241 and
            15 with this limit.)"""
            v_0, v_1 = model.observe(unpack(y0))[1], model.observe(unpack(y1))[1]
            a = (v_1 - v_0) / jnp.where(t1 > t0, t1 - t0, 1.0)
            falls = v_1 * a < 0
            speed = jnp.abs(v_1)
            reach = jnp.maximum(0.9 * (speed - 5 * w), 0.4 * (speed + w))
            return jnp.where(falls, reach / jnp.where(falls, jnp.abs(a), 1.0), jnp.inf)

        # (the carries batched from the start, as the release point; the swing's sign
        # without a tangent)
        no = zeros_of_lanes(x0, bool)
        one = jnp.where(no, 0.0, 1.0).astype(x0.dtype)
        memo = (
            one,
            zeros_of_lanes(x0, jnp.int32),
            jnp.broadcast_to(v0, (n,) + x0.shape),
            jnp.broadcast_to(v0, (n,) + x0.shape),
            events(one, x0, v0),
            no,
            jnp.logical_not(no),
            no,
        )
        sol = ode_solve(
            field,
            y_start,
            t_end,
            dfx.SaveAt(t1=True, solver_state=True),
            t0=zero,
            rtol=rtol,
            atol=rtol,
            max_steps=n * steps,
            solver=recording(ode, record, memo),
            limit=approach,
            adjoint=self._adjoint(),
        )
        _, count, times, positions, _, stuck, _, _ = sol.solver_state[1]
        failed = sol.result != dfx.RESULTS.successful
        k = jnp.arange(n)
        valid = k < count
        last = jnp.maximum(count - 1, 0)
        times = jnp.where(valid, times, jnp.where(count > 0, times[last], 0.0))
        positions = jnp.where(valid, positions, jnp.where(count > 0, positions[last], x0))
        previous = jnp.concatenate([x0[None], positions[:-1]])
        crossed = valid & (positions * previous < 0)
        # `stuck`: the stick rule held at a turning point, or where the mass crept on from
        # one (`arrested`). A mass that only slowed down, without a velocity zero of the exact
        # mass (over-damped, with or without dry friction, or a mass that grows without
        # bound), has not stopped, even where it has crept into the friction's band by the
        # horizon: it was 'stopped' there, where the exact solver says 'no velocity zero'.
        stopped = stuck
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
        return DecaySequence.from_code(times, positions, crossed, count, code)


def _components(model, x0, v0, w):
    """`(y0, field, unpack)`: the smoothed ODE of `model` (smoothing velocity `w`) from
    `(x0, v0)` in the tuple of its state's components, each in units of its scale
    (`model.state_scale(x0, v0)`), in which every smoothed solve integrates: the initial state,
    the vector field `field(t, y, args)`, and `unpack`, back to the model's state (an array,
    its components along the last axis). In these units the absolute tolerance is the relative
    one (the same error norm). XLA's CPU kernels made a stacked state of every stage a
    concatenation of its own and transposed each for the dense output (14 kernels a step);
    separate components need neither: a chunk of the 1617-point smoothed sweep, 809 lanes,
    60 -> 42 ms."""
    scale = model.state_scale(x0, v0)

    def pack(y):
        return tuple(y[..., i] / scale[i] for i in range(scale.shape[0]))

    def unpack(components):
        return jnp.stack([c * scale[i] for i, c in enumerate(components)], axis=-1)

    def field(t, y, args):
        return pack(model.vector_field(t, unpack(y), w))

    return pack(model.initial_state(x0, v0)), field, unpack


def _stops(model, s, t, x, speed):
    """Whether the exact (non-smooth) mass, at `(t, x)` moving in direction `s` at `speed`
    (`CREEP w`, where `tanh` is 1 to 1e-17 and the smoothed motion is the exact one), comes to
    a velocity zero: it decelerates, and where that deceleration would stop it, `x + s speed^2 /
    (2 |a|)`, the dry friction holds it at rest (`s x'' < 0` at `v = 0`: a velocity zero on
    the near side of `x = 0` needs friction above the spring force). An over-damped mass
    approaching its rest decelerates as `|a| = lambda |v|` (its slow rate `lambda`), so that
    its extrapolated stop lies half-way to its rest, where nothing holds it: without this
    test, its slowing down through `CREEP w` counted as a turning point (released from rest
    at `-a0` with `zeta = 1.5`, one at `x = -5.2e-3 a0` where the exact solver has none)."""
    a = s * model.acceleration(t, x, s * speed, s)  # < 0: decelerating
    reach = x + s * speed * speed / (2 * jnp.where(a < 0, -a, 1.0))
    held = s * model.acceleration(t, reach, jnp.zeros_like(reach), s) < 0
    return (a < 0) & held


def _turning_point(interpolation, t0, t1, g, g0, g1, position, found):
    """Time and position where `g(y(t))` falls through zero within a step from `t0` to `t1`
    (`g0 > 0 >= g1` at its ends, where `found`), `y(t)` the step's dense output: vmj's root
    finder on the step's fraction, three bracketed Newton steps from the secant's root written
    out, then one with gradients (the implicit function's derivative). Dopri8's steps are long
    (a tenth of a period where the motion is smooth), and where the event function is curved
    over the step the secant's root is far from the root: the arrest of a last swing whose
    speed only just exceeds `CREEP w` lies on a flat peak, where one Newton step (enough for
    Tsit5's steps, a third as long) left the time 1.1e-4 off (relative, against a solve at rtol
    1e-13), two about 1e-5, three 1.7e-8 (over the benchmark grid: amplitudes to 5.6e-8 at most).

    Computed only in a step where some lane of a `vmap`ped batch has found its turning point,
    in a `lax.cond`: XLA's CPU backend has no multi-output fusion, and recomputed the
    iterations in each of the half-dozen kernels that read the result otherwise (808 lanes:
    about 60 us per step, as much as the step itself)."""
    at = getattr(interpolation, "at_fraction", None)  # (vmj's Dopri8: a polynomial in it)
    if at is None:

        def at(u):
            return interpolation.evaluate(t0 + (t1 - t0) * u)

    def f(u):  # (0 where no turning point was found: those lanes stop at once)
        value, slope = jax.jvp(lambda u: g(at(u)), (u,), (jnp.ones_like(u),))
        return jnp.where(found, value, 0.0), slope

    def locate():
        fs = lambda u: lax.stop_gradient(f(u))  # noqa: E731
        secant = jnp.clip(g0 / jnp.where(g0 > g1, g0 - g1, 1.0), 0.0, 1.0)
        zero = jnp.zeros_like(secant)
        u = bracketed_newton(fs, zero, zero + 1.0, lax.stop_gradient(secant), 3, unrolled=True)
        u = implicit_step(f, u)
        return t0 + (t1 - t0) * u, position(at(u))

    return lax.cond(eqxi.unvmap_any(found), locate, lambda: (t1, jnp.zeros_like(g0)))
