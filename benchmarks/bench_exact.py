"""The exact turning points at scale, their arithmetic, and one warm call.

1. `vmj.sweep(vmj.turning_points, model, a0=0.06, n=12)` over 4096 random points (eps in [0, 1],
   mu in [0, 10] kg/s, delta in [-3, 3] kg/s; the paper's m0 = 5 kg, c = 4900 N/m,
   F_T = 14.7 N) against the event-driven SciPy loop (tests/scipy_reference.py: DOP853, rtol
   1e-12, a terminal velocity-zero event per half-swing) on a subset of the same points, per
   point, median against median (goal: >= 5000 x); the accuracy on that subset.
2. The arithmetic per point: operations counted in the solver's own program (jaxpr) for one
   substep, one Newton iteration and the rest of a half-swing, times the loop iterations
   actually run (a replay of the loops, step for step, reproduces the solver's turning points:
   it gives each lane's iterations and each batch's, where every loop runs to its slowest
   lane), against fixed loops (8 substeps, 8 Newton iterations, 12 half-swings). The
   counted-flop floor is the operations the lanes need divided by this machine's measured rate
   of elementwise multiply-adds in XLA on all cores (goal: the sweep within 3 x of it). The
   sweep, the SciPy loop and the multiply-add kernel are measured in turns (`interleaved`), so
   that the machine's changes of speed during the run reach them alike.
3. One warm `vmj.turning_points(model, 0.06, 12)` call (goal: <= 100 us), run as the `vmj`
   command runs it (JAX's CPU dispatch synchronous, `jax_cpu_enable_async_dispatch = False`,
   as this whole benchmark) and, in a process of its own, with JAX's default asynchronous
   dispatch; on an accelerator, also on the machine's CPU (`jax.default_device`).

`--float32` runs vmj in float32 (JAX's x64 off; SciPy stays float64, its only precision), as
the issue asks for on a GPU besides float64. Part 2 is a CPU's floor and is skipped on other
platforms.

Run: .venv/bin/python benchmarks/bench_exact.py [--points 4096] [--scipy-points 32] [--quick]
[--float32]
"""

import argparse
import functools
import json
import os
import subprocess
import sys
import threading

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.join(HERE, "..", "tests"))
from _timing import REPEAT, Timing, interleaved, machine, ratio, repeat, set_up_jax  # noqa: E402

FLOAT32 = set_up_jax()  # as the vmj command runs (float32 with --float32)

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
from jax import lax  # noqa: E402
from scipy_reference import variable_mass_turning_points  # noqa: E402

import vmj  # noqa: E402
from vmj._numerics._roots import converged_fraction  # noqa: E402
from vmj._numerics._series import derivative, horner, horner_and_derivative  # noqa: E402
from vmj._solvers import _exact  # noqa: E402
from vmj._sweep._sweep import chunk_options  # noqa: E402

M0, C, FT, A0, N = 5.0, 4900.0, 14.7, 0.06, 12
MAX_SUBSTEPS = 8  #: vmj.Exact()'s default for the variable-mass model

#: arithmetic primitives counted as operations (comparisons and selects are not)
ARITHMETIC = {
    "add",
    "sub",
    "mul",
    "div",
    "neg",
    "abs",
    "sqrt",
    "rsqrt",
    "exp",
    "log",
    "max",
    "min",
    "sign",
    "integer_pow",
    "pow",
    "expm1",
    "log1p",
    "tanh",
    "square",
}


def points(n, seed=0):
    rng = np.random.default_rng(seed)
    return rng.uniform(0, 1, n), rng.uniform(0, 10, n), rng.uniform(-3, 3, n)


def model_of(eps, mu, delta):
    return vmj.VariableMass(M0, C, delta, eps, mu, vmj.Coulomb(FT))


# -- operations in the solver's program ---------------------------------------------------------
def _ops(jaxpr, loops, conds=None):
    """Arithmetic operations of `jaxpr` outside its while loops, whose (cond, body) jaxprs are
    appended to `loops` in program order; of a conditional, its cheapest branch, the extra
    operations of its dearest appended to `conds`."""
    count = 0
    for eqn in jaxpr.eqns:
        name = eqn.primitive.name
        if name == "while":
            loops.append((eqn.params["cond_jaxpr"].jaxpr, eqn.params["body_jaxpr"].jaxpr))
            continue
        if name == "cond":
            branches = sorted(_ops(b.jaxpr, loops) for b in eqn.params["branches"])
            count += branches[0]
            if conds is not None:
                conds.append(branches[-1] - branches[0])
            continue
        if name in ARITHMETIC:
            count += int(np.prod(eqn.outvars[0].aval.shape, dtype=int)) or 1
        for value in eqn.params.values():
            for sub in value if isinstance(value, (tuple, list)) else (value,):
                inner = getattr(sub, "jaxpr", None)
                if inner is not None and hasattr(inner, "eqns"):
                    count += _ops(inner, loops)
                elif hasattr(sub, "eqns"):
                    count += _ops(sub, loops)
    return count


