"""Linear one-degree-of-freedom oscillator, free and harmonically forced (`SYSTEMS.md` section 4;
the problem book's chapter 4 and the Lagrange-equation paper).

    m x'' + c x' + k x = F(t),

with `F(t) = 0`, `F0 sin(p t)` (harmonic force) or `k y + c y'` for a harmonic base motion
`y(t) = Y0 sin(p t)` (the spring and damper are attached to the moving base; `x` is absolute).
Analytic responses (under-, critically and over-damped), the logarithmic decrement, the
amplification factor and phase ([`vmj.ClosedForm`][]); [`vmj.Smoothed`][] integrates the same
equation with diffrax (nothing is smoothed: the model has no dry friction).
"""

from __future__ import annotations

import math
from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import lax
from jaxtyping import Array

from .._checks import _float, _is_traced, fail_if, nonnegative, positive
from .._exported import filter_jit
from .._laws._forcing import Forcing, NoForcing
from ._base import AbstractAnalytic

__all__ = ["LinearOscillator"]


class LinearOscillator(AbstractAnalytic):
    """Linear one-degree-of-freedom oscillator `m x'' + c x' + k x = F(t)`.

    **Arguments:**

    - `m`: mass [kg] (or moment of inertia [kg m^2]), `> 0`.
    - `c`: viscous damping coefficient [N s/m], `>= 0`.
    - `k`: stiffness [N/m], `> 0`.
    - `forcing`: [`vmj.NoForcing`][] (default), [`vmj.HarmonicForce`][]`(F0, p)` or
      [`vmj.BaseMotion`][]`(Y0, p)`.

    In the book's notation `omega_c^2 = k/m`, `2 eta omega_c = c/m`, `omega_3 = omega_c
    sqrt(1 - eta^2)`; in the paper's `k^2 = k/m`, `2 b = c/m`, `k* = sqrt(k^2 - b^2)`.
    """

    m: Array = eqx.field(converter=_float)
    c: Array = eqx.field(converter=_float)
    k: Array = eqx.field(converter=_float)
    forcing: Forcing = eqx.field(default_factory=NoForcing)
    _limits: ClassVar[dict] = {
        "m": (positive, "> 0 [kg]"),
        "c": (nonnegative, ">= 0 [N s/m]"),
        "k": (positive, "> 0 [N/m]"),
    }

    def __check_init__(self):
        if not isinstance(self.forcing, Forcing):
            raise ValueError(
                "forcing must be vmj.NoForcing(), vmj.HarmonicForce(F0, p) or vmj.BaseMotion(Y0, p)"
            )

    # -- the equation of motion, written once --------------------------------------------------
    def acceleration(self, t, x, v, sgn=None):
        """`x''` [m/s^2] at time `t` [s], position `x` [m], velocity `v` [m/s] (`sgn` unused:
        no dry friction)."""
        return (self.forcing.force(self, t) - self.c * v - self.k * x) / self.m

    smoothed_rtol: ClassVar[float] = 1e-12

    def velocity_scale(self, a0):
        """`a0 omega_c` [m/s]."""
        return a0 * self.natural_frequency

    def smoothing_scale(self, x0, v0):
        """No dry friction: the smoothing velocity is unused (any positive value)."""
        return jnp.ones_like(self.m)

    def length_scale(self, x0, v0):
        """`|x0| + |v0|/omega_c + |Q|/k`: the free and the forced motion's scale."""
        Q, _ = self.forcing.complex_amplitude(self)
        return jnp.abs(x0) + jnp.abs(v0) / self.natural_frequency + jnp.abs(Q) / self.k + 1e-300

    # -- characteristics -------------------------------------------------------------------------
    @property
    def natural_frequency(self) -> Array:
        """Undamped natural frequency `omega_c = sqrt(k/m)` [1/s]."""
        return jnp.sqrt(self.k / self.m)

    @property
    def damping_ratio(self) -> Array:
        """`eta = c / (2 sqrt(k m))` [-]."""
        return self.c / (2.0 * jnp.sqrt(self.k * self.m))

    @property
    def decay_rate(self) -> Array:
        """`b = eta omega_c = c/(2m)` [1/s]."""
        return self.c / (2.0 * self.m)

    @property
    def damped_frequency(self) -> Array:
        """`omega_3 = omega_c sqrt(1 - eta^2)` [1/s] (NaN-free: 0 when `eta >= 1`)."""
        return self.natural_frequency * jnp.sqrt(jnp.maximum(1.0 - self.damping_ratio**2, 0.0))

    @property
    def log_decrement(self) -> Array:
        """Logarithmic decrement `delta = ln(A_n / A_{n+1}) = 2 pi eta / sqrt(1 - eta^2)` [-]
        (`inf` when `eta >= 1`)."""
        eta = self.damping_ratio
        under = eta < 1
        return jnp.where(
            under, 2 * jnp.pi * eta / jnp.sqrt(jnp.where(under, 1 - eta**2, 1.0)), jnp.inf
        )

    def free_amplitude(self, x0, v0):
        """Free response `x = A e^{-eta omega_c t} sin(omega_3 t + alpha)` (under-damped):
        returns `(A, alpha)` [m, rad], `A = sqrt(x0^2 + ((v0 + eta omega_c x0)/omega_3)^2)`.
        (The book writes `sin(omega_3 t - alpha)` with its alpha of opposite sign.)"""
        b, wd, eta = self.decay_rate, self.damped_frequency, self.damping_ratio
        message = (
            "free_amplitude/transient/settling_time need an under-damped oscillator (damping "
            "ratio eta = c/(2 sqrt(k m)) < 1); use response() otherwise"
        )
        if _is_traced(eta):
            wd = fail_if(wd, eta >= 1, message)
        elif np.any(np.asarray(eta) >= 1):  # a ValueError, as every concrete check
            got = np.asarray(eta)
            raise ValueError(f"{message} (got eta = {got.item() if got.ndim == 0 else got})")
        B = (v0 + b * x0) / wd
        return jnp.sqrt(x0**2 + B**2), jnp.arctan2(x0, B)

    def amplification(self, p=None):
        """Amplification factor `|X| k / |F|` = `1 / sqrt((1 - r^2)^2 + (2 eta r)^2)`,
        `r = p / omega_c` [-], at forcing frequency `p` [1/s] (default: the forcing's).
        For base motion this is the force-to-response factor; the transmissibility `|X/Y0|` is
        [`vmj.LinearOscillator.forced_response`][]'s amplitude over `Y0`."""
        p = self.forcing.complex_amplitude(self)[1] if p is None else p
        r = p / self.natural_frequency
        return 1.0 / jnp.sqrt((1 - r**2) ** 2 + (2 * self.damping_ratio * r) ** 2)

    def forced_response(self):
        """Steady forced response `x_p = D sin(p t - beta)`: returns `(D, beta)` [m, rad] with
        `beta` in `[0, pi]` the phase lag behind the force `sin(p t)` (base motion: behind
        `sin(p t)` of the base). `tan(beta) = 2 eta omega_c p / (omega_c^2 - p^2)`; for
        `p > omega_c` the lag is beyond `pi/2`, i.e. `beta = pi + arctan(tan beta)` (the
        branch the Lagrange-equation paper misses, see docs/linear.md). At undamped resonance
        there is no steady state: `D = inf`, `beta = pi/2` (the response grows like `t`)."""
        Q, p = self.forcing.complex_amplitude(self)
        H, resonant, _ = self._receptance(Q, p)  # x_p = Im(H e^{i p t})
        D = jnp.where(resonant & (Q != 0), jnp.inf, jnp.abs(H))
        return D, jnp.where(resonant, jnp.pi / 2, -jnp.angle(H))

    def _receptance(self, Q, p):
        """`(H, resonant, G)`: steady amplitude `H = Q / (k - m p^2 + i c p)`; at undamped
        resonance (`c = 0`, `k = m p^2` exactly) `H = 0` and the particular solution is the
        secular `Im(G t e^{i p t})`, `G = Q / (2 i m p)`."""
        den = self.k - self.m * p**2 + 1j * self.c * p
        resonant = den == 0
        H = jnp.where(resonant, 0.0, Q / jnp.where(resonant, 1.0, den))
        G = jnp.where(resonant, Q / (2j * self.m * jnp.where(resonant, p, 1.0)), 0.0)
        return H, resonant, G

    def transient(self, x0, v0):
        """Free-vibration part `(A, alpha)` of the full response `x = A e^{-b t} sin(omega_3 t +
        alpha) + x_p(t)` with `x(0) = x0`, `x'(0) = v0` (under-damped); `x_p` is the steady
        response `D sin(p t - beta)`, or at undamped resonance the secular one (`response`), so
        that the free part is defined there too."""
        return self.free_amplitude(*self._free_start(x0, v0))

    def _free_start(self, x0, v0):
        """The free part's initial state: `(x0 - x_p(0), v0 - x_p'(0))` [m, m/s]."""
        Q, p = self.forcing.complex_amplitude(self)
        H, _, G = self._receptance(Q, p)
        return x0 - jnp.imag(H), v0 - jnp.imag(1j * p * H) - jnp.imag(G)

    def settling_time(self, x0, v0, fraction=0.01):
        """Time [s] after which the transient's envelope `A e^{-b t}` stays below `fraction`
        of the forced amplitude `D`: `t_y = ln(A / (fraction D)) / b` (the paper's
        `ln(100 A/D)/b`), `0` where it is below from the start, `inf` where it never gets
        there (undamped), NaN at undamped resonance (no steady state)."""
        A, _ = self.transient(x0, v0)
        D, _ = self.forced_response()
        t = jnp.maximum(jnp.log(A / (fraction * D)) / self.decay_rate, 0.0)
        return jnp.where(jnp.isinf(D), jnp.nan, t)

    @filter_jit
    def response(self, t, x0, v0):
        """Analytic displacement and velocity `(x, v)` [m, m/s] at times `t` [s] from `x(0) = x0`
        [m], `x'(0) = v0` [m/s], by one formula for every damping and forcing frequency.

        With `r1, r2` the roots of `m r^2 + c r + k = 0` and `E[z1, ..](t)` the divided
        difference of `exp(z t)` over the points `z1, ..` (in `z`), the impulse response is
        `E = E[r1, r2]`, the free motion `x0 E' + (v0 + (c/m) x0) E` and the forced motion from
        rest `Im(Q E[r1, r2, i p]) / m` (the force `Im(Q e^{i p t})`). The divided differences
        are evaluated so that no point's coincidence costs digits: resonance (`i p` at a root),
        undamped, critically damped (`r1 = r2`), over-damped, and early times (all three points
        within `1/t` of each other, a Taylor series); see `_kernels`.
        Relative to the trajectory's size it agrees with a 60-digit evaluation to about `1e-16
        (omega_c |t| + omega_c/p)` (the rounding of the phase `p t`; for forcing much slower
        than the natural frequency the forced part is a difference of terms `omega_c/p` times
        its size); derivatives in `m`, `c`, `k`, `p`, `x0`,
        `v0`, `t` are finite everywhere, critical damping and exact resonance included."""
        t = jnp.asarray(t, dtype=self.m.dtype)
        Q, p = self.forcing.complex_amplitude(self)
        m, c, k = self.m, self.c, self.k
        b = c / (2 * m)
        E, dE, E3 = _kernels(b, k / m, p, t)
        x = x0 * dE + (v0 + 2 * b * x0) * E + jnp.imag(Q * E3) / m
        v = v0 * dE - (k / m) * x0 * E + jnp.imag(Q * (E + 1j * p * E3)) / m
        return x, v


