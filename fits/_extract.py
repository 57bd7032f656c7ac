"""Turning points of a raw signal: the decay located, noise measured, spikes and clipping
removed, each extremum refined, the dry-friction level read off the decrements.
"""

from __future__ import annotations

import functools
import math
from typing import NamedTuple

import numpy as np

from ._record import EDGE_RELEASE, HELD_RELEASE, Record
from ._signal import Signal
from ._text import fail


class _NoDecay(ValueError):
    """A signal that holds no decay to extract (constant, noise, growing): where the file has
    other columns, the message names them."""


# -- turning points of a raw signal ------------------------------------------------------------
def _noise(t, y) -> float:
    """Robust noise level of a sampled signal [signal units].

    The smallest of MAD estimates from differences that cancel the smooth signal: the
    deviation from linear interpolation between neighbours in time (any sampling), and the 3rd
    and 4th differences of successive samples (an oversampled oscillation's curvature
    dominates the 2nd differences, not its noise; and where the stamps are wrong, the samples'
    order still holds). Each overestimates where it does not apply, so the smallest is taken.
    Never below the quantisation noise `q / sqrt(12)` of a signal read in steps of `q` (the
    smallest change between samples; the MAD of a signal that mostly repeats its value would
    be zero)."""
    if len(y) < 7:
        return 0.0
    h1, h2 = t[1:-1] - t[:-2], t[2:] - t[1:-1]
    ok = (h1 > 0) & (h2 > 0)
    interp = (y[:-2] * h2 + y[2:] * h1) / np.where(ok, h1 + h2, 1.0)
    d = (y[1:-1] - interp)[ok]
    w = np.sqrt(1 + (h1**2 + h2**2) / (h1 + h2) ** 2)[ok]  # std of d for white noise of unit std
    estimates = [1.4826 * float(np.median(np.abs(d - np.median(d)) / w))] if d.size else []
    for order in (3, 4):
        dk = np.diff(y, order)
        estimates.append(
            1.4826
            * float(np.median(np.abs(dk - np.median(dk))))
            / math.sqrt(math.comb(2 * order, order))
        )
    return max(min(estimates) if estimates else 0.0, _quantum(y) / math.sqrt(12))


def _quantum(y) -> float:
    """The smallest change between successive samples (the step of a quantised signal;
    changes below 1e-12 of the signal's size are rounding)."""
    steps = np.abs(np.diff(y))
    steps = steps[steps > 1e-12 * max(float(np.max(np.abs(y))), 1e-300)]
    return float(np.min(steps)) if steps.size else 0.0


def _despike(t, y, sigma, threshold, keep=None):
    """Replace isolated spikes: a sample farther than `threshold` noise standard deviations
    (`sigma`) from the cubic through its two neighbours on either side (at times `t`) is
    replaced by that cubic's value, unless `keep` (a mask) holds it. A smooth oscillation
    sampled `N` times per period departs from the cubic by about `(2 pi / N)^4 / 6` of its
    amplitude (4e-3 at `N = 16`, 7e-4 at 25), so this is for signals of at least 16 samples
    per period (`_SMOOTH_MIN`). (A running median of 5 samples took a swing's peak for a spike
    below about 30 samples per period: on synthetic records at 25, the extrema 4 times the
    noise off, against 0.6 times without it; on the pendulum records 60, 70 and 90p.txt, 1-10
    peak samples of swings of 30 deg.)"""
    if len(y) < 5:
        return y
    tc, others = t[2:-2], [t[:-4], t[1:-3], t[3:-1], t[4:]]
    values = [y[:-4], y[1:-3], y[3:-1], y[4:]]
    weights = []
    for j, tj in enumerate(others):
        w = np.ones_like(tc)
        for m, tm in enumerate(others):
            if m != j:
                w = w * (tc - tm) / (tj - tm)
        weights.append(w)
    cubic = sum(w * v for w, v in zip(weights, values))
    sd = sigma * np.sqrt(1.0 + sum(w * w for w in weights))
    candidate = np.zeros(y.shape, dtype=bool)
    candidate[2:-2] = np.abs(y[2:-2] - cubic) > threshold * sd
    if keep is not None:
        candidate &= ~keep
    # a spike throws its neighbours' cubics off too (unevenly spaced samples: by more than
    # itself): of the candidates within two samples the spike is the one farthest from the
    # running median of 5
    median = np.median(np.lib.stride_tricks.sliding_window_view(np.pad(y, 2, mode="edge"), 5), 1)
    score = np.where(candidate, np.abs(y - median), -1.0)
    nearby = np.max(np.lib.stride_tricks.sliding_window_view(np.pad(score, 2), 5), axis=1)
    spike = candidate & (score >= nearby)
    out = y.copy()
    out[2:-2][spike[2:-2]] = cubic[spike[2:-2]]
    return out


def _zigzag(y, h):
    """Indices of alternating extrema that the signal leaves by more than `h` (peak detection
    with hysteresis: noise wiggles smaller than `h` are no turning points)."""
    idx = []
    i_max = i_min = 0
    direction = 0  # +1 looking for a max, -1 for a min, 0 undecided
    for i in range(1, len(y)):
        if y[i] > y[i_max]:
            i_max = i
        if y[i] < y[i_min]:
            i_min = i
        if direction >= 0 and y[i_max] - y[i] > h:
            idx.append(i_max)
            direction, i_min = -1, i
        elif direction <= 0 and y[i] - y[i_min] > h:
            idx.append(i_min)
            direction, i_max = 1, i
    return np.asarray(idx, dtype=int)


#: how far a faster oscillation's spectral line stands above the noise's median bin
_LINE = 300.0
#: the swing's harmonics that are its shape, not another oscillation (`_faster_period`)
_HARMONICS = 9
#: the weakest faster oscillation taken for one, in amplitude relative to the swing's spectral
#: peak (`_faster_period`): a sinusoid this small moves a turning point by less than 1e-4 of
#: the swing; on a signal without noise (a simulation's output) the swing's higher harmonics
#: stand far above the empty bins around them, at 1e-6 to 3e-5 of its peak
_LINE_FLOOR = 1e-4


