"""Stick-slip self-oscillation of a one-mass torsional model with instantaneous velocity reversal
(Belokobylsky & Koronatov; `SYSTEMS.md` section 3).

    I phi'' = -c (phi - omega t) - M0 sign(phi'),   static friction M1 > M0 while the disk rests.

Dimensionless (tau = sqrt(c/I) t, xi = c (phi - omega t)/M0, Omega = omega sqrt(c I)/M0,
eps = M1/M0): slip obeys `xi'' + xi = -sign(xi' + Omega)`, the disk rests while `xi' = -Omega`,
breaks away when `xi` reaches `-eps`, and at a velocity zero during slip reverses at once when
`|xi| > 1` (the spring overcomes sliding friction in the other direction), otherwise it sticks.

Three solvers of [`vmj.limit_cycle`][] share the model:

- [`vmj.Exact`][]: event-driven; each slip phase uses the analytic harmonic solution of the
  phase's equation of motion and its velocity zero is found by the shared safeguarded Newton
  (implicit-function-theorem gradient), then the rules above pick reversal or stick. Works
  under `jit`, `vmap` and `grad`.
- [`vmj.ClosedForm`][]: the paper's formulas (11)-(20) (`_closed_forms/_belokobylsky.py`).
- [`vmj.Smoothed`][]: the cycle measured on the smoothed diffrax model (a rest memory `z` makes
  the friction limit static while the disk rests).
"""

from __future__ import annotations

from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import lax
from jaxtyping import Array

from .._checks import (
    _float,
    _is_traced,
    check,
    check_int,
    positive,
    validated,
    warn_if_float32,
)
from .._closed_forms._belokobylsky import closed_form_cycle
from .._exported import filter_jit
from .._numerics._roots import bracketed_newton, implicit_step
from .._solution import RESULTS, Trajectory
from ._base import AbstractLimitCycle, require_scalar_fields

__all__ = ["StickSlip", "StickSlipCycle", "MAX_REVERSALS"]

#: a reversal needs |xi| > 1 + REVERSAL_MARGIN at the velocity zero. At |xi| = 1 exactly the
#: disk would leave with zero acceleration (a degenerate case); the margin 2e-5 is the one the
#: paper's formula (16) uses, k* = floor((eps - 1)/2 - 1e-5), so that eps = 3, 5, 7, ... give
#: the same k* in every solver.
REVERSAL_MARGIN = 2e-5
NEWTON = 7  #: Newton iterations per velocity zero, at most (started at the root: 1 is taken)
MAX_REVERSALS = 10  #: default static bound on reversals per cycle (eps below 23)


def _greater_than_one(x):
    return x > 1


