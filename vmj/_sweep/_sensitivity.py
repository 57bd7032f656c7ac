"""Sensitivities: derivatives of a solution with respect to chosen model parameters."""

from __future__ import annotations

from collections.abc import Callable, Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._checks import _float, collecting
from .._exported import filter_jit
from .._names import name_list
from ._grid import Grid
from ._tree import _get, resolve_field

__all__ = ["sensitivity"]


def sensitivity(
    fn: Callable,
    model: eqx.Module,
    wrt: Sequence[str],
    *,
    mode: str = "forward",
    chunk_size: int | None = None,
    progress=None,
    devices=None,
    client=None,
    store=None,
    resume: bool = False,
    **solver_args,
):
    """Derivatives of `fn(model, **solver_args)` with respect to the parameters named in `wrt`,
    at one point or at every point of a grid.

    **Arguments:**

    - `fn`: a function of the model returning a float array or a pytree of float arrays, e.g.
      `lambda m, a0, n: vmj.turning_points(m, a0, n).amplitudes` (amplitudes [m]) or
      `.stop_time` [s]. Integer and boolean outputs (counts, flags) have no derivative: select
      the float fields you need.
    - `model`: a model with scalar parameters; or a [`vmj.Grid`][] or a model with array
      parameters (paired points, as in [`vmj.sweep`][]): the derivatives at every point, through
      the sweep's machinery (chunks, threads, a Dask cluster, a resumable store). The scalar
      form is also vmappable and jittable.
    - `wrt`: parameter names: model fields (`"eps"`, `"mu"`, `"delta"`, `"F"` for `friction.F`,
      or a dotted path) and float keyword arguments of `fn` (e.g. `"a0"`).
    - `mode`: `"forward"` (`jax.jacfwd`, best for few parameters) or `"reverse"`
      (`jax.jacrev`, best for a scalar output); both give the same numbers. A smoothed solve
      differentiates in its `derivatives` mode: [`vmj.Smoothed`][]`()` in reverse mode,
      `vmj.Smoothed(derivatives="forward")` in forward mode.
    - `chunk_size`, `progress`, `devices`, `client`, `store`, `resume`: for a grid, as in
      [`vmj.sweep`][].
    - `**solver_args`: passed to `fn` (e.g. `a0=0.06, n=12`).

    **Returns:** a dict mapping each name in `wrt` to `d fn / d parameter`, shaped like the
    output of `fn` (in the output's unit per the parameter's unit, e.g. m per kg/s). For a grid,
    a [`vmj.SweepResult`][] whose `values` map `"d_" + name` to the derivative at every point
    (the grid's shape in front; the prefix keeps the fields apart from the grid's coordinates
    in exports).
    """
    if mode not in ("forward", "reverse"):
        raise ValueError(f"mode must be 'forward' or 'reverse' (got {mode!r})")
    wrt = name_list(wrt)
    if not wrt:
        raise ValueError("wrt must name at least one parameter")
    if len(set(wrt)) != len(wrt):
        raise ValueError(f"wrt names a parameter twice: {wrt}")
    base = model.model if isinstance(model, Grid) else model
    field_names = [w for w in wrt if w not in solver_args]
    paths = [resolve_field(base, w) for w in field_names]
    for w in wrt:
        if w in solver_args and isinstance(solver_args[w], (bool, str)):
            raise ValueError(f"{w} is not a float argument of fn (got {solver_args[w]!r})")
    if isinstance(model, Grid) or any(np.ndim(x) for x in jax.tree.leaves(model)):
        from ._sweep import sweep

        return sweep(
            _PointSensitivity(fn, wrt, mode),
            model,
            chunk_size=chunk_size,
            progress=progress,
            devices=devices,
            client=client,
            store=store,
            resume=resume,
            **solver_args,
        )
    theta0 = {
        w: _float(solver_args[w] if w in solver_args else _get(model, paths[field_names.index(w)]))
        for w in wrt
    }
    for w, v in theta0.items():
        if jnp.ndim(v) != 0:
            raise ValueError(
                f"sensitivity takes scalar parameters ({w} has shape "
                f"{jnp.shape(v)}); use vmj.sweep or jax.vmap over a batch"
            )

    try:
        out = _sensitivity(
            fn, model, tuple(paths), tuple(field_names), wrt, mode, theta0, solver_args
        )
    except TypeError as err:
        if "custom_vjp" not in str(err):
            raise
        raise ValueError(
            "mode='forward' cannot differentiate fn: it solves by reverse mode only (e.g. "
            "vmj.Smoothed(), through diffrax's adjoint): use mode='reverse', or solve with "
            "vmj.Smoothed(derivatives='forward')"
        ) from None
    return {w: out[w] for w in wrt}


