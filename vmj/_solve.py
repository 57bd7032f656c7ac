"""Public entry points for decay sequences and simulations (one jitted function per task)."""

from __future__ import annotations

from typing import Callable

import equinox as eqx
import jax
import jax.numpy as jnp

from ._checks import _is_traced, check, check_int, positive, warn_if_float32
from ._energy import energy_balance_sequence
from ._exact import turning_points_exact
from ._models import VariableMass, _float, validated
from ._smooth import default_smoothing, simulate_smooth, turning_points_smooth
from ._solution import DecaySequence, Trajectory, throw_if_failed

__all__ = ["turning_points", "energy_balance", "simulate", "register_solver"]

#: (model type, method) -> function(model, a0, n, **options) -> DecaySequence
_SOLVERS: dict[tuple[type, str], Callable] = {}


def register_solver(model_type: type, method: str):
    """Register `fn(model, a0, n, **options)` as `turning_points(..., method=method)` for a model."""

    def wrap(fn):
        _SOLVERS[(model_type, method)] = fn
        return fn

    return wrap


def _require_scalar_fields(model) -> None:
    for leaf in jax.tree.leaves(model):
        if not _is_traced(leaf) and jnp.ndim(leaf) != 0:
            raise ValueError(
                "this entry point takes a model with scalar parameters; for arrays of parameters "
                "use vmj.sweep or jax.vmap"
            )


@register_solver(VariableMass, "exact")
def _variable_mass_exact(model, a0, n, *, smoothing, max_substeps):
    return turning_points_exact(model, a0, n, max_substeps)


@register_solver(VariableMass, "smooth")
def _variable_mass_smooth(model, a0, n, *, smoothing, max_substeps):
    return turning_points_smooth(model, a0, n, smoothing)


@register_solver(VariableMass, "energy")
def _variable_mass_energy(model, a0, n, *, smoothing, max_substeps):
    return energy_balance_sequence(model, a0, n)


@eqx.filter_jit
def _turning_points(model, a0, n, method, smoothing, max_substeps, throw):
    model = validated(model)
    a0 = check("a0", a0, positive, "> 0 [m]")
    if smoothing is not None:
        smoothing = check("smoothing", smoothing, positive, "> 0 [m/s]")
    solver = _SOLVERS[(type(model), method)]
    seq = solver(model, a0, n, smoothing=smoothing, max_substeps=max_substeps)
    return throw_if_failed(seq, seq.result, throw)


def turning_points(
    model,
    a0,
    n: int,
    method: str = "exact",
    *,
    smoothing=None,
    max_substeps: int = 8,
    throw: bool = False,
) -> DecaySequence:
    """Turning points (velocity zeros) of the free decay released from rest at `x(0) = -a0`.

    **Arguments:**

    - `model`: a model such as [`vmj.VariableMass`][].
    - `a0`: initial deflection [m], `> 0`.
    - `n`: number of turning points to compute (static; the result is padded to `n`).
    - `method`: `"exact"` integrates the non-smooth system half-swing by half-swing with a fixed
      friction sign to each velocity zero and applies the stick rule `|c x| <= F(t)` there
      (a stuck mass stays put while its static friction holds; friction that falls with the
      mass releases it again). `"smooth"` returns the turning points of the smoothed ODE
      (see [`vmj.simulate`][]). `"energy"` is [`vmj.energy_balance`][].
    - `smoothing`: smoothing velocity `w` [m/s] of the smoothed model (`method="smooth"`);
      default `1e-4 * a0 * sqrt(c/m0)`.
    - `max_substeps`: step limit per half-swing of the exact solver (substeps of
      `2 sqrt(m/c)`, about 0.64 of a half-period each).
    - `throw`: raise on failure (mass exhausted, step limit) instead of returning it in
      `result`. With `throw=False` check `result`/`message`.

    **Returns:** a [`vmj.DecaySequence`][]. Differentiable with `jax.grad`/`jax.jacfwd` with
    respect to every model parameter and `a0`.
    """
    warn_if_float32()
    methods = sorted(m for (t, m) in _SOLVERS if t is type(model))
    if not methods:
        raise ValueError(f"no turning-point solver for {type(model).__name__}")
    if method not in methods:
        raise ValueError(f"method must be one of {methods} for {type(model).__name__} "
                         f"(got {method!r})")
    n = check_int("n", n, 1)
    max_substeps = check_int("max_substeps", max_substeps, 1)
    _require_scalar_fields(model)
    # arrays, not Python floats: filter_jit would treat floats as static and recompile per value
    a0 = _float(check("a0", a0, positive, "> 0 [m]"))
    if smoothing is not None:
        smoothing = _float(check("smoothing", smoothing, positive, "> 0 [m/s]"))
    elif method == "smooth":  # the default as an array too: one compilation for every w
        smoothing = default_smoothing(model, a0, 0.0)
    return _turning_points(model, a0, n, method, smoothing, max_substeps, throw)


