"""Closed forms and averaged laws of the rope model (`SYSTEMS.md` section 2).

- `kbm_amplitude`, `kbm_frequency`: the paper's first-order Krylov-Bogolyubov results, with the
  amplitude in the corrected form (the printed (2.7) does not solve (2.6)).
- `action_amplitude`, `action_frequency`: averaging on the exact action of the nonlinear rope
  (valid when the cubic term is not small): the action `I = (1/2 pi) oint p dx` is an adiabatic
  invariant of the slowly changing rope, so only friction changes it,
  `dI/dt = -(A T / pi) (x_+ - x_-)` (friction work `2 A T (x_+ - x_-)` per period times
  `dI/dE = 1/Omega = period/(2 pi)`), and the amplitude and frequency follow from `I` and `l`.
- `energy_map` (`turning_points(..., method="energy")`): for a fixed length the exact
  half-swing map `V(x_k) + s A T x_k = V(x_{k+1}) + s A T x_{k+1}`, with the half-swing times
  from the same energy integral.

The integrals over a swing between turning points `r1 < r2` of a quartic potential use
`x = (r1 + r2)/2 + (r2 - r1)/2 sin(theta)` after dividing `E - W(x)` by `(x - r1)(x - r2)`, so
the integrands are analytic and Gauss-Legendre quadrature converges to machine precision.
"""

from __future__ import annotations

import diffrax as dfx
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import lax

from ._checks import _is_traced, check, positive, warn_if_float32
from ._models import _float, validated
from ._rope import ConstantSpeed, Rope, check_horizon
from ._roots import bracketed_newton, implicit_step
from ._solution import RESULTS, DecaySequence
from ._solve import _require_scalar_fields, register_solver

__all__ = ["kbm_amplitude", "kbm_frequency", "action_amplitude", "action_frequency",
           "rope_energy_map"]

_NODES, _WEIGHTS = np.polynomial.legendre.leggauss(40)
_THETA = 0.5 * np.pi * _NODES  # Gauss-Legendre nodes on [-pi/2, pi/2]
_W = 0.5 * np.pi * _WEIGHTS
ROOT_ITERATIONS = 60


# -- shared checks ----------------------------------------------------------------------------
def _constant_speed(rope) -> None:
    if not isinstance(rope, Rope):
        raise ValueError(f"rope must be a vmj.Rope (got {type(rope).__name__})")
    if not isinstance(rope.length, ConstantSpeed):
        raise ValueError("the averaged laws need a vmj.ConstantSpeed length profile "
                         f"(got {type(rope.length).__name__})")


def _times(rope, t):
    t = check("t", t, lambda x: x >= 0, ">= 0 [s]")
    check_horizon(rope, t, "t")
    return _float(t)


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
    gap = jnp.where(moving, (l0 ** 1.25 * l ** 0.25 - l ** 1.5) / safe_u, 1.25 * jnp.sqrt(l0) * t)
    return jnp.maximum(a0 * ratio ** 0.25 - 0.8 * D * gap, 0.0)


def _kbm_printed(rope, a0, t):
    """The paper's printed (2.7), kept only to show that it does not solve (2.6)."""
    l0, u = rope.length.l0, rope.length.u
    l = l0 - u * t
    D = _kbm_D(rope)
    return a0 * (l / l0) ** 0.25 - (D / u) * (4 / 7) * (l0 ** 2 * l ** 0.25 / l0 ** 0.25 - l ** 2)


def _kbm_frequency(rope, a, t):
    l = rope.length.length(t)
    omega = jnp.sqrt(rope.A * rope.e / (rope.m * l))
    return omega + 3 * rope.A * rope.d * a * a / (8 * rope.m * omega * l ** 3)


@eqx.filter_jit
def _kbm(rope, a0, t):
    rope = validated(rope)
    _, _, xp0 = _check_bounded(rope, a0)  # first order ignores b and d: refuse an unbounded swing
    a = _kbm_amplitude(rope, a0 + 0 * xp0, t)
    return a, _kbm_frequency(rope, a, t)


def _kbm_entry(rope, a0, t):
    warn_if_float32()
    _constant_speed(rope)
    _require_scalar_fields(rope)
    a0 = check("a0", a0, positive, "> 0 [m]")
    return _kbm(rope, _float(a0), _times(rope, t))


