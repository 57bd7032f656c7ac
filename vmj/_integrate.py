"""The entry points, one per problem type: [`vmj.turning_points`][] (a free decay),
[`vmj.simulate`][] (a trajectory), [`vmj.limit_cycle`][] (a self-excited cycle). Each takes a
model and a solver object, validates the input once (concrete values raise `ValueError` here;
traced ones are guarded inside the caller's `jit`/`vmap`), and calls one compiled function per
task. The older per-model functions are thin wrappers kept for compatibility."""

from __future__ import annotations

from typing import TYPE_CHECKING

import jax.numpy as jnp

from ._checks import (
    _float,
    _is_traced,
    anything,
    check,
    check_int,
    check_room,
    default_float,
    guard,
    positive,
    scalar,
    validated,
    warn_if_float32,
)
from ._exported import exported_jit
from ._models._base import check_horizon, require_scalar_fields
from ._models._rope import Rope
from ._models._stick_slip import MAX_REVERSALS, StickSlip, smoothed_states
from ._solution import DecaySequence, Trajectory, throw_if_failed
from ._solvers._closed import ClosedForm, EnergyBalance
from ._solvers._dense import decay_motion
from ._solvers._exact import Exact
from ._solvers._smoothed import Smoothed

if TYPE_CHECKING:  # names used in annotations only
    from jaxtyping import Array, ArrayLike

    from ._models._base import (
        AbstractDecayModel,
        AbstractEnergyMap,
        AbstractLimitCycle,
        AbstractModel,
    )
    from ._models._linear import LinearOscillator
    from ._models._stick_slip import StickSlipCycle
    from ._solvers._base import AbstractSolver

__all__ = [
    "turning_points",
    "decay_trajectory",
    "simulate",
    "limit_cycle",
    "energy_balance",
    "rope_energy_map",
    "stick_slip_cycle",
    "stick_slip_closed_form",
    "stick_slip_simulate",
    "linear_simulate",
]

#: memory per turning point of a solve's results (times, positions, amplitudes, crossing
#: flags: 27 bytes measured for the exact and smoothed solvers, n = 10^6 -> 4 * 10^6) and per
#: substep of `decay_trajectory`'s table of the half-swings' polynomials (2.5 kB measured per
#: turning point with 8 substeps) [bytes]
TURNING_POINT_BYTES, SUBSTEP_BYTES = 32, 320

_METHODS = {"exact": Exact, "smooth": Smoothed, "energy": EnergyBalance, "closed": ClosedForm}


def _solver(solver, method, smoothing, max_substeps, default):
    """The solver object, from `solver` or the older `method=`/`smoothing=`/`max_substeps=`."""
    if isinstance(solver, str):  # turning_points(model, a0, n, "smooth"): the older positional
        solver, method = None, solver
    if solver is not None:
        if method is not None:
            raise ValueError("give either solver or method, not both")
        if smoothing is not None or max_substeps is not None:
            raise ValueError(
                "smoothing and max_substeps are settings of the solver object: "
                "vmj.Smoothed(smoothing=...), vmj.Exact(max_substeps=...)"
            )
        return solver
    if method is None:
        kind = default
    elif method in _METHODS:
        kind = _METHODS[method]
    else:
        raise ValueError(f"method must be one of {sorted(_METHODS)} (got {method!r})")
    if kind is Smoothed:
        return Smoothed(smoothing=smoothing)
    if smoothing is not None:
        raise ValueError(
            f"smoothing applies to the smoothed solver (method 'smooth'), not {kind.name!r}"
        )
    if kind is Exact and max_substeps is not None:
        return Exact(max_substeps=check_int("max_substeps", max_substeps, 1))
    return _default(kind)


def _default(kind):
    """The default instance of a solver class (made once: equinox modules cost microseconds
    to build, and these have no arrays)."""
    if kind not in _DEFAULTS:
        _DEFAULTS[kind] = kind()
    return _DEFAULTS[kind]


_DEFAULTS: dict = {}


def _checked(solver, model, task: str):
    """`solver.check(validated(model), task)`. (Methods are called through the class in the
    entry points: an equinox module binds a method into a new module at every access, which
    costs more than a warm solve.)"""
    return type(solver).check(solver, validated(model), task)


# The compiled entry points: `jax.jit` (its dispatch runs in C++; every leaf of a model and a
# solver is an array, their settings are static fields) with the integer settings static. They
# hold no host callbacks for concrete inputs, so JAX's persistent compilation cache can store
# them, and `jax.export` can serialize them: while an entry point (the `vmj` command) has
# switched the exported-program cache on, a new process loads them without tracing
# (`vmj/_exported.py`).


