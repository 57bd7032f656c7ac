"""Grids: outer products of parameter axes with names."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import jax
import numpy as np

from .._checks import NotANumber, not_a_number
from ._tree import _set_fields, resolve_field

if TYPE_CHECKING:  # names used in annotations only
    import equinox as eqx
    from jaxtyping import ArrayLike

__all__ = ["Grid", "grid"]


@dataclass(frozen=True)
class Grid:
    """An outer product of parameter axes, made by [`vmj.grid`][].

    **Fields:** `model` (its swept fields shaped for broadcasting: axis `i` has shape
    `(1, ..., n_i, ..., 1)`), `dims` (the axis names, e.g. `("eps", "mu", "delta")`), `coords`
    (the axis values, one 1-D array per name).
    """

    model: Any
    dims: tuple
    coords: dict


def grid(model: eqx.Module, **axes: ArrayLike) -> Grid:
    """Outer product of parameter axes, e.g. `vmj.grid(model, eps=np.linspace(0, 1, 11), mu=...)`.

    **Arguments:**

    - `model`: a model with scalar parameters (e.g. [`vmj.VariableMass`][]); its other fields
      stay fixed.
    - `**axes`: parameter name (a field name such as `eps`, `F` for `friction.F`, or a dotted
      path) to a 1-D sequence of values in the parameter's unit. The order of the keywords is the
      order of the axes.

    **Returns:** a [`vmj.Grid`][] for [`vmj.sweep`][]; the result's axes are named after the
    keywords.
    """
    if not axes:
        raise ValueError("grid needs at least one axis, e.g. grid(model, eps=[0, 0.5, 1])")
    for leaf in jax.tree.leaves(model):
        if np.ndim(leaf) != 0:
            raise ValueError(
                "grid takes a model with scalar parameters; the swept ones are the keyword axes"
            )
    names = list(axes)
    paths = [resolve_field(model, n) for n in names]
    if len(set(paths)) != len(paths):
        raise ValueError("each parameter may be given once in grid")
    coords, shaped = {}, []
    for i, (name, values) in enumerate(axes.items()):
        if not_a_number(values):  # (np.asarray would take True as 1.0, "0.5" as 0.5)
            raise NotANumber(values, f"each value of grid axis {name}")
        arr = np.asarray(values, dtype=float)
        if arr.ndim != 1 or arr.size == 0:
            raise ValueError(
                f"grid axis {name} must be a non-empty 1-D sequence (got shape {arr.shape})"
            )
        _set_fields(model, [paths[i]], [arr])  # ValueError naming the parameter and range
        coords[name] = arr
        shape = [1] * len(names)
        shape[i] = arr.size
        shaped.append(arr.reshape(shape))
    return Grid(_set_fields(model, paths, shaped), tuple(names), coords)
