"""Speed of the variable-mass solvers at scale, as ratios measured in this run.

1. Exact turning points, 12 swings, 4096 random (eps, mu, delta) points, float64: `vmj.sweep`
   of `vmj.turning_points` against the event-driven SciPy loop (tests/scipy_reference.py,
   DOP853, rtol 1e-12) timed point by point on a subset; accuracy on that subset; forward-mode
   sensitivities over the same batch (gradients intact). Compile time reported separately.
2. Energy-balance recurrences, 10^6 points x 12 swings: `vmj.sweep` of the amplitudes (what a
   plain `vmap` of a `lax.scan` of the recurrence returns) and of the whole `DecaySequence`
   (times, positions, crossings, count, status), both into new NumPy arrays, each against one
   plain jitted `jax.vmap` of the same function over all points; the amplitude sweep once more
   in a new process without `vmj.retain_host_memory` (which this benchmark, like the `vmj`
   command, calls at start-up).
3. Cold start of `vmj table 1` (a new process). A persistent compilation cache does not help:
   JAX does not store executables with host callbacks, which `equinox.error_if` uses.

Run: .venv/bin/python benchmarks/bench_sweep.py [--points 4096] [--scipy-points 40] [--quick]
"""

import argparse
import os
import subprocess
import sys
import time

import jax

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

import vmj  # noqa: E402

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "tests"))
from scipy_reference import variable_mass_turning_points  # noqa: E402

M0, C, FT, A0, N = 5.0, 4900.0, 14.7, 0.06, 12
ENERGY_CHUNK = 32768  #: points per compiled call in the energy-balance sweeps


CPU = {}  #: label -> best process CPU time [s] (all threads), printed next to the wall times
MEDIAN = {}  #: label -> median wall time [s]


def best_of(fn, repeat, label=None):
    """Best wall time of `repeat` runs (and, under `label`, the median wall time and the best
    CPU time, which a machine shared with other jobs disturbs less)."""
    times, cpus = [], []
    for _ in range(repeat):
        t, c = time.perf_counter(), time.process_time()
        out = fn()
        jax.block_until_ready(out)
        times.append(time.perf_counter() - t)
        cpus.append(time.process_time() - c)
    if label:
        CPU[label] = min(cpus)
        MEDIAN[label] = float(np.median(times))
    return min(times), out


def random_points(n, seed=0):
    rng = np.random.default_rng(seed)
    return rng.uniform(0, 1, n), rng.uniform(0, 10, n), rng.uniform(-3, 3, n)


def model_of(eps, mu, delta):
    return vmj.VariableMass(M0, C, delta, eps, mu, vmj.Coulomb(FT))


def bench_exact(points, scipy_points, repeat):
    eps, mu, delta = random_points(points)
    model = model_of(eps, mu, delta)
    run = lambda: vmj.sweep(vmj.turning_points, model, a0=A0, n=N, chunk_size=points)  # noqa
    t0 = time.perf_counter()
    first = run()
    first_call = time.perf_counter() - t0
    t_run, res = best_of(lambda: run().values.positions, repeat, "exact")
    res = run().values
    per_point = t_run / points
    # SciPy, point by point, on a subset
    idx = np.linspace(0, points - 1, scipy_points).astype(int)
    t0 = time.perf_counter()
    refs = [variable_mass_turning_points(M0, C, delta[i], eps[i], mu[i], A0, N, F=FT) for i in idx]
    scipy_per_point = (time.perf_counter() - t0) / len(idx)
    err_x = err_t = 0.0
    mismatched = 0
    for i, (t_ref, x_ref, _) in zip(idx, refs):
        k = len(x_ref)
        mismatched += int(res.count[i]) != k
        if k:
            err_x = max(err_x, float(np.max(np.abs(res.positions[i, :k] - x_ref))) / A0)
            err_t = max(err_t, float(np.max(np.abs(res.times[i, :k] - t_ref) / t_ref)))
    # gradients intact: forward-mode sensitivities of every amplitude over the same batch
    amp = lambda m, a0, n: vmj.turning_points(m, a0, n).amplitudes  # noqa: E731
    sens = lambda m: vmj.sensitivity(amp, m, ("F", "mu", "eps", "delta"), a0=A0, n=N)  # noqa
    t0 = time.perf_counter()
    g = vmj.sweep(sens, model, chunk_size=points)
    g_first = time.perf_counter() - t0
    t_grad, _ = best_of(lambda: vmj.sweep(sens, model, chunk_size=points).values["mu"],
                        max(1, repeat - 1))
    finite = all(np.isfinite(v).all() for v in g.values.values())
    print(f"exact turning points, {N} swings, {points} random points (eps in [0,1], "
          f"mu in [0,10] kg/s, delta in [-3,3] kg/s), float64")
    print(f"  vmj.sweep:      {t_run * 1e3:8.1f} ms  = {per_point * 1e6:7.2f} us/point "
          f"(CPU {CPU['exact'] * 1e3:.1f} ms; compile + first call {first_call:.1f} s)")
    print(f"  SciPy DOP853:   {scipy_per_point * 1e3:8.2f} ms/point ({len(idx)} points, "
          f"rtol 1e-12, event loop)")
    print(f"  ratio:          {scipy_per_point / per_point:8.0f} x faster per point "
          f"(target >= 300 x)")
    print(f"  accuracy vs SciPy on {len(idx)} points: max |x - x_ref|/a0 = {err_x:.1e}, "
          f"max rel. time error = {err_t:.1e}, count mismatches = {mismatched}")
    print(f"  sensitivities d a_k/d(F, mu, eps, delta), forward mode: {t_grad * 1e3:.1f} ms = "
          f"{t_grad / points * 1e6:.1f} us/point (compile + first {g_first:.1f} s), "
          f"all finite: {finite}")
    return first