# -- turning points of a free decay ------------------------------------------------------------
#: XLA's options for one concrete solve: its loop-invariant code motion would hoist what a
#: loop recomputes (`Exact.one_lane`) back out of it, each hoisted scalar a kernel of its own
#: (both together, alternating processes: a warm exact call 114-122 -> 83-88 us; smoothed and
#: energy-balance calls unchanged by the option)
_ONE_SOLVE = {"xla_disable_hlo_passes": "while-loop-invariant-code-motion"}


@exported_jit(static_argnums=2, compiler_options=_ONE_SOLVE)
def _turning_points(model, a0, n, solver):
    return solver.turning_points(model, a0, n)


def _one_lane(solver):
    """The exact solver compiled for a single solve (`Exact.one_lane`), made once per solver
    object and kept on it (read through `vars`: an equinox module's attribute access costs a
    microsecond or more, a warm solve's Python overhead is a few)."""
    if type(solver) is not Exact:
        return solver
    fields = vars(solver)
    variant = fields.get(_ONE_LANE)
    if variant is None:
        variant = solver
        if not fields["one_lane"]:
            variant = Exact(fields["max_substeps"], fields["derivatives"], one_lane=True)
        object.__setattr__(solver, _ONE_LANE, variant)
    return variant


_ONE_LANE = "_vmj_one_lane"  #: set on an exact solver: its one-lane variant


def turning_points(
    model: AbstractDecayModel,
    a0: ArrayLike,
    n: int,
    solver: AbstractSolver | str | None = None,
    *,
    method: str | None = None,
    smoothing: ArrayLike | None = None,
    max_substeps: int | None = None,
    throw: bool = False,
) -> DecaySequence:
    """Turning points (velocity zeros) of the free decay released from rest at `x(0) = -a0`.

    **Arguments:**

    - `model`: a decay model: [`vmj.VariableMass`][], [`vmj.Rope`][], [`vmj.Oscillator`][].
    - `a0`: initial deflection [m] (the model's position unit), `> 0`.
    - `n`: number of turning points to compute (static; the result is padded to `n`).
    - `solver`: [`vmj.Exact`][] (default) integrates the non-smooth system half-swing by
      half-swing with a fixed friction sign to each velocity zero and applies the stick rule
      there (a stuck mass stays put while its static friction holds; friction that falls with
      the mass releases it again). [`vmj.Smoothed`][] returns the turning points of the
      smoothed ODE. [`vmj.EnergyBalance`][] evaluates the model's closed-form half-swing map.
    - `method`, `smoothing`, `max_substeps`: the older spelling, `method="exact" | "smooth" |
      "energy"` with the solver's settings (kept for compatibility).
    - `throw`: raise [`vmj.SolverError`][] on failure (mass exhausted, step limit) instead of
      returning it in `result`. With `throw=False` check `result`/`message`.

    **Returns:** a [`vmj.DecaySequence`][]. Differentiable with `jax.grad`/`jax.jacfwd` with
    respect to every model parameter and `a0` (with [`vmj.Smoothed`][]: reverse mode only).
    """
    warn_if_float32()
    solver = _solver(solver, method, smoothing, max_substeps, Exact)
    n = check_int("n", n, 1)
    check_room(f"the results of n = {n}", n * TURNING_POINT_BYTES, "ask for fewer")
    concrete = require_scalar_fields(model)
    model = _checked(solver, model, "turning_points")
    a0 = scalar("a0", check("a0", a0, *type(model).release_range(model)))
    if isinstance(solver, Smoothed):
        solver = solver.with_defaults(model, a0, 0.0)
    elif concrete and not _is_traced(a0):
        solver = _one_lane(solver)
    seq = _turning_points(model, a0, n, solver)
    return throw_if_failed(seq, seq.result, throw)