#: `|(b^2 - w^2) t^2|` below which the impulse response is its Taylor series (4 terms: 3e-21)
SERIES_Q, SERIES_TERMS = 1e-4, 4
#: `rho t` (the three points' spread times the time) up to which the forced kernel is its
#: Taylor series (`TAYLOR_TERMS` terms: below 1e-18 of the sum); above it the other forms lose
#: at most a factor `2 / (rho t)` (20) of rounding
TAYLOR_RHO, TAYLOR_TERMS = 0.1, 11
#: `|u|` below which `(e^u - 1)/u` is its Taylor series (12 terms: 2e-22 relative); above, the
#: half-angle sine of `Im u` (an absolute error of rounding) costs at most `1/PHI_SMALL` of it
PHI_SMALL, PHI_TERMS = 0.1, 12


def _horner(coefficients, t):
    """`sum_n coefficients[n] t^n`: per-model coefficients, a polynomial in the times."""
    total = coefficients[-1]
    for c in reversed(coefficients[:-1]):
        total = c + t * total
    return total


def _kernels(b, w2, p, t):
    """`(E, E', E3)` at times `t` [s] for `x'' + 2 b x' + w2 x`, `b` [1/s], `w2` [1/s^2] and
    the forcing frequency `p` [1/s]: the impulse response `E = E[r1, r2](t)` (`x(0) = 0`,
    `x'(0) = 1`) and its time derivative, real, and the response from rest to `e^{i p t}`,
    `E3 = E[r1, r2, i p](t)`, complex (`E[..]` divided differences of `exp(z t)` in `z`, `r1,2
    = -b +- d` the characteristic roots, `d^2 = q = b^2 - w2`).

    `E` and `E'` are entire in `q` (exact and differentiable at critical damping): their
    Taylor series where `|q t^2| <= SERIES_Q`; else `e^{-bt} (cos, sin/wd)(wd t)`, `wd =
    sqrt(-q)`, under-damped, and over-damped `e^{r1 t}` times `(1 - e^{-2dt}) / (2d)`, `r1 =
    -w2/(b + d)` (no overflow of `cosh`, no cancellation in the slow root).

    `E3`, in the form that loses no digits where it is taken:

    - early (`rho t <= TAYLOR_RHO`, `rho` the spread of `ip, r1, r2` about `-b`): its Taylor
      series `e^{-bt} sum_n h_n(ip + b, d, -d) t^{n+2}/(n+2)!` (`h_n` the complete homogeneous
      symmetric polynomial, in which only `d^2 = q` enters), coefficients once per model;
    - damping ratio below `sqrt(3)/2` (`r1 = -b + i wd` the root next to `ip`): `(E[ip, r1] -
      E[r1, r2]) / (ip - r2)`, the near pair first, `E[ip, r1] = e^{ipt} (e^u - 1)/(r1 - ip)`,
      `u = (r1 - ip) t`, with `e^u - 1` from `expm1` and half-angle sines (its series in `t`
      where `|u| < PHI_SMALL`), and `|ip - r2| >= omega_c/2`: exact through resonance, with or
      without damping;
    - otherwise `(e^{ipt} - E' - (ip + 2b) E) / D(ip)`, `D(ip) = w2 - p^2 + 2 i b p`, whose
      modulus is then at least `w2` (no resonance to cancel).

    The sines and cosines (the costly part: 11 ns each on a CPU core) are those of the half
    angles `p t/2` and `wd t/2` only; the others follow from them."""
    q = b * b - w2
    Q = q * t * t
    series = jnp.abs(Q) <= SERIES_Q
    sa, ca = jnp.sin(0.5 * p * t), jnp.cos(0.5 * p * t)  # the half angle of p t
    e_ipt = (1 - 2 * sa * sa) + 2j * sa * ca
    em = jnp.expm1(-b * t)
    decay = 1 + em  # e^{-bt}
    # -- E and E' where |Q| is small: cosh(sqrt Q), sinh(sqrt Q)/sqrt Q ------------------------
    Qs = jnp.where(series, Q, 0.0)
    C_s = S_s = 0.0
    for n in reversed(range(SERIES_TERMS)):
        C_s = 1.0 / math.factorial(2 * n) + Qs * C_s
        S_s = 1.0 / math.factorial(2 * n + 1) + Qs * S_s
    S_s = t * S_s
    # -- E3, early: Taylor series -------------------------------------------------------------
    a = 1j * p + b  # ip about the roots' mean -b
    early = jnp.maximum(jnp.abs(a), jnp.sqrt(jnp.abs(q))) * jnp.abs(t) <= TAYLOR_RHO
    h, even = jnp.ones_like(a), jnp.ones_like(q)  # h_0 and q^0
    coefficients = [h / 2]
    for n in range(1, TAYLOR_TERMS):
        if n % 2 == 0:
            even = even * q
        h = a * h + (even if n % 2 == 0 else 0.0)  # h_n = a h_{n-1} + h_n(d, -d)
        coefficients.append(h / math.factorial(n + 2))
    ts = jnp.where(early, t, 0.0)
    taylor = decay * ts * ts * _horner(coefficients, ts)
    light = 4 * q < -w2

    def steady(E, dE):  # heavier damping: the steady part minus the free one
        D = w2 - p * p + 2j * b * p
        return (e_ipt - dE - (1j * p + 2 * b) * E) * (1 / jnp.where(light, 1.0, D))

    def oscillating(near_root_first):  # q <= 0
        wd = jnp.sqrt(jnp.where(q < 0, -q, w2))
        sb, cb = jnp.sin(0.5 * wd * t), jnp.cos(0.5 * wd * t)  # the half angle of wd t
        C = jnp.where(series, C_s, 1 - 2 * sb * sb)
        S = jnp.where(series, S_s, 2 * sb * cb / wd)
        E, dE = decay * S, decay * (C - b * S)
        if not near_root_first:
            return E, dE, steady(E, dE)
        # light damping: E[ip, r1] = e^{ipt} (e^u - 1)/kappa, kappa = r1 - ip, u = kappa t
        kappa = -b + 1j * (wd - p)
        small = jnp.abs(kappa * t) < PHI_SMALL
        tu = jnp.where(small, t, 0.0)
        phi = _horner([kappa**n / math.factorial(n + 1) for n in range(PHI_TERMS)], tu)
        sd, cd = sb * ca - cb * sa, cb * ca + sb * sa  # sin, cos of (wd - p) t/2
        expm1 = em * (1 - 2 * sd * sd) - 2 * sd * sd + 2j * decay * sd * cd  # e^u - 1
        ratio = jnp.where(small, tu * phi, expm1 * (1 / jnp.where(kappa == 0, 1.0, kappa)))
        return E, dE, (e_ipt * ratio - E) * (1 / (b + 1j * (p + wd)))

    def over_damped():  # E = (e^{r1 t} - e^{r2 t}) / (2d), r1,2 = -b +- d
        d = jnp.sqrt(jnp.where(q > 0, q, 1.0))
        r1, r2 = -w2 / (b + d), -b - d
        slow, fast = jnp.exp(r1 * t), jnp.expm1(-2 * d * t)  # e^{r1 t}, e^{-2dt} - 1
        E = jnp.where(series, decay * S_s, slow * -fast / (2 * d))
        dE = jnp.where(series, decay * (C_s - b * S_s), slow * (r1 - r2 * (fast + 1)) / (2 * d))
        return E, dE, steady(E, dE)

    branch = jnp.where(light, 0, jnp.where(q <= 0, 1, 2))
    branches = [lambda: oscillating(True), lambda: oscillating(False), over_damped]
    E, dE, E3 = _switch(branch, branches)
    return E, dE, jnp.where(early, taylor, E3)


def _switch(index, branches):
    """`branches[index]()`: only that one computed where `index` is a scalar (a model's; a
    batch of them under `jax.vmap` computes each and selects), else each and a select."""
    if jnp.ndim(index) == 0:
        return lax.switch(index, branches)
    outs = [f() for f in branches]
    return jax.tree.map(lambda *xs: jnp.select([index == i for i in range(len(xs))], xs), *outs)