def operation_counts():
    """Operations per lane: outside the swings, per half-swing (its first substep, the rest
    rule, the Newton start, the implicit step, the bookkeeping), per further substep and per
    Newton iteration (each with its loop test), and the series recomputed for Newton where a
    further substep held the zero."""
    model = model_of(0.5, 2.0, 1.0)
    jaxpr = jax.make_jaxpr(
        lambda m, a0: _exact._solve_decay(m, a0, N, MAX_SUBSTEPS, "lax", values=True)
    )(model, jnp.asarray(A0)).jaxpr
    top = []
    outside = _ops(jaxpr, top)
    ((swing_cond, swing_body),) = top
    inner, conds = [], []
    per_swing = _ops(swing_body, inner, conds) + _ops(swing_cond, [])
    (sub_cond, sub_body), (newton_cond, newton_body) = inner
    return {
        "outside": outside,
        "swing": per_swing,
        "substep": _ops(sub_body, []) + _ops(sub_cond, []),
        "newton": _ops(newton_body, []) + _ops(newton_cond, []),
        "recompute": max(conds),
    }


# -- the loops, replayed step by step with their iterations counted -----------------------------
def _replay_swing(model, t, x, active):
    """One half-swing of one lane as the solver runs it: `(t1, x1, moving, substeps, newton
    iterations)` (a lane that has stopped takes none)."""
    s, t_go, stuck = model.rest(t, x)
    moving = active & jnp.logical_not(stuck)
    scale = model.swing_scale(t_go, x)

    def substep(carry, _):  # (a loop: unrolled, XLA computed each substep's chains anew in
        # every kernel that reads them, and the next substep's in those, without end)
        tt, xx, vv, found, start, substeps = carry
        h, _, t_next = model.substep(tt, scale)
        cs = model.taylor(tt, xx, vv, s, _exact.ORDER)
        x1, v1 = horner_and_derivative(cs, h)
        early = horner(derivative(cs), 0.5 * h) * s <= 0
        hit = jnp.logical_not(found) & (early | (v1 * s <= 0))
        held = (tt, xx, vv, jnp.where(early, 0.5 * h, h))
        start = tuple(jnp.where(hit, a, b) for a, b in zip(held, start))
        substeps = substeps + jnp.logical_not(found)
        found = found | hit
        tt, xx, vv = (jnp.where(found, a, b) for a, b in ((tt, t_next), (xx, x1), (vv, v1)))
        return (tt, xx, vv, found, start, substeps), None

    zero = jnp.zeros_like(x)
    init = (t_go, x, zero, jnp.logical_not(moving), (t_go, x, zero, zero), jnp.zeros((), jnp.int32))
    *_, start, substeps = lax.scan(substep, init, None, length=MAX_SUBSTEPS)[0]
    t0, x0, v0, h = start
    cs = model.taylor(t0, x0, v0, s, _exact.ORDER)
    f_cs = [c * s for c in derivative(cs)]
    tau = jnp.clip(t_go + model.half_period(t_go, scale) - t0, 0.05 * h, h)
    lo, hi, done, newton = jnp.zeros_like(h), h, jnp.zeros((), bool), jnp.zeros((), jnp.int32)
    for _ in range(_exact.NEWTON):
        fx, dfx = horner_and_derivative(f_cs, tau)
        ahead = fx > 0
        lo2, hi2 = jnp.where(ahead, tau, lo), jnp.where(ahead, hi, tau)
        step = tau - fx / jnp.where(dfx != 0, dfx, 1.0)
        ok = (dfx != 0) & (step >= lo2) & (step <= hi2)
        new = jnp.where(ok, step, 0.5 * (lo2 + hi2))
        newton = newton + jnp.logical_not(done)
        converged = (jnp.abs(new - tau) <= converged_fraction(h.dtype) * h) | (fx == 0)
        tau, lo, hi = (jnp.where(done, a, b) for a, b in ((tau, new), (lo, lo2), (hi, hi2)))
        done = done | converged
    fx, dfx = horner_and_derivative(derivative(cs), tau)
    tau = tau - fx / jnp.where(dfx != 0, dfx, 1.0)
    t1, x1 = t0 + tau, horner(cs, tau)
    return (
        jnp.where(moving, t1, t),
        jnp.where(moving, x1, x),
        moving,
        jnp.where(moving, substeps, 0),
        jnp.where(moving, newton, 0),
    )


