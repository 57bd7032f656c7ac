"""The decay scan that every turning-point solver shares: the stick rule at each turning point,
a model-specific swing to the next one, fixed shapes; and the loop that it and the exact
solver's substeps run in."""

from __future__ import annotations

import equinox.internal as eqxi
import jax
import jax.numpy as jnp
import numpy as np
from jax import lax

from .._solution import RESULTS, DecaySequence

__all__ = [
    "computed_once",
    "decay_scan",
    "early_exit_loop",
    "lanes_of",
    "release_point",
    "zeros_of_lanes",
]


def computed_once(values, step):
    """`values` (a tuple of arrays of one shape), each computed once. XLA's CPU backend has no
    multi-output fusion: every kernel that reads an elementwise expression computes it again,
    so a long chain (a Taylor recurrence, a Horner evaluation) read by several consumers runs
    once per consumer. Here the values are packed in pairs as complex numbers (one kernel
    computes both halves of a pair, their shared chain once) and passed through a conditional,
    whose operands are buffers (`step`, an unbatched integer such as a loop counter, keeps its
    predicate opaque). Other platforms fuse several outputs into one kernel: there `values`
    pass unchanged."""

    def conditional(values):
        pairs = [
            lax.complex(*values[i : i + 2]) if i + 1 < len(values) else values[i]
            for i in range(0, len(values), 2)
        ]
        pairs = lax.cond(step >= 0, lambda p: p, lambda p: [jnp.zeros_like(a) for a in p], pairs)
        out = []
        for p in pairs:
            out += [jnp.real(p), jnp.imag(p)] if jnp.iscomplexobj(p) else [p]
        return tuple(out)

    return lax.platform_dependent(tuple(values), cpu=conditional, default=tuple)


def zeros_of_lanes(x, dtype=None):
    """Zeros of `x`'s shape (in `dtype`, default `x`'s) batched wherever `x` is, under `vmap`
    and `jax.jacfwd` alike (a floating result carries a tangent of `x`'s batching too). The
    initial carry of a loop: JAX's batching rule batches a loop's body once more for every
    carry that turns batched in it, and every loop nested in it with it, while a carry that
    starts batched takes one pass; `jnp.zeros_like` is batched nowhere. The fit of the table 1
    record traced its decay loops' bodies 3, 2 and 3 times under its three `vmap`s."""
    dtype = x.dtype if dtype is None else dtype
    if jnp.issubdtype(dtype, jnp.floating):
        return jnp.where(jnp.isfinite(x), 0 * jnp.abs(x), 0).astype(dtype)  # (+0, never -0)
    return jnp.where(x == x, 0, 0).astype(dtype)


def lanes_of(x, tree):
    """`x`, its value unchanged, batched under `vmap` and carrying a tangent under `jax.jvp`
    wherever a floating leaf of `tree` does (`x + zeros_of_lanes(sum(leaf))` for each): a
    loop's start that every lane's state comes to depend on. JAX batches (and differentiates)
    a loop by tracing its body again until the batching (the non-zero tangents) of its
    carries stops changing, and every loop nested in it with it: a decay released from
    `x = -a0` of a model swept in parameters `x` does not depend on (`eps`, `mu`, `delta`,
    `F_T` of the variable mass) traced its decay loop's body twice, the substeps' three
    times, Newton's six (the tracing times in docs/performance.md)."""
    for leaf in jax.tree.leaves(tree):
        if isinstance(leaf, jax.Array | np.ndarray) and jnp.issubdtype(leaf.dtype, jnp.floating):
            x = x + zeros_of_lanes(jnp.sum(leaf), x.dtype)
    return x


def release_point(model, a0, *more):
    """`x = -a0` at every lane of `model`, the start of its decay (`lanes_of` the model, `a0`
    and `more`, the solver's own parameters)."""
    return lanes_of(-a0 * jnp.ones_like(model.velocity_scale(1.0)), (model, a0, *more))


