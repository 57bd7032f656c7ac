"""Solvers that evaluate a model's closed forms: the energy-balance half-swing map of a decay
model ([`vmj.EnergyBalance`][]) and the closed-form response or limit cycle
([`vmj.ClosedForm`][])."""

from __future__ import annotations

from typing import ClassVar

import jax.numpy as jnp

from .._checks import instance_of
from .._models._base import AbstractAnalytic, AbstractEnergyMap, AbstractLimitCycle
from .._solution import RESULTS, Trajectory
from ._base import AbstractSolver, unsupported

__all__ = ["EnergyBalance", "ClosedForm"]


class EnergyBalance(AbstractSolver):
    """Turning points from the model's energy balance over each half-swing, a closed-form map
    from one turning point to the next: the variable-mass paper's recurrences (11)-(13) (an
    approximation for a varying mass, as the paper's), the exact energy map of a rope of fixed
    length, and for [`vmj.Oscillator`][] the exact map with dry friction (any restoring law) and
    the exact closed form of the linear law with viscous damping; with viscous or quadratic
    damping and a nonlinear law (or quadratic drag) an averaged map, the loss evaluated on the
    chord swing (amplitude error `O(zeta^3)` per half-swing, time error `O(zeta^2)`; measured
    2e-4 in amplitude and 5e-4 in time after 24 half-swings losing 5 % each).

    Use it as `vmj.turning_points(model, a0, n, vmj.EnergyBalance())` (and for the motion
    between the turning points, [`vmj.decay_trajectory`][]).

    **[`vmj.VariableMass`][]**: the paper's energy-balance recurrences (11)-(12) and the
    corrected (13). With `lambda = delta - 2 delta eps - 2 mu` and
    `m_k = m_{k-1} + pi delta sqrt(m_{k-1}/c)`:

        a_k = a_{k-1} E_k + 8 F_k sqrt(m_{k-1}) / (pi lambda sqrt(c)) (1 - E_k),
        E_k = exp(pi lambda / (4 sqrt(c m_{k-1}))),

    evaluated so that `lambda -> 0` tends smoothly to `a_k = a_{k-1} - 2 F/c`. `F_k = F_T`, or
    `f g (m_{k-1} + (pi delta/2) sqrt(m_{k-1}/c))` for mass-proportional friction. A negative
    `a_k` is a swing that did not pass `x = 0` (the tables' `*`); the mass stops when
    `c |a_k| <= F`. Times are the sums of the half-periods `pi sqrt(m_{k-1}/c)`. The map needs
    an oscillation: where `lambda^2 >= 16 m c` the swing is over-damped (or runs away) and has
    no turning point, reported as `RESULTS.step_limit`, as the exact solver reports it.

    **[`vmj.Rope`][] of fixed length** (`vmj.ConstantSpeed(l0, 0.0)`): the exact turning points
    from the energy balance over each half-swing, `V(x_k) - V(x_{k+1}) = A T |x_k - x_{k+1}|`
    (for `b = 0`: `V(a_k) - V(-a_{k+1}) = A T (a_k + a_{k+1})`), solved per swing; the times
    are the exact half-swing durations (energy integral, Gauss-Legendre).
    """

    name: ClassVar[str] = "energy"

    def check(self, model, task):
        if task != "turning_points" or not instance_of(model, AbstractEnergyMap):
            raise unsupported(
                self,
                model,
                task.replace("_", " "),
                "the energy balance gives the turning points of the variable-mass "
                "model, the rope of fixed length and the oscillator",
            )
        return model.guard_energy_map()

    def turning_points(self, model, a0, n: int):
        return model.energy_map(a0, n)


class ClosedForm(AbstractSolver):
    """The model's closed forms: the analytic response of [`vmj.LinearOscillator`][]
    ([`vmj.simulate`][]) and the paper's limit cycle of [`vmj.StickSlip`][]
    ([`vmj.limit_cycle`][])."""

    name: ClassVar[str] = "closed"

    def check(self, model, task):
        ok = {"simulate": AbstractAnalytic, "limit_cycle": AbstractLimitCycle}.get(task)
        if ok is None or not instance_of(model, ok):
            raise unsupported(
                self,
                model,
                task.replace("_", " "),
                "closed forms exist for the linear oscillator's response and the "
                "stick-slip limit cycle",
            )
        return model

    def simulate(self, model, x0, v0, t1, n_save: int) -> Trajectory:
        ts = jnp.linspace(0.0, t1, n_save)
        xs, vs = model.response(ts, x0, v0)
        return Trajectory(ts=ts, xs=xs, vs=vs, result=jnp.array(RESULTS.successful))

    def limit_cycle(self, model, max_reversals: int):
        return model.closed_form_cycle(max_reversals)