def replay(eps, mu, delta):
    """Per lane and half-swing: turning points, whether it moved, substeps and Newton
    iterations."""

    def one(e, m, d):
        model = model_of(e, m, d)

        def body(carry, _):
            t, x, active = carry
            t1, x1, moving, k, it = _replay_swing(model, t, x, active)
            return (t1, x1, moving), (t1, x1, moving, k, it)

        return lax.scan(
            body, (jnp.zeros(()), -A0 * jnp.ones(()), jnp.ones((), bool)), None, length=N
        )[1]

    return [np.asarray(a) for a in jax.jit(jax.vmap(one))(eps, mu, delta)]


# -- this machine's rate of elementwise multiply-adds (XLA, all cores) --------------------------
def multiply_add_kernel(lanes=4096, chain=25, steps=400):
    """Dependent multiply-add chains (`x = x a + b`) over `lanes` elements, one thread per core
    as the sweeps run, compiled with the XLA options of the sweep's chunks (`chunk_options`):
    `(run, operations, cores)`, `run()` evaluating them on all cores at once (two operations
    per multiply-add)."""

    @functools.partial(jax.jit, compiler_options=chunk_options(jax.local_devices()) or None)
    def kernel(x, a, b):
        def body(_, x):
            for _ in range(chain):
                x = x * a + b
            return x

        return lax.fori_loop(0, steps, body, x)

    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    args = [
        jnp.asarray(np.random.default_rng(i).uniform(0.5, 0.9, (3, lanes))) for i in range(cores)
    ]
    for a in args:
        kernel(*a).block_until_ready()

    def all_cores():
        threads = [
            threading.Thread(target=lambda a=a: kernel(*a).block_until_ready()) for a in args
        ]
        for th in threads:
            th.start()
        for th in threads:
            th.join()

    return all_cores, 2 * chain * steps * lanes * cores, cores


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--points", type=int, default=4096)
    ap.add_argument("--scipy-points", type=int, default=32)
    ap.add_argument("--quick", action="store_true", help="small sizes (a smoke run)")
    ap.add_argument("--one-call", action="store_true", help="only part 3, its times as JSON")
    ap.add_argument("--async-dispatch", action="store_true", help="JAX's default dispatch")
    ap.add_argument("--float32", action="store_true", help="vmj in float32")
    args = ap.parse_args()
    if args.one_call:
        print(json.dumps(one_call().times.tolist()))
        return
    if args.quick:
        args.points, args.scipy_points = 256, 4
    vmj.retain_host_memory()  # as the vmj command does
    print(machine())
    platform = jax.devices()[0].platform
    P = args.points
    eps, mu, delta = points(P)
    model = model_of(eps, mu, delta)

    # 1. the sweep against SciPy on a subset of the same points
    def sweep():
        return vmj.sweep(vmj.turning_points, model, a0=A0, n=N, progress=False)

    first = repeat(sweep, times=1)
    res = sweep()
    idx = np.linspace(0, P - 1, args.scipy_points).astype(int)
    refs = {}

    def scipy_subset():
        for i in idx:
            refs[i] = variable_mass_turning_points(M0, C, delta[i], eps[i], mu[i], A0, N, F=FT)

    # in turns: three sweeps (milliseconds each: more runs steady the median), the SciPy loop and,
    # on a CPU, three runs of the multiply-add kernel that sets the floor
    rate = multiply_add_kernel() if platform == "cpu" else None
    t_sweep, t_scipy, *t_rate = interleaved(
        (sweep, 3),
        (scipy_subset, 1),
        *([(rate[0], 3)] if rate else []),
        rounds=max(REPEAT, 7),
        warm_up=True,
    )
    t_sweep, t_scipy = t_sweep.per(P), t_scipy.per(len(idx))
    err_x = err_t = 0.0
    mismatched = 0
    for i in idx:
        t_ref, x_ref, _ = refs[i]
        k = len(x_ref)
        mismatched += int(res.values.count[i]) != k
        if k:
            big = np.abs(x_ref) > 0.01 * A0
            err_x = max(
                err_x,
                float(
                    np.max(
                        np.abs(res.values.positions[i, :k] - x_ref)[big] / np.abs(x_ref[big]),
                        initial=0.0,
                    )
                ),
            )
            err_t = max(err_t, float(np.max(np.abs(res.values.times[i, :k] - t_ref) / t_ref)))
    print(
        f"exact turning points, {N} half-swings, {P} random points, "
        f"{'float32' if FLOAT32 else 'float64'} on {platform} ({res.chunks} chunk(s); compile + "
        f"first call {first.median:.1f} s)"
    )
    print(f"  vmj.sweep:         {t_sweep} per point")
    print(f"  SciPy event loop:  {t_scipy} per point ({len(idx)} of the same points)")
    ratio("SciPy / vmj, per point", t_scipy, t_sweep, ">= 5000")
    print(
        f"  accuracy on those points: amplitudes (> 1 % of a0) {err_x:.1e} relative, times "
        f"{err_t:.1e} relative, turning point counts differing: {mismatched}"
    )

    # 2. the arithmetic
    if rate:
        floor_of(res, P, eps, mu, delta, t_sweep, t_rate[0], *rate[1:])
    else:
        print(f"  (the counted-flop floor is a CPU's: skipped on {platform})")

    # 3. one warm call, as the vmj command runs it and with JAX's default dispatch (a setting
    # read once per process)
    t_one = one_call()
    default = subprocess.run(
        [sys.executable, __file__, "--one-call", "--async-dispatch"] + ["--float32"] * FLOAT32,
        capture_output=True,
        text=True,
        check=True,
    )
    t_async = Timing(json.loads(default.stdout.splitlines()[-1]))
    print(f"  one warm vmj.turning_points(model, {A0}, {N}) call: {t_one}  (goal <= 100 us)")
    print(f"  the same with JAX's asynchronous dispatch (its default): {t_async}")
    if platform != "cpu":  # a single solve on this machine's CPU instead (jax.default_device)
        with jax.default_device(jax.devices("cpu")[0]):
            print(f"  the same on this machine's CPU: {one_call()}")