class StickSlip(AbstractLimitCycle):
    """Torsional one-mass stick-slip model in the paper's dimensionless form.

    **Arguments:**

    - `eps`: ratio of static to sliding friction `M1/M0` [-], `> 1`.
    - `Omega`: dimensionless drive speed `omega sqrt(c I)/M0` [-], `> 0`.
    - `time_scale`: seconds per unit of dimensionless time, `sqrt(I/c)` [s] (default 1: results
      stay dimensionless).
    - `angle_scale`: radians per unit of `xi`, `M0/c` [rad] (default 1).

    Use [`vmj.StickSlip.from_physical`][] to build it from `I, c, omega, M0, M1`; the scales are
    then set so that [`vmj.StickSlipCycle.physical`][] and `trajectory(physical=True)` report
    seconds and radians.
    """

    eps: Array = eqx.field(converter=_float)
    Omega: Array = eqx.field(converter=_float)
    time_scale: Array = eqx.field(converter=_float, default=1.0)
    angle_scale: Array = eqx.field(converter=_float, default=1.0)
    _limits: ClassVar[dict] = {
        "eps": (_greater_than_one, "> 1 (static friction M1 must exceed sliding friction M0) [-]"),
        "Omega": (positive, "> 0 [-]"),
        "time_scale": (positive, "> 0 [s]"),
        "angle_scale": (positive, "> 0 [rad]"),
    }

    @classmethod
    def from_physical(cls, I, c, omega, M0, M1) -> StickSlip:
        """Build the model from physical parameters.

        **Arguments:** `I` disk moment of inertia [kg m^2] `> 0`; `c` torsional stiffness
        [N m/rad] `> 0`; `omega` drive speed of the upper end [rad/s] `> 0`; `M0` sliding
        friction moment [N m] `> 0`; `M1` static friction moment [N m] `> M0`.

        Then `eps = M1/M0`, `Omega = omega sqrt(c I)/M0`, `time_scale = sqrt(I/c)` [s] and
        `angle_scale = M0/c` [rad].
        """
        I = check("I", I, positive, "> 0 [kg m^2]")
        c = check("c", c, positive, "> 0 [N m/rad]")
        omega = check("omega", omega, positive, "> 0 [rad/s]")
        M0 = check("M0", M0, positive, "> 0 [N m]")
        M1 = check("M1", M1, positive, "> 0 [N m]")
        I, c, omega, M0, M1 = (_float(v) for v in (I, c, omega, M0, M1))
        M1 = check("M1", M1, lambda m: m > M0, "> M0 (static friction exceeds sliding) [N m]")
        return cls(M1 / M0, omega * jnp.sqrt(c * I) / M0, jnp.sqrt(I / c), M0 / c)

    # -- the equation of motion of a slip phase, written once ---------------------------------
    def slip_phase(self, xi0, s, tau):
        """Analytic solution of `xi'' + xi = -s` from rest of the disk (`xi' = -Omega`) at
        `xi = xi0`: returns `(xi, xi')` after the local time `tau`."""
        return _phase_state(self, xi0, s, jnp.cos(tau), jnp.sin(tau))

    def acceleration(self, t, x, v, sgn):
        """`xi''` at `xi = x`, `xi' = v`, with `sgn` standing for `sign(xi' + Omega)` (exactly
        +-1 in the exact solver, a smooth function in the smoothed one)."""
        return -x - sgn

    def friction_peak(self, z):
        """Friction magnitude limit (units of M0) of the smoothed model with rest memory `z`."""
        return 1.0 + (self.eps - 1.0) * z

    # -- the smoothed model -------------------------------------------------------------------
    smoothed_rtol: ClassVar[float] = 1e-8
    smoothed_max_steps: ClassVar[int] = 1_000_000
    smoothed_stiff: ClassVar[bool] = True

    def velocity_scale(self, a0):
        """`a0` (dimensionless: the slip phases oscillate at unit frequency)."""
        return a0 * jnp.ones_like(self.Omega)

    def smoothing_scale(self, x0, v0):
        """1: the dimensionless velocity unit `M0/sqrt(c I)` (default `w = 1e-4`)."""
        return jnp.ones_like(self.Omega)

    def length_scale(self, x0, v0):
        return jnp.abs(x0) + jnp.zeros_like(v0)

    def state_scale(self, x0, v0):
        """`|x0|` for each of `(xi, xi', z)` (dimensionless; the velocity unit is the slip
        phases' unit frequency)."""
        length = self.length_scale(x0, v0)
        return jnp.stack([length, length, length])

    def initial_state(self, x0, v0):
        """`(xi, xi', z)` with the rest memory `z = 0`."""
        return jnp.stack([x0, v0, jnp.zeros_like(x0)])

    def vector_field(self, t, y, w):
        """The smoothed model: `sign(u)` (`u = xi' + Omega`, the disk velocity) replaced by
        `P(z) tanh(u/w)` and the rest/slip switch by a rest memory `z` in `[0, 1]`:

            xi'' + xi = -(1 + (eps - 1) z) tanh(u/w),   z' = (exp(-(u/sqrt(w))^2) - z) / w**0.25.

        `z` relaxes to 1 while the disk (nearly) rests, so the friction limit grows to the static
        `eps`, and to 0 while it slides; a quick passage through `u = 0` (a reversal) leaves `z`
        small, so the disk reverses against sliding friction only -- the paper's rule."""
        v_mem, t_mem = jnp.sqrt(w), w**0.25
        xi, dxi, z = y
        u = dxi + self.Omega
        sgn = self.friction_peak(z) * jnp.tanh(u / w)
        rest = jnp.exp(-((u / v_mem) ** 2))
        return jnp.stack([dxi, self.acceleration(t, xi, dxi, sgn), (rest - z) / t_mem])

    # -- the limit cycle ------------------------------------------------------------------------
    def breakaway(self):
        """`(xi, xi') = (-eps, -Omega)`: the disk at rest at breakaway."""
        return -self.eps, -self.Omega

    def exact_cycle(self, max_reversals: int) -> StickSlipCycle:
        """Event-driven limit cycle (see the module docstring); traceable."""
        return _exact_cycle(self, max_reversals)

    def closed_form_cycle(self, max_reversals: int) -> StickSlipCycle:
        """The paper's closed forms (11)-(20)."""
        fields = closed_form_cycle(self.eps, self.Omega, max_reversals)
        return StickSlipCycle(
            **fields,
            result=jnp.where(
                fields["count"] == fields["reversals"] + 1,
                RESULTS.successful,
                RESULTS.too_many_reversals,
            ),
            model=self,
            method="closed",
        )

    def smoothed_cycle(self, max_reversals: int, solver) -> StickSlipCycle:
        """The cycle measured on the smoothed model (NumPy post-processing; concrete scalar
        models only)."""
        return _smooth_cycle(self, max_reversals, solver)

    def rest_memory(self, t1, solver=None, n_save: int = 2001) -> Array:
        """The rest memory `z` of the smoothed model (see `vector_field`) from breakaway, at the
        times of `vmj.simulate(model, *model.breakaway(), t1, solver, n_save=n_save)`.

        **Arguments:**

        - `t1`: final dimensionless time `tau`, `> 0`.
        - `solver`: a [`vmj.Smoothed`][] (default `vmj.Smoothed()`: smoothing velocity
          `w = 1e-4`, Kvaerno5, rtol 1e-8), the one given to [`vmj.simulate`][].
        - `n_save`: number of equally spaced saved times from 0 to `t1` (`>= 2`).

        **Returns:** `z` [-] in `[0, 1]` at the `n_save` times (NaN where the solve failed:
        the trajectory's `result` says why). `z` near 1 is a rest (the friction limit raised to
        the static `eps`), near 0 a slip.
        """
        from .._solvers._smoothed import Smoothed

        solver = Smoothed() if solver is None else solver
        if not isinstance(solver, Smoothed):
            raise ValueError(
                "solver must be a vmj.Smoothed: the rest memory z is a state of the smoothed "
                f"model only (got {type(solver).__name__})"
            )
        warn_if_float32()
        n_save = check_int("n_save", n_save, 2)
        require_scalar_fields(self)
        model = type(solver).check(solver, validated(self), "simulate")  # (as vmj.simulate)
        t1 = check("t1", t1, positive, "> 0 (dimensionless time)")
        x0, v0 = model.breakaway()
        _, ys, _ = smoothed_states(model, solver.with_defaults(model, x0, v0), _float(t1), n_save)
        return ys[:, 2]


