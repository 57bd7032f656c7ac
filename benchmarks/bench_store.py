"""What reading a sweep's Zarr store costs in memory and time, against the store's size.

A grid energy-balance sweep (`vmj.turning_points`, 12 swings, `--eps` x 100 x 100 points,
float64, default chunks) is written to a store once; then each operation runs in a fresh
process, which prints its wall time, its CPU time and how much its peak RSS (VmHWM) grew:

- `resume`: `vmj.sweep(..., store=path, resume=True)` of the finished sweep (every finished
  chunk read once and checked against its checksums; nothing left to compute);
- `open`: `vmj.SweepResult.read_zarr(path)` (the completion markers only);
- `mean`: `values["positions"].mean(axis=0).compute()`, a reduction over the first axis
  (every chunk of one field read once and checked);
- `columns`: `SweepResult.columns()` (every field read into memory, chunk by chunk);
- `asarray`: `np.asarray(values["positions"])`, one field loaded whole, for comparison;
- `limited`: the reduction of `mean` with the address space capped
  (`resource.setrlimit(RLIMIT_AS)`) at what the process had mapped after opening the store and a
  first small read (dask's threads started) plus `--budget` MB (default: half the field); then
  `np.asarray` of the field under the same cap (expected: MemoryError).

Run: .venv/bin/python benchmarks/bench_store.py [--eps 400] [--budget MB] [--dir DIR]
"""

import argparse
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time

import jax

jax.config.update("jax_enable_x64", True)

import numpy as np  # noqa: E402

import vmj  # noqa: E402

OPS = ("resume", "open", "mean", "columns", "asarray", "limited")


def sweep_of(n_eps):
    model = vmj.VariableMass(5.0, 4900.0, 3.0, 0.0, 2.0, vmj.Coulomb(14.7))
    g = vmj.grid(
        model,
        eps=np.linspace(0, 1, n_eps),
        mu=np.linspace(0, 10, 100),
        delta=np.linspace(-3, 3, 100),
    )
    return g, dict(a0=0.06, n=12, solver=vmj.EnergyBalance())


def status(key):
    for line in open("/proc/self/status"):
        if line.startswith(key + ":"):
            return int(line.split()[1]) * 1024
    raise KeyError(key)


def cpu():
    return sum(resource.getrusage(resource.RUSAGE_SELF)[:2])


def one(op, path, n_eps, budget):
    """Run `op` on the store at `path` in this process; print its figures as JSON."""
    import dask.array  # noqa: F401  (imported before the clock starts, as vmj's own are)
    import zarr  # noqa: F401

    g, kw = sweep_of(n_eps)
    out = {}
    result = None
    if op not in ("resume", "open"):
        result = vmj.SweepResult.read_zarr(path)
    if op == "limited":
        result.values["positions"][0, 0].compute()  # (dask's threads started)
        cap = status("VmSize") + budget * 2**20
        resource.setrlimit(resource.RLIMIT_AS, (cap, resource.getrlimit(resource.RLIMIT_AS)[1]))
        out["cap_mb"] = cap / 2**20
    open("/proc/self/clear_refs", "w").write("5")  # (resets VmHWM)
    base, t, c = status("VmHWM"), time.perf_counter(), cpu()
    if op == "resume":
        r = vmj.sweep(vmj.turning_points, g, store=path, resume=True, **kw)
        out["computed"] = r.computed
    elif op == "open":
        vmj.SweepResult.read_zarr(path)
    elif op in ("mean", "limited"):
        m = result.values["positions"].mean(axis=0).compute()
        out["mean_shape"] = list(m.shape)
    elif op == "columns":
        out["columns"] = len(result.columns())
    elif op == "asarray":
        np.asarray(result.values["positions"])
    out.update(
        wall=time.perf_counter() - t,
        cpu=cpu() - c,
        grew_mb=(status("VmHWM") - base) / 2**20,
        base_mb=base / 2**20,
    )
    if op == "limited":
        try:
            np.asarray(result.values["positions"])
            out["whole_field"] = "loaded"
        except MemoryError:
            out["whole_field"] = "MemoryError"
    print(json.dumps(out))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--eps", type=int, default=400, help="values of eps (x 100 x 100 points)")
    ap.add_argument("--budget", type=int, help="MB above the mapped memory (half the field)")
    ap.add_argument("--dir", default=None, help="where to write the store (default: a temp dir)")
    ap.add_argument("--op", choices=OPS, help=argparse.SUPPRESS)
    ap.add_argument("--store", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.op:
        return one(args.op, args.store, args.eps, args.budget)

    where = tempfile.mkdtemp(dir=args.dir)
    try:
        path = os.path.join(where, "sweep.zarr")
        g, kw = sweep_of(args.eps)
        t, c = time.perf_counter(), cpu()
        r = vmj.sweep(vmj.turning_points, g, store=path, **kw)
        made, made_cpu = time.perf_counter() - t, cpu() - c
        n = int(np.prod(r.shape))
        values = sum(v.nbytes for v in jax.tree.leaves(r.values))
        field = r.values.positions.nbytes
        disk = sum(os.path.getsize(os.path.join(d, f)) for d, _, fs in os.walk(path) for f in fs)
        budget = args.budget or int(field / 2 / 2**20)
        print(
            f"store: {n} points in {r.chunks} chunks; values {values / 1e6:.0f} MB "
            f"(positions {field / 1e6:.0f} MB), {disk / 1e6:.0f} MB on disk; written in "
            f"{made:.1f} s ({made_cpu:.1f} s CPU); limited: mapped + {budget} MB"
        )
        print(f"{'operation':>9} {'wall s':>7} {'CPU s':>6} {'peak RSS growth MB':>19}")
        for op in OPS:
            cmd = [sys.executable, __file__, "--op", op, "--store", path, "--eps", str(args.eps)]
            cmd += ["--budget", str(budget)]
            done = subprocess.run(cmd, capture_output=True, text=True)
            if done.returncode:
                print(f"{op:>9} failed: {done.stderr.strip().splitlines()[-1]}")
                continue
            got = json.loads(done.stdout.strip().splitlines()[-1])
            extra = {k: v for k, v in got.items() if k not in ("wall", "cpu", "grew_mb")}
            print(f"{op:>9} {got['wall']:7.2f} {got['cpu']:6.2f} {got['grew_mb']:19.0f}   {extra}")
    finally:
        shutil.rmtree(where, ignore_errors=True)


if __name__ == "__main__":
    main()
