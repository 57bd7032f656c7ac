"""The pendulum identification model: a measured angle record explained by a restoring law and a
set of dissipation laws, compared by BIC (issue 11).

The model is [`vmj.Oscillator`][] with

    theta'' + 2 zeta omega theta' + omega^2 xF sign(theta') + cq theta' |theta'|
            + omega^2 r(theta) = 0,   r(theta) = w sin(theta) + (1 - w) theta + b2 theta^2
                                                  + b3 theta^3,

`theta` the angle [rad] from the hanging position, `w` the sine's share of the restoring law
(`vmj.SineRestoring(b2, b3, w)`: `w = 1` the pendulum, `w = 0` a linear spring), released from
rest at `-a0`, read by a sensor with an offset and a side-dependent gain (applied by the fit,
see `fits.Space`).

**Units.** Angles of the record (and `a0`, `offset`, `xF`, `xS`) are in the signal's unit; the
non-fitted `angle_unit` [rad per signal unit] converts them (default: the unit the name of
the record's signal column ends with, `Angle(rad)` or `theta_deg`, else `pi/180`: degrees; the
command line's `--angle-unit`). `cq` is per signal unit [1/signal unit], like the record.
The restoring law is written in radians whatever the signal's unit, so that `b2` [1/rad] and
`b3` [1/rad^2] compare directly with the sine's own `-1/6` cubic term.

**Variants.** The user-facing model `"pendulum"` is the sine law with every dissipation law;
its variants are the law sets a decay record can identify, restoring {sine (`w = 1`), linear
(`w = 0`)} x dissipation {viscous, Coulomb, viscous + Coulomb, viscous + Coulomb +
quadratic}: eight fits of one compiled model, each law set holding the parameters it lacks at
0. Every variant keeps the sensor (`offset`, `asym`), the release `a0`, `omega` and the even
restoring term `b2` free when they are asked for: the centre of the turning points moves with
the amplitude through the sensor's gain (`asym`, proportional to the amplitude) and through an
even restoring term (`b2`, to its square), and a real record needs both
(docs/pendulum-fits.md). `w` is held at 1 or 0 (fit it with `free + ("w",)`: a pendulum with a
torsional stiffness at its pivot), `b3` and `xS` at 0 in every variant (`xS = 0` means "no
static level above the kinetic one"); a fit that frees them is compared with the variants as
asked. The times of the turning points are weighted by their amplitude (`time_noise =
"amplitude"`: an extremum of a sampled signal is timed the less sharply the smaller it is).
The headline result is the variant with the lowest BIC (`select=True`).
"""

from __future__ import annotations

import itertools
import math

import jax.numpy as jnp
import numpy as np

import vmj

from ._decrement import decrement
from ._record import Record, value_name
from ._sensor import _opposite, sensor_start
from ._space import Space, Variant, first_amplitude, record_centre
from ._text import ANGLE_UNIT

__all__ = ["PENDULUM", "DEGREE", "DISSIPATION_SETS", "FREE"]

DEGREE = math.pi / 180.0  #: the default `angle_unit` [rad per signal unit]: degrees


def named_angle_unit(record: Record) -> float:
    """Default `angle_unit` [rad per signal unit]: the unit the name of the record's signal (or
    peak table's value) column ends with (`Angle(rad)`: 1, `theta_deg`: `DEGREE`,
    `phi [mrad]`: 0.001), else degrees. Read as degrees, a record in radians had its `b2`
    [1/rad] 57 times too large, and with a sine law its frequency off by 30 standard errors."""
    m = ANGLE_UNIT.search(value_name(record).strip())
    unit = m.group(1).lower() if m else "deg"
    return 1e-3 if unit == "mrad" else 1.0 if unit.startswith("rad") else DEGREE


NAMES = (
    "omega",
    "zeta",
    "xF",
    "xS",
    "cq",
    "b2",
    "b3",
    "w",
    "a0",
    "offset",
    "asym",
    "drift",
    "angle_unit",
)
KINDS = (
    "positive",
    "damping",
    "positive",
    "positive",
    "positive",
    "real",
    "real",
    "unit",
    "positive",
    "real",
    "real",
    "real",
    "positive",
)
UNITS = (
    "rad/s",
    "-",
    "signal",
    "signal",
    "1/signal",
    "1/rad",
    "1/rad^2",
    "-",
    "signal",
    "signal",
    "-",
    "signal/s",
    "rad/signal",
)