class StickSlipCycle(eqx.Module):
    """One period of the stick-slip limit cycle, starting at breakaway (`xi = -eps`, disk at rest).

    Dimensionless time throughout (use [`vmj.StickSlipCycle.physical`][] for seconds). Arrays over
    slip intervals are padded to `max_reversals + 1` with zeros past `count`.

    **Fields:**

    - `reversals`: number `k*` of instantaneous velocity reversals per period.
    - `count`: number of slip intervals, `k* + 1`.
    - `slip_intervals`: local slip interval lengths `tau_k`, `k = 1..k*+1`.
    - `positions`: `xi_k` at the end of each slip interval.
    - `amplitudes`: `A_k`, amplitude of the harmonic motion within interval `k`.
    - `slip_time`, `stick_time`, `period`: `tau_*`, `tau^*`, `Lambda = tau_* + tau^*`.
    - `result`: `RESULTS.successful`, or `RESULTS.too_many_reversals` when the cycle has more
      than `max_reversals` reversals.
    - `model`: the [`vmj.StickSlip`][] it belongs to (for sampling and unit conversion).
    - `method`: `"exact"`, `"closed"` or `"smooth"` (static): the solver that produced it.
    """

    reversals: Array
    count: Array
    slip_intervals: Array
    positions: Array
    amplitudes: Array
    slip_time: Array
    stick_time: Array
    period: Array
    result: Array
    model: StickSlip
    method: str = eqx.field(static=True, default="exact")

    @staticmethod
    def field_units(model) -> dict:
        """The unit of each field that has one (exports' `units`): times and positions are
        dimensionless (`"1"`; [`vmj.StickSlipCycle.physical`][] converts them); counts and
        status codes have none."""
        names = ("slip_intervals", "positions", "amplitudes", "slip_time", "stick_time", "period")
        return dict.fromkeys(names, "1")

    @property
    def message(self) -> str:
        message = RESULTS.describe(self.result)  # (a batch: a ValueError saying how to read it)
        return "limit cycle found" if int(self.result) == RESULTS.successful else message

    @property
    def failed(self) -> Array:
        return RESULTS.failed(self.result)

    def physical(self) -> dict:
        """Times in seconds: `slip_intervals`, `slip_time`, `stick_time`, `period` [s], and
        `positions` (xi_k) converted to the spring twist `phi - omega t` [rad]."""
        T, A = self.model.time_scale, self.model.angle_scale
        return {
            "slip_intervals": self.slip_intervals * T,
            "slip_time": self.slip_time * T,
            "stick_time": self.stick_time * T,
            "period": self.period * T,
            "positions": self.positions * A,
        }

    def reached(self) -> dict:
        """The cycle as plain Python numbers (unbatched results only)."""
        n = int(self.count)
        return {
            "reversals": int(self.reversals),
            "slip_intervals": np.asarray(self.slip_intervals)[:n].tolist(),
            "slip_time": float(self.slip_time),
            "stick_time": float(self.stick_time),
            "period": float(self.period),
        }

    def trajectory(self, n_save: int = 2001, periods: float = 1.0, physical: bool = False):
        """Sample the cycle (analytic within each phase), starting at breakaway.

        Returns a [`vmj.Trajectory`][] with `ts` = dimensionless time, `xs` = `xi`, `vs` = `xi'`
        (the disk rests where `xi' = -Omega`). With `physical=True`: `ts` [s], `xs` = disk
        angle `phi` [rad] (`phi = 0` at breakaway) and `vs` = `phi'` [rad/s].
        """
        n_save = check_int("n_save", n_save, 2)
        if self.method == "smooth":
            raise ValueError(
                "a cycle measured on the smoothed model has no analytic trajectory; "
                "sample it with vmj.simulate(model, *model.breakaway(), t1, vmj.Smoothed())"
            )
        return _sample(self, n_save, jnp.asarray(periods, dtype=self.period.dtype), physical)


