"""The paper's energy-balance recurrences (11)-(13), with (13) as corrected in SYSTEMS.md.

Written for sweeps of millions of points: between swings a point's state is three numbers (time,
`u = 1/sqrt(m)`, signed position of the turning point; the last two as one complex number), and
the mass itself where the friction depends on it. A swing that cannot advance (the mass sticks
for good, or the mass would run out) leaves the state unchanged, so stopping is absorbing and the
status is read off the final state instead of being carried through the loop (docs/performance.md
has the measurements).

Why `u`: XLA's CPU backend has no multi-output fusion, so a value that two updates read (it was
`sqrt(m)`, read by the mass and the amplitude updates) becomes a kernel of its own, and every
carried array is copied once per swing. With `u` carried, the exponent is a product, the mass
ratio `m_next/m = 1 + pi delta u/sqrt(c)` and the tests `m_next > 0` and `lam^2 < 16 m c` need no
mass, and the swing's one `rsqrt` lives in the kernel that updates `u` (the amplitudes of one
16384-point chunk x 12 swings on one core, same run: 1.65 ms carrying `m`, 1.28 ms carrying `m`
and `u`, 1.12 ms carrying `u`; results within 5e-16 of a0).

Why `u` and the position travel as one complex number: the same missing multi-output fusion
made the two updates two kernels, each recomputing the swing's common part, and since each
read both carries, XLA copied both before every swing. Carried as `u + 1j p`, a swing is one
kernel that writes its result in place (the amplitudes of a 16384-point chunk x 12 swings, the
same run, medians of 12 x 16 calls on the 2-core machine: 1455 -> 1036 us with XLA's own
threads, 1121 -> 966 us with two chunks side by side as `vmj.sweep` runs them; 4 -> 1 kernels
per swing; results within 1e-15 of a0).

Why two paths: the swing's exponential and quotient `phi(x) = (exp(x) - 1)/x` are most of its
arithmetic, and where every exponent is small, `|x| < 0.25` (a half-swing's viscous decrement:
a lightly damped oscillator), thirteen terms of phi's series give both, `exp(x) = 1 + x phi(x)`.
The exponents' bound is known before the swings run (`u` is monotonic), so a batch takes one
path for all its lanes (a conditional: it never runs both); as a conditional's batched results
have the points first, an energy-balance sweep's chunk comes back points first (`vmap_in_place`
finds no transpose to drop). The 10^6-point sweep of `benchmarks/bench_energy.py`, old and new
in turns on the 2-core machine, medians of 11: 63.5 -> 53.7 ms (3.62 -> 3.06 x the elementwise
limit); results within 3e-17 of a0.
"""

from __future__ import annotations

import math

import jax.numpy as jnp
from equinox.internal import unvmap_any
from jax import lax

from .._numerics._series import horner
from .._solution import RESULTS, DecaySequence

#: Taylor coefficients of phi(x) = (exp(x) - 1)/x = sum_j x^j/(j + 1)!
_PHI = tuple(1.0 / math.factorial(j + 1) for j in range(13))
#: phi by its first ten terms inside this radius (truncation below 3e-18 relative), by the
#: quotient outside it (rounding below 1.2e-15 relative)
_SERIES_RADIUS = 0.1
#: a batch whose every exponent stays inside this radius takes exp(x) as 1 + x phi(x), phi by
#: all thirteen terms (truncation below 2e-19 relative): no exponential, no quotient
_FAST_RADIUS = 0.25


def _exp_and_phi(x, inverse_x, fast: bool):
    """`exp(x)` and `phi(x) = (exp(x) - 1)/x`, smooth through `x = 0` (value and gradient);
    `inverse_x` is `1/x` where `|x| >= _SERIES_RADIUS` (any finite value elsewhere). `fast`:
    both from the series, for `|x| < _FAST_RADIUS` only."""
    if fast:
        phi = horner(_PHI, x)
        return 1.0 + x * phi, phi
    e = jnp.exp(x)
    series = horner(_PHI[:10], x)
    return e, jnp.where(jnp.abs(x) < _SERIES_RADIUS, series, (e - 1.0) * inverse_x)


def _pack(u, p):
    """`u + 1j p` (the carried pair, module docstring), in their common precision."""
    dtype = jnp.result_type(u, p)
    return lax.complex(u.astype(dtype), p.astype(dtype))