def _faster_period(t, y) -> tuple | None:
    """`(samples per period, angular frequency [rad/s])` of an oscillation faster than the
    decay's that rides on it (mains hum, a higher mode of the structure), or `None`. The
    signal less its average over a quarter of its half-swing (from the spectrum's highest
    peak) holds the noise and what is faster; there, above 1.5 times the decay's
    frequency, a spectral line (a local peak `_LINE` times the median of the bins around it:
    white noise's highest bin is some 15 times it) is such an oscillation, away from the
    swing's own harmonics (up to the `_HARMONICS`-th, +-0.15 of the swing's frequency, and
    their skirts: the shape of a pendulum's large swings, not another oscillation) and at
    least `_LINE_FLOOR` of the swing's peak in amplitude (else, on a signal without noise, a
    higher harmonic of a kinked or chirping swing would be taken for one). A decaying higher
    mode whose power is spread over a band is not found."""
    dt = float(np.median(np.diff(t)))
    window = np.hanning(y.size)
    n = 1 << (y.size - 1).bit_length()  # (a fast length: zeros after the data)
    f = np.fft.rfftfreq(n, dt)
    power = np.abs(np.fft.rfft((y - y.mean()) * window, n)) ** 2
    slow = np.flatnonzero(f > 2 / (y.size * dt))  # (not a drift)
    if slow.size < 16:
        return None
    main = slow[np.argmax(power[slow])]  # the swing's bin
    main_half = 1 / (2 * f[main] * dt)  # [samples]
    floor = _LINE_FLOOR**2 * float(power[main])
    rest = y - _smooth(y, max(2, int(main_half // 4)))
    power = np.abs(np.fft.rfft((rest - rest.mean()) * window, n)) ** 2
    ratio = f * (2 * main_half * dt)  # (multiples of the swing's frequency)
    harmonic = (np.round(ratio) <= _HARMONICS) & (np.abs(ratio - np.round(ratio)) < 0.15)
    usable = (ratio > 1.5) & ~harmonic
    lobe = int(math.ceil(2 * n / y.size))  # the window's main lobe [bins]
    peaks = (
        np.flatnonzero(usable[1:-1] & (power[1:-1] >= power[:-2]) & (power[1:-1] >= power[2:])) + 1
    )
    for k in peaks[np.argsort(power[peaks])[::-1][:8]]:
        if k - lobe < 0 or k + lobe >= f.size or not np.all(usable[k - lobe : k + lobe + 1]):
            continue  # (on a harmonic's skirt)
        around = np.r_[max(k - 16 * lobe, 0) : k - lobe, k + lobe + 1 : k + 16 * lobe + 1]
        around = around[around < f.size]
        around = around[usable[around]]
        if around.size >= 4 and power[k] >= max(_LINE * np.median(power[around]), floor):
            break
    else:
        return None
    shift = 0.0
    if 0 < k < f.size - 1 and np.all(power[k - 1 : k + 2] > 0):
        a, b, c = np.log(power[k - 1 : k + 2])
        shift = 0.5 * (a - c) / (a - 2 * b + c) if a - 2 * b + c < 0 else 0.0
    rate = float(f[k] + shift * (f[1] - f[0]))
    return max(2, int(round(1 / (rate * dt)))), 2 * np.pi * rate


def _smooth(y, width: int) -> np.ndarray:
    """`y` averaged twice over `width` samples (a triangle of `2 width - 1`): an oscillation of
    `width` samples per period (and its multiples) removed, a much slower one kept but for
    `1 - sinc(width / P)^2` of its amplitude. Used only to find the turning points."""
    out = y
    for left in (width // 2, (width - 1) // 2):  # (the two passes' shifts cancel)
        padded = np.concatenate([[0.0], np.full(left, out[0]), out, np.full(width, out[-1])])
        sums = np.cumsum(padded)
        out = (sums[width:] - sums[:-width])[: y.size] / width
    return out


def _harmonic_noise(t, y, idx) -> float:
    """Noise level [signal units] of a signal of few samples per period, from the residuals of
    the arcs through the samples within the mean half-period of each extremum `idx` (`c0 +
    c1 cos(w tau) + c2 sin(w tau) + c3 sign(tau) (1 - cos(w tau))`, the last the dry-friction
    kink of `_refine`), each standardised by its leverage; 1.4826 times their median absolute
    value (inf with fewer than 10). The differences of `_noise` see the swings' curvature
    there: at 8 samples per period, a signal without a tail at rest, 0.04 for noise of 1e-4
    (this: 6e-4, the damping within the arcs; 0.033 for noise of 0.02)."""
    if len(idx) < 3:
        return math.inf
    hp = (t[idx[-1]] - t[idx[0]]) / (len(idx) - 1)  # (each interval is a sample period off)
    rate = math.pi / hp
    z = []
    for i in idx:
        lo, hi = np.searchsorted(t, [t[i] - hp, t[i] + hp])
        tau = t[lo:hi] - t[i]
        if tau.size < 6:
            continue
        cos, sin = np.cos(rate * tau), np.sin(rate * tau)
        basis = np.column_stack([np.ones_like(tau), cos, sin, np.sign(tau) * (1.0 - cos)])
        q, _ = np.linalg.qr(basis)
        resid = y[lo:hi] - q @ (q.T @ y[lo:hi])
        leverage = np.sum(q * q, axis=1)
        keep = leverage < 1.0 - 1e-9
        z.extend(resid[keep] / np.sqrt(1.0 - leverage[keep]))
    return 1.4826 * float(np.median(np.abs(z))) if len(z) >= 10 else math.inf


def _local_half_periods(times) -> np.ndarray:
    """Each extremum's local half-period [s]: the median of the 4 nearest intervals between
    the extrema at `times` (robust to a hold before the release)."""
    gaps = np.diff(times)
    return np.array([np.median(gaps[max(0, i - 2) : i + 2]) for i in range(len(times))])


def _samples_per_half_period(idx) -> float:
    """Mean number of samples between the successive extrema at the sample indices `idx`; inf
    with fewer than 3 extrema."""
    return (idx[-1] - idx[0]) / (idx.size - 1) if idx.size >= 3 else math.inf


#: the least samples per half-period of a signal whose turning points are extracted (a
#: sinusoid through the samples near each, `_refine_harmonic`)
_SAMPLES_MIN = 3
#: the least samples per half-period at which the swings are smooth over a few samples: isolated
#: spikes are removed (`_despike`) and the noise is measured from differences (`_noise`); below
#: it from sinusoids through the samples near each extremum (`_harmonic_noise`)
_SMOOTH_MIN = 8
_WINDOW = 0.4  #: half-width of the local fit around an extremum, in local half-periods


def _refine(t, y, i, half, peak, kink=0.0, degree=4, fast=None):
    """Time and value of the extremum near sample `i`: a least-squares polynomial of `degree`
    (a quartic by default; where fewer than `degree + 3` samples fall inside, a sinusoid:
    `_refine_harmonic`) through the samples within `0.4 half` of it, less the dry-friction kink `kink sign(tau)
    (1 - cos(pi tau / half))` about its vertex, the vertex nearest the centre, the window
    re-centred on that vertex twice. `half` is the local
    half-period [s]; `peak` says a maximum is sought (else a minimum). The sample itself is
    kept where the fit has no such vertex inside the window.

    The kink: at a turning point with Coulomb friction the friction force reverses, and the
    motion is an arc of a cosine about the centre shifted by the friction level `xF` on one
    side and by `-xF` on the other: `kink = xF` at a maximum, `-xF` at a minimum [signal
    units] (a record's level, from the decay of its extrema: `_dry_level`). A smooth quartic
    through such a turning point times it late by about `0.07 half xF / a` (`a` the
    amplitude).

    At 37 samples per half-period (the pendulum records) and noise of 0.2 % of the amplitude
    this times an extremum to about 0.2 ms (a twentieth of a sample period) and biases its value
    by less than 1e-3 of the amplitude for a sinusoid; the window is wide enough that quantised
    or flat-topped peaks still show their curvature.

    `fast` [rad/s]: the angular frequency of a faster oscillation on the signal
    (`_faster_period`): a sinusoid at it is fitted with the polynomial (its two terms, a few
    of its periods in the window), so that it does not move the vertex."""
    width = _WINDOW * half
    rate = math.pi / half  # the local angular frequency [rad/s]
    centre, value = t[i], y[i]
    for _ in range(3 if kink else 2):
        lo, hi = np.searchsorted(t, [centre - width, centre + width], side="left")
        lo, hi = max(lo, 0), min(hi + 1, len(t))
        tau = (t[lo:hi] - centre) / width
        inside = np.abs(tau) <= 1.0
        tau, ys = tau[inside], y[lo:hi][inside]
        if tau.size < degree + 3:
            return _refine_harmonic(t, y, i, half, peak, kink)
        bump = np.sign(tau) * (1.0 - np.cos(rate * width * tau))
        design = np.vander(tau, degree + 1)
        if fast is not None:
            phase = fast * width * tau
            design = np.column_stack([design, np.cos(phase), np.sin(phase)])
        c = np.linalg.lstsq(design, ys - kink * bump, rcond=None)[0][: degree + 1]
        slope = np.polyder(c)  # (coefficients highest power first)
        roots = np.roots(slope)
        roots = roots[np.abs(roots.imag) < 1e-9].real
        curv = np.polyval(np.polyder(slope), roots)
        roots = roots[(np.abs(roots) <= 1.0) & ((curv < 0) if peak else (curv > 0))]
        if roots.size == 0:
            return t[i], y[i]
        u = roots[np.argmin(np.abs(roots))]
        value = float(np.polyval(c, u) + kink * np.sign(u) * (1.0 - math.cos(rate * width * u)))
        centre = centre + u * width
    return float(centre), value


def _refine_harmonic(t, y, i, half, peak, kink=0.0):
    """`_refine` where too few samples fall in its window for a quartic (below about 16
    samples per period): a sinusoid at the local rate `w = pi / half`, `c0 + c1 cos(w tau) +
    c2 sin(w tau)`, through the samples within `half / 2` of the extremum (the motion between
    two turning points is such an arc, about a centre shifted by the dry-friction `kink` on
    either side of the vertex, subtracted as in `_refine`; with `0.75 half` neighbouring
    windows shared samples, and zeta's errors over 24 fits at 12 samples per period were 1.35
    of its standard errors), its
    vertex the extremum, the window re-centred on it twice. The sample itself is kept where
    fewer than 3 samples fall inside."""
    rate = math.pi / half
    width = 0.5 * half
    centre, value = t[i], y[i]
    for _ in range(3):
        lo, hi = np.searchsorted(t, [centre - width, centre + width], side="left")
        lo, hi = max(lo, 0), min(hi + 1, len(t))
        tau = t[lo:hi] - centre
        inside = np.abs(tau) <= width
        tau, ys = tau[inside], y[lo:hi][inside]
        if tau.size < 3:
            return t[i], y[i]
        bump = np.sign(tau) * (1.0 - np.cos(rate * tau))
        basis = np.column_stack([np.ones_like(tau), np.cos(rate * tau), np.sin(rate * tau)])
        c0, c1, c2 = np.linalg.lstsq(basis, ys - kink * bump, rcond=None)[0]
        amplitude = math.hypot(c1, c2)
        # c1 cos + c2 sin = amplitude cos(w tau - phi): a maximum at w tau = phi, a minimum at
        # phi + pi, the one nearest the window's centre
        phase = math.atan2(c2, c1) + (0.0 if peak else math.pi)
        u = (phase + math.pi) % (2 * math.pi) - math.pi
        if abs(u) > rate * width:
            return t[i], y[i]
        value = float(c0 + (amplitude if peak else -amplitude))
        centre = centre + u / rate
    return float(centre), value


def _shape_bias(x4, x6, raw, usable) -> np.ndarray:
    """The bias of the quartic's extremum values `x4` where the waveform is not quartic near
    its extrema over the fitting window (a pendulum's swings far from sinusoidal), from their
    difference with sextic fits `x6` through the same samples (unbiased, but noisier: +23 % in
    the values and +70 % in the times, measured on synthetic pendulum records with noise 0.2 %
    of the amplitude), smoothed over the record: `x4 - x6 = s f(a)` for extrema at distance
    `a` from the median centre on side `s`, `f(a) = b1 a + b3 a^3 + b5 a^5` by least squares
    over the `usable` extrema whose fits found a vertex (`raw` the extrema's samples: a fit
    that did not keeps them), the first left out (a hold before the release is no vertex,
    and a release at the signal's start is fitted from one side). Returns the bias to
    subtract (`s f(a)`, not extrapolated beyond the largest amplitude fitted) where `f` is
    significant (somewhere over the record's amplitudes more than 3 standard errors from 0),
    else zeros: where the quartic suffices its values are kept as they are.

    Measured (noise-free synthetic pendulum records, sine law, the extrema above half the
    release): the quartic overstates the amplitudes by 1.5e-3 deg released from 27 deg, 2.8e-3
    from 60 deg and 4.3e-2 from 120 deg (half the scatter of a turning point at 0.2 %
    noise there), a trend in the amplitude that a fit reads as quadratic drag."""
    x4, x6 = np.asarray(x4, dtype=float), np.asarray(x6, dtype=float)
    ok = usable & (x4 != raw) & (x6 != raw) & np.isfinite(x6)
    ok[0] = False  # the first extremum may be a hold before the release, or cut by the start
    out = np.zeros_like(x4)
    if np.count_nonzero(ok) < 12:
        return out
    c = float(np.median(local_centres(x4))) if x4.size >= 3 else 0.0
    side, a = np.sign(x4 - c), np.abs(x4 - c)
    scale = float(np.max(a[ok]))
    u = np.minimum(a, scale) / scale  # (not extrapolated beyond the extrema fitted)
    basis = np.column_stack([u, u**3, u**5])
    d = (x4 - x6) * side  # the quartic's bias, on each side away from the centre
    coef, *_ = np.linalg.lstsq(basis[ok], d[ok], rcond=None)
    resid = d[ok] - basis[ok] @ coef
    dof = max(np.count_nonzero(ok) - 3, 1)
    cov = np.linalg.pinv(basis[ok].T @ basis[ok]) * float(resid @ resid) / dof
    grid = np.linspace(0.0, 1.0, 21)[1:]
    g = np.column_stack([grid, grid**3, grid**5])
    se = np.sqrt(np.maximum(np.einsum("ij,jk,ik->i", g, cov, g), 0.0))
    if not np.any(np.abs(g @ coef) > 3 * se):
        return out
    return side * (basis @ coef)


def _pendulum_decrements(angle) -> tuple:
    """Shapes of a pendulum's decrements per half-swing at the amplitudes `angle` [rad], each
    relative to the linear oscillator's (1 at small swings), for weak damping (from the energy
    lost over a half-swing, `dA = dE / (omega^2 sin A)`): Coulomb `A / sin A`; viscous
    `2 I1 / (pi A sin A)` with `I1 = int sqrt(2 (cos t - cos A)) dt` over `(-A, A)`; quadratic
    drag `3 (sin A - A cos A) / (A^2 sin A)`. `I1 = 4 k^2 int cos^2 p / sqrt(1 - k^2 sin^2 p)
    dp` over `(-pi/2, pi/2)`, `k = sin(A/2)` (Gauss-Legendre, 24 nodes: within 1e-12 up to 120
    deg, 1e-7 at 170)."""
    A = np.clip(np.asarray(angle, dtype=float), 1e-6, 3.0)
    nodes, weights = np.polynomial.legendre.leggauss(24)
    phi = 0.5 * math.pi * nodes
    k2 = np.sin(0.5 * A)[:, None] ** 2
    inner = np.cos(phi) ** 2 / np.sqrt(1.0 - k2 * np.sin(phi) ** 2)
    I1 = 4 * k2[:, 0] * (0.5 * math.pi) * (inner @ weights)
    s = np.sin(A)
    return A / s, 2 * I1 / (math.pi * A * s), 3 * (s - A * np.cos(A)) / (A * A * s)


def _dry_level(t, x, peak, angle_unit=None, cut=None, tail=None) -> list:
    """The dry-friction level seen at the maxima and at the minima of a decay [signal units],
    from the decay of each side's amplitudes `a` (about the local centre) over a period:
    `a[j] - a[j+1] = 4 xF g_c + c1 a g_v + c2 a^2 g_q` (Coulomb, viscous and quadratic
    decrements at `a[j]`), at least 0; 0 with fewer than 6 extrema on a side, and at most a
    quarter of the median decay over a period (all of the decay dry friction's). For a linear
    restoring law the shapes `g` are 1; for a pendulum's angle (`angle_unit` [rad per signal
    unit] given) they are its own (`_pendulum_decrements`: Coulomb's 2.4 at 120 deg), without
    which the level of a record released from 120 deg came out 3-4 times too large. The first
    extremum is left out (it may be a hold before the release).

    The centre is the least-squares line through the local centres (`local_centres`) over
    the extrema's times `t` [s]: a sensor's zero that drifts by `d` [signal units/s] lowers
    one side's decrements by `d T` and raises the other's (`T` the period), and about a fixed
    centre took `d T / 4` from the level at the maxima and gave it to the minima (the fit's
    omega 2-4 of its standard errors off: docs/signals.md, "The level under a drifting
    zero"). A side's gain and a drift both move the local centres with time, and the extrema
    alone cannot always tell them apart (the amplitude falls linearly under dry friction
    alone); the fit can, with `asym` and `drift`. A side of fewer than 6 extrema takes the
    level of both sides' decrements per half-swing (`2 xF` each) before the `tail` (the
    extrema beyond the first swing below the floor: where a decay of few swings sticks, the
    noise's at rest); 0 where those are fewer than 5 too.

    `cut` marks extrema a saturated sensor cut off (`_clipped`): they are in the sequence, so
    that the others keep their places, and take part in neither a local centre nor a
    decrement. (Until 2026-11-28 the extrema left were passed on their own: a record clipped
    on both sides keeps a run of one side's extrema, whose "local centres" lay among them,
    and the level came out 0: the turning points were timed up to 1.1 ms late, the fit's
    omega 6 standard errors off.)"""
    t, x, peak = np.asarray(t, float)[1:], np.asarray(x, float)[1:], np.asarray(peak)[1:]
    cut = np.zeros(x.size, dtype=bool) if cut is None else np.asarray(cut, dtype=bool)[1:]
    c = np.zeros_like(x)
    whole = ~(cut[:-2] | cut[1:-1] | cut[2:])  # successive extrema, none cut off
    if np.count_nonzero(whole) >= 3:  # (a line through at least 3 local centres)
        c = np.polyval(np.polyfit(t[1:-1][whole], local_centres(x)[whole], 1), t)

    def level(use, step):
        """The level from the decrements between the extrema `use` `step` half-swings apart
        (2: a side's, 4 xF each; 1: both sides', 2 xF each); None with fewer than 5."""
        j = np.nonzero(use & ~cut)[0]
        a = np.abs(x[j] - c[j])
        pair = np.diff(j) == step
        if np.count_nonzero(pair) < 5:
            return None
        d = (a[:-1] - a[1:])[pair]
        mid = (0.5 * (a[:-1] + a[1:]))[pair]  # (the loss rate at the pair's middle)
        shapes = np.ones((3, d.size))
        if angle_unit is not None:
            shapes = np.array(_pendulum_decrements(mid * angle_unit))
        A = np.column_stack([shapes[0], mid * shapes[1], mid**2 * shapes[2]])
        got = float(np.linalg.lstsq(A, d, rcond=None)[0][0]) / (2 * step)
        return min(max(got, 0.0), max(float(np.median(d / shapes[0])), 0.0) / (2 * step))

    # a side of fewer than 6 extrema: both sides' level (a decay that sticks after a few
    # swings; 0 until 2026-11-28: dry friction of 8 % of a0, 7 turning points, their times
    # 1-14 ms late and the fit's omega 19.92 [19.85, 19.995] for 20)
    out = [level(peak, 2), level(~peak, 2)]
    if None in out:
        both = level(np.ones(x.size, dtype=bool) if tail is None else ~np.asarray(tail)[1:], 1)
        out = [both if v is None else v for v in out]
    return [0.0 if v is None else v for v in out]


def _decays(y, idx, h, starts_at_edge: bool) -> list:
    """The free decays among a signal's extrema `idx` (hysteresis `h`): a swing more than 1.5
    times the one before it (and 2 h) was excited anew, by a tap, a pluck or a release (the
    first swing of a decay started at rest from the centre is half the next one: its start is
    no turning point). Returns `(a, b, largest swing)` per decay, its extrema `idx[a:b]`; a
    decay's first extremum much nearer the centre than the next (where the excitation found
    the mass at rest) is left out. A partial first swing at the signal's first sample
    (`starts_at_edge`) is left to the extraction's own edge rule."""
    s = np.abs(np.diff(y[idx]))
    starts = [0] + [
        j
        for j in range(1, s.size)
        if s[j] > 1.5 * s[j - 1] + 2 * h and not (starts_at_edge and j == 1)
    ]
    out = []
    for a, b in zip(starts, starts[1:] + [idx.size]):
        if 0 < a and b - a >= 4:
            centre = float(np.median(local_centres(y[idx[a + 1 : b]])))
            if abs(y[idx[a]] - centre) < 0.5 * abs(y[idx[a + 1]] - centre):
                a += 1
        out.append((a, b, float(np.max(s[a : b - 1])) if b - a >= 2 else 0.0))
    return out


def local_centres(x):
    """Local centre of each interior extremum: `(x[k-1] + 2 x[k] + x[k+1]) / 4`, which cancels
    the alternation and, to first order, the decay."""
    x = np.asarray(x, dtype=float)
    return (x[:-2] + 2 * x[1:-1] + x[2:]) / 4


def _clipped(t, y, idx, peak, half):
    """Which extrema `idx` (samples of `y`; `peak`: maxima) a saturated sensor cut off, and
    the levels it clipped at: `(mask, {"max": level or None, "min": level or None})`.

    A side (the maxima, or the minima) is clipped when at least two of its extrema sit on
    a flat run of samples equal to the signal's extreme value that lasts more than three
    times as long as an unclipped sinusoidal extremum of that amplitude stays within one
    quantisation step of its vertex, and more than 2.5 sample intervals. A decay reaches its
    extreme value once (at the release, or over a hold before it); a sensor at the end of its
    range reads the same value at every swing beyond it. Every extremum of a clipped side at
    the level is then cut off: its true value lies beyond."""
    quantum = _quantum(y)
    dt = float(np.median(np.diff(t)))
    centre = float(np.median(y))
    mask = np.zeros(idx.size, dtype=bool)
    levels = {"max": None, "min": None}
    for name, side, level in (("max", peak, float(np.max(y))), ("min", ~peak, float(np.min(y)))):
        at = y == level
        amplitude = max(abs(level - centre), 1e-300)
        # an unclipped vertex of amplitude a stays within q of it for (2 h / pi) sqrt(2 q / a)
        long_runs, touching = 0, []
        for j in np.nonzero(side)[0]:
            i = int(idx[j])
            if not at[i]:
                continue
            touching.append(j)
            lo, hi = i, i
            while lo > 0 and at[lo - 1]:
                lo -= 1
            while hi + 1 < y.size and at[hi + 1]:
                hi += 1
            natural = 2 * half[j] / math.pi * math.sqrt(2 * quantum / amplitude)
            long_runs += bool(t[hi] - t[lo] > max(3 * natural, 2.5 * dt))
        if long_runs >= 2:
            mask[touching] = True
            levels[name] = level
    return mask, levels


def _maxima(y, idx) -> np.ndarray:
    """Which of the alternating extrema `y[idx]` are maxima."""
    peak = np.empty(idx.size, dtype=bool)
    peak[:-1] = y[idx[:-1]] > y[idx[1:]]
    peak[-1] = not peak[-2]
    return peak


def _near_clipping(t, y, idx):
    """The samples at a saturated sensor's levels (`_clipped`, judged at the raw signal's
    extrema `idx`) and the two on either side of each: the corners of a flat run depart from
    the cubic through their neighbours like spikes, and replaced they would hide the run."""
    near = np.zeros(y.shape, dtype=bool)
    if idx.size < 3:
        return near
    _, levels = _clipped(t, y, idx, _maxima(y, idx), _local_half_periods(t[idx]))
    for level in levels.values():
        if level is not None:
            near |= y == level
    at = near.copy()
    for shift in (1, 2):
        near[shift:] |= at[:-shift]
        near[:-shift] |= at[shift:]
    return near


def naming_other_columns(extract):
    """`extract(signal, ...)` (`extract_turning_points`, `_every_decay`), whose failure to find
    a decay names the file's other columns (the signal is the last column unless one is named:
    a trigger or a second sensor may be last)."""

    @functools.wraps(extract)
    def named(signal: Signal, *args, **kwargs):
        try:
            return extract(signal, *args, **kwargs)
        except _NoDecay as err:
            if not signal.others:
                raise
            others = ", ".join(map(repr, signal.others))
            raise ValueError(
                f"{err} (in the column {signal.signal_name!r}; the file's other "
                f"column{'s' if len(signal.others) > 1 else ''}: {others}: name the signal's "
                "with --signal-col NAME, signal_col=NAME)"
            ) from None

    return named


@naming_other_columns
def extract_turning_points(
    signal: Signal,
    *,
    hysteresis: float | None = None,
    min_amplitude: float | None = None,
    angle_unit: float | None = None,
    decay: int | None = None,
) -> Record:
    """Turning points of a raw decaying signal, robust to irregular sampling, noise,
    quantisation, a constant offset and a few spurious extrema.

    1. the noise level `sigma` is estimated (MAD of differences that cancel the smooth signal,
       at least the quantisation noise) and isolated spikes (far from the cubic through their
       neighbours, `_despike`) are removed; a signal of fewer than 16 samples per period is
       not despiked and its noise is measured from sinusoids through the samples near each
       extremum (`_harmonic_noise`), and one of fewer than 6 is refused;
    2. extrema are found with hysteresis `h` (default `max(6 sigma, 1e-3 range)`): a turning
       point counts only once the signal has moved back from it by more than `h`; a swing
       more than 1.5 times the one before it starts a new free decay (`_decays`: a tap, a
       pluck or a release, after a quiet lead-in or during another decay), and the decay of
       the largest swing is kept, or the `decay`-th (0-based, in time order) where it is
       given (`meta["decays"]`: where each starts, the one taken and its index, where there
       are several; [`fits.read_decays`][] reads every one). An oscillation faster than the
       decay's riding on it (mains hum: a spectral line, `_faster_period`) is averaged out
       of the signal they are found on, and fitted beside the local polynomial that locates
       each (`meta["faster"]`: its period [s] and amplitude);
    3. pairs of extrema much closer in time than the median half-period (spurious wiggles) are
       dropped; each extremum is refined by a local quartic over +-0.4 local half-periods
       (sub-sample time and value; a sinusoid over +-0.5 where fewer than 7 samples fall
       inside, `_refine_harmonic`), bent by the dry-friction level that the extrema's decay
       shows (at a turning point the friction force reverses: the curvature steps), less the
       quartic's bias where the record shows one (`_shape_bias`: a pendulum's large swings
       are not quartic over the window); leading
       extrema on the same side of the centre as the next one (the mass held or nudged before
       its release) are dropped, so the record starts at the release;
    4. the record ends where the swings fall below `min_amplitude` (default `10 h`); where
       that floor would cut the decay short (swings down to 90 noise sd above a fifth of the
       largest), at 16 or more samples per half-swing, the turning points are found on the
       signal averaged over a quarter of a half-swing, its noise and so `h` lower by
       `sqrt(2 / (3 width))` (`width` the samples averaged; `meta["averaged"]` [s]), and
       located on the samples as above;
    5. extrema cut off by a saturated sensor (flat runs at the signal's extreme value at two
       or more swings, `_clipped`) are left out of the record (their `k` skipped; positions
       and times), of the dry-friction level and of the centre; `meta["clipped"]` holds the
       levels (`{"max": ..., "min": ...}`, `None` for a side not clipped), and a fit on the
       whole time series leaves out the samples at those levels.

    The first turning point is the release (`k = 0`); times are measured from it. `centre` is
    the median local centre `(x[k-1] + 2 x[k] + x[k+1]) / 4`. A release from a hold (the first
    half-swing more than 10 % longer or shorter than the second: the first extremum is then a
    flat stretch, not a sharp turning point) is timed one half-swing before the end of the
    first swing, at the hold's level; `meta` says so (`"release"`: `HELD_RELEASE`, the fits do
    not weigh its time), as it does of a release at the signal's first samples
    (`EDGE_RELEASE`: located from one side only, the fits weigh neither its position nor its
    time), and holds the `hysteresis`, the `min_amplitude`, the `angle_unit` and the
    dry-friction `kink` levels of the maxima and the minima [signal units].

    `angle_unit` [rad per signal unit]: the signal is a pendulum's angle; the dry-friction
    level is then measured with a pendulum's decrements (`_dry_level`). The fits of a model
    with an angle unit (the pendulum) extract a record again with theirs.
    The signal's clock report is `record.clock`.
    """
    return extract_record(signal, find_decays(signal, hysteresis), min_amplitude, angle_unit, decay)


class _Found(NamedTuple):
    """What `find_decays` found on a signal, before any one decay is taken."""

    t: np.ndarray
    y_clean: np.ndarray  # despiked
    y_found: np.ndarray  # where the turning points were found (averaged, or `y_clean`)
    idx: np.ndarray  # the turning points' samples
    h: float  # the hysteresis
    starts_at_edge: bool
    sigma: float  # the noise of `y_found`
    per_half: float  # samples per half-swing
    width: int | None  # samples averaged over (`y_found`)
    fast: tuple | None  # (amplitude, angular frequency [rad/s]) of a faster oscillation


def find_decays(signal: Signal, hysteresis) -> _Found:
    """Steps 1 and 2 of `extract_turning_points` on the whole signal: its noise, spikes,
    faster oscillation and turning points (every decay's: `read_decays` takes each of them
    from one `find_decays`)."""
    t, y = np.asarray(signal.t, dtype=float), np.asarray(signal.y, dtype=float)
    source = signal.source
    sigma = _noise(t, y)
    span = float(np.max(y) - np.min(y))
    if span <= 0:
        fail(source, "the signal is constant: no decay to fit", _NoDecay)
    # the extrema at the noise's hysteresis (a given `hysteresis` applies to the turning points
    # only): how many samples a swing spans, and whether the signal is too noisy for them
    fast, rate = _faster_period(t, y) or (None, None)
    if fast:  # the turning points are found on the signal without it, refined on the signal
        smoothed = _smooth(y, fast)
        fast_amp = float(np.sqrt(2) * np.std(y - smoothed))
        sigma_found = _noise(t, smoothed)
        first = _zigzag(smoothed, max(6 * sigma_found, 1e-3 * span))
    else:
        first = _zigzag(y, max(6 * sigma, 1e-3 * span))
    per_half = _samples_per_half_period(first)
    if per_half < _SAMPLES_MIN:
        fail(
            source,
            f"about {2 * per_half:.3g} samples per period: at least {2 * _SAMPLES_MIN} are needed "
            f"to locate the turning points",
            _NoDecay,
        )
    if per_half >= _SMOOTH_MIN:  # spikes are told from the swings (`_despike`)
        y_clean = _despike(t, y, sigma, 8.0, keep=_near_clipping(t, y, first))
    else:  # the differences of `_noise` see the swings: their residuals from sinusoids
        y_clean = y
        sigma = min(sigma, _harmonic_noise(t, y, first))
    width = fast  # samples averaged over in the signal the turning points are found on
    if fast:
        sigma = sigma_found
    elif (
        per_half >= 2 * _SMOOTH_MIN
        and first.size >= 2
        and 90 * sigma > 0.2 * float(np.max(np.abs(np.diff(y_clean[first]))))
    ):
        # the noise floor (swings down to 1.5 x 10 h = 90 sigma) would cut the decay short
        # (above a fifth of its largest swing): found on the signal averaged over a quarter of
        # a half-swing, whose noise is sqrt(2 / (3 width)) of the samples' (located on the
        # samples, over +-0.4 half-swings, as ever)
        width = int(per_half // 4)
        sigma *= math.sqrt(2 / (3 * width))
    h = (
        float(hysteresis)
        if hysteresis is not None
        else max(6 * sigma, 1e-3 * float(np.max(y_clean) - np.min(y_clean)))
    )
    y_found = _smooth(y_clean, width) if width else y_clean  # (where they are found)
    idx = _zigzag(y_found, h)
    starts_at_edge = bool(idx.size and idx[0] == 0)
    # spurious wiggles: remove the closest pair while an interval is far below the median
    while idx.size >= 4:
        gaps = np.diff(t[idx])
        j = int(np.argmin(gaps))
        if gaps[j] >= 0.35 * np.median(gaps):
            break
        idx = np.delete(idx, [j, j + 1]) if j + 1 < idx.size else np.delete(idx, j)
    if idx.size < 3:
        fail(
            source,
            f"found only {idx.size} turning points in the signal (hysteresis {h:.3g})",
            _NoDecay,
        )
    return _Found(
        t,
        y_clean,
        y_found,
        idx,
        h,
        starts_at_edge,
        sigma,
        per_half,
        width,
        (fast_amp, rate) if fast else None,
    )


def extract_record(signal: Signal, found: _Found, min_amplitude, angle_unit, decay) -> Record:
    """Steps 2-6 of `extract_turning_points` for one decay of what `find_decays` found."""
    t, y_clean, y_found, idx, h, starts_at_edge, sigma, per_half, width, fast = found
    rate = fast[1] if fast else None
    source = signal.source
    floor = float(min_amplitude) if min_amplitude is not None else 10 * h
    decays = _decays(y_found, idx, h, starts_at_edge)
    decays = [d for d in decays if d[2] >= 2 * floor] or decays  # (none: refused below)
    if decay is None:
        decay = max(range(len(decays)), key=lambda i: decays[i][2])  # of the largest swing
    elif not 0 <= decay < len(decays):
        fail(
            source,
            f"decay {decay} asked for, but the signal holds {len(decays)} free "
            f"decay{'s' if len(decays) > 1 else ''} (numbered from 0 in time order)",
        )
    a, b = decays[decay][:2]
    others = [float(t[idx[d[0]]]) for d in decays]
    if a > 0:
        starts_at_edge = False
    idx = idx[a:b]
    if idx.size < 3:
        fail(source, f"decay {decay} of the signal holds only {idx.size} turning points")
    swings = np.abs(np.diff(y_found[idx]))
    small = np.nonzero(swings[int(np.argmax(swings)) :] < 1.5 * floor)[0] + int(np.argmax(swings))
    if small.size and small[0] + 3 < idx.size:  # the tail far below the floor: not refined
        idx = idx[: small[0] + 3]
    half = _local_half_periods(t[idx])
    peak = _maxima(y_clean, idx)
    clipped, clip_levels = _clipped(t, y_clean, idx, peak, half)

    def refine(kinks, degree=4):  # every extremum, (time, value) rows
        return np.array(
            [
                _refine(t, y_clean, i, hp, pk, kinks[0] if pk else -kinks[1], degree, rate)
                for i, hp, pk in zip(idx, half, peak)
            ]
        )

    # a dry-friction level bends every turning point (`_refine`): measured from the decay of
    # the extrema refined without it, then each extremum refined again with it
    refined = refine((0.0, 0.0))
    tail = np.zeros(idx.size, dtype=bool)  # beyond a swing below the floor (cut below)
    small = np.nonzero(np.abs(np.diff(refined[:, 1])) < 2 * floor)[0]
    tail[small[0] + 1 if small.size else idx.size :] = True
    kinks = _dry_level(refined[:, 0], refined[:, 1], peak, angle_unit, clipped, tail)
    if max(kinks) > 0:
        refined = refine(kinks)
    if per_half < _SMOOTH_MIN:
        # the samples' intervals are up to a sample period off (15 % of a half-period at 7
        # samples per period), and a sinusoid's vertex moves with its rate: once more with
        # the half-periods of the refined extrema
        half = _local_half_periods(refined[:, 0])
        refined = refine(kinks)
    tk, xk = refined[:, 0], refined[:, 1]
    xk = xk - _shape_bias(xk, refine(kinks, 6)[:, 1], y_clean[idx], ~clipped)
    # the first extremum's window reaches before the first sample: located from one side only
    one_sided = bool(tk[0] - t[0] < _WINDOW * half[0])
    if xk.size >= 5:
        # before the release the mass may be held, or nudged, on the release side: extrema on
        # the same side of the centre as their successor are no swings; the release is the
        # last of them
        c = np.median(local_centres(xk[1:]))
        lead = 0
        while lead + 3 < xk.size and (xk[lead] - c) * (xk[lead + 1] - c) > 0:
            lead += 1
        if lead:
            tk, xk, starts_at_edge, one_sided = tk[lead:], xk[lead:], False, False
            clipped = clipped[lead:]
    if starts_at_edge and xk.size >= 5:
        # an extremum at the first sample is a release from rest only if it is at least as far
        # from the centre as the next one on its side (not a record that starts mid-swing).
        # Judged by the first sample itself: the local fit of an extremum at the edge is
        # one-sided, and for a record that starts mid-swing its vertex may lie far beyond the
        # data, beyond even the next swing
        # (a first sample at a saturated sensor's level is at the extremum it cut off, which
        # lies beyond the level; the vertex fitted to the next one's flat run may lie beyond it)
        c = np.median(local_centres(xk[1:]))
        if not clipped[0] and abs(y_clean[0] - c) < 0.98 * abs(xk[2] - c):
            tk, xk, one_sided, clipped = tk[1:], xk[1:], False, clipped[1:]
    meta = {"hysteresis": h, "min_amplitude": floor, "angle_unit": angle_unit, "kink": kinks}
    if fast:
        meta["faster"] = {"period": 2 * np.pi / rate, "amplitude": fast[0]}
    elif width:
        meta["averaged"] = float(width * np.median(np.diff(t)))
    if len(others) > 1:  # several free decays: where each starts, and the one taken
        meta["decays"] = {"starts": others, "taken": others[decay], "index": decay}
    if one_sided:
        # released at (or just after) the first sample: its extremum is located from one side,
        # biased towards the centre (by 0.020 of a0 = 1 noise sd on average, 20 synthetic
        # signals sampled 0.5-6 ms apart), and timed late (1.5 ms); the fits weigh neither
        meta["release"] = EDGE_RELEASE
    if xk.size >= 4 and abs((tk[1] - tk[0]) - (tk[2] - tk[1])) > 0.1 * (tk[2] - tk[1]):
        # released from a hold: the first extremum is no sharp turning point, its time is
        # anywhere in the hold. The release is one half-swing before the first swing's end;
        # the position is the hold level just before it
        tk[0] = tk[1] - (tk[2] - tk[1])
        held = (t >= tk[0] - 0.2 * (tk[2] - tk[1])) & (t <= tk[0])
        if np.any(held):
            xk[0] = float(np.median(y_clean[held]))
        meta["release"] = HELD_RELEASE
    small = np.nonzero(np.abs(np.diff(xk)) < 2 * floor)[0]
    if small.size:
        tk, xk, clipped = tk[: small[0] + 1], xk[: small[0] + 1], clipped[: small[0] + 1]
    if xk.size < 3:
        early = float(np.median(swings[: max(3, swings.size // 4)]))
        if int(np.argmax(swings)) >= swings.size - 3 and swings.max() > 2 * early:
            # the largest swing at the end: the swings below the floor are the record's start
            fail(
                source,
                f"the swings grow (peak to peak about {early:.3g} over the record's first quarter, "
                f"{swings.max():.3g} at its end): not a free decay (a driven or self-excited "
                f"motion?)",
                _NoDecay,
            )
        fail(
            source,
            "fewer than 3 turning points above the amplitude floor: no decay to fit",
            _NoDecay,
        )
    centres = local_centres(xk)
    whole = ~(clipped[:-2] | clipped[1:-1] | clipped[2:])
    centre = float(np.median(centres[whole] if np.any(whole) else centres))
    origin = float(tk[0])
    if np.any(clipped):
        meta["clipped"] = clip_levels
        if np.count_nonzero(~clipped) < 3:
            levels = ", ".join(f"{v:.6g}" for v in clip_levels.values() if v is not None)
            fail(
                source,
                f"the signal is clipped at {levels} (a saturated sensor): fewer than 3 "
                f"turning points are not cut off",
            )
    keep = ~clipped
    return Record(
        k=np.arange(xk.size)[keep],
        positions=xk[keep],
        times=(tk - origin)[keep],
        centre=centre,
        noise=sigma,
        signal=signal,
        source=source,
        time_origin=origin,
        meta=meta,
    )


def sample_window(record: Record) -> tuple[np.ndarray, np.ndarray]:
    """`(t [s] from the release, samples)` of an extracted record's raw signal from its release
    to its last turning point, less the samples at a saturated sensor's levels
    (`meta["clipped"]`) and less a faster oscillation found on it (`meta["faster"]`: its
    least-squares sinusoid over the whole signal, as mains hum is): the data of a fit on the
    whole time series."""
    t = np.asarray(record.signal.t, dtype=float) - record.time_origin
    y = np.asarray(record.signal.y, dtype=float)
    faster = record.meta.get("faster")
    if faster:  # a stationary faster oscillation (mains hum): its least-squares sinusoid
        width = max(2, int(round(faster["period"] / np.median(np.diff(t)))))
        phase = 2 * np.pi * t / faster["period"]
        basis = np.column_stack([np.cos(phase), np.sin(phase)])
        y = y - basis @ np.linalg.lstsq(basis, y - _smooth(y, width), rcond=None)[0]
    keep = (t >= 0) & (t <= record.times[-1])
    for level in record.meta.get("clipped", {}).values():
        if level is not None:  # samples at a saturated sensor's level are no measurements
            keep &= y != level
    return t[keep], y[keep]
