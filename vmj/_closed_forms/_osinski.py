"""Closed forms and averaged laws of the rope model (`SYSTEMS.md` section 2).

- `kbm_amplitude`, `kbm_frequency`: the paper's first-order Krylov-Bogolyubov results, with the
  amplitude in the corrected form (the printed (2.7) does not solve (2.6)).
- `action_amplitude`, `action_frequency`: averaging on the exact action of the nonlinear rope
  (valid when the cubic term is not small): the action `I = (1/2 pi) oint p dx` is an adiabatic
  invariant of the slowly changing rope, so only friction changes it,
  `dI/dt = -(A T / pi) (x_+ - x_-)` (friction work `2 A T (x_+ - x_-)` per period times
  `dI/dE = 1/Omega = period/(2 pi)`), and the amplitude and frequency follow from `I` and `l`.
- `energy_map` (`turning_points(..., vmj.EnergyBalance())`): for a fixed length the exact
  half-swing map `V(x_k) + s A T x_k = V(x_{k+1}) + s A T x_{k+1}`, with the half-swing times
  from the same energy integral.

The integrals over a swing between turning points `r1 < r2` of a quartic potential use
`x = (r1 + r2)/2 + (r2 - r1)/2 sin(theta)` after dividing `E - W(x)` by `(x - r1)(x - r2)`, so
the integrands are analytic and Gauss-Legendre quadrature converges to machine precision.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
from jax import lax

from .._checks import fail_if
from .._numerics._ode import ode_solve
from .._numerics._roots import expanding_root
from .._numerics._scan import decay_scan
from .._solution import RESULTS

__all__ = ["kbm", "action_law", "energy_map_sequence", "half_swings_until", "swing_nodes"]


@functools.cache
def _quadrature():
    """40 Gauss-Legendre nodes on `[-pi/2, pi/2]` and their weights (computed where first
    needed: `numpy.polynomial` takes a tenth of a `vmj table`'s imports)."""
    nodes, weights = np.polynomial.legendre.leggauss(40)
    return 0.5 * np.pi * nodes, 0.5 * np.pi * weights


# -- first-order averaging (the paper, corrected) ---------------------------------------------
def _kbm_D(rope):
    """`D = 2 T / (pi sqrt(e m / A))` [m^(1/2)/s]."""
    return 2 * rope.T / (jnp.pi * jnp.sqrt(rope.e * rope.m / rope.A))


def _kbm_amplitude(rope, a0, t):
    l0, u = rope.length.l0, rope.length.u
    l = l0 - u * t
    D = _kbm_D(rope)
    ratio = l / l0
    moving = u != 0
    safe_u = jnp.where(moving, u, 1.0)
    # (l0^(5/4) l^(1/4) - l^(3/2)) / u, and its u -> 0 limit (5/4) sqrt(l0) t
    gap = jnp.where(moving, (l0**1.25 * l**0.25 - l**1.5) / safe_u, 1.25 * jnp.sqrt(l0) * t)
    return jnp.maximum(a0 * ratio**0.25 - 0.8 * D * gap, 0.0)


def _kbm_printed(rope, a0, t):
    """The paper's printed (2.7), kept only to show that it does not solve (2.6)."""
    l0, u = rope.length.l0, rope.length.u
    l = l0 - u * t
    D = _kbm_D(rope)
    return a0 * (l / l0) ** 0.25 - (D / u) * (4 / 7) * (l0**2 * l**0.25 / l0**0.25 - l**2)


def _kbm_frequency(rope, a, t):
    l = rope.length.length(t)
    omega = jnp.sqrt(rope.A * rope.e / (rope.m * l))
    return omega + 3 * rope.A * rope.d * a * a / (8 * rope.m * omega * l**3)


def kbm(rope, a0, t):
    """First-order amplitude and frequency at times `t` (refusing an unbounded swing)."""
    # first order ignores b and d: refuse an unbounded swing
    _, _, xp0, _ = _check_bounded(rope, a0)
    a = _kbm_amplitude(rope, a0 + 0 * xp0, t)
    return a, _kbm_frequency(rope, a, t)


# -- swing integrals of a quartic potential ---------------------------------------------------
def _poly(rope, l):
    """Coefficients `(c2, c3, c4)` of `V(x) = c2 x^2 + c3 x^3 + c4 x^4` at length `l`."""
    A = rope.A
    return A * rope.e / (2 * l), A * rope.b / (3 * l * l), A * rope.d / (4 * l**3)


def _quotient(c, p1, r1, r2):
    """`q(x)` with `-(c2 x^2 + c3 x^3 + c4 x^4) - p1 x + E = (x - r1)(x - r2) q(x)`:
    returns `(q2, q1, q0)`."""
    c2, c3, c4 = c
    sigma, prod = r1 + r2, r1 * r2
    q2 = -c4
    q1 = -c3 + sigma * q2
    q0 = -c2 + sigma * q1 - prod * q2
    return q2, q1, q0


def swing_nodes(r1, r2):
    """Quadrature of a swing between turning points `r1 < r2`: the nodes `x` of
    `x = (r1 + r2)/2 + (r2 - r1)/2 sin(theta)`, Gauss-Legendre in `theta` on `[-pi/2, pi/2]`,
    with their weights in `theta` and `cos(theta)`. Where the kinetic energy is
    `(x - r1)(r2 - x) q(x)` with `q` smooth, the time, action and loss integrands are analytic
    in `theta` and converge to machine precision."""
    centre, half = (r1 + r2) / 2, (r2 - r1) / 2
    theta, w = _quadrature()
    return centre + half * jnp.sin(theta), w, np.cos(theta)


def _swing_nodes(q, r1, r2):
    """`-q(x)` (> 0 between the roots) at the quadrature nodes."""
    x = swing_nodes(r1, r2)[0]
    return -((q[0] * x + q[1]) * x + q[2])


def _half_swing_time(rope, c, p1, r1, r2):
    """Time between turning points `r1`, `r2` of `E - V(x) - p1 x` [s]."""
    mq = _swing_nodes(_quotient(c, p1, r1, r2), r1, r2)
    return jnp.sum(_quadrature()[1] / jnp.sqrt(2 * mq / rope.m))


def _action(rope, c, r1, r2):
    """Action `(1/pi) int_{r1}^{r2} sqrt(2 m (E - V)) dx` of a frictionless swing [J s]."""
    mq = _swing_nodes(_quotient(c, 0.0, r1, r2), r1, r2)
    theta, w = _quadrature()
    half = (r2 - r1) / 2
    return (
        jnp.sqrt(2 * rope.m)
        * half
        * half
        / jnp.pi
        * jnp.sum(w * jnp.cos(theta) ** 2 * jnp.sqrt(mq))
    )


_UNBOUNDED = (
    "no turning point: the energy of the swing is above the potential barrier of "
    "the rope's quadratic/cubic law (the motion is unbounded)"
)


def _turning_point(c, E, side):
    """The turning point `x` on `side` (+-1) of `V(x) = E`, and whether it exists (found by a
    bracketing search; False above the potential barrier, `_UNBOUNDED`)."""
    c2, c3, c4 = c

    def f(y):  # E - V(side * y), positive inside the swing
        x = side * y
        return E - x * x * (c2 + x * (c3 + x * c4))

    y, bracketed = expanding_root(f, jnp.sqrt(jnp.maximum(E, 0.0) / c2))
    return side * y, bracketed


def _check_bounded(rope, a0):
    """Fail (`fail_if`) when a swing from `-a0` has no turning point at the initial length:
    `(c0, E0, x_plus, bounded)`."""
    c0 = _poly(rope, rope.length.l0)
    E0 = a0 * a0 * (c0[0] - a0 * c0[1] + a0 * a0 * c0[2])  # V(-a0)
    xp, bounded = _turning_point(c0, E0, 1.0)
    return c0, E0, fail_if(xp, jnp.logical_not(bounded), _UNBOUNDED), bounded


# -- exact energy map for a fixed length -------------------------------------------------------
def energy_map_sequence(rope, a0, n: int):
    """Turning points of a rope of fixed length from the exact half-swing energy map
    `W(x_k) = W(x_{k+1})`, `W = V + s A T x`, and the exact half-swing times."""
    c = _poly(rope, rope.length.l0)
    static = rope.friction_force()

    def swing(t, x, s, moving):  # (every lane solved: the root finder is cheap)
        p1 = s * static  # friction potential s A T x during the swing

        def g(y):  # (W(x) - W(x + s y)) / y: positive until the next turning point
            z = s * y
            c2, c3, c4 = c
            return s * (
                -(
                    c2 * (2 * x + z)
                    + c3 * (3 * x * x + 3 * x * z + z * z)
                    + c4 * (4 * x**3 + 6 * x * x * z + 4 * x * z * z + z**3)
                )
                - p1
            )

        y, bounded = expanding_root(g, 2 * jnp.abs(x))
        x1 = x + s * y
        dt = _half_swing_time(rope, c, p1, jnp.minimum(x, x1), jnp.maximum(x, x1))
        return bounded, RESULTS.unbounded, t + dt, x1

    return decay_scan(rope, a0, n, swing)


# -- action-based averaging ---------------------------------------------------------------------
def _swing_of_action(rope, I, l):
    """Energy, turning points and angular frequency of the frictionless swing of action `I` at
    length `l`, and whether the swing has both turning points: `(E, x_minus, x_plus, Omega,
    bounded)`."""
    c = _poly(rope, l)
    omega = jnp.sqrt(2 * c[0] / rope.m)

    def state(E):
        (xm, okm), (xp, okp) = _turning_point(c, E, -1.0), _turning_point(c, E, 1.0)
        return xm, xp, okm & okp

    def body(_, E):  # Newton on I(E) = I (concave increasing: monotone from below)
        xm, xp, _ = state(E)
        period = 2 * _half_swing_time(rope, c, 0.0, xm, xp)
        return E + (I - _action(rope, c, xm, xp)) * (2 * jnp.pi) / period

    E = lax.fori_loop(0, 30, body, I * omega)
    xm, xp, bounded = state(E)
    period = 2 * _half_swing_time(rope, c, 0.0, xm, xp)
    return E, xm, xp, 2 * jnp.pi / period, bounded


def action_law(rope, a0, ts):
    """Amplitude and frequency of the action-averaged law at times `ts` (see
    `vmj.action_amplitude`)."""
    c0, E0, xp0, bounded0 = _check_bounded(rope, a0)
    J0 = jnp.sqrt(_action(rope, c0, -a0, xp0))
    friction = rope.friction_force()
    tiny = 1e-9 * J0

    def field(t, y, args):  # J = sqrt(I): dJ/dt = -(A T/pi)(x_+ - x_-) / (2 J)
        J, _ = y  # (and the time spent above the potential barrier, checked after the solve)
        l = rope.length.length(t)
        alive = J > tiny
        Js = jnp.where(alive, J, J0)
        _, xm, xp, _, bounded = _swing_of_action(rope, Js * Js, l)
        dJ = jnp.where(alive, -friction / jnp.pi * (xp - xm) / (2 * Js), 0.0)
        return dJ, jnp.where(alive & ~bounded, 1.0, 0.0)

    def output(J, t):
        alive = J > tiny
        Js = jnp.where(alive, J, J0)
        _, xm, xp, Om, bounded = _swing_of_action(rope, Js * Js, rope.length.length(t))
        l = rope.length.length(t)
        return (
            jnp.where(alive, (xp - xm) / 2, 0.0),
            jnp.where(alive, Om, jnp.sqrt(rope.A * rope.e / (rope.m * l))),
            bounded | ~alive,
        )

    order = jnp.argsort(ts)  # any order of the requested times: solve sorted, then put back
    ts = ts[order]
    import diffrax as dfx  # only where an ODE is solved (light imports)
    import optimistix as optx

    def solved(_):
        # diffrax's Dopri8, whose stages run in a loop: the field (a Newton solve of I(E) with
        # two root finders per iteration) is then traced 4 times instead of 30 with vmj's
        # written-out stages (`dopri8()`, made for cheap vmapped fields); the first call
        # compiled in 3.0 s instead of 10.4, a warm one took 6.5 ms instead of 9.6, the
        # amplitudes agree to 2e-15. The steps are controlled by J's error alone (the time above
        # the barrier only counts); the values at `ts` come from the dense output, the
        # interpolant `SaveAt(ts=ts)` saves, without its check of `ts` (a host callback: JAX's
        # persistent compilation cache stores no program with one; `ts` were checked on the
        # host)
        sol = ode_solve(
            field,
            (J0, jnp.zeros_like(J0)),
            ts[-1],
            dfx.SaveAt(dense=True),
            rtol=1e-10,
            atol=1e-10 * J0,
            max_steps=100_000,
            solver=dfx.Dopri8(),
            norm=lambda y: optx.rms_norm(y[0]),
        )
        Js, above = jax.vmap(sol.evaluate)(ts)
        amp, freq, bounded = jax.vmap(output)(Js, ts)
        above = jnp.any((above > 0) & jnp.isfinite(above)) | ~jnp.all(bounded)
        return amp, freq, above, sol.result == dfx.RESULTS.successful

    def refused(_):  # a release above the barrier (`_check_bounded` fails): nothing to solve,
        nan = jnp.full_like(ts, jnp.nan)  # and a swing without turning points would make the
        return nan, nan, jnp.asarray(False), jnp.asarray(True)  # root finders run to their limit

    amp, freq, above, ok = lax.cond(bounded0, solved, refused, None)
    amp = fail_if(amp, above, _UNBOUNDED)
    amp = fail_if(amp, jnp.logical_not(ok), "the averaged (action) law's ODE solve failed")
    back = jnp.argsort(order)
    return amp[back], freq[back]


def half_swings_until(rope, a0, t1) -> int:
    """Upper estimate of the number of half-swings before `t1` [s] (a static count)."""
    l_min = float(rope.length.min_length(t1))
    a = float(a0) * 1.5 * max(1.0, (float(rope.length.length(t1)) / float(rope.length.l0)) ** 0.25)
    A, m = float(rope.A), float(rope.m)
    s = a / l_min
    k = A * (float(rope.e) + 2 * abs(float(rope.b)) * s + 3 * float(rope.d) * s * s) / l_min
    omega = np.sqrt(k / m)
    return int(np.ceil(1.2 * float(t1) * omega / np.pi)) + 4
