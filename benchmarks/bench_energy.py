"""The energy-balance recurrences at scale: 10^6 random points x 12 half-swings (eps in [0, 1],
mu in [0, 10] kg/s, delta in [-3, 3] kg/s; the paper's m0, c, F_T, a0).

- `vmj.sweep` of the amplitudes `vmj.turning_points(m, a0, n, vmj.EnergyBalance()).amplitudes`
  into a new (10^6, 12) NumPy array (96 MB);
- the same recurrences written with NumPy, tuned: every array preallocated and every operation
  in place (one core, as NumPy runs), the result a (10^6, 12) view;
- the elementwise limit of this machine: one `exp`, `sqrt` and division per half-swing and
  point, 96 MB written, one XLA program over all points (XLA spreads it over the cores), its
  result a NumPy array as the sweep's is (on an accelerator written to pinned host memory, as
  the sweep's chunks are: `host_output`), compiled with the XLA options of the sweep's chunks
  (`chunk_options`: 512-bit vectors on a CPU with AVX-512).

Goals: vmj >= 3 x faster than the NumPy version, and within 2 x of the limit. The three are
measured in turns (`interleaved`: one call of each per round), so that the machine's changes of
speed during the run reach all three alike.

`--float32` runs all three in float32 (JAX's x64 off, the NumPy arrays float32), as the issue
asks for on a GPU besides float64; on a GPU the sweep and the limit run there, NumPy on the host.

Run: .venv/bin/python benchmarks/bench_energy.py [--points 1000000] [--quick] [--float32]
"""

import argparse
import functools
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _timing import REPEAT, interleaved, machine, ratio, repeat, set_up_jax  # noqa: E402

FLOAT32 = set_up_jax()  # as the vmj command runs (float32 with --float32)

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

import vmj  # noqa: E402
from vmj._sweep._sweep import chunk_options, host_output  # noqa: E402

M0, C, FT, A0, N = 5.0, 4900.0, 14.7, 0.06, 12


def numpy_in_place(eps, mu, delta):
    """Amplitudes of the recurrences (vmj.EnergyBalance's docstring), Coulomb friction, with
    preallocated work arrays and in-place operations."""
    P, dtype = eps.size, eps.dtype
    k = np.pi / np.sqrt(C)  # half-period / sqrt(m)
    e = (delta - 2 * delta * eps - 2 * mu) * (k / 4)  # exponent * sqrt(m)
    kd = k * delta  # mass change / sqrt(m)
    q = 2 * FT / C
    out = np.empty((N, P), dtype)
    m, a = np.full(P, M0, dtype), np.full(P, A0, dtype)
    r, x, E, phi, w = (np.empty(P, dtype) for _ in range(5))
    go, flag = np.empty(P, bool), np.empty(P, bool)
    for i in range(N):
        np.sqrt(m, out=r)
        np.divide(e, r, out=x)  # the exponent of E_k
        np.exp(x, out=E)
        np.expm1(x, out=phi)  # phi = (E - 1)/x, 1 at x = 0
        np.not_equal(x, 0, out=flag)
        np.divide(phi, x, out=phi, where=flag)
        np.logical_not(flag, out=flag)
        phi[flag] = 1.0
        np.multiply(r, kd, out=w)
        np.add(w, m, out=w)  # the next mass
        np.greater(a, FT / C, out=go)  # c a > F: the mass moves on
        np.greater(w, 0, out=flag)
        np.logical_and(go, flag, out=go)
        np.multiply(a, E, out=x)
        np.multiply(phi, q, out=phi)
        np.subtract(x, phi, out=x)  # the next amplitude (< 0: did not pass x = 0)
        np.abs(x, out=x)
        np.copyto(m, w, where=go)
        np.copyto(a, x, where=go)
        out[i] = a
    return out.T


@functools.partial(
    jax.jit,
    out_shardings=host_output(jax.local_devices(), None),
    compiler_options=chunk_options(jax.local_devices()) or None,
)
def limit(x):
    """One exp, sqrt and division per half-swing and point, (P, 12) float64 written."""
    y = x[:, None] + jnp.arange(N, dtype=x.dtype)
    return jnp.exp(-y) / jnp.sqrt(y)


def amplitudes(model, a0, n):
    return vmj.turning_points(model, a0, n, vmj.EnergyBalance()).amplitudes


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--points", type=int, default=10**6)
    ap.add_argument("--quick", action="store_true", help="small sizes (a smoke run)")
    ap.add_argument("--float32", action="store_true", help="everything in float32")
    args = ap.parse_args()
    if args.quick:
        args.points = 10**4
    vmj.retain_host_memory()  # as the vmj command does
    print(machine())
    P = args.points
    rng = np.random.default_rng(1)
    dtype = np.float32 if FLOAT32 else np.float64
    eps, mu, delta = (rng.uniform(lo, hi, P).astype(dtype) for lo, hi in ((0, 1), (0, 10), (-3, 3)))
    model = vmj.VariableMass(M0, C, delta, eps, mu, vmj.Coulomb(FT))

    def sweep():
        return vmj.sweep(amplitudes, model, a0=A0, n=N, progress=False).values

    first = repeat(sweep, times=1)
    got, ref = sweep(), numpy_in_place(eps, mu, delta)
    agree = float(np.max(np.abs(got - ref))) / A0
    del got, ref
    x = jnp.asarray(rng.uniform(1, 2, P).astype(dtype))
    t_vmj, t_numpy, t_limit = interleaved(
        (sweep, 1),
        (lambda: numpy_in_place(eps, mu, delta), 1),
        (lambda: np.asarray(limit(x)), 1),
        rounds=max(REPEAT, 7),
        warm_up=True,
    )
    print(
        f"energy balance, {P} points x {N} half-swings, amplitudes into a ({P}, {N}) "
        f"{np.dtype(dtype).name} array on {jax.devices()[0].platform} (compile + first call "
        f"{first.median:.1f} s)"
    )
    print(f"  vmj.sweep:                 {t_vmj}")
    print(f"  NumPy, in place (1 core):  {t_numpy}   (agrees with vmj to {agree:.0e} of a0)")
    print(f"  elementwise limit (XLA):   {t_limit}")
    ratio("NumPy / vmj", t_numpy, t_vmj, ">= 3")
    ratio("vmj / limit", t_vmj, t_limit, "<= 2")


if __name__ == "__main__":
    main()
