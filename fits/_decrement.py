"""The classical decrement method (a linear regression of successive amplitudes), used as the
starting guess of every fit and reported next to it for comparison.

For a constant-mass oscillator with viscous damping `zeta` and Coulomb dead band `xF`, each
half-swing is exactly the affine map (Feeny & Liang's decrement method for simultaneous Coulomb
and viscous friction)

    A_{k+1} = r A_k - (1 + r) xF,   r = exp(-pi zeta / sqrt(1 - zeta^2)),

where `A_k = |x_k - offset|` and `A_{k+1}` is counted negative when the swing did not pass the
centre. A least-squares line through the pairs `(A_k, A_{k+1})` gives `r` and `xF`; a line
through `(k, t_k)` gives the half-period.
"""

from __future__ import annotations

import itertools
import math

import numpy as np

from ._record import Record

__all__ = ["decrement", "starting_guess"]


def decrement(record: Record, centre: float | None = None) -> dict:
    """Decrement-method estimate from a record's turning points.

    **Returns** a dict: `r` (amplitude ratio per half-swing), `xF` (Coulomb dead band, in the
    record's units), `zeta`, `half_period` [s] and `omega` [rad/s] (when the record has times,
    else `None`), `slope`, `intercept`, `stderr_r`, `stderr_xF`, `pairs` (the regression data
    `A_k`, `A_{k+1}`, the second negative where the swing did not pass the centre), `pair_k`
    (the swing index `k` of each pair's first point), `step` (1; 2 for a record of one side's
    peaks, whose pairs are `A_k`, `A_{k+2}` and whose `slope` is `r^2`), `centre`.

    Raises `ValueError` when the amplitudes do not decay.
    """
    c = record.centre if centre is None else centre
    x = np.asarray(record.positions, dtype=float) - c
    k = np.asarray(record.k)
    src = f"{record.source}: " if record.source else ""
    if len(x) < 3:
        raise ValueError(
            f"{src}need at least 3 turning points for the decrement method (got {len(x)})"
        )
    amp = np.abs(x)
    kf = k.astype(float)
    (trend, level), res, *_ = np.polyfit(kf, amp, 1, full=True)
    spread = float(np.sqrt(res[0] / max(len(x) - 2, 1))) if len(res) else 0.0
    se_trend = spread / max(float(np.std(kf)) * math.sqrt(len(x)), 1e-300)
    drop = -trend * float(kf[-1] - kf[0])
    if not (trend < 0 and -trend > 3 * se_trend and drop > 1e-6 * float(np.max(amp))):
        what = "grow" if trend > 3 * se_trend else "stay constant"
        raise ValueError(
            f"{src}the sequence does not decay (the amplitudes {what}: "
            f"{trend:.3g} +- {se_trend:.2g} per swing on average): nothing to "
            f"identify"
        )
    gaps = np.diff(k)
    # peaks of one side (a table of full periods, `k` even): pairs one period apart, for which
    # the map is the half-swing's twice, A_{k+2} = r^2 A_k - (1 + r)^2 xF
    step = 2 if np.count_nonzero(gaps == 1) < 2 and np.count_nonzero(gaps == 2) >= 2 else 1
    paired = gaps == step
    a_now = amp[:-1][paired]
    # negative where the swing ended on the wrong side (did not pass the centre)
    a_next = ((-1) ** step * np.sign(x[:-1]) * x[1:])[paired]
    moving = np.abs(x[1:] - x[:-1])[paired] > 0
    a_now, a_next = a_now[moving], a_next[moving]
    k_now = k[:-1][paired][moving]
    if a_now.size < 2:
        raise ValueError(
            f"{src}need at least 2 pairs of successive turning points (or of peaks one period "
            f"apart)"
        )
    A = np.stack([a_now, np.ones_like(a_now)], axis=1)
    coef, *_ = np.linalg.lstsq(A, a_next, rcond=None)
    slope, intercept = float(coef[0]), float(coef[1])
    dof = max(a_now.size - 2, 1)
    resid = a_next - A @ coef
    s2 = float(resid @ resid) / dof
    try:
        cov = s2 * np.linalg.inv(A.T @ A)
    except np.linalg.LinAlgError:
        cov = np.full((2, 2), np.nan)
    power = min(max(slope, 1e-6), 1 - 1e-9)  # r^step
    r = power ** (1 / step)
    xF = -intercept / (1 + r) ** step
    # d(r, xF) / d(slope, intercept) for the standard errors
    dr = r / (step * power)
    g = np.array([intercept * step * dr / (1 + r) ** (step + 1), -1 / (1 + r) ** step])
    log_r = math.log(r)
    zeta = -log_r / math.sqrt(math.pi**2 + log_r**2)
    half = omega = None
    if record.times is not None:
        half = float(np.polyfit(k.astype(float), record.times, 1)[0])
        if half > 0:
            omega = math.pi / half / math.sqrt(1 - zeta * zeta)
    return {
        "r": r,
        "xF": xF,
        "zeta": zeta,
        "half_period": half,
        "omega": omega,
        "slope": slope,
        "intercept": intercept,
        "stderr_r": dr * float(math.sqrt(max(cov[0, 0], 0.0))),
        "stderr_xF": float(math.sqrt(max(g @ cov @ g, 0.0))),
        "pairs": (a_now, a_next),
        "pair_k": k_now,
        "step": step,
        "centre": c,
    }


