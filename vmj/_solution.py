"""Result types shared by the solvers."""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array

__all__ = ["RESULTS", "DecaySequence", "Trajectory", "result_message"]


class RESULTS:
    """Status codes of a solve (`DecaySequence.result`, `Trajectory.result`)."""

    successful = 0  #: every requested turning point was reached
    stopped = 1  #: the mass came to rest for good (stick rule); not a failure
    mass_exhausted = 2  #: the mass reaches zero (delta < 0) before the next turning point
    step_limit = 3  #: no velocity zero within the step limit (overdamped or creeping motion)
    solver_failed = 4  #: the diffrax solve of the smoothed model did not finish
    length_exhausted = 5  #: the rope length l(t) reaches zero before the next turning point
    unbounded = 6  #: no turning point: the swing goes over the potential barrier

    messages = (
        "reached every requested turning point",
        "the mass came to rest for good: |spring force| <= static friction at a turning point",
        "the mass m0 + delta*t reaches zero (at t = m0/|delta|) before the next turning point; "
        "the solve stopped there",
        "no velocity zero within the step limit: the motion is overdamped or creeping "
        "(raise max_substeps if it is only slow)",
        "the smoothed ODE solve failed (step limit or non-finite state); try a larger smoothing "
        "or max_steps",
        "the rope length l(t) reaches zero before the next turning point; the solve stopped there",
        "no turning point: the energy of the swing is above the potential barrier (the motion is "
        "unbounded)",
    )
    failures = (mass_exhausted, step_limit, solver_failed, length_exhausted, unbounded)


def result_message(code) -> str:
    return RESULTS.messages[int(code)]


def throw_if_failed(value, result, throw: bool):
    """With `throw=True`, raise (inside jit) the failure's message."""
    if not throw:
        return value
    return eqx.branched_error_if(
        value, jnp.any(result >= RESULTS.mass_exhausted), jnp.max(result), RESULTS.messages
    )


class DecaySequence(eqx.Module):
    """Turning points (velocity zeros) of a free decay, padded to a fixed length `n`.

    Turning point `k = 1..n` follows the release at `k = 0`. Entries past `count` repeat the
    last turning point reached (same time and position, `crossed=False`), so a mass that sticks
    early keeps a continuous, fixed-shape record that works under `jit`, `vmap` and `grad`.

    **Fields:**

    - `times`: time of each turning point [s].
    - `positions`: signed position `x` at each turning point [m].
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

    @classmethod
    def from_scan(cls, times, positions, crossed, advanced, code) -> "DecaySequence":
        """Assemble a sequence from a solver's per-swing outputs (`advanced`: the swing was
        reached) and its final status code."""
        return cls(
            times=times,
            positions=positions,
            crossed=crossed,
            count=jnp.sum(advanced.astype(jnp.int32)),
            stopped=code == RESULTS.stopped,
            result=code,
        )

    @property
    def amplitudes(self) -> Array:
        """`|x|` at each turning point [m]."""
        return jnp.abs(self.positions)

    @property
    def stop_time(self) -> Array:
        """Time at which the mass comes to rest for good [s]; `inf` if it has not stopped."""
        last = jnp.take_along_axis(
            self.times, jnp.maximum(self.count - 1, 0)[..., None], axis=-1
        )[..., 0]
        last = jnp.where(self.count > 0, last, 0.0)
        return jnp.where(self.stopped, last, jnp.inf)

    @property
    def message(self) -> str:
        """Readable status (for an unbatched result)."""
        return result_message(np.asarray(self.result))

    @property
    def failed(self) -> Array:
        return self.result >= RESULTS.mass_exhausted

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
    """A sampled solution of a smoothed model.

    **Fields:** `ts` [s], `xs` [m], `vs` [m/s] at the saved times, and `result` (a status code
    of [`vmj.RESULTS`][]).
    """

    ts: Array
    xs: Array
    vs: Array
    result: Array

    @property
    def message(self) -> str:
        return result_message(np.asarray(self.result))
