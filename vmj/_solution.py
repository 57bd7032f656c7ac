"""Result types shared by the solvers, and the one failure vocabulary of vmj."""

from __future__ import annotations

import enum

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike

from ._checks import _is_traced, fail_branched

__all__ = ["RESULTS", "SolverError", "DecaySequence", "Trajectory", "throw_if_failed"]


class RESULTS(enum.IntEnum):
    """Status of a solve, stored as an integer array in every result (`DecaySequence.result`,
    `Trajectory.result`, `StickSlipCycle.result`), so that it works under `jit` and `vmap` and
    exports as a column.

    `successful` and `stopped` are *okay* ([`vmj.RESULTS.okay`][]): `stopped` is a decay that
    ended because the mass stuck for good, not a failure. Every other member is a failure, and
    its [`message`][vmj.RESULTS.message] says what to change.
    """

    successful = 0  #: every requested turning point was reached
    stopped = 1  #: the mass came to rest for good (stick rule); okay, not a failure
    mass_exhausted = 2  #: the mass reaches zero (delta < 0) before the next turning point
    step_limit = 3  #: no velocity zero within the step limit (overdamped, creeping, not turning)
    solver_failed = 4  #: the diffrax solve of the smoothed model did not finish
    length_exhausted = 5  #: the rope length l(t) reaches zero before the next turning point
    unbounded = 6  #: no turning point: the swing goes over the potential barrier
    too_many_reversals = 7  #: a stick-slip cycle with more reversals than `max_reversals`
    no_cycle = 8  #: the smoothed stick-slip model did not settle into a cycle
    beyond_turning_points = 9  #: a time past the last computed turning point of a moving mass
    map_diverged = 10  #: the energy map's half-swing time diverges (a swing at the separatrix)

    @property
    def message(self) -> str:
        """What happened, and what to change."""
        return _MESSAGES[self]

    @classmethod
    def okay(cls, code: ArrayLike) -> Array | bool:
        """`successful` or `stopped` (elementwise for arrays)."""
        return _host(code) <= cls.stopped

    @classmethod
    def failed(cls, code: ArrayLike) -> Array | bool:
        """Not okay (elementwise for arrays)."""
        return _host(code) > cls.stopped

    @classmethod
    def describe(cls, code: ArrayLike) -> str:
        """The message of a (concrete, scalar) status code."""
        code = np.asarray(code)
        if code.ndim != 0:  # (int() of it was a TypeError that named no status)
            raise ValueError(
                f"a message is of one solve; this result holds {code.size} (shape "
                f"{code.shape}): vmj.RESULTS(int(c)).message for each code c of result"
            )
        return cls(int(code)).message


def _host(code):
    """A concrete status code as a NumPy array (comparing a JAX array runs, and in a new process
    loads, a program of its own); traced codes as they are."""
    return code if _is_traced(code) else np.asarray(code)


_MESSAGES = {
    RESULTS.successful: "reached every requested turning point",
    RESULTS.stopped: "the mass came to rest for good: |spring force| <= static friction at a "
    "turning point",
    RESULTS.mass_exhausted: "the mass m0 + delta*t reaches zero (at t = m0/|delta|) before the "
    "next turning point (for vmj.Exact: or so close to it that the substeps ran out first; "
    "a larger max_substeps may reach a turning point just before); the solve stopped there",
    RESULTS.step_limit: "no velocity zero within the step limit: the motion is overdamped, "
    "creeping (raise max_substeps if it is only slow), or does not turn back (a pendulum "
    "over the top: a restoring law that does not hold the swing)",
    RESULTS.solver_failed: "the smoothed ODE solve failed (step limit or non-finite state); try a "
    "larger smoothing or max_steps",
    RESULTS.length_exhausted: "the rope length l(t) reaches zero before the next turning point "
    "(for vmj.Exact: or so close to it that the substeps ran out first; a larger max_substeps "
    "may reach a turning point just before); the solve stopped there",
    RESULTS.unbounded: "no turning point: the energy of the swing is above the potential barrier "
    "(the motion is unbounded)",
    RESULTS.too_many_reversals: "more reversals per cycle than max_reversals: raise max_reversals "
    "(a cycle has floor((eps - 1)/2) reversals)",
    RESULTS.no_cycle: "the smoothed model did not settle into a stick-slip cycle within the "
    "simulated periods; try a smaller smoothing",
    RESULTS.beyond_turning_points: "a requested time lies past the last computed turning point "
    "of a mass that still moves: raise n",
    RESULTS.map_diverged: "the energy-balance map's half-swing time diverges (a swing at the "
    "separatrix, where the averaged map does not hold): use vmj.Exact()",
}
#: the messages indexed by code (for `equinox.branched_error_if` and tables)
RESULTS.messages = tuple(_MESSAGES[r] for r in RESULTS)