def energy_balance(
    model: AbstractEnergyMap, a0: ArrayLike, n: int, *, throw: bool = False
) -> DecaySequence:
    """The paper's energy-balance recurrences (11)-(12) and the corrected (13); the same as
    `vmj.turning_points(model, a0, n, vmj.EnergyBalance())`.

    With `lambda = delta - 2 delta eps - 2 mu` and `m_k = m_{k-1} + pi delta sqrt(m_{k-1}/c)`:

        a_k = a_{k-1} E_k + 8 F_k sqrt(m_{k-1}) / (pi lambda sqrt(c)) (1 - E_k),
        E_k = exp(pi lambda / (4 sqrt(c m_{k-1}))),

    evaluated so that `lambda -> 0` tends smoothly to `a_k = a_{k-1} - 2 F/c`. `F_k = F_T`, or
    `f g (m_{k-1} + (pi delta/2) sqrt(m_{k-1}/c))` for mass-proportional friction. A negative
    `a_k` is a swing that did not pass `x = 0` (the tables' `*`); the mass stops when
    `c |a_k| <= F`. Times are the sums of the half-periods `pi sqrt(m_{k-1}/c)`. The map needs
    an oscillation: where `lambda^2 >= 16 m c` the swing is over-damped (or runs away) and has
    no turning point, reported as `RESULTS.step_limit`, as the exact solver reports it.

    **Arguments:** `model` ([`vmj.VariableMass`][], or any model with an energy map), `a0` [m]
    `> 0`, `n` (number of swings), `throw` as in [`vmj.turning_points`][].
    **Returns:** a [`vmj.DecaySequence`][].
    """
    return turning_points(model, a0, n, EnergyBalance(), throw=throw)


def rope_energy_map(rope: Rope, a0: ArrayLike, n: int, *, throw: bool = False) -> DecaySequence:
    """Exact turning points of a rope of fixed length (`u = 0`) from the energy balance over
    each half-swing, `V(x_k) - V(x_{k+1}) = A T |x_k - x_{k+1}|` (for `b = 0`:
    `V(a_k) - V(-a_{k+1}) = A T (a_k + a_{k+1})`), solved per swing; the times are the exact
    half-swing durations (energy integral, Gauss-Legendre). The same as
    `vmj.turning_points(rope, a0, n, vmj.EnergyBalance())`.

    **Arguments:** `rope` ([`vmj.Rope`][] with `vmj.ConstantSpeed(l0, 0.0)`), `a0` [m] `> 0`,
    `n` (number of turning points). **Returns:** a [`vmj.DecaySequence`][].
    """
    if not isinstance(rope, Rope):
        raise ValueError(f"rope must be a vmj.Rope (got {type(rope).__name__})")
    return turning_points(rope, a0, n, EnergyBalance(), throw=throw)


@exported_jit(static_argnums=(3, 5))
def _decay_trajectory(model, a0, ts, n, solver, substeps):
    seq = solver.turning_points(model, a0, n)
    return decay_motion(model, a0, seq, ts, substeps)


def decay_trajectory(
    model: AbstractDecayModel,
    a0: ArrayLike,
    ts: ArrayLike,
    n: int,
    solver: AbstractSolver | None = None,
    *,
    throw: bool = False,
) -> Trajectory:
    """The exact motion of the free decay released from rest at `x(0) = -a0`, at times `ts`.

    The turning points come from `solver`; between them the motion is the exact half-swing
    solution (friction sign fixed) that [`vmj.Exact`][] integrates, the Taylor polynomials of
    its substeps evaluated at each time (dense output: the cost per time is one polynomial).
    Differentiable with `jax.grad`/`jax.jacfwd` with respect to every model parameter and `a0`,
    through the turning points' times (implicit-function derivatives) as well.

    **Arguments:**

    - `model`: a decay model: [`vmj.VariableMass`][], [`vmj.Rope`][], [`vmj.Oscillator`][].
    - `a0`: initial deflection [m] (the model's position unit), `> 0`.
    - `ts`: times [s] from the release, a 1-D array in any order. Times before 0 give the
      release point; times after the mass stopped for good, its rest position.
    - `n`: number of turning points computed (static): the times must not reach past the
      `n`-th turning point of a mass that still moves (those give NaN and
      `RESULTS.beyond_turning_points`).
    - `solver`: [`vmj.Exact`][] (default) or [`vmj.EnergyBalance`][] (the model's closed-form
      half-swing map for the turning points: exact for [`vmj.Oscillator`][]'s linear law with
      viscous and Coulomb damping; where the map is averaged, the motion between turning points
      misses them by the map's error).
    - `throw`: raise [`vmj.SolverError`][] on failure instead of returning it in `result`.

    **Returns:** a [`vmj.Trajectory`][] (`ts`, `xs` [m], `vs` [m/s], `result`).
    """
    warn_if_float32()
    solver = _solver(solver, None, None, None, Exact)
    if not isinstance(solver, (Exact, EnergyBalance)):
        raise ValueError(
            f"decay_trajectory takes vmj.Exact() or vmj.EnergyBalance() (got "
            f"{type(solver).__name__}); for the smoothed ODE use vmj.simulate"
        )
    n = check_int("n", n, 1)
    require_scalar_fields(model)
    model = _checked(solver, model, "turning_points")
    a0 = scalar("a0", check("a0", a0, *type(model).release_range(model)))
    ts = check("ts", jnp.asarray(ts, dtype=default_float()), anything, "times [s]")
    if ts.ndim != 1:
        raise ValueError(f"ts must be a 1-D array of times [s] (got shape {ts.shape})")
    substeps = getattr(solver, "max_substeps", None) or type(model).exact_substeps
    check_room(
        f"the results of n = {n}",
        n * (TURNING_POINT_BYTES + SUBSTEP_BYTES * substeps),
        "ask for fewer",
    )
    traj = _decay_trajectory(model, a0, ts, n, solver, substeps)
    return throw_if_failed(traj, traj.result, throw)


