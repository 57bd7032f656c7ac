"""Variable-mass oscillator: exact solver vs SciPy, closed-form limits, smoothed model, gradients,
invariants and failure reporting. Tolerances are the acceptance criteria of the foundation issue."""

import math
import sys

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import example, given, strategies as st
from scipy_reference import variable_mass_turning_points

import vmj

M0, C, A0, FT = 5.0, 4900.0, 0.06, 14.7
#: XLA's CPU code reads and makes numbers below the smallest normal float as zero; a GPU's
#: float64 arithmetic keeps them
FLUSHES_SUBNORMALS = jax.default_backend() == "cpu"


def model(delta=3.0, eps=0.0, mu=2.0, F=FT, f=None):
    law = vmj.Coulomb(F) if f is None else vmj.MassProportional(f)
    return vmj.VariableMass(M0, C, delta, eps, mu, law)


# -- one compiled batch solver reused by the SciPy and property tests ---------------------------
N_SWINGS = 12


@eqx.filter_jit
def batch_exact(m0, c, delta, eps, mu, F, f, use_f):
    def one(m0, c, delta, eps, mu, F, f, use_f):
        # the friction law is selected per point: F(t) = F + use_f * f g m(t)
        law_c = vmj.Coulomb(F)
        law_f = vmj.MassProportional(f)
        a = vmj.turning_points(vmj.VariableMass(m0, c, delta, eps, mu, law_c), A0, N_SWINGS)
        b = vmj.turning_points(vmj.VariableMass(m0, c, delta, eps, mu, law_f), A0, N_SWINGS)
        return jax.tree.map(lambda x, y: jnp.where(use_f, y, x), a, b)

    return jax.vmap(one)(m0, c, delta, eps, mu, F, f, use_f)


def random_parameters(rng, size):
    return dict(
        m0=rng.uniform(1.0, 10.0, size),
        c=rng.uniform(1e3, 1e4, size),
        delta=rng.uniform(-3.0, 3.0, size),
        eps=rng.uniform(0.0, 1.0, size),
        mu=rng.uniform(0.0, 10.0, size),
        F=rng.uniform(0.0, 20.0, size),
        f=rng.uniform(0.0, 0.3, size),
        use_f=rng.random(size) < 0.5,
    )


def test_exact_matches_scipy_event_integration():
    """Exact amplitudes vs SciPy DOP853 (rtol 1e-12, velocity-zero events): 1e-7 relative for
    amplitudes above 1 % of a0, both friction laws, growing and shrinking mass."""
    p = random_parameters(np.random.default_rng(20261121), 16)
    seq = batch_exact(**{k: jnp.asarray(v) for k, v in p.items()})
    worst, worst_t, compared = 0.0, 0.0, 0
    for i in range(16):
        law = {"f": p["f"][i]} if p["use_f"][i] else {"F": p["F"][i]}
        t_ref, x_ref, c_ref = variable_mass_turning_points(
            p["m0"][i], p["c"][i], p["delta"][i], p["eps"][i], p["mu"][i], A0, N_SWINGS, **law
        )
        k = len(t_ref)
        assert int(seq.count[i]) == k
        x = np.asarray(seq.positions[i, :k])
        big = np.abs(x_ref) > 0.01 * A0
        worst = max(worst, np.max(np.abs(x - x_ref)[big] / np.abs(x_ref[big]), initial=0.0))
        worst_t = max(
            worst_t, np.max(np.abs(np.asarray(seq.times[i, :k]) - t_ref) / t_ref, initial=0.0)
        )
        np.testing.assert_array_equal(np.asarray(seq.crossed[i, :k]), c_ref)
        compared += k
    print(
        f"compared {compared} turning points: worst relative amplitude error {worst:.2e}, "
        f"time error {worst_t:.2e}"
    )
    assert compared > 100
    assert worst < 1e-7
    assert worst_t < 1e-9
    assert np.any(p["delta"] < 0) and np.any(p["delta"] > 0) and np.any(p["use_f"])


