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

from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array

from .._checks import _float, _is_traced, nonnegative, positive
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
            wd = eqx.error_if(wd, jnp.any(eta >= 1), message)
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
        """Analytic displacement and velocity `(x, v)` [m, m/s] at times `t` [s] from `x(0) = x0`,
        `x'(0) = v0`: steady forced response plus the homogeneous solution (any damping,
        via the roots of `m r^2 + c r + k = 0`)."""
        t = jnp.asarray(t, dtype=self.m.dtype)
        Q, p = self.forcing.complex_amplitude(self)
        H, _, G = self._receptance(Q, p)
        e_ipt = jnp.exp(1j * p * t)
        xp = jnp.imag(H * e_ipt) + jnp.imag(G * t * e_ipt)
        vp = jnp.imag(1j * p * H * e_ipt) + jnp.imag(G * (1 + 1j * p * t) * e_ipt)
        y0, w0 = self._free_start(x0, v0)  # homogeneous initial state
        b = self.decay_rate
        disc = self.natural_frequency**2 - b**2  # > 0: under-damped
        wd = jnp.sqrt(jnp.abs(disc) + 0j)
        # x_h = e^{-bt} (y0 C(t) + (w0 + b y0) S(t)), C = cos/cosh(wd t), S = sin/sinh(wd t)/wd
        under = disc > 0
        crit = disc == 0
        wr = jnp.real(wd)
        safe = jnp.where(wr > 0, wr, 1.0)
        C = jnp.where(under, jnp.cos(wr * t), jnp.cosh(wr * t))
        S = jnp.where(crit, t, jnp.where(under, jnp.sin(wr * t), jnp.sinh(wr * t)) / safe)
        dC = jnp.where(under, -wr * jnp.sin(wr * t), wr * jnp.sinh(wr * t))
        dS = jnp.where(crit, 1.0, jnp.where(under, jnp.cos(wr * t), jnp.cosh(wr * t)))
        e = jnp.exp(-b * t)
        B = w0 + b * y0
        xh = e * (y0 * C + B * S)
        vh = e * (y0 * dC + B * dS) - b * xh
        x, v = xh + xp, vh + vp
        # Undamped near resonance, the steady part H = Q/(k - m p^2) and the free part that
        # cancels it at t = 0 grow without bound, and their sum loses digits (about eps times
        # k/|k - m p^2|): at p = sqrt(k/m) (rounded, not exactly resonant) x was 0 for every t.
        # There the response is written as a divided difference, exact through resonance: with
        # K'' + w^2 K = e^{ipt} from rest, K = (e^{ipt} - cos wt - i (p/w) sin wt)/(w^2 - p^2)
        # in sines of half-sums and half-differences, sigma = sin((p - w) t/2)/(p - w) =
        # (t/2) sinc(...). (Within that band, as at exact resonance before, the derivative in
        # c at c = 0 is not carried: the undamped formula has no c.)
        w = self.natural_frequency
        sig = 0.5 * t * jnp.sinc((p - w) * t / (2 * jnp.pi))
        sh, ch = jnp.sin(0.5 * (p + w) * t), jnp.cos(0.5 * (p + w) * t)
        K = (2 * sh * sig + 1j * (jnp.sin(w * t) / w - 2 * ch * sig)) / (p + w)
        dK = (jnp.sin(p * t) + 2 * w * ch * sig + 2j * p * sh * sig) / (p + w)
        x_u = x0 * jnp.cos(w * t) + v0 * jnp.sin(w * t) / w + jnp.imag(Q * K) / self.m
        v_u = -x0 * w * jnp.sin(w * t) + v0 * jnp.cos(w * t) + jnp.imag(Q * dK) / self.m
        undamped = (self.c == 0) & (jnp.abs(self.k - self.m * p**2) <= 1e-3 * self.k)
        return jnp.where(undamped, x_u, x), jnp.where(undamped, v_u, v)