class _PointSensitivity(eqx.Module):
    """The sensitivities at one point of a grid, named `d_<parameter>` (a picklable function
    of the point's model, so that a cluster's workers receive it once)."""

    fn: Callable = eqx.field(static=True)
    wrt: tuple = eqx.field(static=True)
    mode: str = eqx.field(static=True)

    @property
    def _vmj_description(self) -> str:
        """What a sweep's `function` attribute says: `vmj.sensitivity(module.fn, wrt=(F, mu),
        mode=forward)`."""
        from ._store import describe_fn

        return (
            f"vmj.sensitivity({describe_fn(self.fn)}, wrt=({', '.join(self.wrt)}), "
            f"mode={self.mode})"
        )

    def __call__(self, model, **solver_args):
        got = sensitivity(self.fn, model, self.wrt, mode=self.mode, **solver_args)
        return {f"d_{w}": got[w] for w in self.wrt}


@filter_jit
def _sensitivity(fn, model, paths, field_names, wrt, mode, theta0, solver_args):
    def of(theta):
        m = model
        if paths:
            m = eqx.tree_at(
                lambda m: [_get(m, p) for p in paths], m, [theta[w] for w in field_names]
            )
        args = {**solver_args, **{w: theta[w] for w in wrt if w in solver_args}}
        with collecting() as checks:  # returned out of the derivative's trace (`Failures`)
            out = fn(m, **args)
        for leaf in jax.tree.leaves(out):
            if not jnp.issubdtype(jnp.result_type(leaf), jnp.inexact):
                raise ValueError(
                    "sensitivity needs fn to return float arrays only (got an integer or boolean "
                    "output: select float fields such as .amplitudes, .times or .stop_time)"
                )
        return out, checks.failures()

    jac, failures = (jax.jacfwd if mode == "forward" else jax.jacrev)(of, has_aux=True)(theta0)
    jac = failures.guard(jac)  # fn's checks, in this trace: values of `filter_jit`'s program
    # jac has the output's structure with a dict over `wrt` at each leaf: put `wrt` outside
    outer = jax.tree.structure(jax.eval_shape(lambda theta: of(theta)[0], theta0))
    inner = jax.tree.structure(theta0)
    swapped = jax.tree.transpose(outer, inner, jac)
    return {w: swapped[w] for w in wrt}


def central_difference(fn, model, name: str, step: float, **solver_args):
    """Central finite difference of `fn` in one parameter (used by tests and examples)."""
    if name in solver_args:
        x = float(solver_args[name])
        hi = fn(model, **{**solver_args, name: x + step})
        lo = fn(model, **{**solver_args, name: x - step})
    else:
        path = resolve_field(model, name)
        x = float(_get(model, path))
        at = lambda v: eqx.tree_at(lambda m: _get(m, path), model, jnp.asarray(v))  # noqa: E731
        hi, lo = fn(at(x + step), **solver_args), fn(at(x - step), **solver_args)
    return jax.tree.map(lambda a, b: (np.asarray(a) - np.asarray(b)) / (2 * step), hi, lo)
