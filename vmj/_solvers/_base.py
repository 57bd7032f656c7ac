"""The solver interface and the decay scan that every turning-point solver shares."""

from __future__ import annotations

import abc
from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
from jax import lax

from .._solution import RESULTS, DecaySequence

__all__ = ["AbstractSolver", "decay_scan"]


class AbstractSolver(eqx.Module):
    """Base of the solver objects passed to [`vmj.turning_points`][], [`vmj.simulate`][] and
    [`vmj.limit_cycle`][]. A solver is an `equinox.Module`: its array fields (a smoothing
    velocity) are traced, its settings static, so one compilation serves every value."""

    #: the name of the solver in `method="..."` strings and on the command line
    name: ClassVar[str]

    @abc.abstractmethod
    def check(self, model, task: str) -> None:
        """Raise `ValueError` when this solver does not apply to `model` for `task`
        (`"turning_points"`, `"simulate"` or `"limit_cycle"`), saying what does."""


def unsupported(solver, model, task: str, use: str) -> ValueError:
    return ValueError(f"{type(solver).__name__} does not solve {task} of "
                      f"{type(model).__name__}; {use}")


def decay_scan(model, a0, n: int, swing) -> DecaySequence:
    """The first `n` turning points of `model` released from rest at `x = -a0`: at each turning
    point the model's stick rule (`model.rest`) decides whether and when the mass moves on, and
    `swing(t, x, s) -> (found, failure, t1, x1)` takes it to the next one (`failure`: the status
    to report when `found` is False). A mass that stops, or a solve that fails, stays put for
    the remaining entries (fixed shapes for `jit`, `vmap` and `grad`)."""

    def body(carry, _):
        t, x, code = carry
        active = code == RESULTS.successful
        s, t_go, stuck = model.rest(t, x)
        found, failure, t1, x1 = swing(t_go, x, s)
        new_code = jnp.where(stuck, RESULTS.stopped, jnp.where(found, RESULTS.successful, failure))
        code = jnp.where(active, new_code, code)
        advance = active & (code == RESULTS.successful)
        crossed = advance & (x1 * x < 0)
        t = jnp.where(advance, t1, t)
        x = jnp.where(advance, x1, x)
        return (t, x, code), (t, x, crossed, advance)

    x0 = -a0 * jnp.ones_like(model.velocity_scale(1.0))
    init = (jnp.zeros_like(x0), x0, jnp.array(RESULTS.successful, dtype=jnp.int32))
    (t, x, code), (times, positions, crossed, advanced) = lax.scan(body, init, None, length=n)
    _, _, stuck = model.rest(t, x)
    code = jnp.where((code == RESULTS.successful) & stuck, RESULTS.stopped, code)
    return DecaySequence.from_scan(times, positions, crossed, advanced, code)
