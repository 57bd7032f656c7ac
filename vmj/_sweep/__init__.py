"""Sweeps over model parameters: grids, chunked evaluation, results and their export,
sensitivities."""

from ._grid import Grid, grid
from ._map import map_chunks
from ._result import SweepResult
from ._sensitivity import sensitivity
from ._sweep import SweepError, sweep
from ._tree import resolve_field

__all__ = [
    "Grid",
    "grid",
    "SweepResult",
    "sensitivity",
    "sweep",
    "SweepError",
    "map_chunks",
    "resolve_field",
]
