"""Parameter names as a user gives them: a sequence, or one comma-separated string (the command
line's spelling). Standard library only, so that the command line's option parsing can use it
without importing JAX."""

from __future__ import annotations

__all__ = ["name_list"]


def name_list(names) -> tuple:
    """Parameter names given as a sequence or as one comma-separated string (`"FT,mu"`; a bare
    string would otherwise be split into its letters)."""
    if isinstance(names, str):
        return tuple(n.strip() for n in names.split(","))
    return tuple(names)
