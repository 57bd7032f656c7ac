"""vmj's one root finder (`vmj._numerics._roots`), the loop and its written-out form, and the
numerics its loops run on (`computed_once`, `slope_and_curvature`)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import vmj
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


def test_a_release_point_is_batched_and_differentiated_wherever_the_model_is():
    """`lanes_of`: `x`'s value unchanged (a leaf that is not finite adds +0, not NaN), batched
    under `vmap` wherever a floating leaf of the tree is, its derivative in each leaf zero; the
    exact decay of a model swept in parameters its release point does not depend on is then
    batched in one pass of each loop's body (JAX's batching rule repeats a loop's body until
    its carries' batching stops changing: two, three and six passes before, the decay's,
    the substeps' and Newton's loops)."""
    import pytest

    from vmj._numerics._scan import lanes_of

    x = jnp.array(-0.06)
    leaves = {"mu": jnp.array([1.0, jnp.inf, jnp.nan]), "n": jnp.arange(3)}
    assert float(lanes_of(x, leaves)) == -0.06
    assert jax.vmap(lambda u: lanes_of(x, {"n": u}), out_axes=None)(leaves["n"]).shape == ()
    with pytest.raises(ValueError, match="output was batched"):
        jax.vmap(lambda u: lanes_of(x, {"mu": u}), out_axes=None)(leaves["mu"])
    np.testing.assert_array_equal(jax.grad(lambda u: lanes_of(x, (u,)))(jnp.array(2.0)), 0.0)

    batching = pytest.importorskip("jax._src.interpreters.batching")
    passes = {}
    original = batching.batch_jaxpr

    def counted(closed, axis_data, in_batched, *args, **kwargs):
        passes.setdefault(id(closed), set()).add(tuple(in_batched))
        return original(closed, axis_data, in_batched, *args, **kwargs)

    def amplitudes(mu, delta):
        m = vmj.VariableMass(5.0, 4900.0, delta, 0.0, mu, vmj.Coulomb(14.7))
        return vmj.turning_points(m, 0.06, 4).amplitudes

    batching.batch_jaxpr = counted
    try:
        jax.jit(jax.vmap(amplitudes)).lower(jnp.linspace(0.0, 3.0, 4), jnp.linspace(-3, 3, 4))
    finally:
        batching.batch_jaxpr = original
    assert passes and max(len(p) for p in passes.values()) == 1


@pytest.mark.production_compile
def test_values_computed_once_keep_their_values_and_derivatives_and_their_chain_runs_once():
    """`computed_once`: the same values to the last bit, under `vmap` in a loop, with their
    derivatives (forward and reverse); on a CPU, a chain that three values read is computed
    once (XLA's CPU kernels would otherwise each compute it)."""
    from vmj._numerics._scan import computed_once

    def outputs(x):  # a long chain read by three values
        y = x
        for j in range(40):
            y = y * (1.0 + 1e-3 * j) + 0.5 * x
        return y, y * x, jnp.abs(y) + x

    def loop(x, once):
        def body(carry):
            i, a, b, c = carry
            values = outputs(a + b + c)
            if once:
                values = computed_once(values, i)
            return (i + 1, *(0.3 * v for v in values))

        return jax.lax.while_loop(lambda c: c[0] < 3, body, (0, x, x, x))[1:]

    x = jnp.linspace(0.1, 0.9, 4096)
    plain, once = (jax.jit(jax.vmap(lambda u, o=o: loop(u, o))) for o in (False, True))
    for a, b in zip(plain(x), once(x)):
        np.testing.assert_array_equal(a, b)

    # derivatives pass through (a while loop has forward mode only: here outside one)
    def total(u, once):
        return sum(computed_once(outputs(u), 0) if once else outputs(u))

    for v in (0.2, 0.7):
        assert jax.grad(total)(v, True) == jax.grad(total)(v, False)
        assert jax.jvp(lambda u: total(u, True), (v,), (1.0,)) == jax.jvp(
            lambda u: total(u, False), (v,), (1.0,)
        )
    if jax.default_backend() == "cpu":
        # (three values: two kernels, a pair and the third, instead of three: 40 multiplications
        # each, besides the loop's four)
        count = [f.lower(x).compile().as_text().count(" multiply(") for f in (plain, once)]
        assert count[0] >= 120 and count[1] <= 90, count


def test_slope_and_curvature_of_a_polynomial():
    """`slope_and_curvature` (the Newton iterations' velocity from the position's Taylor
    coefficients) against NumPy's derivatives of the same polynomial, to rounding."""
    from vmj._numerics._series import horner_and_derivative, slope_and_curvature

    rng = np.random.default_rng(3)
    cs = list(rng.normal(size=27) / np.arange(1, 28) ** 2)
    p = np.polynomial.Polynomial(cs)
    for tau in (0.0, 0.3, -0.8, 1.7):
        slope, curvature = slope_and_curvature([jnp.asarray(c) for c in cs], tau)
        np.testing.assert_allclose(slope, p.deriv(1)(tau), rtol=1e-13, atol=1e-15)
        np.testing.assert_allclose(curvature, p.deriv(2)(tau), rtol=1e-13, atol=1e-15)
        # the same pair as the derivative's coefficients evaluated by horner_and_derivative
        dcs = [jnp.asarray(c) for c in p.deriv(1).coef]
        np.testing.assert_allclose((slope, curvature), horner_and_derivative(dcs, tau), rtol=1e-13)
