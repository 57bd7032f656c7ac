"""The entry points, one per problem type: [`vmj.turning_points`][] (a free decay),
[`vmj.simulate`][] (a trajectory), [`vmj.limit_cycle`][] (a self-excited cycle). Each takes a
model and a solver object, validates the input once (concrete values raise `ValueError` here;
traced ones are guarded inside the caller's `jit`/`vmap`), and calls one compiled function per
task. A solver is always an object (`vmj.Smoothed(smoothing=...)`, `vmj.Exact(max_substeps=...)`);
a string or a `method=`/`smoothing=`/`max_substeps=` keyword is refused with the object to pass."""

from __future__ import annotations

import functools
from typing import TYPE_CHECKING

import jax.numpy as jnp

from ._checks import (
    _is_traced,
    anything,
    check,
    check_int,
    check_room,
    default_float,
    guard,
    instance_of,
    own_fields,
    positive,
    scalar,
    validated,
    warn_if_float32,
)
from ._exported import exported_jit
from ._models._base import check_horizon, require_scalar_fields
from ._models._stick_slip import MAX_REVERSALS
from ._solution import DecaySequence, Trajectory, throw_if_failed
from ._solvers._base import AbstractSolver
from ._solvers._closed import ClosedForm, EnergyBalance
from ._solvers._dense import decay_motion
from ._solvers._exact import Exact
from ._solvers._smoothed import Smoothed

if TYPE_CHECKING:  # names used in annotations only
    from jaxtyping import ArrayLike

    from ._models._base import (
        AbstractDecayModel,
        AbstractLimitCycle,
        AbstractModel,
    )
    from ._models._stick_slip import StickSlipCycle

__all__ = ["turning_points", "decay_trajectory", "simulate", "limit_cycle"]

#: memory per turning point of a solve's results (times, positions, amplitudes, crossing
#: flags: 27 bytes measured for the exact and smoothed solvers, n = 10^6 -> 4 * 10^6) and per
#: substep of `decay_trajectory`'s table of the half-swings' polynomials (2.5 kB measured per
#: turning point with 8 substeps) [bytes]
TURNING_POINT_BYTES, SUBSTEP_BYTES = 32, 320

#: the solver class of each solver's name (the command line's `--method`)
SOLVERS = {k.name: k for k in (Exact, Smoothed, EnergyBalance, ClosedForm)}
#: the solver object of each name, for the messages below
_OBJECTS = {name: f"vmj.{k.__name__}()" for name, k in SOLVERS.items()}
#: solver settings refused as keywords of an entry point, with the object that takes them
_SETTINGS = {
    "smoothing": "vmj.Smoothed(smoothing=...)",
    "max_substeps": "vmj.Exact(max_substeps=...)",
}


def _pass(name) -> str:
    """What to pass instead of the solver name `name` (`"smooth"`: `solver=vmj.Smoothed()`)."""
    if isinstance(name, str) and name in _OBJECTS:
        return f"pass solver={_OBJECTS[name]}"
    return "pass a solver object: " + ", ".join(_OBJECTS.values())


def _one_spelling(entry):
    """`entry` refusing a solver given by name or a solver setting given as a keyword of its
    own (`method="smooth"`, `smoothing=`, `max_substeps=`), naming the object to pass."""
    name = entry.__name__

    @functools.wraps(entry)
    def checked(*args, **kwargs):
        if "method" in kwargs:
            raise TypeError(f"{name} takes no method=: {_pass(kwargs['method'])}")
        for key in kwargs.keys() & _SETTINGS.keys():
            raise TypeError(
                f"{name} takes no {key}=: it is a setting of the solver, "
                f"pass solver={_SETTINGS[key]}"
            )
        return entry(*args, **kwargs)

    return checked