def amplitudes(m, a0, n):
    return vmj.energy_balance(m, a0, n).amplitudes


def energy_swept(fn, points):
    """A `vmj.sweep` of `fn` over `points` random points, and the time of its first call."""
    host = model_of(*random_points(points, seed=1))
    run = lambda: vmj.sweep(fn, host, a0=A0, n=N, chunk_size=ENERGY_CHUNK,  # noqa: E731
                            progress=False)
    t0 = time.perf_counter()
    run()
    return time.perf_counter() - t0, run


def bench_energy(points, repeat):
    """The recurrences for `points` random points x 12 swings: `vmj.sweep` against one plain
    jitted `jax.vmap` of the same function, for the amplitudes and for the whole decay sequence;
    and the amplitude sweep once more in a new process whose allocator was left as it is."""
    args = [jnp.asarray(v) for v in random_points(points, seed=1)]
    mb = lambda r: sum(np.asarray(v).nbytes for v in jax.tree.leaves(r)) / 1e6  # noqa: E731
    print(f"energy balance, {points} points x {N} swings, float64 (target < 100 ms)")
    results = {}
    for label, fn in (("amplitudes", amplitudes), ("DecaySequence", vmj.energy_balance)):
        first, run = energy_swept(fn, points)
        t_sweep, res = best_of(run, repeat, label)
        del res
        plain = jax.jit(jax.vmap(lambda e, m, d: fn(model_of(e, m, d), A0, N)))  # noqa: B023
        jax.block_until_ready(plain(*args))
        t_plain, results[label] = best_of(lambda: plain(*args), repeat, label + " plain")
        print(f"  vmj.sweep, {label} ({mb(results[label]):.0f} MB): {t_sweep * 1e3:7.1f} ms "
              f"(median {MEDIAN[label] * 1e3:.1f} ms; CPU {CPU[label] * 1e3:.0f} ms; "
              f"compile + first {first:.1f} s)")
        print(f"    one jit(vmap) over all points: {t_plain * 1e3:7.1f} ms (median "
              f"{MEDIAN[label + ' plain'] * 1e3:.1f} ms); ratio {t_plain / t_sweep:.2f} x")
        if label == "amplitudes":
            default = subprocess.run(
                [sys.executable, __file__, "--default-allocator", "--amplitudes-only",
                 f"--energy-points={points}", f"--repeat={repeat}"],
                check=True, capture_output=True, text=True).stdout.split()
            print(f"    the same sweep without vmj.retain_host_memory (new process): "
                  f"{float(default[0]):7.1f} ms (median {float(default[1]):.1f} ms)")
    same = np.array_equal(results["amplitudes"], np.abs(results["DecaySequence"].positions))
    print(f"  (chunks of {ENERGY_CHUNK} points, one thread per core; amplitudes identical: "
          f"{same})")


def bench_cold_start():
    vmj_bin = os.path.join(os.path.dirname(sys.executable), "vmj")
    times = []
    for _ in range(2):
        t0 = time.perf_counter()
        subprocess.run([vmj_bin, "table", "1"], check=True, stdout=subprocess.DEVNULL)
        times.append(time.perf_counter() - t0)
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-c", "import vmj"], check=True)
    imp = time.perf_counter() - t0
    print("cold start of `vmj table 1` (new process, wall time; target < 10 s)")
    print(f"  {times[0]:5.1f} s, {times[1]:5.1f} s (of which `import vmj` {imp:.1f} s; the rest "
          f"is compiling the vmapped exact and energy-balance solvers)")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--points", type=int, default=4096)
    ap.add_argument("--energy-points", type=int, default=10**6)
    ap.add_argument("--scipy-points", type=int, default=40)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--quick", action="store_true", help="small sizes (a smoke run)")
    ap.add_argument("--default-allocator", action="store_true",
                    help="leave the C allocator as it is (no vmj.retain_host_memory)")
    ap.add_argument("--amplitudes-only", action="store_true",
                    help="only time the energy-balance amplitude sweep; print best and median "
                         "wall time [ms]")
    args = ap.parse_args()
    if args.quick:
        args.points, args.energy_points, args.scipy_points, args.repeat = 256, 10**4, 5, 2
    if not args.default_allocator:
        vmj.retain_host_memory()  # as the vmj command does (docs/performance.md)
    if args.amplitudes_only:
        t, _ = best_of(energy_swept(amplitudes, args.energy_points)[1], args.repeat, "sweep")
        print(f"{t * 1e3:.1f} {MEDIAN['sweep'] * 1e3:.1f}")
        return
    print(f"jax {jax.__version__}, devices {jax.devices()}, {os.cpu_count()} CPUs, "
          f"load average {os.getloadavg()[0]:.1f}")
    bench_exact(args.points, args.scipy_points, args.repeat)
    bench_energy(args.energy_points, args.repeat)
    bench_cold_start()


if __name__ == "__main__":
    main()