#: the parameters fitted by default (`fits.fit(record, "pendulum")`, `vmj fit --model pendulum`)
FREE = ("omega", "zeta", "xF", "cq", "b2", "a0", "offset", "asym")

#: dissipation law sets compared, as the parameters each holds at 0
DISSIPATION_SETS = {
    "viscous": ("xF", "cq"),
    "coulomb": ("zeta", "cq"),
    "viscous+coulomb": ("cq",),
    "viscous+coulomb+quadratic": (),
}


def _builder():
    def build(theta: dict):
        """The vmj oscillator in radians, its release angle [rad] and `angle_unit`."""
        u = theta["angle_unit"]
        kinetic = theta["xF"] * u
        static = jnp.maximum(theta["xS"], theta["xF"]) * u  # xS below xF: no static excess
        model = vmj.Oscillator(
            theta["omega"],
            vmj.SineRestoring(theta["b2"], theta["b3"], theta["w"]),
            (
                vmj.ViscousDamping(theta["zeta"]),
                vmj.CoulombDamping(kinetic, static),
                vmj.QuadraticDamping(theta["cq"] / u),
            ),
        )
        return model, theta["a0"] * u, u

    return build


def _losses(amplitudes: np.ndarray) -> tuple[float, float, float]:
    """`(xF, zeta, cq)` from the amplitude lost per half-swing, `a_k - a_{k+1} = 2 xF +
    pi zeta a + (4/3) cq a^2` (the linear oscillator's half-swing losses of the three laws,
    `a` the mean amplitude of the pair), by non-negative least squares; `None` where too few
    swings."""
    a = amplitudes
    if a.size < 6:
        return None
    mean, loss = 0.5 * (a[:-1] + a[1:]), a[:-1] - a[1:]
    design = np.stack([2 * np.ones_like(mean), np.pi * mean, 4 / 3 * mean**2], axis=1)
    best, coef = np.inf, np.zeros(3)
    for subset in itertools.product((False, True), repeat=3):  # non-negative least squares
        cols = np.nonzero(subset)[0]
        c = np.zeros(3)
        if cols.size:
            c[cols] = np.linalg.lstsq(design[:, cols], loss, rcond=None)[0]
        rss = float(np.sum((design @ c - loss) ** 2))
        if np.all(c >= 0) and rss < best:
            best, coef = rss, c
    return float(coef[0]), float(coef[1]), float(coef[2])


def _centres(record: Record, u: float) -> dict | None:
    """`offset`, `asym` and `b2` from the centres of successive extrema: the centre `c` of a
    pair at amplitude `d` [signal units] moves as `c = offset + asym d + gamma d^2`, the gain
    giving the linear term and an even restoring term `b2` the quadratic one (the turning
    points of `r = theta + b2 theta^2` at amplitude `A` [rad] both shift by `-b2 A^2 / 3`, so
    `gamma = -o b2 u / 3`, `o` the record's orientation, `u` [rad per signal unit]). Least
    squares over the local centres of [`fits.sensor_start`][]'s interpolation; `None` with
    fewer than 8 centres or amplitudes that change by less than a factor 1.5."""
    if not record.sides_known or record.k[-1] - record.k[0] != len(record) - 1:
        return None
    x = np.asarray(record.positions, dtype=float)
    if x.size < 10:
        return None
    opposite = _opposite(x)[1:-1]
    c, d = (x[1:-1] + opposite) / 2, np.abs(x[1:-1] - opposite) / 2
    if np.max(d) < 1.5 * np.min(d):
        return None
    design = np.stack([np.ones_like(d), d, d * d], axis=1)
    offset, asym, gamma = np.linalg.lstsq(design, c, rcond=None)[0]
    return {
        "offset": float(offset),
        "asym": float(asym),
        "b2": float(-3 * gamma / (record.orientation * u)),
    }


