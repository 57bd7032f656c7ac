"""The solver interface."""

from __future__ import annotations

import abc
from typing import ClassVar

import equinox as eqx

__all__ = ["AbstractSolver", "unsupported"]


class AbstractSolver(eqx.Module):
    """Base of the solver objects passed to [`vmj.turning_points`][], [`vmj.simulate`][] and
    [`vmj.limit_cycle`][]. A solver is an `equinox.Module`: its array fields (a smoothing
    velocity) are traced, its settings static, so one compilation serves every value."""

    #: the solver's name on the command line (`--method exact | smooth | energy | closed`)
    name: ClassVar[str]

    @abc.abstractmethod
    def check(self, model, task: str):
        """Raise `ValueError` when this solver does not apply to `model` for `task`
        (`"turning_points"`, `"simulate"` or `"limit_cycle"`), saying what does; return the
        model (guarded with `equinox.error_if` where applicability depends on traced values)."""


def unsupported(solver, model, task: str, use: str) -> ValueError:
    return ValueError(
        f"{type(solver).__name__} does not solve {task} of {type(model).__name__}; {use}"
    )
