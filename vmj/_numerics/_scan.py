"""The decay scan that every turning-point solver shares: the stick rule at each turning point,
a model-specific swing to the next one, fixed shapes."""

from __future__ import annotations

import jax.numpy as jnp
from jax import lax

from .._solution import RESULTS, DecaySequence

__all__ = ["decay_scan"]


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