def test_exact_finds_every_velocity_zero_far_from_the_papers_parameters():
    """Against SciPy over a wide domain (masses growing by up to 300 kg/s from 0.5-50 kg,
    stiffness 1e2-1e5 N/m, a0 1-200 mm): every turning point, none skipped. A substep of the
    growing mass is longer than the half-swing that follows it; testing the velocity's sign
    only at substep ends skipped pairs of turning points in 23 of 150 such points."""
    rng = np.random.default_rng(20261128)
    size = 24
    p = dict(
        m0=rng.uniform(0.5, 50, size),
        c=10 ** rng.uniform(2, 5, size),
        delta=rng.uniform(-30, 300, size),
        eps=rng.uniform(0, 1, size),
        mu=rng.uniform(0, 30, size),
        F=rng.uniform(0, 30, size),
    )
    a0 = 10 ** rng.uniform(-3, -0.7, size)
    # the first found: after 8 turning points the next two were skipped
    p = {k: np.append(v, x) for (k, v), x in zip(p.items(), (5.0, 4900.0, 300.0, 0.0, 2.0, FT))}
    a0 = np.append(a0, A0)
    models = vmj.VariableMass(p["m0"], p["c"], p["delta"], p["eps"], p["mu"], vmj.Coulomb(p["F"]))
    seq = eqx.filter_jit(
        eqx.filter_vmap(lambda m, a: vmj.turning_points(m, a, N_SWINGS, vmj.Exact(max_substeps=48)))
    )(models, jnp.asarray(a0))
    compared = 0
    for i in range(size + 1):
        t_ref, x_ref, _ = variable_mass_turning_points(
            *(p[k][i] for k in ("m0", "c", "delta", "eps", "mu")), a0[i], N_SWINGS, F=p["F"][i]
        )
        k = len(t_ref)
        assert int(seq.count[i]) == k, i
        np.testing.assert_allclose(seq.times[i, :k], t_ref, rtol=1e-9, err_msg=str(i))
        np.testing.assert_allclose(seq.positions[i, :k], x_ref, rtol=0, atol=1e-7 * a0[i])
        compared += k
    assert compared > 80


@pytest.mark.parametrize("delta,eps,mu", [(3.0, 0.0, 2.0), (-3.0, 1.0, 10.0), (0.0, 0.5, 0.0)])
def test_exact_half_swing_is_one_substep(delta, eps, mu):
    """A substep is `3.5/omega` long, longer than a half-swing's `pi/omega`: with one substep
    per half-swing the turning points are those of the default limit (8), to rounding. (At
    `2/omega`, two substeps per half-swing, one substep found no velocity zero.)"""
    m = model(delta=delta, eps=eps, mu=mu)
    one, default = (vmj.turning_points(m, A0, 12, vmj.Exact(max_substeps=k)) for k in (1, 8))
    assert int(one.result) == int(default.result) and bool(vmj.RESULTS.okay(one.result))
    assert int(one.count) == int(default.count) >= 6
    np.testing.assert_allclose(one.positions, default.positions, rtol=0, atol=1e-15 * A0)


def test_constant_mass_coulomb_decrement_is_exactly_2F_over_c():
    m = model(delta=0.0, mu=0.0)
    for solver in (vmj.Exact(), vmj.EnergyBalance()):
        seq = vmj.turning_points(m, A0, 12, solver)
        a = np.concatenate([[A0], np.asarray(seq.amplitudes)[: int(seq.count)]])
        crossed = np.asarray(seq.crossed)[: int(seq.count)]
        np.testing.assert_allclose(-np.diff(a)[crossed], 2 * FT / C, rtol=1e-9, atol=0)
    seq = vmj.turning_points(m, A0, 12)
    # constant mass: every half-swing lasts exactly pi sqrt(m/c)
    np.testing.assert_allclose(
        np.diff(np.concatenate([[0], np.asarray(seq.times)[:9]])),
        np.pi * np.sqrt(M0 / C),
        rtol=1e-12,
    )


@pytest.mark.parametrize("eps,delta", [(0.0, 3.0), (0.75, -4.0), (1.0, -3.0)])
def test_arithmetic_decay_on_the_papers_boundary(eps, delta):
    """delta = 2 mu / (1 - 2 eps) (lambda = 0): the paper's remark that the decay is arithmetic.
    The energy balance gives exactly 2F/c per swing; the exact solution too, to 1e-6."""
    mu = delta * (1 - 2 * eps) / 2
    if mu < 0:
        pytest.skip("mu would be negative")
    m = model(delta=delta, eps=eps, mu=mu)
    for solver, rtol in ((vmj.EnergyBalance(), 1e-12), (vmj.Exact(), 1e-6)):
        seq = vmj.turning_points(m, A0, 12, solver)  # (the first 8 of 12: a shared program)
        a = np.concatenate([[A0], np.asarray(seq.amplitudes)[:8]])
        np.testing.assert_allclose(-np.diff(a), 2 * FT / C, rtol=rtol)


def test_smoothed_turning_points_converge_to_exact():
    """At the default smoothing the first five amplitudes agree with the exact ones to 1e-3
    relative, and the error shrinks as w shrinks."""
    w0 = 1e-4 * A0 * np.sqrt(C / M0)  # the default smoothing velocity of these models
    for m in (model(delta=-3.0, eps=1.0, mu=9.0), model(delta=-3.0, f=0.3, mu=5.0)):
        exact = np.asarray(vmj.turning_points(m, A0, 6).amplitudes)[:5]

        def error(w):
            smooth = vmj.turning_points(m, A0, 6, vmj.Smoothed(smoothing=w))
            return np.max(np.abs(np.asarray(smooth.amplitudes)[:5] / exact - 1))

        default = error(None)
        errors = [error(k * w0) for k in (1000, 100, 10)]
        print(f"smoothing error at the default w: {default:.1e}; at 1000, 100, 10 w0: {errors}")
        assert default < 1e-3
        assert errors[0] > errors[1] > errors[2]