# -- trajectories ------------------------------------------------------------------------------
@exported_jit(static_argnums=4)
def _simulate(model, x0, v0, t1, n_save, solver):
    return solver.simulate(model, x0, v0, t1, n_save)


def simulate(
    model: AbstractModel,
    x0: ArrayLike,
    v0: ArrayLike,
    t1: ArrayLike,
    solver: AbstractSolver | None = None,
    *,
    smoothing: ArrayLike | None = None,
    n_save: int = 2001,
    throw: bool = False,
) -> Trajectory:
    """The trajectory of `model` from `x(0) = x0`, `x'(0) = v0` to `t1`.

    **Arguments:**

    - `model`: any model: [`vmj.VariableMass`][], [`vmj.Rope`][], [`vmj.Oscillator`][],
      [`vmj.LinearOscillator`][], [`vmj.StickSlip`][] (dimensionless `xi`, `xi'`).
    - `x0`, `v0`: initial position [m] and velocity [m/s] at `t = 0`.
    - `t1`: final time [s], `> 0`, below the model's lifetime (zero mass, zero rope length).
    - `solver`: [`vmj.Smoothed`][] (default; `sign(v)` replaced by `tanh(v/w)`, diffrax Dopri8,
      rtol 1e-10) or [`vmj.ClosedForm`][] (the analytic response of the linear oscillator).
    - `smoothing`: the older spelling of `vmj.Smoothed(smoothing=w)`: the smoothing velocity
      `w` [m/s], `> 0`; default `1e-4` of the velocity scale `|x0| sqrt(c/m0) + |v0|`, with
      which the turning points agree with the exact solver to about 1e-8 relative.
    - `n_save`: number of equally spaced saved times (static).
    - `throw`: raise [`vmj.SolverError`][] if the ODE solve failed.

    **Returns:** a [`vmj.Trajectory`][] (`ts`, `xs`, `vs`, `result`).
    """
    warn_if_float32()
    solver = _solver(solver, None, smoothing, None, Smoothed)
    n_save = check_int("n_save", n_save, 2)
    check_room(f"the results of n_save = {n_save}", n_save * TURNING_POINT_BYTES, "ask for fewer")
    require_scalar_fields(model)
    model = _checked(solver, model, "simulate")
    unit = model.position_unit
    x0 = scalar("x0", check("x0", x0, anything, f"a real number [{unit}]"))
    v0 = scalar("v0", check("v0", v0, anything, f"a real number [{unit}/s]"))
    t1 = scalar("t1", check("t1", t1, positive, "> 0 [s]"))
    check_horizon(model, t1)
    if _is_traced(t1) or _is_traced(model.lifetime()):
        t1 = guard(t1, t1 >= model.lifetime(), f"t1 must be below {model.lifetime_text}")
    if isinstance(solver, Smoothed):
        solver = solver.with_defaults(model, x0, v0)
    traj = _simulate(model, x0, v0, t1, n_save, solver)
    return throw_if_failed(traj, traj.result, throw)


def linear_simulate(
    osc: LinearOscillator,
    x0: ArrayLike,
    v0: ArrayLike,
    t1: ArrayLike,
    *,
    n_save: int = 2001,
    rtol: float = 1e-12,
    throw: bool = False,
) -> Trajectory:
    """Integrate `m x'' + c x' + k x = F(t)` with diffrax (Dopri8) from `x(0) = x0` [m],
    `x'(0) = v0` [m/s] to `t1` [s] `> 0`: `vmj.simulate(osc, x0, v0, t1,
    vmj.Smoothed(rtol=rtol))`. `rtol` is the relative tolerance (the absolute one is `rtol`
    times the motion's length scale). **Returns:** a [`vmj.Trajectory`][]."""
    rtol = float(check("rtol", rtol, positive, "> 0"))
    return simulate(osc, x0, v0, t1, Smoothed(rtol=rtol), n_save=n_save, throw=throw)