def kbm_amplitude(rope: Rope, a0, t):
    """First-order (Krylov-Bogolyubov) amplitude of the paper, corrected (`SYSTEMS.md` s. 2):

        a(t) = a0 (l/l0)^(1/4) - (4 D / (5 u)) (l0^(5/4) l^(1/4) - l^(3/2)),
        a(t) = a0 - D sqrt(l0) t  for u = 0,   D = 2 T / (pi sqrt(e m / A)),

    the solution of `da/dt = -a u/(4 l) - D sqrt(l)` (the paper's (2.6)); clipped at 0 once
    friction has stopped the motion. The cubic and quadratic terms do not enter at first order.

    **Arguments:** `rope` ([`vmj.Rope`][] with a [`vmj.ConstantSpeed`][] profile), `a0` [m] `> 0`,
    `t` [s] (array), `0 <= t` below the zero-length time `l0/u`.
    **Returns:** the amplitude [m] at each `t`. Differentiable in every parameter.
    """
    return _kbm_entry(rope, a0, t)[0]


def kbm_frequency(rope: Rope, a0, t):
    """First-order frequency (the paper's (2.9)) [rad/s]:
    `Omega = omega + 3 A d a^2 / (8 m omega l^3)`, `omega = sqrt(A e/(m l))`, with `a` from
    [`vmj.kbm_amplitude`][]. Arguments as for [`vmj.kbm_amplitude`][]."""
    return _kbm_entry(rope, a0, t)[1]


# -- swing integrals of a quartic potential ---------------------------------------------------
def _poly(rope, l):
    """Coefficients `(c2, c3, c4)` of `V(x) = c2 x^2 + c3 x^3 + c4 x^4` at length `l`."""
    A = rope.A
    return A * rope.e / (2 * l), A * rope.b / (3 * l * l), A * rope.d / (4 * l ** 3)


def _quotient(c, p1, r1, r2):
    """`q(x)` with `-(c2 x^2 + c3 x^3 + c4 x^4) - p1 x + E = (x - r1)(x - r2) q(x)`:
    returns `(q2, q1, q0)`."""
    c2, c3, c4 = c
    sigma, prod = r1 + r2, r1 * r2
    q2 = -c4
    q1 = -c3 + sigma * q2
    q0 = -c2 + sigma * q1 - prod * q2
    return q2, q1, q0


def _swing_nodes(q, r1, r2):
    """`-q(x)` (> 0 between the roots) at the quadrature nodes."""
    centre, half = (r1 + r2) / 2, (r2 - r1) / 2
    x = centre + half * jnp.sin(_THETA)
    return -((q[0] * x + q[1]) * x + q[2])


def _half_swing_time(rope, c, p1, r1, r2):
    """Time between turning points `r1`, `r2` of `E - V(x) - p1 x` [s]."""
    mq = _swing_nodes(_quotient(c, p1, r1, r2), r1, r2)
    return jnp.sum(_W / jnp.sqrt(2 * mq / rope.m))


def _action(rope, c, r1, r2):
    """Action `(1/pi) int_{r1}^{r2} sqrt(2 m (E - V)) dx` of a frictionless swing [J s]."""
    mq = _swing_nodes(_quotient(c, 0.0, r1, r2), r1, r2)
    half = (r2 - r1) / 2
    return jnp.sqrt(2 * rope.m) * half * half / jnp.pi * jnp.sum(
        _W * jnp.cos(_THETA) ** 2 * jnp.sqrt(mq))


def _root(f, hi):
    """Root of `f` on `(0, hi]` with `f(0+) > 0 >= f(hi)` (hi doubled until it brackets):
    safeguarded Newton, then one Newton step with gradients (implicit differentiation).
    Returns `(root, bracketed)`; `bracketed` is False when no root was found (an unbounded
    swing over the potential barrier)."""
    fs = lambda y: lax.stop_gradient(f(y))  # noqa: E731
    hi = lax.stop_gradient(hi)
    for _ in range(8):
        hi = jnp.where(fs(hi) > 0, 2 * hi, hi)
    # (a root at hi itself may evaluate to a rounding-level positive value)
    bracketed = fs(hi) <= 1e-12 * jnp.abs(fs(0.5 * hi))
    y = bracketed_newton(fs, jax.grad(fs), jnp.zeros_like(hi), hi, hi, ROOT_ITERATIONS)
    return implicit_step(f, jax.grad(f), y), bracketed


_UNBOUNDED = ("no turning point: the energy of the swing is above the potential barrier of "
              "the rope's quadratic/cubic law (the motion is unbounded)")


def _turning_point(c, E, side):
    """The turning point `x` on `side` (+-1) of `V(x) = E`."""
    c2, c3, c4 = c

    def f(y):  # E - V(side * y), positive inside the swing
        x = side * y
        return E - x * x * (c2 + x * (c3 + x * c4))

    y, bracketed = _root(f, jnp.sqrt(jnp.maximum(E, 0.0) / c2))
    y = eqx.error_if(y, jnp.logical_not(bracketed), _UNBOUNDED)
    return side * y