@pytest.mark.parametrize("n", [12, 16])
def test_smoothed_model_arrest_is_reported_as_stop(n):
    m = model()  # sticks at the 10th turning point (table 1, mu = 2, eps = 0)
    exact = vmj.turning_points(m, A0, n)
    smooth = vmj.turning_points(m, A0, n, vmj.Smoothed())
    assert int(exact.count) == int(smooth.count) == 10
    assert bool(exact.stopped) and bool(smooth.stopped)
    assert not bool(smooth.crossed[9]) and not bool(exact.crossed[9])
    np.testing.assert_allclose(smooth.amplitudes[9], exact.amplitudes[9], rtol=1e-2)


def test_smoothed_creep_after_a_turning_point_is_an_arrest():
    """At the 7th exact turning point of delta = -3 kg/s, mu = 10 kg/s the spring force only
    just exceeds the friction (`c |x| = 14.91 N` against 14.7 N): the exact mass makes a last
    tiny swing, the smoothed one creeps off below `20 w` and, once the stick rule holds where it
    creeps, has stopped there (before: it crept on, stiffly, to the horizon, 2439 steps against
    809). Within 100 steps per half-swing (1200 in all) it is reported stopped, with the six
    turning points before it."""
    m = model(delta=-3.0, mu=10.0)
    exact = vmj.turning_points(m, A0, 12)
    smooth = vmj.turning_points(m, A0, 12, vmj.Smoothed(max_steps=100))
    assert int(exact.count) == 7 and int(smooth.count) == 6
    assert int(smooth.result) == vmj.RESULTS.stopped
    np.testing.assert_allclose(smooth.positions[:6], exact.positions[:6], rtol=0, atol=1e-6 * A0)


def test_smoothed_steps_towards_a_reversal_are_limited():
    """Towards each reversal the smoothed solve's steps are limited to reach the `tanh` layer's
    edge in one step and to cross the layer in steps of 0.4 of the time to the velocity's zero
    (the step-size controller alone grew steps of small error tenfold into the layer, and most
    were rejected). delta = eps = mu = 0: 241 steps (15 rejected) for its 10 turning points,
    436 (169 rejected) without the limit; within 26 steps per half-swing (312 in all) it
    completes, with the exact turning points before the rest to 1e-6 a0 (at the rest the
    smoothed mass creeps on to `20 w`)."""
    m = model(delta=0.0, mu=0.0)
    exact = vmj.turning_points(m, A0, 12)
    smooth = vmj.turning_points(m, A0, 12, vmj.Smoothed(max_steps=26))
    assert int(exact.count) == int(smooth.count) == 10
    assert int(smooth.result) == vmj.RESULTS.stopped
    np.testing.assert_allclose(smooth.positions[:9], exact.positions[:9], rtol=0, atol=1e-6 * A0)


def test_smoothed_lanes_do_not_depend_on_their_batch():
    """The smoothed turning points are found in one solve, each lane of a `vmap`ped batch moving
    on to its next swing by itself (a lane that has stopped stays put while the others step):
    a batch gives each lane's turning points as that lane alone does (measured: to 2e-12
    relative on a CPU, the rounding of vectorised against scalar code carried through the
    adaptive steps; on an H200, positions at rest, 2e-4 a0 from zero, to 4e-12 a0, and the time
    of the rest, where the model creeps to a stop and the velocity's zero is flat, to 6e-9
    relative). Asserted: positions to 1e-9 relative or 1e-10 a0, the solve's relative and
    absolute tolerances; times before the rest to 1e-9, the time of the rest to 1e-7."""
    deltas, mus = jnp.array([-3.0, 0.0, 3.0, 1.0]), jnp.array([10.0, 2.0, 0.0, 6.0])

    def one(delta, mu):
        return vmj.turning_points(model(delta=delta, mu=mu), A0, 12, vmj.Smoothed())

    batch = jax.jit(jax.vmap(one))(deltas, mus)
    counts = set()
    for i in range(4):
        alone = one(deltas[i], mus[i])
        counts.add(int(alone.count))
        assert int(batch.count[i]) == int(alone.count) and int(batch.result[i]) == int(alone.result)
        np.testing.assert_allclose(batch.positions[i], alone.positions, rtol=1e-9, atol=1e-10 * A0)
        moving = np.arange(12) < int(alone.count) - 1  # the turning points before the rest
        np.testing.assert_allclose(batch.times[i][moving], alone.times[moving], rtol=1e-9)
        np.testing.assert_allclose(batch.times[i], alone.times, rtol=1e-7)
    assert len(counts) > 1  # lanes that stop after different numbers of swings


