"""Sweeps, sensitivities and maps on a Dask cluster (a LocalCluster of two worker processes,
localhost only) and in a resumable Zarr store: equal to the in-process sweep to the last bit, a
worker killed mid-sweep, a sweep interrupted (client closed, Ctrl-C) and resumed, a different
definition refused, corrupted and half-written chunks recomputed, failed chunks recorded."""

import glob
import os
import signal
import sys

import jax
import numpy as np
import pytest

import vmj
from vmj._sweep import _sweep as sweep_module

distributed = pytest.importorskip("distributed")
dask = pytest.importorskip("dask")
zarr = pytest.importorskip("zarr")
cloudpickle = pytest.importorskip("cloudpickle")
# the workers cannot import this test module: send its functions by value
cloudpickle.register_pickle_by_value(sys.modules[__name__])

N = 100_000
SWINGS = 6
CHUNK = 5000  # 20 chunks
KW = dict(a0=0.06, n=SWINGS, chunk_size=CHUNK)


class SharedCompilationCache(distributed.WorkerPlugin):
    """The workers (and a worker restarted after a kill) load what this test run compiled."""

    def __init__(self, path):
        self.path = path

    def setup(self, worker):
        jax.config.update("jax_compilation_cache_dir", self.path)
        jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)  # (conftest.py)


@pytest.fixture(scope="module")
def client():
    cluster = distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address=None
    )
    with cluster, distributed.Client(cluster) as c:
        cache = jax.config.jax_compilation_cache_dir
        if cache:
            c.register_plugin(SharedCompilationCache(cache))
        yield c


@pytest.fixture(scope="module")
def points():
    rng = np.random.default_rng(13)
    return vmj.VariableMass(
        5.0,
        4900.0,
        rng.uniform(-3, 3, N),
        rng.uniform(0, 1, N),
        rng.uniform(0, 10, N),
        vmj.Coulomb(rng.uniform(5, 20, N)),
    )


@pytest.fixture(scope="module")
def in_process(points):
    r = vmj.sweep(vmj.turning_points, points, **KW)
    assert r.chunks == 20 and r.computed == 20
    return r


def assert_bitwise_equal(a, b):
    la, lb = jax.tree.leaves(a), jax.tree.leaves(b)
    assert len(la) == len(lb)
    for x, y in zip(la, lb):
        x, y = np.asarray(x), np.asarray(y)
        assert x.dtype == y.dtype and x.shape == y.shape
        assert x.tobytes() == y.tobytes()


def traces():
    return sweep_module._TRACES


def status(path):
    return np.asarray(zarr.open_group(str(path), mode="r")["vmj_status"][:])


def test_cluster_sweep_equals_in_process_to_the_last_bit(client, points, in_process):
    before = client.run(traces)
    r = vmj.sweep(vmj.turning_points, points, client=client, **KW)
    assert_bitwise_equal(r.values, in_process.values)
    assert r.chunks == 20 and r.computed == 20
    # each worker compiled once (one trace of the chunk function), however many chunks it ran
    after = client.run(traces)
    assert {w: after[w] - before.get(w, 0) for w in after} == {w: 1 for w in after}
    # a sweep is a Zarr store labelled like the xarray export
    assert r.values.positions.shape == (N, SWINGS)


def test_worker_killed_mid_sweep(client, points, in_process, tmp_path):
    pids = client.run(os.getpid)
    victim = sorted(pids.values())[0]
    killed = {}

    def kill(done, total):
        if done == 3:
            os.kill(victim, signal.SIGKILL)
            killed["at"] = (done, total)

    store = tmp_path / "killed.zarr"
    r = vmj.sweep(vmj.turning_points, points, client=client, store=str(store), progress=kill, **KW)
    assert killed["at"] == (3, 20)  # while 17 chunks were still to do
    assert_bitwise_equal(r.values, in_process.values)
    # every chunk written once: 20 computed and handed to the store, all marked done
    assert r.computed == 20 and r.resumed == 0
    assert list(status(store)) == [1] * 20
    back = vmj.SweepResult.read_zarr(str(store))
    np.testing.assert_array_equal(back.values["positions"], in_process.values.positions)
    client.wait_for_workers(2, timeout=120)
    assert victim not in client.run(os.getpid).values()


