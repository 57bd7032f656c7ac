"""Sweeps over model parameters: grids, chunked evaluation, results and their export,
sensitivities."""

from ._grid import Grid, grid
from ._result import SweepResult
from ._sensitivity import sensitivity
from ._sweep import sweep
from ._tree import resolve_field

__all__ = ["Grid", "grid", "SweepResult", "sensitivity", "sweep", "resolve_field"]