def value_and_jacrev(f):
    """`f`'s value and its reverse-mode Jacobian (`jax.jacrev`'s: the pullback of each unit
    vector) from one compiled program: central differences take their values from the program
    that gave the Jacobian, one compilation where a second, of `f` alone, took seconds more."""

    @jax.jit
    def both(theta):
        y, pullback = jax.vjp(f, theta)
        (jac,) = jax.vmap(pullback)(jnp.eye(y.size, dtype=y.dtype))
        return y, jac

    return both


@pytest.mark.slow  # 9 s of compiling the reverse pass
def test_smoothed_gradients_match_central_differences():
    """d x_k / d(F, mu, eps, delta) and d t_k / d(...) of the smoothed turning points (reverse
    mode through the solve and the root on its dense output) against central differences
    (h = 1e-4 relative; at 1e-5 the differences of the times are noise): measured 1e-8 of each
    column's scale for the positions, 7e-6 for the times (central differences with h = 1e-3 and
    3e-4 agree with each other to 2e-6). Asserted 1e-6 and 3e-5."""

    def positions(theta):
        F, mu, eps, delta = theta
        m = vmj.VariableMass(M0, C, delta, eps, mu, vmj.Coulomb(F))
        seq = vmj.turning_points(m, A0, 4, vmj.Smoothed(smoothing=1e-3))
        return jnp.concatenate([seq.positions, seq.times])

    theta = jnp.array((14.7, 9.0, 0.7, -3.0))
    both = value_and_jacrev(positions)
    rev = both(theta)[1]
    h = 1e-4 * jnp.maximum(1.0, jnp.abs(theta))
    values = jnp.stack([both(p)[0] for p in theta + jnp.concatenate([jnp.diag(h), -jnp.diag(h)])])
    fd = ((values[:4] - values[4:]) / (2 * h[:, None])).T
    error = jnp.abs(rev - fd) / jnp.max(jnp.abs(fd), axis=0)
    print(f"positions: {float(error[:4].max()):.1e}, times: {float(error[4:].max()):.1e}")
    assert float(error[:4].max()) < 1e-6 and float(error[4:].max()) < 3e-5


def test_simulate_follows_the_exact_turning_points():
    m = model()
    exact = vmj.turning_points(m, A0, 6)
    t1 = float(exact.times[2])
    traj = vmj.simulate(m, -A0, 0.0, t1, n_save=4001)
    assert traj.ts.shape == (4001,) and int(traj.result) == 0
    assert np.all(np.isfinite(np.asarray(traj.xs)))
    np.testing.assert_allclose(traj.xs[-1], exact.positions[2], rtol=1e-6)
    # the sampled extremes bracket the first turning point closely
    assert abs(np.max(np.asarray(traj.xs)) - float(exact.positions[0])) < 1e-5


def _sequence(theta, law="F", solver=None, n=8):
    F, mu, eps, delta = theta
    friction = vmj.Coulomb(F) if law == "F" else vmj.MassProportional(F)
    return vmj.turning_points(vmj.VariableMass(M0, C, delta, eps, mu, friction), A0, n, solver)


def _positions(theta, law):
    seq = _sequence(theta, law)
    return jnp.concatenate([seq.positions, seq.times])


@pytest.mark.parametrize(
    "law,theta",
    [
        ("F", (14.7, 9.0, 0.7, -3.0)),
        # the same machinery with the mass-proportional law: 20 s of compiling, with the long runs
        pytest.param("f", (0.3, 5.0, 0.6, 3.0), marks=pytest.mark.long),
    ],
)
def test_gradients_match_central_differences(law, theta):
    """d x_k / d(F or f, mu, eps, delta) and d t_k / d(...) from the exact solver (reverse mode)
    against central finite differences (h = 1e-5 relative): agreement to 1e-7 of each column's
    scale."""
    theta = jnp.array(theta)
    both = value_and_jacrev(lambda th: _positions(th, law))
    rev = both(theta)[1]
    h = 1e-5 * jnp.maximum(1.0, jnp.abs(theta))
    steps = jnp.concatenate([jnp.diag(h), -jnp.diag(h)])
    values = jnp.stack([both(p)[0] for p in theta + steps])
    fd = ((values[:4] - values[4:]) / (2 * h[:, None])).T
    scale = jnp.max(jnp.abs(fd), axis=0)
    print(
        f"max |reverse - central difference| / scale: {float(jnp.max(jnp.abs(rev - fd) / scale)):.1e}"
    )
    np.testing.assert_allclose(rev / scale, fd / scale, atol=1e-7)


@pytest.mark.long  # 10 s more of compiling, with the long runs for CI's time
def test_forward_mode_gives_the_reverse_mode_jacobian():
    theta = jnp.array((14.7, 9.0, 0.7, -3.0))
    rev = jax.jit(jax.jacrev(_positions), static_argnums=1)(theta, "F")
    fwd = jax.jit(jax.jacfwd(_positions), static_argnums=1)(theta, "F")
    np.testing.assert_allclose(fwd, rev, rtol=1e-9, atol=1e-12)