def _check_bounded(rope, a0):
    """Raise (inside jit) when a swing from `-a0` has no turning point at the initial length."""
    c0 = _poly(rope, rope.length.l0)
    E0 = a0 * a0 * (c0[0] - a0 * c0[1] + a0 * a0 * c0[2])  # V(-a0)
    return c0, E0, _turning_point(c0, E0, 1.0)


# -- exact energy map for a fixed length -------------------------------------------------------
def energy_map_sequence(rope: Rope, a0, n: int) -> DecaySequence:
    """Turning points of a rope of fixed length from the exact half-swing energy map."""
    u = rope.length.u
    rope = eqx.tree_at(lambda r: r.T, rope, eqx.error_if(
        rope.T, u != 0, "the energy map needs a rope of fixed length (u = 0)"))
    l = rope.length.l0
    c = _poly(rope, l)
    static = rope.friction_force()

    def body(carry, _):
        t, x, code = carry
        active = code == RESULTS.successful
        force = -rope.spring(t, x)
        s = jnp.where(force >= 0, 1.0, -1.0)
        stuck = jnp.abs(force) <= static
        p1 = s * static  # friction potential s A T x during the swing

        def g(y):  # (W(x) - W(x + s y)) / y, W = V + p1 x: positive until the next turning point
            z = s * y
            c2, c3, c4 = c
            return s * (-(c2 * (2 * x + z) + c3 * (3 * x * x + 3 * x * z + z * z)
                          + c4 * (4 * x ** 3 + 6 * x * x * z + 4 * x * z * z + z ** 3)) - p1)

        y, bounded = _root(g, 2 * jnp.abs(x))
        x1 = x + s * y
        lo, hi = jnp.minimum(x, x1), jnp.maximum(x, x1)
        dt = _half_swing_time(rope, c, p1, lo, hi)
        code = jnp.where(active & stuck, RESULTS.stopped,
                         jnp.where(active & jnp.logical_not(bounded), RESULTS.unbounded, code))
        advance = active & (code == RESULTS.successful)
        crossed = advance & (x1 * x < 0)
        t = jnp.where(advance, t + dt, t)
        x = jnp.where(advance, x1, x)
        return (t, x, code), (t, x, crossed, advance)

    x0 = -a0 * jnp.ones_like(rope.m)
    init = (jnp.zeros_like(x0), x0, jnp.array(RESULTS.successful))
    (t, x, code), (times, positions, crossed, advanced) = lax.scan(body, init, None, length=n)
    stuck = jnp.abs(rope.spring(t, x)) <= static
    code = jnp.where((code == RESULTS.successful) & stuck, RESULTS.stopped, code)
    return DecaySequence.from_scan(times, positions, crossed, advanced, code)


@register_solver(Rope, "energy")
def _rope_energy(model, a0, n, *, smoothing, max_substeps):
    return energy_map_sequence(model, a0, n)


def rope_energy_map(rope: Rope, a0, n: int, *, throw: bool = False) -> DecaySequence:
    """Exact turning points of a rope of fixed length (`u = 0`) from the energy balance over
    each half-swing, `V(x_k) - V(x_{k+1}) = A T |x_k - x_{k+1}|` (for `b = 0`:
    `V(a_k) - V(-a_{k+1}) = A T (a_k + a_{k+1})`), solved per swing; the times are the exact
    half-swing durations (energy integral, Gauss-Legendre). Same as
    `vmj.turning_points(rope, a0, n, method="energy")`.

    **Arguments:** `rope` ([`vmj.Rope`][] with `vmj.ConstantSpeed(l0, 0.0)`), `a0` [m] `> 0`,
    `n` (number of turning points). **Returns:** a [`vmj.DecaySequence`][].
    """
    from ._solve import turning_points

    _constant_speed(rope)
    u = rope.length.u
    if not _is_traced(u) and float(u) != 0:
        raise ValueError(f"u must be 0 for the energy map (a rope of fixed length; got {float(u)})")
    return turning_points(rope, a0, n, method="energy", throw=throw)


# -- action-based averaging ---------------------------------------------------------------------
def _swing_of_action(rope, I, l):
    """Energy, turning points and angular frequency of the frictionless swing of action `I` at
    length `l`: `(E, x_minus, x_plus, Omega)`."""
    c = _poly(rope, l)
    omega = jnp.sqrt(2 * c[0] / rope.m)

    def state(E):
        xm, xp = _turning_point(c, E, -1.0), _turning_point(c, E, 1.0)
        return xm, xp

    def body(_, E):  # Newton on I(E) = I (concave increasing: monotone from below)
        xm, xp = state(E)
        period = 2 * _half_swing_time(rope, c, 0.0, xm, xp)
        return E + (I - _action(rope, c, xm, xp)) * (2 * jnp.pi) / period

    E = lax.fori_loop(0, 30, body, I * omega)
    xm, xp = state(E)
    period = 2 * _half_swing_time(rope, c, 0.0, xm, xp)
    return E, xm, xp, 2 * jnp.pi / period