def early_exit_loop(
    cond, body, init, max_steps: int, buffers=None, kind: str = "bounded", base: int | None = None
):
    """`lax.while_loop(cond, body, init)` for at most `max_steps` steps. With
    `kind="bounded"` (equinox's bounded loop: a scan of conditionals, which skip the remaining
    steps once `cond` is False) both `jax.grad` (reverse mode) and `jax.jacfwd` differentiate
    it; `kind="lax"` is a plain `lax.while_loop`, faster, forward-mode only.

    `cond` must bound the steps itself (`k < max_steps`) and return one boolean for the whole
    `vmap`ped batch (`equinox.internal.unvmap_any` of the lanes' own conditions), and `body`
    must leave lanes that are done unchanged itself: the loop then stops as soon as every lane
    is done, and no lane's result depends on the others in its batch. `buffers` as in
    `equinox.internal.while_loop` (arrays written once per index, without copies). `base`:
    the bounded loop's block of steps (default: one level of conditionals up to 64 steps, else
    blocks of 16); reverse mode runs every step of a block that is entered, skipped or not."""
    if kind == "lax":  # (`cond` bounds the steps itself; buffers are updated in place)
        return lax.while_loop(cond, body, init)
    if base is None:
        base = max_steps if max_steps <= 64 else 16
    return eqxi.while_loop(
        cond, body, init, max_steps=max_steps, buffers=buffers, kind="bounded", base=max(base, 2)
    )


def decay_scan(model, a0, n: int, swing, kind: str = "bounded") -> DecaySequence:
    """The first `n` turning points of `model` released from rest at `x = -a0`: at each turning
    point the model's stick rule (`model.rest`) decides whether and when the mass moves on, and
    `swing(t, x, s, moving) -> (found, failure, t1, x1)` takes it to the next one (`failure`:
    the status to report when `found` is False; the results of lanes with `moving` False,
    stuck or already done, are discarded, so a solver may skip their work). A mass that stops,
    or a solve that fails, stays put for the remaining entries (fixed shapes for `jit`, `vmap`
    and `grad`); the swings end as soon as every lane of a `vmap`ped batch has stopped or
    failed (`kind`: of `early_exit_loop`)."""

    def cond(carry):
        k, _, _, code, _, _ = carry
        return (k < n) & eqxi.unvmap_any(code == RESULTS.successful)

    def body(carry):
        k, t, x, code, count, (times, positions, crossed) = carry
        active = code == RESULTS.successful
        s, t_go, stuck = model.rest(t, x)
        found, failure, t1, x1 = swing(t_go, x, s, active & jnp.logical_not(stuck))
        new_code = jnp.where(stuck, RESULTS.stopped, jnp.where(found, RESULTS.successful, failure))
        code = jnp.where(active, new_code, code)
        advance = active & (code == RESULTS.successful)
        cross = advance & (x1 * x < 0)
        t = jnp.where(advance, t1, t)
        x = jnp.where(advance, x1, x)
        out = (times.at[k].set(t), positions.at[k].set(x), crossed.at[k].set(cross))
        return k + 1, t, x, code, count + advance.astype(jnp.int32), out

    x0 = release_point(model, a0)
    t0 = zeros_of_lanes(x0)
    zero = zeros_of_lanes(x0, jnp.int32)
    buffers = tuple(
        jnp.broadcast_to(b, (n,) + x0.shape) for b in (t0, t0, zeros_of_lanes(x0, bool))
    )
    init = (jnp.array(0), t0, x0, zero + RESULTS.successful, zero, buffers)
    # (the count is carried: a sum over the swings afterwards costs more than the loop)
    k, t, x, code, count, (times, positions, crossed) = early_exit_loop(
        cond, body, init, n, buffers=lambda carry: carry[5], kind=kind
    )
    # swings not run (every lane had stopped or failed) repeat the last turning point
    run = (jnp.arange(n) < k).reshape((n,) + (1,) * x0.ndim)
    times = jnp.where(run, times, t)
    positions = jnp.where(run, positions, x)
    crossed = crossed & run
    _, _, stuck = model.rest(t, x)
    code = jnp.where((code == RESULTS.successful) & stuck, RESULTS.stopped, code)
    return DecaySequence.from_code(times, positions, crossed, count, code)