def test_one_lane_solve_matches_the_batched_program():
    """A concrete call compiles the exact solver for one lane (`Exact.one_lane`: Newton's
    iterations recompute the straight-line Taylor recurrence, XLA's loop-invariant code motion
    off); it gives the turning points of the program that a trace or a batch gets (the
    coefficients carried) to rounding, with the same status, and, with `one_lane` set
    explicitly, the same forward-mode derivatives."""

    def sequence(theta, solver=None):
        seq = _sequence(theta, solver=solver, n=12)
        return jnp.concatenate([seq.positions, seq.times]), seq.count, seq.result

    one = vmj.Exact(one_lane=True)
    for theta in [(14.7, 3.0, 0.5, -2.0), (14.7, 9.0, 0.7, -3.0), (14.7, 0.0, 0.0, 2.5)]:
        theta = jnp.array(theta)
        concrete, traced = sequence(theta), jax.jit(sequence)(theta)
        np.testing.assert_allclose(concrete[0], traced[0], rtol=1e-13, atol=1e-17)
        assert int(concrete[1]) == int(traced[1]) and int(concrete[2]) == int(traced[2])
        np.testing.assert_allclose(
            jax.jit(sequence, static_argnums=1)(theta, one)[0], traced[0], rtol=1e-13, atol=1e-17
        )
    jac_one = jax.jacfwd(lambda q: sequence(q, one)[0])(theta)
    jac = jax.jacfwd(lambda q: sequence(q)[0])(theta)
    np.testing.assert_allclose(jac_one, jac, rtol=1e-11, atol=1e-14)


def test_a_creeping_mass_until_it_vanishes_has_no_nan_turning_point():
    """Mass-proportional friction holds the mass until it has fallen to c a0/(f g) (t = 5/9 s);
    the mass then creeps after the falling equilibrium -f g m(t)/c, its velocity only touching
    zero, until the mass is gone (t = 5/3 s). With many substeps the march reached the zero-mass
    singularity, where Newton broke down: a turning point with NaN time and position was
    counted."""
    m = vmj.VariableMass(5.0, 4900.0, -3.0, 0.0, 2.0, vmj.MassProportional(0.3, 9.81))
    seq = vmj.turning_points(m, 0.002, 5, vmj.Exact(max_substeps=200))
    assert int(seq.count) == 0 and int(seq.result) == vmj.RESULTS.mass_exhausted
    assert np.all(np.isfinite(np.asarray(seq.times)))


def test_a_frictionless_mass_that_creeps_has_not_stopped():
    """Without dry friction the mass never sticks. Over-damped (mu = 1000 kg/s, three times
    the critical damping) it creeps towards x = 0: the smoothed solve said "came to rest for
    good: |spring force| <= static friction" where the spring force was 3.6 N and the friction
    0. The exact solver and the energy balance report the step limit (no velocity zero)."""
    m = vmj.VariableMass(5.0, 4900.0, 3.0, 0.0, 1000.0, vmj.Coulomb(0.0))
    for solver in (vmj.Exact(), vmj.Smoothed()):
        seq = vmj.turning_points(m, A0, 6, solver)
        assert not bool(seq.stopped) and int(seq.result) == vmj.RESULTS.step_limit, solver


def test_mass_exhaustion_is_reported_not_nan():
    m = vmj.VariableMass(1.0, C, -3.0, 0.0, 0.0, vmj.Coulomb(1.0))  # mass gone at t = 1/3 s
    for solver in (vmj.Exact(), vmj.Smoothed(), vmj.EnergyBalance()):
        seq = vmj.turning_points(m, A0, 40, solver)
        assert int(seq.result) == vmj.RESULTS.mass_exhausted, solver
        assert "reaches zero" in seq.message
        assert 0 < int(seq.count) < 40
        assert np.all(np.isfinite(np.asarray(seq.positions)))
        assert float(np.max(seq.times)) < 1.0 / 3.0
        with pytest.raises(Exception, match="reaches zero"):
            vmj.turning_points(m, A0, 40, solver, throw=True)


def test_a_turning_point_just_before_the_mass_runs_out():
    """delta = -100 kg/s from 5 kg: the mass is gone at t = 0.05 s and the first turning point
    is at 0.04989 s (0.011 kg left), which the default 8 substeps (each at most a quarter of
    the time left) cannot reach and 50 can. The message said only that the mass reaches zero
    before the next turning point; it now names the substeps as well."""
    m = vmj.VariableMass(5.0, C, -100.0, 0.3, 2.0, vmj.Coulomb(14.7))
    seq = vmj.turning_points(m, 0.06, 2)
    assert int(seq.result) == vmj.RESULTS.mass_exhausted and int(seq.count) == 0
    assert "max_substeps" in seq.message
    more = vmj.turning_points(m, 0.06, 2, vmj.Exact(max_substeps=50))
    assert int(more.count) == 1 and 0.0498 < float(more.times[0]) < 0.05
    assert int(more.result) == vmj.RESULTS.mass_exhausted