def starting_guess(space, record: Record, given: dict, dec: dict) -> dict:
    """Starting values of the parameters of a model family (a `fits._space.Space`) from the
    decrement estimate `dec`; values in `given` (fixed parameters, or starts chosen by the user)
    take precedence. A space with a `start(record, given, dec)` function supplies its own."""
    if getattr(space, "start", None) is not None:
        return {**space.start(record, given, dec), **{k: float(v) for k, v in given.items()}}
    names = set(space.names)  # the family by its parameters (a variant space shares them)
    a0 = float(abs(record.positions[0] - dec["centre"]))
    if record.k[0] > 0:  # no release row: back along the decrement line to k = 0
        for _ in range(int(record.k[0])):
            a0 = (a0 + (1 + dec["r"]) * dec["xF"]) / dec["r"]
        a0 = max(a0, float(np.max(record.amplitudes)))
    zeta = max(dec["zeta"], 1e-3)
    xF = max(dec["xF"], 2e-3 * a0)
    start = {"a0": a0, "offset": dec["centre"]}
    if {"omega", "zeta", "xF"} <= names:
        start.update(zeta=min(zeta, 0.5), xF=xF, omega=dec["omega"] or 1.0)
    elif {"FT", "f", "mu", "m0", "c"} <= names:
        if "m0" not in given or "c" not in given:
            raise ValueError(
                "the variable-mass fit needs m0 and c (give them with --set "
                "m0=VALUE,c=VALUE; a fitted one needs a starting value)"
            )
        m0, c = given["m0"], given["c"]
        delta = given.get("delta", 0.0)
        eps = given.get("eps", 0.0)
        g = given.get("g", 9.81)
        fitted = _energy_balance_start(dec, m0, c, delta, g, given)
        if fitted is not None:  # the mass's change taken into account
            lam, friction = fitted  # (the friction terms in `given` are set below)
        else:  # the constant-ratio decrement at the record's middle mass
            half = math.pi * math.sqrt(m0 / c)
            m_mid = max(m0 + delta * half * int(record.k[-1]) / 2, 0.2 * m0)
            lam = 4 * math.sqrt(c * m_mid) * math.log(dec["r"]) / math.pi
            friction = {"FT": c * xF, "f": c * xF / (g * m_mid)}
        mu = max((delta - 2 * delta * eps - lam) / 2, 2e-3 * math.sqrt(c * m0))
        start.update(mu=mu, eps=min(max(eps, 0.05), 0.95), delta=delta, g=g, m0=m0, c=c, **friction)
    elif {"T", "e", "l0"} <= names:
        # the dead band xF = A T / (A e / l0): T = e xF / l0 (first-order, length at release)
        e = given.get("e", 1.0)
        start.update(
            T=e * xF / given.get("l0", 1.0),
            e=e,
            d=given.get("d", 0.0),
            b=given.get("b", 0.0),
            u=given.get("u", 0.0),
        )
    successive = np.diff(record.k) == 1
    if "asym" in names and record.sides_known and np.any(successive[:-1] & successive[1:]):
        # (the sensor's asymmetry from three successive turning points; one side's peaks
        # alone cannot show it)
        from ._sensor import sensor_start

        start["asym"] = float(np.clip(sensor_start(record)["asym"], -0.4, 0.4))
    start.update({k: float(v) for k, v in given.items()})
    return start