def test_job_lost_with_its_only_worker(client, points, in_process, monkeypatch):
    # the sweep's definition is scattered to one worker only, which is then killed: the chunks
    # waiting on it are cancelled by Dask, the job is scattered again and they rerun. (Killed
    # as soon as it holds the definition: killed after a few chunks, the other worker may
    # already have fetched a copy for its own chunks, and nothing is lost.)
    pids = client.run(os.getpid)
    address, victim = sorted(pids.items(), key=lambda item: item[1])[0]
    scatter, calls = client.scatter, []

    def only_to_victim(data, **kw):
        calls.append(kw)
        if len(calls) == 1:
            future = scatter(data, workers=[address], hash=False)
            os.kill(victim, signal.SIGKILL)
            return future
        return scatter(data, **kw)

    monkeypatch.setattr(client, "scatter", only_to_victim)

    r = vmj.sweep(vmj.turning_points, points, client=client, progress=False, **KW)
    assert len(calls) == 2  # scattered again once
    assert_bitwise_equal(r.values, in_process.values)
    assert r.computed == 20
    client.wait_for_workers(2, timeout=120)


def test_interrupted_sweep_resumes_with_only_the_missing_chunks(
    client, points, in_process, tmp_path
):
    store = str(tmp_path / "stopped.zarr")
    other = distributed.Client(client.scheduler.address)

    def stop(done, total):
        if done == 7:
            other.close()  # the client goes away mid-sweep

    with pytest.raises(Exception, match="interrupted"):
        vmj.sweep(vmj.turning_points, points, client=other, store=store, progress=stop, **KW)
    assert int(np.sum(status(store) == 1)) == 7
    r = vmj.sweep(vmj.turning_points, points, client=client, store=store, resume=True, **KW)
    assert (r.resumed, r.computed) == (7, 13)
    assert_bitwise_equal(r.values, in_process.values)


def test_ctrl_c_in_process_then_resume(points, in_process, tmp_path):
    store = str(tmp_path / "ctrl-c.zarr")

    def ctrl_c(done, total):
        if done == 4:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        vmj.sweep(vmj.turning_points, points, store=store, progress=ctrl_c, **KW)
    assert int(np.sum(status(store) == 1)) == 4
    r = vmj.sweep(vmj.turning_points, points, store=store, resume=True, **KW)
    assert (r.resumed, r.computed) == (4, 16)
    assert_bitwise_equal(r.values, in_process.values)


def test_store_refuses_another_definition_and_recomputes_damaged_chunks(
    points, in_process, tmp_path
):
    store = tmp_path / "sweep.zarr"
    first = vmj.sweep(vmj.turning_points, points, store=str(store), **KW)
    assert_bitwise_equal(first.values, in_process.values)
    with pytest.raises(ValueError, match="already holds this sweep: pass resume=True"):
        vmj.sweep(vmj.turning_points, points, store=str(store), **KW)
    with pytest.raises(
        ValueError,
        match=r"holds a different sweep: solver arguments \(stored "
        r"a0=0.06, n=6",
    ):
        vmj.sweep(vmj.turning_points, points, store=str(store), resume=True, **{**KW, "a0": 0.05})
    with pytest.raises(ValueError, match=r"chunk_size \(stored 5000, now 4000\)"):
        vmj.sweep(
            vmj.turning_points, points, store=str(store), resume=True, **{**KW, "chunk_size": 4000}
        )
    changed = vmj.VariableMass(
        5.0, 4900.0, points.delta, points.eps.at[17].set(0.5), points.mu, points.friction
    )
    with pytest.raises(
        ValueError, match=r"parameter eps \(stored 100000 values in .* now 100000 values in "
    ):
        vmj.sweep(vmj.turning_points, changed, store=str(store), resume=True, **KW)
    with pytest.raises(ValueError, match="fn .*energy_amplitudes"):
        vmj.sweep(energy_amplitudes, points, store=str(store), resume=True, **KW)
    assert list(status(store)) == [1] * 20  # nothing was touched

    # damage four chunks: garbage in a data file, a data file lost after its marker was
    # written, a marker lost after the data (a run killed between them), a marker unreadable
    (garbage,) = glob.glob(str(store / "positions" / "c" / "3" / "0"))
    with open(garbage, "r+b") as fh:
        fh.seek(8)
        fh.write(os.urandom(64))
    os.remove(store / "times" / "c" / "11" / "0")
    os.remove(store / "vmj_status" / "c" / "7")
    (store / "vmj_status" / "c" / "15").write_bytes(b"\xff")
    # (opening reads the markers and checksums only: the two damaged data files are found when read, see
    # tests/test_sweep_audit.py; resuming reads every finished chunk and finds all four)
    with pytest.raises(ValueError, match="unfinished sweep: 2 of 20 chunks"):
        vmj.SweepResult.read_zarr(str(store))
    again = vmj.sweep(vmj.turning_points, points, store=str(store), resume=True, **KW)
    assert (again.resumed, again.computed) == (16, 4)
    assert_bitwise_equal(again.values, in_process.values)
    back = vmj.SweepResult.read_zarr(str(store))
    assert back.shape == (N,) and back.dims == ("point",)
    np.testing.assert_array_equal(back.values["times"], in_process.values.times)
    np.testing.assert_array_equal(back.coords["eps"], np.asarray(points.eps))