def test_the_message_of_a_batch_says_how_to_read_it():
    """`.message` of a vmapped result was `TypeError: only 0-dimensional arrays can be
    converted to Python scalars`."""
    seqs = jax.vmap(lambda mu: vmj.turning_points(model(mu=mu), A0, 3, vmj.EnergyBalance()))(
        np.array([2.0, 9.0])
    )
    with pytest.raises(ValueError, match=r"a message is of one solve; this result holds 2"):
        _ = seqs.message


@pytest.mark.parametrize("delta", [1e3, 1e6])
def test_runaway_growing_mass_has_no_turning_point(delta):
    # m x'' - (delta (1 - 2 eps) - 2 mu)/2 x' + c x = ...: with delta = 1e3 kg/s and m0 = 5 kg
    # the motion runs away without oscillating (real characteristic roots): no turning point,
    # reported as such by both solvers; never "mass reaches zero" (the mass grows), never the
    # averaged map's growing swings or its NaN
    m = vmj.VariableMass(5.0, 4900.0, delta, 0.0, 2.0, vmj.Coulomb(14.7))
    for solver in (vmj.Exact(), vmj.EnergyBalance()):
        seq = vmj.turning_points(m, 0.06, 12, solver)
        assert int(seq.result) == vmj.RESULTS.step_limit, solver
        assert int(seq.count) == 0
        assert np.all(np.asarray(seq.positions) == -0.06)


def test_release_when_friction_falls_with_the_mass():
    """f-law with shrinking mass: a stuck mass moves on once f g m(t) < c |x|, as in SciPy."""
    p = dict(m0=5.0, c=C, delta=-3.0, eps=0.0, mu=60.0, f=0.3)
    seq = vmj.turning_points(
        vmj.VariableMass(5.0, C, -3.0, 0.0, 60.0, vmj.MassProportional(0.3)), A0, 12
    )
    t_ref, x_ref, _ = variable_mass_turning_points(a0=A0, n=12, **p)
    k = len(t_ref)
    assert int(seq.count) == k
    np.testing.assert_allclose(np.asarray(seq.positions)[:k], x_ref, rtol=1e-7)
    np.testing.assert_allclose(np.asarray(seq.times)[:k], t_ref, rtol=1e-9)


# -- invariants (hypothesis) --------------------------------------------------------------------
@given(
    m0=st.floats(0.5, 20),
    c=st.floats(100, 2e4),
    delta=st.floats(-3, 3),
    eps=st.floats(0, 1),
    mu=st.floats(0, 20),
    F=st.floats(0, 30),
    f=st.floats(0, 0.5),
    use_f=st.booleans(),
)
def test_decay_sequence_invariants(m0, c, delta, eps, mu, F, f, use_f):
    # (NumPy arrays: the dtypes of test_exact_matches_scipy_event_integration's call, so that
    # both run one compiled program; `jnp.full` of a Python number is weakly typed, another one)
    args = [jnp.asarray(np.full(16, v)) for v in (m0, c, delta, eps, mu, F, f, use_f)]
    seq = jax.tree.map(lambda x: x[0], batch_exact(*args))
    n = int(seq.count)
    t = np.asarray(seq.times)
    x = np.asarray(seq.positions)
    assert np.all(np.isfinite(t)) and np.all(np.isfinite(x))
    assert 0 <= n <= N_SWINGS
    dt = np.diff(np.concatenate([[0.0], t[:n]]))
    assert np.all(dt >= 0)  # time moves on (strictly, unless a release is astronomically late)
    assert np.all(dt[t[:n] < 1e6] > 0)
    previous = np.concatenate([[-A0], x[: n - 1]]) if n else np.array([])
    np.testing.assert_array_equal(np.asarray(seq.crossed)[:n], x[:n] * previous < 0)
    if n < N_SWINGS:  # padding repeats the last turning point
        assert np.all(x[n:] == (x[n - 1] if n else -A0))
    Ft = f * 9.81 * (m0 + delta * t) if use_f else F + 0 * t
    if bool(seq.stopped) and n:
        assert c * abs(x[n - 1]) <= Ft[n - 1] * (1 + 1e-12)
    if n and not (use_f and delta < 0):
        # a mass moves on from every turning point but the last
        assert np.all(c * np.abs(x[: n - 1]) > Ft[: n - 1])
    if delta == 0 or (1 - 2 * eps) * delta <= 2 * mu:
        # energy decays: amplitudes never grow when the motion decays without dry friction
        a = np.concatenate([[A0], np.abs(x[:n])])
        assert np.all(np.diff(a) <= 1e-12 * A0)