def _start(record: Record, given: dict, dec: dict) -> dict:
    """Starting values: the sensor's offset and gain and the even restoring term from the
    centres of successive extrema (`_centres`; [`fits.sensor_start`][] where too few); the
    three laws' levels from the amplitude lost per half-swing (`_losses`, on the amplitudes
    corrected for the gain); the frequency from the mean half-period, corrected for the sine's
    amplitude dependence; `b3`, `xS` 0."""
    u = float(given.get("angle_unit", named_angle_unit(record)))
    sensor = _centres(record, u)
    if sensor is None:
        sensor = {
            **(
                sensor_start(record)
                if record.sides_known
                else {"offset": dec["centre"], "asym": 0.0}
            ),
            "b2": 0.0,
        }
    offset = float(given.get("offset", sensor["offset"]))
    asym = min(max(float(given.get("asym", sensor["asym"])), -0.2), 0.2)
    b2 = float(given.get("b2", sensor["b2"]))
    side = np.sign(record.positions - offset)
    amplitudes = np.abs(record.positions - offset) / (1 + asym * side)
    consecutive = record.k[-1] - record.k[0] == len(record) - 1
    a0 = float(amplitudes[0]) if record.k[0] == 0 else float(np.max(amplitudes))
    if not a0 * u < math.pi:
        raise ValueError(
            f"{record.source or 'the record'}: its largest swing, {a0:.4g} signal units, is "
            f"{a0 * u:.4g} rad with angle_unit {u:.4g} rad per unit, but a pendulum swings "
            "below pi rad: check --angle-unit (the default is degrees)"
        )
    losses = _losses(amplitudes) if consecutive else None
    dec = decrement(record, offset)
    if losses is None:
        xF, zeta, cq = dec["xF"], dec["zeta"], 0.0
    else:
        xF, zeta, cq = losses
    omega = dec["omega"] or 1.0
    # the sine's frequency falls with the amplitude: the mean half-period is about that of
    # 0.6 of the release amplitude, where the sine's frequency is 1 - A^2/16 (its share w)
    omega /= 1 - float(given.get("w", 1.0)) * (0.6 * a0 * u) ** 2 / 16
    return {
        "omega": omega,
        "zeta": min(max(zeta, 1e-4), 0.5),
        "xF": max(xF, 1e-4 * a0),
        "xS": 0.0,
        "cq": max(cq, 1e-4 / a0),
        "b2": b2,
        "b3": 0.0,
        "w": float(given.get("w", 1.0)),
        "a0": a0,
        "offset": offset,
        "asym": asym,
        "drift": float(given.get("drift", 0.0)),
        "angle_unit": u,
    }


def _space(variants: tuple = (), select: bool = False) -> Space:
    return Space(
        name="pendulum",
        names=NAMES,
        kinds=KINDS,
        units=UNITS,
        dry=("xF",),
        viscous=("zeta",),
        required=("omega",),
        model=_builder(),
        defaults={
            "zeta": 0.0,
            "xF": 0.0,
            "xS": 0.0,
            "cq": 0.0,
            "b2": 0.0,
            "b3": 0.0,
            "w": 1.0,
            "asym": 0.0,
            "drift": 0.0,
            "angle_unit": named_angle_unit,
            "a0": first_amplitude,
            "offset": record_centre,
        },
        variants=variants,
        select=select,
        bounds={"asym": (-0.5, 0.5)},
        label="sine:viscous+coulomb+quadratic",
        start=_start,
        time_noise="amplitude",
        constant_laws=True,
    )


#: the space of the variants: equal to `PENDULUM` (by name), so one compiled solve serves all
_VARIANT_SPACE = _space()


def _variants() -> tuple:
    out = []
    for restoring, w in (("sine", 1.0), ("linear", 0.0)):
        for label, zero in DISSIPATION_SETS.items():
            hold = {"b3": 0.0, "xS": 0.0, "w": w, **{n: 0.0 for n in zero}}
            headline = restoring == "sine" and not zero  # the model asked for (`Space.label`)
            out.append(Variant(f"{restoring}:{label}", None if headline else _VARIANT_SPACE, hold))
    return tuple(out)


#: the pendulum model (`"pendulum"`): every restoring x dissipation law set compared by BIC
PENDULUM = _space(variants=_variants(), select=True)