def energy_balance(model: VariableMass, a0, n: int, *, throw: bool = False) -> DecaySequence:
    """The paper's energy-balance recurrences (11)-(12) and the corrected (13).

    With `lambda = delta - 2 delta eps - 2 mu` and `m_k = m_{k-1} + pi delta sqrt(m_{k-1}/c)`:

        a_k = a_{k-1} E_k + 8 F_k sqrt(m_{k-1}) / (pi lambda sqrt(c)) (1 - E_k),
        E_k = exp(pi lambda / (4 sqrt(c m_{k-1}))),

    evaluated so that `lambda -> 0` tends smoothly to `a_k = a_{k-1} - 2 F/c`. `F_k = F_T`, or
    `f g (m_{k-1} + (pi delta/2) sqrt(m_{k-1}/c))` for mass-proportional friction. A negative
    `a_k` is a swing that did not pass `x = 0` (the tables' `*`); the mass stops when
    `c |a_k| <= F`. Times are the sums of the half-periods `pi sqrt(m_{k-1}/c)`.

    **Arguments:** `model` ([`vmj.VariableMass`][]), `a0` [m] `> 0`, `n` (number of swings),
    `throw` as in [`vmj.turning_points`][]. **Returns:** a [`vmj.DecaySequence`][].
    """
    return turning_points(model, a0, n, method="energy", throw=throw)


@eqx.filter_jit
def _simulate(model, x0, v0, t1, smoothing, n_save, throw):
    model = validated(model)
    if hasattr(model, "lifetime"):
        t1 = eqx.error_if(t1, t1 >= model.lifetime(), "t1 must be below the model's lifetime "
                          "(zero mass or zero rope length)")
    w = check("smoothing", smoothing, positive, "> 0 [m/s]")
    traj = simulate_smooth(model, x0, v0, t1, w, n_save)
    return throw_if_failed(traj, traj.result, throw)


def simulate(
    model,
    x0,
    v0,
    t1,
    *,
    smoothing=None,
    n_save: int = 2001,
    throw: bool = False,
) -> Trajectory:
    """Solve the smoothed model (sign(v) replaced by `tanh(v/w)`) with diffrax (Tsit5, rtol 1e-10).

    **Arguments:**

    - `model`: a model such as [`vmj.VariableMass`][].
    - `x0`, `v0`: initial position [m] and velocity [m/s] at `t = 0`.
    - `t1`: final time [s], `> 0`; for `delta < 0` it must be below the zero-mass time.
    - `smoothing`: smoothing velocity `w` [m/s], `> 0`. Default: `1e-4` of the velocity scale
      `|x0| sqrt(c/m0) + |v0|`; the turning points then agree with the exact solver to about
      1e-8 relative (smaller `w` is closer to the non-smooth model and stiffer to integrate).
    - `n_save`: number of equally spaced saved times (static).

    **Returns:** a [`vmj.Trajectory`][] (`ts`, `xs`, `vs`, `result`).
    """
    warn_if_float32()
    n_save = check_int("n_save", n_save, 2)
    _require_scalar_fields(model)
    x0 = check("x0", x0, lambda x: x == x, "a real number [m]")
    v0 = check("v0", v0, lambda x: x == x, "a real number [m/s]")
    t1 = check("t1", t1, positive, "> 0 [s]")
    if hasattr(model, "lifetime"):
        lifetime = model.lifetime()
        what = getattr(model, "_lifetime_text", "the zero-mass time m0/|delta|")
        if not (_is_traced(lifetime) or _is_traced(t1)):
            if float(t1) >= float(lifetime):
                raise ValueError(
                    f"t1 must be below {what} = {float(lifetime):.6g} s (got {float(t1)})"
                )
    x0, v0, t1 = (_float(v) for v in (x0, v0, t1))
    if smoothing is not None:
        smoothing = _float(check("smoothing", smoothing, positive, "> 0 [m/s]"))
    else:
        if not (_is_traced(x0) or _is_traced(v0)) and x0 == 0 and v0 == 0:
            raise ValueError("smoothing must be given (> 0 [m/s]) when x0 = v0 = 0: its default "
                             "is relative to the initial velocity scale")
        smoothing = default_smoothing(model, x0, v0)
    return _simulate(model, x0, v0, t1, smoothing, n_save, throw)