@filter_jit
def _sample(cycle, n_save, periods, physical):
    m = cycle.model
    ts = jnp.linspace(0.0, periods * cycle.period, n_save)
    local = jnp.mod(ts, cycle.period)
    local = jnp.where((ts > 0) & (local == 0), cycle.period, local) * (ts > 0)
    n = cycle.slip_intervals.shape[-1]
    k = jnp.arange(n)
    used = k < cycle.count
    ends = jnp.cumsum(jnp.where(used, cycle.slip_intervals, 0.0))
    starts = ends - cycle.slip_intervals
    start_xi = jnp.concatenate([-m.eps[None], cycle.positions[:-1]])
    signs = jnp.where(k % 2 == 0, 1.0, -1.0)

    def one(t):
        j = jnp.clip(jnp.sum((t >= ends) & used), 0, cycle.count - 1)
        xi, dxi = m.slip_phase(start_xi[j], signs[j], t - starts[j])
        stuck = t >= cycle.slip_time
        rest = cycle.positions[cycle.count - 1] - m.Omega * (t - cycle.slip_time)
        xi = jnp.where(stuck, rest, xi)
        dxi = jnp.where(stuck, -m.Omega, dxi)
        return xi, dxi

    xi, dxi = jax.vmap(one)(local)
    if physical:
        # phi / angle_scale = xi + Omega tau (+ xi(0) offset so that phi = 0 at breakaway)
        phi = m.angle_scale * (xi + m.Omega * ts + m.eps)
        return Trajectory(
            ts=ts * m.time_scale,
            xs=phi,
            vs=(dxi + m.Omega) * m.angle_scale / m.time_scale,
            result=cycle.result,
        )
    return Trajectory(ts=ts, xs=xi, vs=dxi, result=cycle.result)


# -- exact event-driven solver -------------------------------------------------------------------
def _phase_state(model, xi0, s, cos_tau, sin_tau):
    """`(xi, xi')` of the slip phase from rest at `xi0` (friction sign `s`) at the local time
    whose cosine and sine are given: `xi = -s + (xi0 + s) cos tau - Omega sin tau`."""
    a = xi0 + s
    return -s + a * cos_tau - model.Omega * sin_tau, -a * sin_tau - model.Omega * cos_tau


