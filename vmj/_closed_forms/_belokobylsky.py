"""Closed forms of the stick-slip limit cycle with instantaneous velocity reversal
(Belokobylsky & Koronatov, formulas (11)-(20); `SYSTEMS.md` section 3)."""

from __future__ import annotations

import jax.numpy as jnp

__all__ = ["closed_form_cycle"]


def closed_form_cycle(eps, Omega, max_reversals: int) -> dict:
    """The cycle's fields (see `vmj.StickSlipCycle`) for `eps = M1/M0` and the dimensionless
    drive speed `Omega`, arrays padded to `max_reversals + 1` slip intervals.

    `k* = floor((eps - 1)/2 - 1e-5)` reversals (16) (the `1e-5` makes eps = 3, 5, 7, ... land
    on the lower `k*`: at those values the disk stops with `|xi| = 1` exactly and sticks), and
    at least 0: the printed formula gives -1 for `eps <= 1 + 2e-5`, where the disk slips once
    and sticks (the exact solver's margin, `REVERSAL_MARGIN`, is the same);
    `tau_k = 2 {pi [1 - (-1)^k]/2 + (-1)^(k+1) arctan((2k - (eps + 1))/Omega)}` (14);
    `xi_k = (-1)^k (2k - eps)` (13); `A_k = sqrt((2k - (eps + 1))^2 + Omega^2)` (12);
    slip time (17), stick time `tau^* = (eps + (-1)^k* (eps - 2(k* + 1)))/Omega` (19) and
    period (20)."""
    n = max_reversals + 1
    kstar = jnp.maximum(jnp.floor((eps - 1.0) / 2.0 - 1e-5), 0.0).astype(jnp.int32)  # (16)
    k = jnp.arange(1, n + 1)
    sign_k = jnp.where(k % 2 == 0, 1.0, -1.0)  # (-1)^k
    used = k <= kstar + 1
    tau_k = 2.0 * (
        jnp.pi * (1.0 - sign_k) / 2.0 - sign_k * jnp.arctan((2 * k - (eps + 1.0)) / Omega)
    )  # (14)
    xi_k = sign_k * (2 * k - eps)  # (13)
    A_k = jnp.sqrt((2 * k - (eps + 1.0)) ** 2 + Omega**2)  # (12)
    slip = jnp.sum(jnp.where(used, tau_k, 0.0))  # (17)
    sign_kstar = jnp.where(kstar % 2 == 0, 1.0, -1.0)
    stick = (eps + sign_kstar * (eps - 2.0 * (kstar + 1))) / Omega  # (19)
    return dict(
        reversals=kstar,
        count=jnp.minimum(kstar + 1, n),
        slip_intervals=jnp.where(used, tau_k, 0.0),
        positions=jnp.where(used, xi_k, 0.0),
        amplitudes=jnp.where(used, A_k, 0.0),
        slip_time=slip,
        stick_time=stick,
        period=slip + stick,  # (20)
    )