def energy_balance_sequence(model, a0, n: int) -> DecaySequence:
    """Amplitudes from the energy-balance recurrences (see `vmj.EnergyBalance`)."""
    m0, c, delta = model.m0, model.c, model.delta
    friction = model.friction
    lam = delta - 2 * delta * model.eps - 2 * model.mu
    half_per_root_mass = jnp.pi / jnp.sqrt(c)  # half-period / sqrt(m)
    exponent_root_mass = half_per_root_mass * lam / 4  # exponent of E_k * sqrt(m)
    nonzero = exponent_root_mass != 0
    inverse_exponent_root_mass = jnp.where(nonzero, 1.0, 0.0) / jnp.where(
        nonzero, exponent_root_mass, 1.0
    )
    dF_dm = friction.dforce_dmass()
    # friction that falls with the mass (f-law, delta < 0): a stuck mass waits until it has
    # fallen below the spring force, then moves on (never with constant friction)
    falls = dF_dm * delta < 0

    # carried: the time, u = 1/sqrt(m) and p, the signed position of the current turning point
    # (u + 1j p, `_pack`); the mass itself only where the friction depends on it
    varies = friction.varies_with_mass
    mass_step = delta * half_per_root_mass  # (m_next - m) / sqrt(m)

    def swing(state, fast):
        t_in, z, m_in = state if varies else (*state, m0)
        u_in, p = jnp.real(z), jnp.imag(z)
        a = jnp.abs(p)
        moves = c * a > friction.force(m_in)
        t, u, m = t_in, u_in, m_in
        if varies:
            release = jnp.logical_not(moves) & falls
            m = jnp.where(release, c * a / jnp.where(falls, dF_dm, 1.0), m_in)
            t = jnp.where(release, t_in + (m - m_in) / jnp.where(falls, delta, 1.0), t_in)
            u = jnp.where(release, lax.rsqrt(m), u_in)
            moves = moves | release
        grow = 1 + mass_step * u  # m_next / m
        half = half_per_root_mass / u
        x = exponent_root_mass * u
        E, phi = _exp_and_phi(x, None if fast else inverse_exponent_root_mass / u, fast)
        F_k = friction.force(m + 0.5 * delta * half)  # friction work over the half-swing
        a_next = a * E - (2 * F_k / c) * phi  # < 0: the swing did not pass x = 0
        # the averaged map needs an oscillation: with |lam| >= 4 sqrt(m c) the half-swing is
        # over-damped (or runs away) and has no turning point, as the exact solver finds
        oscillates = lam * lam * (u * u) < 16 * c
        advance = moves & (grow > 0) & oscillates
        t_out = jnp.where(advance, t + half, t_in)
        p_out = jnp.where(advance, -jnp.sign(p) * a_next, p)
        # crossed x = 0; advanced; no turning point (over-damped)
        flags = (advance & (a_next > 0), advance, moves & jnp.logical_not(oscillates))
        # (the guard keeps a mass that would run out, never carried, from a NaN gradient)
        u_next = u * lax.rsqrt(jnp.where(grow > 0, grow, 1.0))
        # the position written out is read off the carried pair behind a barrier: without it
        # XLA would compute it in a kernel of its own, repeating the swing
        z = lax.optimization_barrier(_pack(jnp.where(advance, u_next, u_in), p_out))
        state = (t_out, z)
        if varies:
            state += (jnp.where(advance, m * grow, m_in),)
        return state, (t_out, jnp.imag(z)) + flags

    u0 = lax.rsqrt(m0)
    init = (jnp.zeros_like(m0), _pack(u0, -a0 * jnp.ones_like(m0)))
    init += (m0,) if varies else ()

    # the largest exponent |x| = |exponent_root_mass| u of the n swings, bounded before they
    # run: u = 1/sqrt(m) is largest at the smallest mass, the first (a mass that grows) or
    # after n swings of at most pi sqrt(m0/c) each (one that falls: m >= m0 + n delta pi
    # sqrt(m0/c)); friction that releases a falling mass bounds nothing (its release mass has
    # no lower bound)
    lowest = jnp.where(delta < 0, m0 * (1 + n * mass_step * u0), m0)
    bound = jnp.abs(exponent_root_mass) * lax.rsqrt(jnp.where(lowest > 0, lowest, 0.0))
    small = bound < _FAST_RADIUS
    if varies:
        small = small & jnp.logical_not(falls)

    def scan(fast: bool):
        return lax.scan(lambda state, _: swing(state, fast), init, None, length=n)

    # one path for the whole batch: every lane's exponents small, or the exponential for all
    final, (times, positions, crossed, advanced, over) = lax.cond(
        unvmap_any(jnp.logical_not(small)), lambda: scan(fast=False), lambda: scan(fast=True)
    )
    p, m = jnp.imag(final[1]), final[2] if varies else m0
    stuck = (c * jnp.abs(p) <= friction.force(m)) & jnp.logical_not(falls)
    ended = jnp.logical_not(advanced[-1]) & jnp.logical_not(stuck)
    code = jnp.where(
        stuck,
        RESULTS.stopped,
        jnp.where(
            ended & over[-1],
            RESULTS.step_limit,
            jnp.where(ended, RESULTS.mass_exhausted, RESULTS.successful),
        ),
    )
    return DecaySequence.from_scan(times, positions, crossed, advanced, code)