def _solver(solver, default):
    """The solver object (`default`'s default instance for `None`); anything else, a name such
    as `"smooth"` included, is refused naming the object to pass."""
    if solver is None:
        return _default(default)
    if instance_of(solver, AbstractSolver):
        return solver
    got = f"the string {solver!r}" if isinstance(solver, str) else type(solver).__name__
    raise TypeError(f"solver must be a solver object (got {got}): {_pass(solver)}")


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
    object and kept on it (read through `own_fields`: an equinox module's attribute access
    costs a microsecond or more, a warm solve's Python overhead is a few)."""
    if type(solver) is not Exact:
        return solver
    fields = own_fields(solver)
    variant = fields.get(_ONE_LANE)
    if variant is None:
        variant = solver
        if not fields["one_lane"]:
            variant = Exact(fields["max_substeps"], fields["derivatives"], one_lane=True)
        object.__setattr__(solver, _ONE_LANE, variant)
    return variant


_ONE_LANE = "_vmj_one_lane"  #: set on an exact solver: its one-lane variant


@_one_spelling
def turning_points(
    model: AbstractDecayModel,
    a0: ArrayLike,
    n: int,
    solver: AbstractSolver | None = None,
    *,
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
      Each solver's settings are its own (`vmj.Exact(max_substeps=...)`,
      `vmj.Smoothed(smoothing=...)`).
    - `throw`: raise [`vmj.SolverError`][] on failure (mass exhausted, step limit) instead of
      returning it in `result`. With `throw=False` check `result`/`message`.

    **Returns:** a [`vmj.DecaySequence`][]. Differentiable with `jax.grad`/`jax.jacfwd` with
    respect to every model parameter and `a0` (with [`vmj.Smoothed`][]: in its `derivatives`
    mode, reverse by default).
    """
    warn_if_float32()
    solver = _solver(solver, Exact)
    n = check_int("n", n, 1)
    check_room(f"the results of n = {n}", n * TURNING_POINT_BYTES, "ask for fewer")
    concrete = require_scalar_fields(model)
    model = _checked(solver, model, "turning_points")
    a0 = scalar("a0", check("a0", a0, *type(model).release_range(model)))
    if instance_of(solver, Smoothed):
        solver = solver.with_defaults(model, a0, 0.0)
    elif concrete and not _is_traced(a0):
        solver = _one_lane(solver)
    seq = _turning_points(model, a0, n, solver)
    return throw_if_failed(seq, seq.result, throw)


@exported_jit(static_argnums=(3, 5))
def _decay_trajectory(model, a0, ts, n, solver, substeps):
    seq = solver.turning_points(model, a0, n)
    return decay_motion(model, a0, seq, ts, substeps)


@_one_spelling
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
    solver = _solver(solver, Exact)
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


@_one_spelling
def simulate(
    model: AbstractModel,
    x0: ArrayLike,
    v0: ArrayLike,
    t1: ArrayLike,
    solver: AbstractSolver | None = None,
    *,
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
      rtol 1e-10; `vmj.Smoothed(smoothing=w)` sets the smoothing velocity `w` [m/s], default
      `1e-4` of the velocity scale `|x0| sqrt(c/m0) + |v0|`) or [`vmj.ClosedForm`][] (the
      analytic response of the linear oscillator). From [`vmj.StickSlip`][]`.breakaway()` the
      smoothed stick-slip model runs through its cycles (diffrax Kvaerno5, rtol 1e-8; default
      `w = 1e-4`); [`vmj.StickSlip.rest_memory`][] gives its rest memory `z` at the same times.
    - `n_save`: number of equally spaced saved times (static).
    - `throw`: raise [`vmj.SolverError`][] if the ODE solve failed.

    **Returns:** a [`vmj.Trajectory`][] (`ts`, `xs`, `vs`, `result`).
    """
    warn_if_float32()
    solver = _solver(solver, Smoothed)
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


# -- limit cycles ------------------------------------------------------------------------------
@exported_jit(static_argnums=1)
def _limit_cycle(model, max_reversals, solver):
    return solver.limit_cycle(model, max_reversals)


@_one_spelling
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
    solver = _solver(solver, Exact)
    max_reversals = check_int("max_reversals", max_reversals, 0)
    model = _checked(solver, model, "limit_cycle")
    if isinstance(solver, Smoothed):
        x0, v0 = model.breakaway()
        cycle = model.smoothed_cycle(max_reversals, solver.with_defaults(model, x0, v0))
    else:
        cycle = _limit_cycle(model, max_reversals, solver)
    return throw_if_failed(cycle, cycle.result, throw)