def _energy_balance_start(dec: dict, m0, c, delta, g, given: dict):
    """The variable-mass model's damping exponent `lam` [kg/s] and its unknown friction terms
    (`FT` [N], `f` [-], those not in `given`) from the decrement pairs by least squares on the
    energy-balance recurrences (`vmj.EnergyBalance`), whose masses `m_k` follow from `m0`,
    `c` and `delta` alone:

        A_{k+1} = A_k E_k - (2 F_k / c) phi(x_k),  x_k = pi lam / (4 sqrt(c m_k)),

    `E_k = exp(x_k)`, `phi(x) = (e^x - 1)/x`, `F_k = FT + f g m` at the swing's middle mass:
    linear in the friction terms for each `lam`, searched over the oscillating range
    `|lam| < 4 sqrt(c m)`. The constant-ratio decrement ignores the mass change: with a
    shrinking mass and mass-proportional friction its `mu` can start the fit in the basin of a
    wrong stick count. Only the swings before the first that does not pass the centre are used
    (a mass may have stuck before that one). `None` when the pairs or the masses do not allow
    it."""
    if dec.get("step", 1) != 1:  # pairs one period apart: not the recurrence's
        return None
    k = np.asarray(dec.get("pair_k", ()), dtype=int)
    a_now, a_next = dec["pairs"]
    # the swings that pass the centre, up to the first that does not: a mass that stuck
    # before it may have waited there while its mass changed (friction that falls with the
    # mass releases it later), which the chain of masses below does not know
    last = np.flatnonzero(a_next <= 0)
    end = int(last[0]) if last.size else k.size
    k, a_now, a_next = k[:end], a_now[:end], a_next[:end]
    if k.size < 2:
        return None
    m = np.empty(int(k.max()) + 1)
    m[0] = m0
    for j in range(m.size - 1):
        m[j + 1] = m[j] + delta * math.pi * math.sqrt(max(m[j], 0.0) / c)
    if not np.all(m > 0):
        return None
    mk = m[k]
    mid = mk + 0.5 * delta * math.pi * np.sqrt(mk / c)
    columns = {"FT": np.ones_like(mid), "f": g * mid}
    unknown = [name for name in columns if name not in given]
    known = sum(float(given.get(name, 0.0)) * col for name, col in columns.items())

    def misfit(lams):
        """Per `lam` the least misfit over friction terms >= 0 (each subset of the unknowns
        solved by its normal equations: exact for these one or two terms) and its terms."""
        x = math.pi * lams[:, None] / (4 * np.sqrt(c * mk))
        safe = np.where(x == 0, 1.0, x)
        phi = np.where(x == 0, 1.0, np.expm1(x) / safe)
        y = a_next - a_now * np.exp(x) + (2 / c) * phi * known
        A = np.zeros(y.shape + (len(unknown),))
        for i, name in enumerate(unknown):
            A[..., i] = -(2 / c) * phi * columns[name]
        best = np.einsum("gp,gp->g", y, y)
        coef = np.zeros((lams.size, len(unknown)))
        for subset in itertools.product((False, True), repeat=len(unknown)):
            use = np.flatnonzero(subset)
            if use.size == 0:
                continue
            Au = A[..., use]
            gram = np.einsum("gpi,gpj->gij", Au, Au)
            # (one term: a division; FT and f together: collinear while the mass is constant)
            inverse = 1 / np.where(gram == 0, 1.0, gram) if use.size == 1 else np.linalg.pinv(gram)
            sol = np.einsum("gij,gpj,gp->gi", inverse, Au, y)
            r = y - np.einsum("gpi,gi->gp", Au, sol)
            cost = np.where(np.all(sol >= 0, axis=1), np.einsum("gp,gp->g", r, r), np.inf)
            better = cost < best
            best = np.where(better, cost, best)
            full = np.zeros_like(coef)
            full[:, use] = sol
            coef = np.where(better[:, None], full, coef)
        return best, coef

    top = 4 * math.sqrt(c * float(m.min())) * (1 - 1e-6)
    grid = np.linspace(-top, top, 401)
    i = int(np.argmin(misfit(grid)[0]))
    grid = np.linspace(grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)], 401)  # refined
    cost, coefs = misfit(grid)
    i = int(np.argmin(cost))
    if not np.isfinite(cost[i]):
        return None
    lam, coef = float(grid[i]), coefs[i]
    return lam, {name: float(v) for name, v in zip(unknown, coef)}