def energy_balance_reference(m0, c, delta, eps, mu, F, f, use_f, a0, n):
    """The recurrences of `vmj.EnergyBalance`'s docstring, swing by swing in plain Python
    (math.expm1), with the stick, release, over-damping and exhaustion rules written out."""
    g = 9.81
    force = (lambda m: f * g * m) if use_f else (lambda m: F)

    # friction falls with the mass where dF/dm delta < 0, in XLA's arithmetic (on a CPU,
    # delta = -1.1e-308 kg/s is no change of mass, and no release)
    def flushed(x):
        return 0.0 if FLUSHES_SUBNORMALS and abs(x) < sys.float_info.min else x

    falls = use_f and flushed(flushed(flushed(f) * g) * flushed(delta)) < 0
    lam = delta - 2 * delta * eps - 2 * mu
    t, m, a, side = 0.0, m0, a0, -1.0
    times, positions, crossed, result = [], [], [], vmj.RESULTS.successful
    for _ in range(n):
        if c * a <= force(m):
            if falls:  # friction falls with the mass: wait, move on
                m_go = c * a / (f * g)
                if not math.isfinite(t + (m_go - m) / delta):  # a denormal delta: never moves
                    result = vmj.RESULTS.stopped
                    break
                t, m = t + (m_go - m) / delta, m_go
            else:
                result = vmj.RESULTS.stopped
                break
        if lam * lam >= 16 * m * c:  # over-damped (or running away): no turning point
            result = vmj.RESULTS.step_limit
            break
        half = math.pi * math.sqrt(m / c)
        if m + delta * half <= 0:
            result = vmj.RESULTS.mass_exhausted
            break
        x = math.pi * lam / (4 * math.sqrt(c * m))
        phi = math.expm1(x) / x if x else 1.0
        a_next = a * math.exp(x) - 2 * force(m + 0.5 * delta * half) / c * phi
        t, m = t + half, m + delta * half
        side = -side if a_next > 0 else side
        a = abs(a_next)
        times.append(t)
        positions.append(side * a)
        crossed.append(a_next > 0)
    else:
        if c * a <= force(m) and not falls:
            result = vmj.RESULTS.stopped
    return np.array(times), np.array(positions), np.array(crossed, bool), result


@given(
    m0=st.floats(0.05, 10),
    delta=st.floats(-30, 30),
    eps=st.floats(0, 1),
    mu=st.floats(0, 10),
    F=st.floats(0, 30),
    f=st.floats(0, 0.5),
    use_f=st.booleans(),
    a0=st.floats(1e-3, 0.1),
)
@example(  # (found by CI: a subnormal rate of mass change, no release)
    m0=1.0, delta=-1.1125369292536007e-308, eps=0.0, mu=0.0, F=0.0, f=0.5, use_f=True, a0=0.03125
)
def test_energy_balance_matches_a_plain_swing_by_swing_reference(
    m0, delta, eps, mu, F, f, use_f, a0
):
    """vmj's vectorised energy balance (absorbing state, flags and status read off the states)
    against the recurrences written out: the same count, crossings and status, positions to
    1e-12 of a0 and times to 1e-12 relative."""
    friction = vmj.MassProportional(f) if use_f else vmj.Coulomb(F)
    seq = vmj.turning_points(
        vmj.VariableMass(m0, C, delta, eps, mu, friction), a0, 20, vmj.EnergyBalance()
    )
    t, x, crossed, result = energy_balance_reference(m0, C, delta, eps, mu, F, f, use_f, a0, 20)
    k = len(t)
    assert int(seq.count) == k and int(seq.result) == result
    np.testing.assert_array_equal(np.asarray(seq.crossed)[:k], crossed)
    np.testing.assert_allclose(np.asarray(seq.positions)[:k], x, rtol=0, atol=1e-12 * a0)
    np.testing.assert_allclose(np.asarray(seq.times)[:k], t, rtol=1e-12)