def _velocity_zero(model, xi0, s):
    """First velocity zero of the disk (`xi' = -Omega`) after it starts from rest at `xi0` moving
    in direction `s` (= sign(-xi0), |xi0| > 1). Returns `(tau, xi)` at the zero.

    With `a = xi0 + s` the disk velocity of the phase is
    `u(tau) = Omega (1 - cos tau) - a sin tau = 2 sin(tau/2) h(tau/2)`,
    `h(x) = Omega sin x - a cos x`. The factor `sin(tau/2)` is the start's own zero, so the event
    is the root of `h` in `(0, pi/2)` (`s = -1`) or `(pi/2, pi)` (`s = +1`, as `s a < 0`).

    The root is sought as its distance `y` from the nearer end of the half period,
    `tau = 2 y` (`s = -1`) or `tau = 2 pi - 2 y` (`s = +1`): both cases become the root in
    `(0, pi/2)` of `g(y) = b cos y - Omega sin y`, `b = -s a = |xi0| - 1 > 0`, which lies at
    `y* = arctan(b/Omega)`. For a fast drive `y*` ~ `b/Omega` shrinks with the stick interval
    (like `1/Omega`); written as `y`, it keeps float64's relative precision at any `Omega`,
    where `tau` near `2 pi` would keep only an absolute `1e-15` (a stick-time error
    ~ `Omega 1e-15`). The state at the event is evaluated from `cos 2y`, `sin 2y` for the same
    reason. Newton starts at `atan2(b, Omega)` (a start in the middle of the quarter, as before,
    is thrown back to bisection by the bracket when `y*` is near either end, and 7 iterations then
    left `tau` wrong for `Omega` above about `1e5`); the shared safeguarded Newton confirms the
    root in one step, and its last step is taken with gradients (implicit-function theorem), so
    `tau` differentiates in eps and Omega.
    """

    def g(y, b, Om):  # > 0 before the root (the disk still moves in direction s), <= 0 after
        cos, sin = jnp.cos(y), jnp.sin(y)
        return b * cos - Om * sin, -b * sin - Om * cos

    b = -s * (xi0 + s)
    b_ng, Om_ng = lax.stop_gradient(b), lax.stop_gradient(model.Omega)
    y = bracketed_newton(
        lambda y: g(y, b_ng, Om_ng),
        jnp.zeros_like(b_ng),
        0.5 * jnp.pi * jnp.ones_like(b_ng),
        jnp.arctan2(b_ng, Om_ng),
        NEWTON,
    )
    y = implicit_step(lambda y: g(y, b, model.Omega), y)
    tau = jnp.pi * (1.0 + s) - 2.0 * s * y
    xi, _ = _phase_state(model, xi0, s, jnp.cos(2.0 * y), -s * jnp.sin(2.0 * y))
    return tau, xi


def _exact_cycle(model: StickSlip, max_reversals: int) -> StickSlipCycle:
    n = max_reversals + 1
    xi0 = -model.eps

    def body(carry, _):
        xi, s, done, reversals = carry
        tau, xi1 = _velocity_zero(model, xi, s)
        a = xi + s
        amplitude = jnp.sqrt(a * a + model.Omega**2)
        reverse = jnp.abs(xi1) > 1.0 + REVERSAL_MARGIN
        active = jnp.logical_not(done)
        out = (
            jnp.where(active, tau, 0.0),
            jnp.where(active, xi1, 0.0),
            jnp.where(active, amplitude, 0.0),
            active,
        )
        new_done = done | jnp.logical_not(reverse)
        reversals = reversals + (active & reverse).astype(jnp.int32)
        xi = jnp.where(active, xi1, xi)
        s = jnp.where(active & reverse, -s, s)
        return (xi, s, new_done, reversals), out

    init = (xi0, jnp.ones_like(xi0), jnp.array(False), jnp.array(0, dtype=jnp.int32))
    (xi_end, _, done, reversals), (taus, xis, amps, used) = lax.scan(body, init, None, length=n)
    count = jnp.sum(used.astype(jnp.int32))
    slip = jnp.sum(taus)
    stick = (xi_end + model.eps) / model.Omega  # xi falls at rate Omega from xi_end to -eps
    code = jnp.where(done, RESULTS.successful, RESULTS.too_many_reversals)
    return StickSlipCycle(
        reversals=reversals,
        count=count,
        slip_intervals=taus,
        positions=xis,
        amplitudes=amps,
        slip_time=slip,
        stick_time=stick,
        period=slip + stick,
        result=code,
        model=model,
    )


SMOOTH_PERIODS = 3.3  #: simulated horizon in (closed-form) periods; the last full cycle is kept
SMOOTH_SAMPLES = 20_000  #: saved points per period for the event detection
CREEP = 20.0  #: |u| below CREEP * w counts as a stop of the smoothed disk


@filter_jit
def smoothed_states(model, solver, t1, n_save: int):
    """`(ts, ys, code)`: the smoothed model's state `(xi, xi', z)` at `n_save` times from
    breakaway to `t1`."""
    import diffrax as dfx

    ts = jnp.linspace(0.0, t1, n_save)
    x0, v0 = model.breakaway()
    ys, code = solver.solve(model, x0, v0, t1, dfx.SaveAt(ts=ts))
    return ts, jnp.where(code == RESULTS.successful, ys, jnp.nan), code