def failing_grid():
    # a shrinking mass with almost no friction swings until its mass is gone (t = m0/|delta|)
    m = vmj.VariableMass(5.0, 4900.0, -3.0, 0.0, 0.0, vmj.Coulomb(14.7))
    return vmj.grid(m, F=[14.7, 0.01])


@pytest.mark.parametrize("where", ["in-process", "cluster"])
def test_failed_chunk_is_recorded_and_the_sweep_goes_on(where, client, tmp_path):
    store = str(tmp_path / "failing.zarr")
    kw = dict(
        a0=0.06,
        n=40,
        throw=True,
        chunk_size=1,
        store=store,
        client=client if where == "cluster" else None,
    )
    with pytest.raises(vmj.SweepError, match="1 of 2 chunks failed") as info:
        vmj.sweep(vmj.turning_points, failing_grid(), **kw)
    err = info.value
    code = int(vmj.RESULTS.mass_exhausted)
    assert err.failures == {1: (1, 1, code, vmj.RESULTS.mass_exhausted.message)}
    ok = vmj.turning_points(
        vmj.VariableMass(5.0, 4900.0, -3.0, 0.0, 0.0, vmj.Coulomb(14.7)), 0.06, 40
    )
    np.testing.assert_allclose(
        err.result.values.positions[0], ok.positions, rtol=0, atol=1e-12 * 0.06
    )
    assert np.isnan(err.result.values.positions[1]).all()
    assert list(status(store)) == [1, 2]
    failures = zarr.open_group(store, mode="r").attrs["vmj_failures"]
    assert failures == {"1": {"code": code, "message": vmj.RESULTS.mass_exhausted.message}}
    # a rerun computes the failed chunk only (and records it again)
    with pytest.raises(vmj.SweepError) as again:
        vmj.sweep(vmj.turning_points, failing_grid(), resume=True, **kw)
    assert again.value.result.resumed == 1 and again.value.result.computed == 0


def energy_amplitudes(m, a0, n):
    return vmj.turning_points(m, a0, n, vmj.EnergyBalance()).amplitudes


def test_sensitivity_over_a_grid_on_the_cluster(client, tmp_path):
    model = vmj.VariableMass(5.0, 4900.0, 3.0, 0.0, 2.0, vmj.Coulomb(14.7))
    g = vmj.grid(model, eps=np.linspace(0, 1, 7), mu=np.linspace(0, 9, 5))
    wrt = ("mu", "F", "a0")
    here = vmj.sensitivity(energy_amplitudes, g, wrt, a0=0.06, n=8)
    there = vmj.sensitivity(
        energy_amplitudes, g, wrt, a0=0.06, n=8, client=client, store=str(tmp_path / "sens.zarr")
    )
    assert set(here.values) == {"d_mu", "d_F", "d_a0"} and here.dims == ("eps", "mu")
    assert_bitwise_equal(here.values, there.values)
    one = vmj.sensitivity(
        energy_amplitudes,
        vmj.VariableMass(5.0, 4900.0, 3.0, 0.5, 4.5, vmj.Coulomb(14.7)),
        wrt,
        a0=0.06,
        n=8,
    )
    for w in wrt:
        np.testing.assert_allclose(here.values[f"d_{w}"][3, 2], one[w], rtol=1e-12)
    ds = vmj.SweepResult.read_zarr(str(tmp_path / "sens.zarr")).to_xarray()
    assert ds.d_mu.dims == ("eps", "mu", "k")


def norms(rows):
    return [float(np.linalg.norm(r)) for r in rows]


def test_map_chunks_on_the_cluster_resumes(client, tmp_path):
    items = [np.arange(i, i + 5, dtype=float) for i in range(40)]
    want = norms(items)
    store = str(tmp_path / "map.zarr")

    def ctrl_c(done, total):
        if done == 2:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        vmj.map_chunks(norms, items, chunk_size=4, store=store, progress=ctrl_c)
    got = vmj.map_chunks(norms, items, chunk_size=4, store=store, resume=True, client=client)
    assert got == want
    assert list(status(store)) == [1] * 10
    with pytest.raises(ValueError, match="holds a different map: items"):
        vmj.map_chunks(norms, items[:-1], chunk_size=4, store=store, resume=True)