# -- limit cycles ------------------------------------------------------------------------------
@exported_jit(static_argnums=1)
def _limit_cycle(model, max_reversals, solver):
    return solver.limit_cycle(model, max_reversals)


def limit_cycle(
    model: AbstractLimitCycle,
    solver: AbstractSolver | None = None,
    *,
    max_reversals: int = MAX_REVERSALS,
    throw: bool = False,
) -> StickSlipCycle:
    """The limit cycle of a self-excited model ([`vmj.StickSlip`][]), from breakaway to the
    next breakaway.

    **Arguments:**

    - `model`: a [`vmj.StickSlip`][].
    - `solver`: [`vmj.Exact`][] (default): event-driven solution of the non-smooth rules; each
      slip phase is the analytic solution of `xi'' + xi = -+1`, its velocity zero found by
      Newton iteration with an implicit-function-theorem gradient. Runs under `jax.jit`,
      `jax.vmap` (batched models) and `jax.grad` (the period, slip and stick times
      differentiate in `eps` and `Omega`). [`vmj.ClosedForm`][]: the paper's formulas
      (11)-(20). [`vmj.Smoothed`][]: the cycle measured on the smoothed diffrax model (NumPy
      post-processing; concrete scalar models only).
    - `max_reversals`: static bound on reversals per cycle (arrays are padded to it + 1).
    - `throw`: raise [`vmj.SolverError`][] when the cycle has more than `max_reversals`
      reversals (or the smoothed model did not settle) instead of returning it in `result`.

    **Returns:** a [`vmj.StickSlipCycle`][] (dimensionless times; `.physical()` for seconds).
    """
    warn_if_float32()
    solver = _default(Exact) if solver is None else solver
    max_reversals = check_int("max_reversals", max_reversals, 0)
    model = _checked(solver, model, "limit_cycle")
    if isinstance(solver, Smoothed):
        x0, v0 = model.breakaway()
        cycle = model.smoothed_cycle(max_reversals, solver.with_defaults(model, x0, v0))
    else:
        cycle = _limit_cycle(model, max_reversals, solver)
    return throw_if_failed(cycle, cycle.result, throw)


def stick_slip_cycle(
    model: StickSlip,
    *,
    method: str = "exact",
    max_reversals: int = MAX_REVERSALS,
    smoothing: ArrayLike | None = None,
    throw: bool = False,
) -> StickSlipCycle:
    """`vmj.limit_cycle` with `method="exact" | "smooth"` (the older spelling)."""
    if method not in ("exact", "smooth"):
        raise ValueError(f"method must be 'exact' or 'smooth' (got {method!r})")
    solver = _solver(None, method, smoothing, None, Exact)
    return limit_cycle(model, solver, max_reversals=max_reversals, throw=throw)


def stick_slip_closed_form(
    model: StickSlip, *, max_reversals: int = MAX_REVERSALS, throw: bool = False
) -> StickSlipCycle:
    """The paper's closed forms (11)-(20) for the limit cycle of `model`:
    `vmj.limit_cycle(model, vmj.ClosedForm())` (see `_closed_forms/_belokobylsky.py`)."""
    return limit_cycle(model, ClosedForm(), max_reversals=max_reversals, throw=throw)


def stick_slip_simulate(
    model: StickSlip,
    t1: ArrayLike,
    *,
    smoothing: ArrayLike | None = None,
    n_save: int = 4001,
    throw: bool = False,
    memory: bool = False,
) -> Trajectory | tuple[Trajectory, Array]:
    """The smoothed stick-slip model (diffrax Kvaerno5, rtol 1e-8) from breakaway:
    `vmj.simulate(model, -eps, -Omega, t1, vmj.Smoothed(smoothing=w))` (default `w = 1e-4`;
    see `vmj.StickSlip.vector_field` for the smoothed equations).

    **Returns:** a [`vmj.Trajectory`][] (`ts` = tau, `xs` = xi, `vs` = xi'), and the rest memory
    `z` at the same times if `memory`.
    """
    if not isinstance(model, StickSlip):
        raise ValueError(f"model must be a vmj.StickSlip (got {type(model).__name__})")
    x0, v0 = model.breakaway()
    traj = simulate(model, x0, v0, t1, Smoothed(smoothing=smoothing), n_save=n_save, throw=throw)
    if not memory:
        return traj
    solver = Smoothed(smoothing=smoothing).with_defaults(model, x0, v0)
    _, ys, _ = smoothed_states(model, solver, _float(t1), check_int("n_save", n_save, 2))
    return traj, ys[:, 2]