def _failed_cycle(model, max_reversals, code) -> StickSlipCycle:
    zeros = jnp.zeros(max_reversals + 1)
    nan = jnp.asarray(jnp.nan)
    return StickSlipCycle(
        reversals=jnp.asarray(0),
        count=jnp.asarray(0),
        slip_intervals=zeros,
        positions=zeros,
        amplitudes=zeros,
        slip_time=nan,
        stick_time=nan,
        period=nan,
        result=jnp.asarray(code),
        model=model,
        method="smooth",
    )


def _smooth_cycle(model, max_reversals, solver) -> StickSlipCycle:
    for leaf in jax.tree.leaves(model):
        if _is_traced(leaf) or jnp.ndim(leaf) != 0:
            raise ValueError("the smoothed limit cycle takes a concrete scalar model (no jit/vmap)")
    w = solver.smoothing
    guess = float(model.closed_form_cycle(64).period)  # only sets the simulated horizon
    n_save = int(SMOOTH_PERIODS * SMOOTH_SAMPLES)
    ts, ys, code = smoothed_states(model, solver, _float(SMOOTH_PERIODS * guess), n_save)
    if int(code) != RESULTS.successful:
        return _failed_cycle(model, max_reversals, RESULTS.solver_failed)
    ts, u = np.asarray(ts), np.asarray(ys[:, 1]) + float(model.Omega)
    z = np.asarray(ys[:, 2])
    slow = np.abs(u) <= CREEP * float(w)

    def level(i, target):  # linear interpolation of the crossing of `target` inside [i, i+1]
        return ts[i] + (ts[i + 1] - ts[i]) * (target[i] / (target[i] - target[i + 1]))

    over = np.abs(u) - CREEP * float(w)
    # rests: runs of |u| <= CREEP w during which the rest memory z builds up past 1/2
    starts = np.nonzero(~slow[:-1] & slow[1:])[0]
    stops = np.nonzero(slow[:-1] & ~slow[1:])[0]
    rests = []
    for i in starts:
        j = stops[stops > i]
        if j.size and z[i : j[0] + 1].max() > 0.5:
            rests.append((level(i, over), level(j[0], over), i, j[0]))
    if len(rests) < 2:
        return _failed_cycle(model, max_reversals, RESULTS.no_cycle)
    (_, b1, _, i1), (d2, b2, i2, _) = rests[-2], rests[-1]
    # reversals: sign changes of the disk velocity while slipping between the two rests
    flips = np.nonzero(
        (u[:-1] * u[1:] < 0) & (np.arange(len(u) - 1) > i1) & (np.arange(len(u) - 1) < i2)
    )[0]
    marks = [b1] + [level(i, u) for i in flips] + [d2]
    taus = np.diff(marks)
    n = max_reversals + 1
    rev = len(taus) - 1
    padded = np.zeros(n)
    padded[: min(n, len(taus))] = taus[:n]
    code = RESULTS.successful if rev <= max_reversals else RESULTS.too_many_reversals
    xs = np.asarray(ys[:, 0])
    xi_at = np.interp(marks[1:], ts, xs)
    positions = np.zeros(n)
    positions[: min(n, len(taus))] = xi_at[:n]
    # each slip phase oscillates about xi = -s (s: sign of the disk velocity), starting with
    # xi' = -Omega: amplitude sqrt((xi_start + s)^2 + Omega^2), as (12) for the exact cycle
    s_phase = np.sign(np.interp(0.5 * (np.asarray(marks[:-1]) + np.asarray(marks[1:])), ts, u))
    amps = np.sqrt((np.interp(marks[:-1], ts, xs) + s_phase) ** 2 + float(model.Omega) ** 2)
    amplitudes = np.zeros(n)
    amplitudes[: min(n, len(taus))] = amps[:n]
    return StickSlipCycle(
        reversals=jnp.asarray(rev),
        count=jnp.asarray(min(n, len(taus))),
        slip_intervals=jnp.asarray(padded),
        positions=jnp.asarray(positions),
        amplitudes=jnp.asarray(amplitudes),
        slip_time=jnp.asarray(d2 - b1),
        stick_time=jnp.asarray(b2 - d2),
        period=jnp.asarray(b2 - b1),
        result=jnp.asarray(code),
        model=model,
        method="smooth",
    )
