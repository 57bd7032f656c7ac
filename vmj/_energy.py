"""The paper's energy-balance recurrences (11)-(13), with (13) as corrected in SYSTEMS.md."""

from __future__ import annotations

import jax.numpy as jnp
from jax import lax

from ._solution import RESULTS, DecaySequence


def _expm1_over_x(x):
    """(exp(x) - 1)/x, smooth through x = 0 (value and gradient)."""
    small = jnp.abs(x) < 1e-5
    safe = jnp.where(small, 1.0, x)
    return jnp.where(small, 1.0 + x / 2 + x * x / 6, jnp.expm1(safe) / safe)


def energy_balance_sequence(model, a0, n: int) -> DecaySequence:
    """Amplitudes from the energy-balance recurrences (see `vmj.energy_balance`)."""
    m0, c, delta = model.m0, model.c, model.delta
    lam = delta - 2 * delta * model.eps - 2 * model.mu
    dF_dm = model.friction.dforce_dmass()

    def body(carry, _):
        t, m, a, side, code = carry  # a >= 0: distance from x = 0 of the current turning point
        active = code == RESULTS.successful
        F_here = model.friction.force(m)
        moves = c * a > F_here
        # friction that falls with the mass (f-law, delta < 0): the mass sticks until it falls
        # below the spring force, then moves on
        release = jnp.logical_not(moves) & (dF_dm * delta < 0)
        m_go = jnp.where(release, c * a / jnp.where(dF_dm > 0, dF_dm, 1.0), m)
        t = jnp.where(release, t + (m_go - m) / jnp.where(delta != 0, delta, 1.0), t)
        m = m_go
        stuck = jnp.logical_not(moves | release)
        root_m = jnp.sqrt(jnp.maximum(m, 0.0))
        half = jnp.pi * root_m / jnp.sqrt(c)
        m_next = m + delta * half
        Fk = model.friction.force(m + 0.5 * delta * half)  # friction work over the half-swing
        x = jnp.pi * lam / (4 * jnp.sqrt(c) * jnp.maximum(root_m, 1e-300))
        a_next = a * jnp.exp(x) - (2 * Fk / c) * _expm1_over_x(x)
        exhausted = m_next <= 0
        new_code = jnp.where(
            stuck, RESULTS.stopped, jnp.where(exhausted, RESULTS.mass_exhausted, code)
        )
        code = jnp.where(active, new_code, code)
        advance = active & (code == RESULTS.successful)
        crossed = a_next > 0
        side = jnp.where(advance & crossed, -side, side)
        t = jnp.where(advance, t + half, t)
        m = jnp.where(advance, m_next, m)
        a = jnp.where(advance, jnp.abs(a_next), a)
        return (t, m, a, side, code), (t, side * a, advance & crossed, advance)

    init = (jnp.zeros_like(m0), m0, a0 * jnp.ones_like(m0), -jnp.ones_like(m0),
            jnp.array(RESULTS.successful))
    (t, m, a, _, code), (times, positions, crossed, advanced) = lax.scan(
        body, init, None, length=n
    )
    stuck = (c * a <= model.friction.force(m)) & jnp.logical_not(dF_dm * delta < 0)
    code = jnp.where((code == RESULTS.successful) & stuck, RESULTS.stopped, code)
    return DecaySequence.from_scan(times, positions, crossed, advanced, code)