def floor_of(res, P, eps, mu, delta, t_sweep, t_rate, rate_ops, cores):
    """Part 2: the operations the sweep ran and needed, and the counted-flop floor (`t_rate`:
    the multiply-add kernel's times, `rate_ops` operations on `cores` cores each)."""
    ops = operation_counts()
    tr, xr, moving, substeps, newton = replay(*(jnp.asarray(v) for v in (eps, mu, delta)))
    replay_error = float(np.max(np.abs(np.where(moving, xr - res.values.positions, 0.0))))
    chunk = -(-P // res.chunks)
    batches = [slice(c * chunk, min((c + 1) * chunk, P)) for c in range(res.chunks)]

    def total(swings, k, it):  # (`k` substeps per swing: the first is the swing's own)
        further = np.maximum(k - 1, 0)
        return (
            ops["outside"]
            + swings * ops["swing"]
            + further.sum(-1) * ops["substep"]
            + (further > 0).sum(-1) * ops["recompute"]
            + it * ops["newton"]
        )

    lane = total(moving.sum(1), substeps, newton.sum(1))  # what each lane needs
    run = np.concatenate(
        [
            np.full(
                b.stop - b.start,
                total(int(moving[b].any(0).sum()), substeps[b].max(0), int(newton[b].max(0).sum())),
            )
            for b in batches
        ]
    )  # what each lane's batch runs
    fixed = total(N, np.full(N, MAX_SUBSTEPS), N * _exact.NEWTON)
    rate, fastest = rate_ops / t_rate.median, rate_ops / t_rate.times.min()
    floor = lane.sum() / rate / P
    print(
        f"  operations: {ops['swing']} per half-swing with its first substep, "
        f"{ops['substep']} per further substep (and {ops['recompute']} for Newton's series), "
        f"{ops['newton']} per Newton iteration, {ops['outside']} once"
    )
    print(
        f"  iterations per point: {moving.sum(1).mean():.2f} half-swings, "
        f"{substeps.sum(1).mean():.2f} substeps, {newton.sum(1).mean():.2f} Newton iterations "
        f"needed; the batches run {np.mean([moving[b].any(0).sum() for b in batches]):.2f}, "
        f"{np.mean([substeps[b].max(0).sum() for b in batches]):.2f}, "
        f"{np.mean([newton[b].max(0).sum() for b in batches]):.2f} (replay of the loops "
        f"reproduces the turning points to {replay_error:.0e} m)"
    )
    print(
        f"  operations per point: {lane.mean():.0f} needed, {run.mean():.0f} run (batches), "
        f"{fixed} with fixed loops (8 substeps, 8 Newton iterations, {N} half-swings)"
    )
    print(
        f"  multiply-adds on {cores} cores: {rate / 1e9:.1f} G operations/s (median; fastest run "
        f"{fastest / 1e9:.1f}) -> counted-flop floor {floor * 1e9:.0f} ns per point"
    )
    ratio("sweep / floor", t_sweep, Timing([floor]), "<= 3")
    # (this machine's rate moves by up to 2 x between runs: the floor at its fastest run too)
    ratio(
        "sweep / floor at the fastest multiply-add run",
        t_sweep,
        Timing([floor * rate / fastest]),
        "",
    )


def one_call() -> Timing:
    one = model_of(0.0, 2.0, 3.0)
    jax.block_until_ready(vmj.turning_points(one, A0, N))
    return repeat(
        lambda: vmj.turning_points(one, A0, N),
        times=max(REPEAT, 7),
        number=1000,
        block=jax.block_until_ready,
    )


if __name__ == "__main__":
    main()