@eqx.filter_jit
def _action_solve(rope, a0, ts):
    rope = validated(rope)
    c0, E0, xp0 = _check_bounded(rope, a0)
    J0 = jnp.sqrt(_action(rope, c0, -a0, xp0))
    friction = rope.friction_force()
    tiny = 1e-9 * J0

    def field(t, J, args):  # J = sqrt(I): dJ/dt = -(A T/pi)(x_+ - x_-) / (2 J)
        l = rope.length.length(t)
        alive = J > tiny
        Js = jnp.where(alive, J, J0)
        _, xm, xp, _ = _swing_of_action(rope, Js * Js, l)
        return jnp.where(alive, -friction / jnp.pi * (xp - xm) / (2 * Js), 0.0)

    order = jnp.argsort(ts)  # any order of the requested times: solve sorted, then put back
    ts = ts[order]
    t1 = ts[-1]
    sol = dfx.diffeqsolve(
        dfx.ODETerm(field), dfx.Tsit5(), t0=0.0, t1=t1, dt0=None, y0=J0,
        saveat=dfx.SaveAt(ts=ts),
        stepsize_controller=dfx.PIDController(rtol=1e-10, atol=1e-10 * J0),
        max_steps=100_000, throw=False,
    )
    Js = sol.ys

    def output(J, t):
        alive = J > tiny
        Js = jnp.where(alive, J, J0)
        _, xm, xp, Om = _swing_of_action(rope, Js * Js, rope.length.length(t))
        l = rope.length.length(t)
        return jnp.where(alive, (xp - xm) / 2, 0.0), jnp.where(
            alive, Om, jnp.sqrt(rope.A * rope.e / (rope.m * l)))

    amp, freq = jax.vmap(output)(Js, ts)
    ok = sol.result == dfx.RESULTS.successful
    amp = eqx.error_if(amp, jnp.logical_not(ok), "the averaged (action) law's ODE solve failed")
    back = jnp.argsort(order)
    return amp[back], freq[back]


def _action_entry(rope, a0, t):
    warn_if_float32()
    _constant_speed(rope)
    _require_scalar_fields(rope)
    a0 = check("a0", a0, positive, "> 0 [m]")
    ts = jnp.atleast_1d(_times(rope, t))
    amp, freq = _action_solve(rope, jnp.asarray(a0, dtype=ts.dtype), ts)
    shape = jnp.shape(t)
    return amp.reshape(shape), freq.reshape(shape)


def action_amplitude(rope: Rope, a0, t):
    """Averaged amplitude from the action of the nonlinear rope, valid when the cubic term is
    not small (beyond the paper's first order).

    The action `I(E, l) = (1/pi) int sqrt(2 m (E - V(x, l))) dx` over a swing is an adiabatic
    invariant of the slowly changing length, so only friction changes it:
    `dI/dt = -(A T/pi)(x_+ - x_-)`, with the turning points `x_+-` of the swing of action `I` at
    the current length. Integrated with diffrax in `J = sqrt(I)`. Returns the half peak-to-peak
    amplitude `(x_+ - x_-)/2` [m] (the amplitude for `b = 0`), 0 once friction has stopped the
    motion. With `d = b = 0` it reduces to [`vmj.kbm_amplitude`][].

    **Arguments:** `rope` ([`vmj.Rope`][] with a [`vmj.ConstantSpeed`][] profile), `a0` [m] `> 0`
    (release from rest at `x = -a0`), `t` [s] (array, `>= 0`, below the zero-length time).
    """
    return _action_entry(rope, a0, t)[0]


def action_frequency(rope: Rope, a0, t):
    """Angular frequency `2 pi / period` [rad/s] of the swing of the action-averaged law (the
    amplitude-dependent frequency of the nonlinear rope), at times `t` [s]. Arguments as for
    [`vmj.action_amplitude`][]."""
    return _action_entry(rope, a0, t)[1]


def half_swings_until(rope: Rope, a0, t1) -> int:
    """Upper estimate of the number of half-swings before `t1` [s] (a static count)."""
    l_min = float(rope.length.min_length(t1))
    a = float(a0) * 1.5 * max(1.0, (float(rope.length.length(t1)) / float(rope.length.l0)) ** 0.25)
    A, m = float(rope.A), float(rope.m)
    s = a / l_min
    k = A * (float(rope.e) + 2 * abs(float(rope.b)) * s + 3 * float(rope.d) * s * s) / l_min
    omega = np.sqrt(k / m)
    return int(np.ceil(1.2 * float(t1) * omega / np.pi)) + 4