def test_energy_balance_takes_one_path_per_batch_and_both_agree(monkeypatch):
    """A batch whose exponents all stay small takes exp(x) as 1 + x phi(x), phi from its series
    (no exponential, no quotient: `vmj/_closed_forms/_olshansky.py`); any other batch takes the
    exponential for every lane. A lane's turning points do not depend on the path to 1e-15 of
    a0 (a heavily damped lane beside it, or no small batch at all), the times not at all, and
    their derivatives agree to 1e-12 relative."""
    import vmj._closed_forms._olshansky as olshansky

    rng = np.random.default_rng(7)
    light = [rng.uniform(-3, 3, 64), rng.uniform(0, 1, 64), rng.uniform(0, 10, 64)]
    heavy = [np.append(v, x) for v, x in zip(light, (3.0, 0.0, 200.0))]

    def solve(delta, eps, mu):  # traced anew each time: the radius is read while tracing
        full = lambda x: np.full(len(delta), x)  # noqa: E731
        m = vmj.VariableMass(full(M0), full(C), delta, eps, mu, vmj.Coulomb(full(FT)))
        return jax.jit(jax.vmap(lambda p: olshansky.energy_balance_sequence(p, A0, 12)))(m)

    def a5(mu):  # d x_5 / d mu of one solve
        return jax.grad(
            lambda mu: olshansky.energy_balance_sequence(model(mu=mu), A0, 6).positions[5]
        )(mu)

    fast, beside, grad = solve(*light), solve(*heavy), a5(2.0)
    monkeypatch.setattr(olshansky, "_FAST_RADIUS", 0.0)  # no batch is small: the exponential
    exponential = solve(*light)
    for other in (beside, exponential):
        np.testing.assert_array_equal(np.asarray(other.times)[:64], fast.times)
        np.testing.assert_allclose(other.positions[:64], fast.positions, rtol=0, atol=1e-15 * A0)
    assert not np.array_equal(exponential.positions, fast.positions)  # (two paths ran)
    np.testing.assert_allclose(a5(2.0), grad, rtol=1e-12)


# -- bad input ----------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "kwargs,name",
    [
        (dict(m0=0.0), "m0"),
        (dict(m0=-1.0), "m0"),
        (dict(c=0.0), "c"),
        (dict(c=-5.0), "c"),
        (dict(mu=-1.0), "mu"),
        (dict(eps=-0.1), "eps"),
        (dict(eps=1.5), "eps"),
        (dict(delta=float("nan")), "delta"),
        (dict(m0=float("inf")), "m0"),
        (dict(mu=float("nan")), "mu"),
    ],
)
def test_bad_model_parameters_raise_value_error(kwargs, name):
    p = dict(m0=M0, c=C, delta=3.0, eps=0.0, mu=2.0)
    p.update(kwargs)
    with pytest.raises(ValueError, match=rf"^{name} must be"):
        vmj.VariableMass(friction=vmj.Coulomb(FT), **p)


@pytest.mark.parametrize(
    "make,name",
    [
        (lambda: vmj.Coulomb(-1.0), "F"),
        (lambda: vmj.Coulomb(float("nan")), "F"),
        (lambda: vmj.MassProportional(-0.1), "f"),
        (lambda: vmj.MassProportional(0.3, g=0.0), "g"),
    ],
)
def test_bad_friction_raises_value_error(make, name):
    with pytest.raises(ValueError, match=rf"^{name} must be"):
        make()


@pytest.mark.parametrize(
    "call,name",
    [
        (lambda m: vmj.turning_points(m, 0.0, 5), "a0"),
        (lambda m: vmj.turning_points(m, -0.01, 5), "a0"),
        (lambda m: vmj.turning_points(m, float("nan"), 5), "a0"),
        (lambda m: vmj.turning_points(m, A0, 0), "n"),
        (lambda m: vmj.turning_points(m, A0, 5, vmj.Smoothed(smoothing=0.0)), "smoothing"),
        (lambda m: vmj.turning_points(m, A0, 5, vmj.Smoothed(smoothing=-1.0)), "smoothing"),
        (lambda m: vmj.turning_points(m, -1.0, 5, vmj.EnergyBalance()), "a0"),
        (lambda m: vmj.simulate(m, -A0, 0.0, 0.0), "t1"),
        (lambda m: vmj.simulate(m, -A0, 0.0, 1.0, vmj.Smoothed(smoothing=0.0)), "smoothing"),
        (lambda m: vmj.simulate(m, float("inf"), 0.0, 1.0), "x0"),
        (lambda m: vmj.simulate(m, 0.0, 0.0, 1.0), "smoothing"),  # no velocity scale for a default
    ],
)
def test_bad_solver_arguments_raise_value_error(call, name):
    with pytest.raises(ValueError, match=rf"^{name} must be"):
        call(model())


def test_simulate_refuses_a_horizon_past_zero_mass():
    with pytest.raises(ValueError, match=r"^t1 must be below the zero-mass time"):
        vmj.simulate(model(delta=-3.0), -A0, 0.0, 2.0)


def test_traced_horizon_past_zero_mass_raises():
    f = jax.jit(lambda t1: vmj.simulate(model(delta=-3.0), -A0, 0.0, t1).xs)
    with pytest.raises(Exception, match="t1 must be below"):
        f(2.0).block_until_ready()


def test_traced_bad_parameters_raise_inside_jit():
    f = jax.jit(lambda mu: vmj.turning_points(model(mu=mu), A0, 4).positions)
    assert np.all(np.isfinite(np.asarray(f(2.0))))
    with pytest.raises(Exception, match="mu must be finite and >= 0"):
        f(-1.0).block_until_ready()


def test_batched_model_needs_sweep_or_vmap():
    with pytest.raises(ValueError, match="scalar parameters"):
        vmj.turning_points(model(mu=jnp.array([1.0, 2.0])), A0, 4)
