"""A sweep on a Dask cluster against the same sweep in-process, measured in this run.

1. Throughput: the same 10^6-point exact sweep (`vmj.turning_points`, 12 swings, random
   (eps, mu, delta, F) points, float64, default chunks) in-process (one thread per core) and on
   a LocalCluster of one single-threaded worker process per core (localhost), alternating,
   after one warm-up run of each (compilation). Medians with min/max; the ratio of medians;
   the CPU time of all the processes involved (less disturbed than wall time on a shared
   machine); the results compared to the last bit.
2. The cost of a chunk: the same two paths on 4096 points in chunks of 16 (256 chunks of
   negligible work), so that the difference per chunk is the Dask overhead (submit, schedule,
   run, send the result back, hand it over).
3. Writing to a Zarr store as the chunks complete: the cluster sweep of (1) with `store=`; what
   the client receives per second from a worker and writes per second to a store.
4. A paper estimate of a 10^9-point sweep on 100 such workers from the figures above: the
   arithmetic, the per-chunk overhead, the scheduler's rate and what the client receives.

Run: .venv/bin/python benchmarks/bench_distributed.py [--points 1000000] [--repeat 5]
"""

import argparse
import os
import shutil
import sys
import tempfile
import time

import jax

jax.config.update("jax_enable_x64", True)

import numpy as np  # noqa: E402

import vmj  # noqa: E402
from vmj._sweep._engine import CORES  # noqa: E402

M0, C, A0, N = 5.0, 4900.0, 0.06, 12


def points(n, seed=0):
    rng = np.random.default_rng(seed)
    return vmj.VariableMass(
        M0,
        C,
        rng.uniform(-3, 3, n),
        rng.uniform(0, 1, n),
        rng.uniform(0, 10, n),
        vmj.Coulomb(rng.uniform(5, 20, n)),
    )


def timed(fn):
    t = time.perf_counter()
    out = fn()
    return time.perf_counter() - t, out


def stats(times):
    return f"median {np.median(times):7.3f} s (min {min(times):.3f}, max {max(times):.3f})"


def same_bits(a, b):
    return all(
        np.asarray(x).tobytes() == np.asarray(y).tobytes()
        for x, y in zip(jax.tree.leaves(a.values), jax.tree.leaves(b.values))
    )