def test_bad_arguments(points, tmp_path):
    with pytest.raises(ValueError, match="resume=True needs a store"):
        vmj.sweep(vmj.turning_points, points, resume=True, **KW)
    with pytest.raises(ValueError, match="resume must be True or False"):
        vmj.sweep(vmj.turning_points, points, store=str(tmp_path / "s.zarr"), resume="yes", **KW)
    with pytest.raises(ValueError, match="client must be a dask.distributed.Client"):
        vmj.sweep(vmj.turning_points, points, client=3, **KW)
    # Dask's own messages ("invalid literal for int()") named no argument; and the failed
    # client left itself as the process's scheduler (later store reads failed)
    scheduler = dask.config.get("scheduler", None)
    with pytest.raises(ValueError, match="client 'tcp://127.0.0.1:abc' is not a scheduler"):
        vmj.sweep(vmj.turning_points, points, client="tcp://127.0.0.1:abc", **KW)
    assert dask.config.get("scheduler", None) == scheduler
    (tmp_path / "plain").mkdir()
    with pytest.raises(ValueError, match="is not a vmj store"):
        vmj.sweep(vmj.turning_points, points, store=str(tmp_path / "plain"), resume=True, **KW)
    with pytest.raises(ValueError, match="items must not be empty"):
        vmj.map_chunks(norms, [])


def test_cli_bad_scheduler_address(capsys):
    from vmj.cli import main

    argv = ["sweep", "variable-mass", "--eps", "0,1", "--method", "energy", "--n", "2"]
    argv += ["--set", "m0=5,c=4900,delta=3,mu=2,FT=14.7,a0=0.06", "--scheduler", "bogus"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("vmj: error: --scheduler 'bogus' is not a scheduler address"), err


def synthetic_records(count):
    import fits

    rng = np.random.default_rng(5)
    records = []
    for i in range(count):
        F, mu = rng.uniform(8, 20), rng.uniform(0.5, 4)
        seq = vmj.turning_points(
            vmj.VariableMass(5.0, 4900.0, 3.0, 0.0, mu, vmj.Coulomb(F)),
            0.06,
            8,
            vmj.EnergyBalance(),
        )
        n = int(seq.count)
        positions = np.concatenate([[-0.06], np.asarray(seq.positions)[:n]])
        positions = positions + rng.normal(0, 2e-4, n + 1)
        records.append(fits.record_from_sequence(positions=positions, source=f"record {i}"))
    return records


@pytest.mark.long
@pytest.mark.filterwarnings("ignore::UserWarning")  # FT and mu correlated in short records
def test_batched_fit_of_200_records_on_the_cluster(client, tmp_path):
    import fits

    records = synthetic_records(200)
    given = {"m0": 5.0, "c": 4900.0, "delta": 3.0, "eps": 0.0, "a0": 0.06}
    kw = dict(forward="energy", compare=False, intervals=False, chunk_size=50)
    here = fits.fit_batch(records, "variable-mass", ("FT", "mu"), given, **kw)
    there = fits.fit_batch(
        records,
        "variable-mass",
        ("FT", "mu"),
        given,
        client=client,
        store=str(tmp_path / "fits.zarr"),
        **kw,
    )
    assert len(here) == len(there) == 200
    for a, b in zip(here, there):
        assert a.params == b.params and a.stderr == b.stderr and a.iterations == b.iterations
        assert a.record.source == b.record.source
        for name in a.residuals:
            assert (
                np.asarray(a.residuals[name]).tobytes() == np.asarray(b.residuals[name]).tobytes()
            )
    # all 200 in one batch: the same fits to within the solver's convergence (the chunks pad
    # and batch the records differently)
    whole = fits.fit_batch(
        records, "variable-mass", ("FT", "mu"), given, forward="energy", compare=False
    )
    for a, b in zip(here, whole):
        for name in a.params:
            np.testing.assert_allclose(a.params[name], b.params[name], rtol=1e-6)
    again = fits.fit_batch(
        records,
        "variable-mass",
        ("FT", "mu"),
        given,
        client=client,
        store=str(tmp_path / "fits.zarr"),
        resume=True,
        **kw,
    )
    assert [r.params for r in again] == [r.params for r in there]
