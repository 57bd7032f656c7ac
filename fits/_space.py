"""What a model family of the fits is: `Space`, its sub-models (`Variant`), the forward
methods, and the defaults that most families share.

A `Space` names its parameters, how each is kept in range during the fit (`kinds`), which
parameters are dry and which viscous friction (for the model comparison), and `model(theta)`,
the vmj model it stands for. From it `Space.predict(theta, n, forward)` returns the release
point and the first `n` turning points `(times [s], signed positions)` of the model released
from rest at `-a0` (`vmj.turning_points`, one solver per method), and `Space.motion(theta, ts,
n, forward)` the positions at times `ts` (`vmj.decay_trajectory`: the exact motion between the
turning points, for fits on the whole time series). The constant offset, the sensor's gain and
the orientation of the record are applied by the fit, not here. The families themselves are in
`fits._models` (and `fits._pendulum`).
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import jax.numpy as jnp
import numpy as np

import vmj

from ._params import Interval, Positive, Real, Transform, transform_for
from ._record import Record

__all__ = ["Space", "Variant", "FORWARDS", "SOLVERS", "series_space"]

FORWARDS = ("exact", "smooth", "energy")
SMOOTH_RTOL = 1e-8  #: the smoothed forward model's relative (and scaled absolute) tolerance
#: the Jacobians of every forward model are forward-mode (fits._solve): the exact solver's
#: early-exit loops serve them, and the smoothed model's diffrax forward adjoint (a residual
#: per turning point against a few parameters; until 2026-11-28 reverse mode, a pass per
#: residual: one job of 2 records of 24 turning points, 7 parameters, its Jacobian 186 ms
#: warm and 43 s to compile against 41 ms and 17 s; the same Jacobian to 7e-9 of its
#: largest entry)
SOLVERS = {
    "exact": functools.partial(vmj.Exact, derivatives="forward"),
    # (the smoothed model's own tolerance, 1e-12 for the linear oscillator, took twice as long
    # a solve for turning points that move by 3e-8 of the amplitude and 1e-7 s: far below any
    # record's noise, and the smoothing's own offset from the exact model is 1e-7)
    "smooth": functools.partial(vmj.Smoothed, rtol=SMOOTH_RTOL, derivatives="forward"),
    "energy": vmj.EnergyBalance,
}

_UNDERDAMPED = 1.0 - 1e-9  #: the damping kind's upper end (an underdamped oscillator)
#: the range of each kind of parameter (a Space's `bounds` narrows it per parameter)
_KIND_TRANSFORMS = {
    "real": Real,
    "positive": Positive,
    "unit": lambda: Interval(0.0, 1.0),
    "damping": lambda: Interval(0.0, _UNDERDAMPED),
}


@dataclass(frozen=True)
class Variant:
    """A sub-model (or an alternative model) fitted beside the one asked for and compared with
    it by AIC/BIC: `label`; `space` (`None`: the same space); `hold`: parameters removed from
    the free set and held at these values [their units]."""

    label: str
    space: Space | None = None
    hold: Mapping = field(default_factory=dict)


@dataclass(frozen=True)
class Space:
    """A model family for fitting (static; compared by name).

    **Fields:** `name`; `names`, `kinds` (`"real"`, `"positive"`, `"unit"`, `"damping"`) and
    `units` of its parameters; `dry` and `viscous` parameters; `required` (kept for reference:
    the parameters without a default); `model(theta)` -> `(vmj model, a0, u)`: the vmj decay
    model of the parameters `theta` (`{name: value}`), its release deflection in the model's
    position unit and `u`, model position units per signal unit (1 but for angle records);
    `solvers` (`{forward: vmj solver class}`); `defaults` (`{name: value or function of the
    Record}`: physical values of parameters neither fitted nor given; a parameter with none
    must be given or fitted); `variants`
    (sub-models compared with the fit); `select` (the headline result is the variant preferred
    by BIC); `bounds` (`{name: (lo, hi)}`, narrower physical ranges than the kind's);
    `label` (the label of the full model in the comparison); `start(record, values, dec)`
    (optional: starting values from a record, the known values and its decrement estimate,
    instead of `fits._decrement.starting_guess`'s); `series` (a space of residuals on the whole
    time series, with the time shift `t0` [s] of the release: see `series_space`);
    `time_noise` (`"constant"`: every turning point's time equally precise; `"amplitude"`: the
    times' noise inversely proportional to the amplitude, as for extrema located in a sampled
    signal, weighted accordingly; records extracted from a raw signal are weighted so
    whatever the space's value); `constant_laws` (the model's decrement per half-swing cannot
    grow as the amplitude falls, so a record whose amplitudes fall faster later than earlier is
    warned of: `fits._result._steepening`; not for a varying mass or rope length).

    Sensor parameters, applied by the fit when present in `names`: `offset` (the reading's
    zero), `drift` (its change per second, on the record's clock) and `asym` (side-dependent
    gain): the reading is `offset + drift t + o y (1 + asym sign(o y))`, `y` the model's
    position, `o` the record's orientation.
    """

    name: str
    names: tuple
    kinds: tuple
    units: tuple
    dry: tuple  #: dry-friction parameters (fixed to 0 for the viscous-only comparison)
    viscous: tuple  #: viscous parameters (fixed to 0 for the Coulomb-only comparison)
    required: tuple  #: parameters that must be given when not fitted
    model: Callable = None
    solvers: Mapping = field(default_factory=lambda: dict(SOLVERS))
    defaults: Mapping = field(default_factory=dict)
    variants: tuple = ()
    select: bool = False
    bounds: Mapping = field(default_factory=dict)
    label: str = "both"
    start: Callable | None = None  #: `start(record, given, dec) -> {name: value}` (optional)
    series: bool = False
    time_noise: str = "constant"  #: how the times' noise scales: "constant" or "amplitude"
    constant_laws: bool = False  #: the decrement cannot grow as the amplitude falls

    def predict(self, theta: dict, n: int, forward: str):
        """`(times [s], signed positions [signal units])` of the release and the first `n`
        turning points of the model released from rest at `-a0`."""
        model, a0, u = self.model(theta)
        seq = vmj.turning_points(model, a0, n, self.solvers[forward]())
        times = jnp.concatenate([jnp.zeros((1,)), seq.times])
        positions = jnp.concatenate([-jnp.reshape(a0, (1,)), seq.positions])
        return times, positions / u

    def motion(self, theta: dict, ts, n: int, forward: str):
        """Positions [signal units] at times `ts` [s] from the release: the exact motion between
        the first `n` turning points (`forward` `"exact"` or `"energy"`: how the turning points
        are found)."""
        model, a0, u = self.model(theta)
        return vmj.decay_trajectory(model, a0, ts, n, self.solvers[forward]()).xs / u

    def extremum_shift(self, theta: dict, times, positions, slope):
        """How far [s] the extremum of the motion plus a line of `slope` [signal units/s] lies
        from each turning point `(times [s], positions [signal units])`: `-slope / x''`, `x''`
        the model's acceleration there with the velocity's sign at the extremum
        (`-sign(slope)`); 0 where `x''` is 0. (A reading whose zero drifts turns where the
        drift and the motion's velocity cancel, not at the motion's velocity zero.)"""
        model, _, u = self.model(theta)
        x = positions * u
        acc = model.acceleration(times, x, jnp.zeros_like(x), -jnp.sign(slope)) / u
        return jnp.where(acc != 0, -slope / jnp.where(acc != 0, acc, 1.0), 0.0)

    def index(self, name: str) -> int:
        return self.names.index(name)

    def unit(self, name: str) -> str:
        return self.units[self.index(name)]

    def transform(self, name: str) -> Transform:
        """The physical range of a parameter as a bijection (its kind, narrowed by `bounds`)."""
        if name in self.bounds:
            lo, hi = self.bounds[name]
            if self.kinds[self.index(name)] == "damping":
                hi = min(hi, _UNDERDAMPED)
            return transform_for(lo, hi)
        return _KIND_TRANSFORMS[self.kinds[self.index(name)]]()

    def default(self, name: str, record: Record):
        """The physical default of `name` for `record`, or `None` when it has none."""
        value = self.defaults.get(name)
        return value(record) if callable(value) else value

    def __hash__(self):
        return hash(self.name)

    def __eq__(self, other):
        return isinstance(other, Space) and other.name == self.name


def record_centre(record: Record) -> float:
    """Default `offset`: the record's centre [signal units]."""
    return float(record.centre)


def first_amplitude(record: Record) -> float:
    """Default `a0`: the distance of the release point (`k = 0`) from the record's centre."""
    if record.k[0] != 0:
        raise ValueError("the record has no k = 0 row: give a0 with --set a0=VALUE or fit it")
    return float(np.abs(record.positions[0] - record.centre))


def friction_variants(dry: tuple, viscous: tuple) -> tuple:
    """The Coulomb-only and viscous-only sub-models."""
    return (
        Variant("coulomb", None, {n: 0.0 for n in viscous}),
        Variant("viscous", None, {n: 0.0 for n in dry}),
    )


_SERIES: dict = {}


def series_space(space: Space) -> Space:
    """The space of a fit on the whole time series: `space` with the time shift `t0` [s] of the
    release (the model's release at `t0` on the record's clock, whose zero is the extracted
    release), and its variants' spaces likewise. Made once per space."""
    if space.series:
        return space
    if space.name not in _SERIES:
        variants = tuple(
            dataclasses.replace(v, space=None if v.space is None else series_space(v.space))
            for v in space.variants
        )
        _SERIES[space.name] = dataclasses.replace(
            space,
            name=space.name + ":series",
            names=space.names + ("t0",),
            kinds=space.kinds + ("real",),
            units=space.units + ("s",),
            defaults={**space.defaults, "t0": 0.0},
            variants=variants,
            series=True,
        )
    return _SERIES[space.name]


def theta_dict(space: Space, theta) -> dict:
    return {name: theta[..., i] for i, name in enumerate(space.names)}