def result_bytes(r):
    return sum(np.asarray(x).nbytes for x in jax.tree.leaves(r.values))


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--points", type=int, default=10**6)
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    import distributed

    vmj.retain_host_memory()
    n, rep = args.points, args.repeat
    model = points(n)
    print(
        f"{n} points x {N} swings, exact solver, float64; {CORES} cores; in-process: "
        f"{CORES} threads; cluster: LocalCluster of {CORES} single-threaded worker processes"
    )
    cluster = distributed.LocalCluster(
        n_workers=CORES,
        threads_per_worker=1,
        processes=True,
        host="127.0.0.1",
        dashboard_address=None,
    )
    client = distributed.Client(cluster)
    try:

        def here(**kw):
            return vmj.sweep(vmj.turning_points, model, a0=A0, n=N, **kw)

        def there(**kw):
            return vmj.sweep(vmj.turning_points, model, a0=A0, n=N, client=client, **kw)

        t_first_here, ref = timed(here)
        t_first_there, got = timed(there)
        print(
            f"first runs (compilation included): in-process {t_first_here:.2f} s, cluster "
            f"{t_first_there:.2f} s; {ref.chunks} chunks; equal to the last bit: "
            f"{same_bits(ref, got)}"
        )

        def worker_cpu():
            return sum(client.run(time.process_time).values())

        th, tc, ch, cc = [], [], [], []
        for _ in range(rep):
            c0 = time.process_time()
            th.append(timed(here)[0])
            ch.append(time.process_time() - c0)
            c0, w0 = time.process_time(), worker_cpu()
            tc.append(timed(there)[0])
            cc.append(time.process_time() - c0 + worker_cpu() - w0)
        ratio = np.median(tc) / np.median(th)
        big_overhead = (np.median(tc) - np.median(th)) * CORES / ref.chunks
        print(f"in-process: {stats(th)}  ({n / np.median(th):.3g} points/s)")
        print(f"cluster:    {stats(tc)}  ({n / np.median(tc):.3g} points/s)")
        print(
            f"cluster / in-process (medians): {ratio:.3f}  (goal <= 1.3); the difference is "
            f"{big_overhead * 1e3:.1f} ms per chunk of {-(-n // ref.chunks)} points and "
            f"worker"
        )
        print(
            f"CPU time of all processes (client and scheduler, workers): in-process "
            f"{stats(ch)}, cluster {stats(cc)}: ratio of medians "
            f"{np.median(cc) / np.median(ch):.3f}"
        )

        # 2. the cost of a chunk
        small = points(4096, seed=1)
        tiny = 16

        def k_here():
            return vmj.sweep(vmj.turning_points, small, a0=A0, n=N, chunk_size=tiny)

        def k_there():
            return vmj.sweep(vmj.turning_points, small, a0=A0, n=N, chunk_size=tiny, client=client)

        k_here(), k_there()
        sh, sc = [], []
        for _ in range(rep):
            sh.append(timed(k_here)[0])
            sc.append(timed(k_there)[0])
        chunks = -(-4096 // tiny)
        per_here = np.median(sh) * CORES / chunks
        per_there = np.median(sc) * CORES / chunks
        overhead = per_there - per_here
        print(f"{chunks} chunks of {tiny} points: in-process {stats(sh)}, cluster {stats(sc)}")
        print(
            f"per chunk and worker: in-process {per_here * 1e3:.2f} ms, cluster "
            f"{per_there * 1e3:.2f} ms: Dask overhead {overhead * 1e3:.2f} ms per chunk "
            f"({overhead / (np.median(ch) / ref.chunks) * 100:.2f} % of the CPU time of a "
            f"default chunk of {-(-n // ref.chunks)} points)"
        )

        # the scheduler's rate: tasks per second for empty tasks through the same cluster
        client.gather(client.map(abs, range(2000), pure=False))  # warm-up
        futures = client.map(abs, range(-2000, 0), pure=False)
        t0 = time.perf_counter()
        client.gather(futures)
        per_task = (time.perf_counter() - t0) / 2000
        del futures
        print(f"empty tasks through the scheduler: {1 / per_task:.0f} per second")

        # 3. what the client does per byte: receive results from a worker, write them
        nbytes = result_bytes(ref)
        block = client.submit(np.ones, 2**22, pure=False)  # 32 MB on a worker
        client.gather(block)
        tr = []
        for _ in range(rep):
            block = client.submit(np.ones, 2**22 + len(tr), pure=False)
            distributed.wait(block)
            tr.append(timed(lambda: client.gather(block))[0])
        receive_rate = 2**25 / np.median(tr)
        tmp = tempfile.mkdtemp()
        try:
            ts, tw = [], []
            for i in range(max(3, rep // 2)):
                path = os.path.join(tmp, f"s{i}.zarr")
                ts.append(timed(lambda: there(store=path))[0])
                # the client's writing alone: the same result into a new store, chunk by chunk
                copy = os.path.join(tmp, f"w{i}.zarr")
                tw.append(timed(lambda: write_only(copy, ref))[0])
            write_rate = nbytes / np.median(tw)
            print(
                f"cluster with store=: {stats(ts)} ({nbytes / 1e6:.0f} MB of results; store on "
                f"disk {du(os.path.join(tmp, 's0.zarr')) / 1e6:.0f} MB)"
            )
            print(
                f"the client receives {receive_rate / 1e6:.0f} MB/s from a worker (32 MB "
                f"blocks, median) and writes a sweep's store at about "
                f"{write_rate / 1e6:.0f} MB/s (the same result written chunk by chunk: "
                f"{stats(tw)})"
            )
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
    finally:
        client.close()
        cluster.close()

    # 4. a paper estimate: 10^9 points on 100 workers like these. The arithmetic per point and
    # core from the in-process CPU time (wall time on a shared machine is not a core's work)
    big, workers = 10**9, 100
    core_per_point = np.median(ch) / n
    compute = big * core_per_point / workers
    per_chunk = max(overhead, big_overhead, 0.0)
    per_point_bytes = result_bytes(ref) / n
    per_byte = 1 / receive_rate + 1 / write_rate  # the client receives, then writes
    print(
        f"paper estimate, 10^9 points on {workers} single-threaded workers like these: "
        f"arithmetic {compute:.0f} s ({core_per_point * 1e6:.2f} us CPU per point)"
    )
    for chunk in (16384, 65536):
        chunks = -(-big // chunk)
        over = chunks * per_chunk / workers
        sched = chunks * per_task
        whole = big * per_point_bytes * per_byte
        one = big * 8 * per_byte
        print(
            f"  chunks of {chunk} ({chunks}): Dask overhead {over:.1f} s "
            f"({per_chunk * 1e3:.1f} ms per chunk), the scheduler {sched:.0f} s (overlapping "
            f"the work), the client {whole:.0f} s for the whole DecaySequence "
            f"({per_point_bytes:.0f} bytes per point, {big * per_point_bytes / 1e9:.0f} GB) "
            f"or {one:.0f} s for one 8-byte field: wall about "
            f"{max(compute + over, sched, whole):.0f} s, or {max(compute + over, sched, one):.0f}"
            f" s for one field (plus one compilation per worker, in parallel)"
        )
    return 0


def write_only(path, r):
    """Write a sweep result of paired points into a new store, chunk by chunk, as the client
    does when the chunks come in (the same store code, without evaluating anything)."""
    from vmj._sweep._result import export_names
    from vmj._sweep._store import ChunkStore

    n = r.shape[0]
    leaves = [np.asarray(x) for x in jax.tree.leaves(r.values)]
    names, kdims, kcoords = export_names(r.values, 1, {"point"})
    chunk = -(-n // r.chunks)
    st = ChunkStore.create(
        path,
        kind="sweep",
        definition={"copy": path},
        described={},
        plan={"n": n, "chunk": chunk, "n_chunks": r.chunks},
    )
    st.create_sweep_arrays(
        [(nm, x.dtype, x.shape[1:], kd) for nm, x, kd in zip(names, leaves, kdims)], {}, {}, kcoords
    )
    for c in range(r.chunks):
        st.write(c, [x[c * chunk : (c + 1) * chunk] for x in leaves], names)


def du(path):
    return sum(os.path.getsize(os.path.join(d, f)) for d, _, fs in os.walk(path) for f in fs)


if __name__ == "__main__":
    sys.exit(main())
