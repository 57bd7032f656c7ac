"""Naming the array fields of a model tree: paths, short names, replacement."""

from __future__ import annotations

import dataclasses

import equinox as eqx
import jax

from .._checks import _float, validated

__all__ = ["resolve_field"]


def _field_paths(model, prefix=()):
    """Paths (tuples of attribute names, and positions in a tuple of laws as digit strings) to
    every array field of a module tree."""
    out = []
    if isinstance(model, eqx.Module):
        for name in (f.name for f in dataclasses.fields(model)):
            out += _field_paths(getattr(model, name), prefix + (name,))
    elif isinstance(model, (tuple, list)):
        for i, item in enumerate(model):
            out += _field_paths(item, prefix + (str(i),))
    elif eqx.is_array_like(model) and not isinstance(model, (str, bytes)):
        out.append(prefix)
    return out


def resolve_field(model: eqx.Module, name: str) -> tuple[str, ...]:
    """The path of the array field `name` of `model`: a field name (`"eps"`), unique among the
    nested modules (`"F"` is `friction.F`), or a dotted path (`"friction.F"`,
    `"dissipation.0.zeta"`)."""
    paths = _field_paths(model)
    want = tuple(name.split("."))
    hits = [p for p in paths if p[-len(want) :] == want]
    if len(hits) != 1:
        known = ", ".join(sorted(".".join(p) for p in paths))
        why = "is ambiguous" if hits else "is not a parameter"
        raise ValueError(f"{name!r} {why} of {type(model).__name__} (parameters: {known})")
    return hits[0]


def _short_name(paths, path) -> str:
    """The shortest dotted suffix of `path` that names it uniquely among `paths`."""
    for k in range(1, len(path) + 1):
        if sum(p[-k:] == path[-k:] for p in paths) == 1:
            return ".".join(path[-k:])
    return ".".join(path)


_NAMED: dict = {}  #: tree structure -> what `named_paths` says of it


def named_paths(model) -> list[tuple[tuple[str, ...], str]]:
    """`(path, short name)` of every array field of `model` (`_field_paths`, `_short_name`),
    worked out once per tree structure (a sweep names its coordinates so: about 20 us of its
    fixed cost, warm, in the Python attribute lookups of `equinox.Module`s)."""
    structure = jax.tree.structure(model)
    try:
        return _NAMED[structure]
    except TypeError:  # (a static field that cannot be hashed)
        structure = None
    except KeyError:
        pass
    paths = _field_paths(model)
    named = [(path, _short_name(paths, path)) for path in paths]
    if structure is not None:
        if len(_NAMED) >= 256:
            _NAMED.clear()
        _NAMED[structure] = named
    return named


def _get(model, path):
    for p in path:
        model = model[int(p)] if isinstance(model, (tuple, list)) else getattr(model, p)
    return model


def _set_fields(model, paths, values):
    """Replace the fields at `paths` by float arrays and re-validate (ValueError on bad values)."""
    values = [_float(v) for v in values]
    model = eqx.tree_at(lambda m: [_get(m, p) for p in paths], model, values)
    return validated(model)