class SolverError(RuntimeError):
    """A solve failed and `throw=True` was asked for; the message is the [`vmj.RESULTS`][]
    member's."""


def throw_if_failed(value, result, throw: bool):
    """The one `throw=True` path (`vmj._checks.fail_branched`): a concrete result raises
    [`vmj.SolverError`][] on the host (compiled entry points stay free of host callbacks); a
    traced one is returned as a value where a compiled entry point collects its checks
    (`vmj._checks.collecting`), else (inside the user's `jit` or `vmap`) guarded with
    `equinox.branched_error_if`."""
    if not throw:
        return value
    codes = _host(result)  # (NumPy for a concrete result: no JAX dispatch)
    failed = RESULTS.failed(codes)
    return fail_branched(value, failed.any(), codes.max(), RESULTS.messages, SolverError)


class DecaySequence(eqx.Module):
    """Turning points (velocity zeros) of a free decay, padded to a fixed length `n`.

    Turning point `k = 1..n` follows the release at `k = 0`. Entries past `count` repeat the
    last turning point reached (same time and position, `crossed=False`), so a mass that sticks
    early keeps a continuous, fixed-shape record that works under `jit`, `vmap` and `grad`.

    **Fields:**

    - `times`: time of each turning point [s].
    - `positions`: signed position `x` at each turning point [m] (rad for angle models).
    - `crossed`: whether the swing ending there passed `x = 0` (the paper's `*` is `not crossed`).
    - `count`: number of turning points actually reached (`<= n`).
    - `stopped`: the mass is at rest for good after the last reached turning point.
    - `result`: a status code of [`vmj.RESULTS`][]; `message` explains it.
    """

    times: Array
    positions: Array
    crossed: Array
    count: Array
    stopped: Array
    result: Array

    @staticmethod
    def field_units(model) -> dict:
        """The unit of each field that has one, for a decay of `model` (exports' `units`):
        `times` [s], `positions` in the model's `position_unit` (none where the model leaves
        it to the user); counts, flags and status codes have none."""
        unit = getattr(model, "position_unit", None)
        return {"times": "s"} | ({"positions": unit} if unit not in (None, "position unit") else {})

    @classmethod
    def from_code(cls, times, positions, crossed, count, code) -> DecaySequence:
        """Assemble a sequence from a solver's turning points, their count and its final status
        code (`stopped` read off the code)."""
        return cls(times, positions, crossed, count, code == RESULTS.stopped, code)

    @classmethod
    def from_scan(cls, times, positions, crossed, advanced, code) -> DecaySequence:
        """The same from per-swing outputs (`advanced`: the swing was reached)."""
        return cls.from_code(times, positions, crossed, jnp.sum(advanced.astype(jnp.int32)), code)

    @property
    def amplitudes(self) -> Array:
        """`|x|` at each turning point [m]."""
        return jnp.abs(self.positions)

    @property
    def stop_time(self) -> Array:
        """Time at which the mass comes to rest for good [s]; `inf` if it has not stopped."""
        last = jnp.take_along_axis(self.times, jnp.maximum(self.count - 1, 0)[..., None], axis=-1)[
            ..., 0
        ]
        last = jnp.where(self.count > 0, last, 0.0)
        return jnp.where(self.stopped, last, jnp.inf)

    @property
    def message(self) -> str:
        """Readable status (for an unbatched result)."""
        return RESULTS.describe(self.result)

    @property
    def failed(self) -> Array:
        """Whether the solve failed (not [`vmj.RESULTS.okay`][])."""
        return RESULTS.failed(self.result)

    def reached(self) -> dict:
        """The turning points actually reached, as NumPy arrays (unbatched results only)."""
        n = int(self.count)
        return {
            "times": np.asarray(self.times)[:n],
            "positions": np.asarray(self.positions)[:n],
            "amplitudes": np.abs(np.asarray(self.positions)[:n]),
            "crossed": np.asarray(self.crossed)[:n].astype(bool),
        }


class Trajectory(eqx.Module):
    """A sampled solution.

    **Fields:** `ts` [s], `xs` [m], `vs` [m/s] at the saved times, and `result` (a status code
    of [`vmj.RESULTS`][]).
    """

    ts: Array
    xs: Array
    vs: Array
    result: Array

    @property
    def message(self) -> str:
        return RESULTS.describe(self.result)
