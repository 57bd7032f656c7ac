"""vmj's one root finder (`vmj._numerics._roots`): the loop and its written-out form."""

import jax
import jax.numpy as jnp
import numpy as np

from vmj._numerics._roots import bracketed_newton, implicit_step


def _f(p):
    """A cubic falling through zero in [0, 1] at a root that moves with `p`, and its slope."""
    return lambda u: (p - u - u**3, -1.0 - 3 * u**2)


def test_written_out_steps_find_the_loops_root_and_its_derivative():
    p = jnp.linspace(0.1, 1.9, 7)  # roots from 0.1 to 0.93
    zero = jnp.zeros_like(p)
    secant = p / 2.0  # f(0) = p, f(1) = p - 2: the secant's root
    # each finished by one more Newton step (as every caller does)
    loop = implicit_step(_f(p), bracketed_newton(_f(p), zero, zero + 1, secant, 60))
    written = bracketed_newton(_f(p), zero, zero + 1, secant, 4, unrolled=True)
    written = implicit_step(_f(p), written)
    np.testing.assert_allclose(written, loop, rtol=0, atol=1e-15)
    np.testing.assert_allclose(loop + loop**3, p, rtol=1e-15)

    def root(p):
        u = bracketed_newton(
            _f(jax.lax.stop_gradient(p)), 0.0, 1.0, jax.lax.stop_gradient(p) / 2, 4, unrolled=True
        )
        return implicit_step(_f(p), u)

    u = root(0.7)
    np.testing.assert_allclose(jax.grad(root)(0.7), 1 / (1 + 3 * u**2), rtol=1e-12)
    # from 0 the first Newton step goes to p, out of the bracket where p > 1: bisection there
    far = bracketed_newton(_f(p), zero, zero + 1, zero, 60, unrolled=True)
    np.testing.assert_allclose(implicit_step(_f(p), far), loop, rtol=0, atol=1e-15)


def test_loop_carries_start_batched_wherever_their_lane_is():
    """`zeros_of_lanes`, the loops' initial carries: zeros (+0, never -0) in the dtype asked
    for, batched under `vmap` where the lane is (a `vmap` that asks for an unbatched result
    refuses them, as it takes `jnp.zeros_like`), a floating one with a zero tangent."""
    import pytest

    from vmj._numerics._scan import zeros_of_lanes

    x = jnp.array([-1.0, 2.0, jnp.nan, -jnp.inf])
    for dtype in (None, bool, jnp.int32):
        z = zeros_of_lanes(x, dtype)
        assert z.dtype == (x.dtype if dtype is None else dtype) and not np.any(z)
        assert jax.vmap(lambda u: jnp.zeros_like(u, dtype), out_axes=None)(x).shape == ()
        with pytest.raises(ValueError, match="output was batched"):
            jax.vmap(lambda u: zeros_of_lanes(u, dtype), out_axes=None)(x)  # noqa: B023
    assert not np.any(np.signbit(zeros_of_lanes(x)))
    value, tangent = jax.jvp(zeros_of_lanes, (x,), (jnp.ones(4),))
    assert not np.any(value) and not np.any(tangent)
