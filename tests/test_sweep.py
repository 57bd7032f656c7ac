"""vmj.sweep / vmj.grid: point-by-point equality, the SciPy reference, broadcasting, chunking,
bounded memory, sharding over 4 devices, CSV / NetCDF export and the `vmj sweep` command."""

import gc
import json
import os
import platform
import subprocess
import sys
import textwrap
import weakref

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy_reference import variable_mass_turning_points

import vmj
from vmj._sweep._engine import CORES, Progress, run_chunks
from vmj._sweep._sweep import (
    ACCELERATOR_CHUNK,
    DEFAULT_CHUNK,
    _SweepJob,
    chunk_lanes,
    chunk_options,
    chunk_plan,
    default_chunk,
    host_output,
    pinned_host,
    vmap_in_place,
)

LANES = chunk_lanes(jax.local_devices())  #: this machine's cores on a CPU, 1 on a GPU


def n_chunks(n, chunk_size, lanes=LANES):
    return -(-n // chunk_plan(n, chunk_size, lanes))


A0 = 0.06
N_SWINGS = 12
EPS, MU, DELTA = [0.0, 0.4, 1.0], [0.0, 2.0, 9.0], [-3.0, 3.0]


def paper_model(delta=3.0, eps=0.0, mu=2.0, F=14.7):
    return vmj.VariableMass(5.0, 4900.0, delta, eps, mu, vmj.Coulomb(F))


@pytest.fixture(scope="module")
def exact_grid():
    g = vmj.grid(paper_model(), eps=EPS, mu=MU, delta=DELTA)
    # 18 points in chunks of at most 8, at least one per core, of equal size (4 of 5 on two
    # cores, the last overlapping the one before)
    return vmj.sweep(vmj.turning_points, g, a0=A0, n=N_SWINGS, chunk_size=8)


def test_grid_axes_and_shape(exact_grid):
    r = exact_grid
    assert r.dims == ("eps", "mu", "delta")
    assert r.shape == (3, 3, 2) and r.chunks == n_chunks(18, 8) >= 3
    assert r.values.positions.shape == (3, 3, 2, N_SWINGS)
    assert r.values.count.shape == (3, 3, 2)
    np.testing.assert_array_equal(r.coords["mu"], MU)


def test_sweep_equals_point_by_point(exact_grid):
    r = exact_grid
    for i, e in enumerate(EPS):
        for j, m in enumerate(MU):
            for k, d in enumerate(DELTA):
                one = vmj.turning_points(paper_model(d, e, m), A0, N_SWINGS)
                np.testing.assert_allclose(
                    r.values.positions[i, j, k], one.positions, rtol=0, atol=1e-12 * A0
                )
                np.testing.assert_allclose(r.values.times[i, j, k], one.times, rtol=1e-12)
                for name in ("crossed", "count", "stopped", "result"):
                    np.testing.assert_array_equal(
                        getattr(r.values, name)[i, j, k], getattr(one, name)
                    )


@pytest.mark.parametrize("idx", [(0, 0, 1), (1, 1, 0), (2, 2, 1), (2, 0, 0)])
def test_sweep_matches_scipy(exact_grid, idx):
    i, j, k = idx
    t_ref, x_ref, c_ref = variable_mass_turning_points(
        5.0, 4900.0, DELTA[k], EPS[i], MU[j], A0, N_SWINGS, F=14.7
    )
    seq = exact_grid.values
    count = int(seq.count[idx])
    assert count == len(x_ref)
    np.testing.assert_allclose(seq.positions[idx][:count], x_ref, rtol=0, atol=1e-7 * A0)
    np.testing.assert_allclose(seq.times[idx][:count], t_ref, rtol=1e-7)
    np.testing.assert_array_equal(seq.crossed[idx][:count], c_ref)


def test_paired_points_broadcast_like_numpy():
    eps = np.array([0.0, 0.3, 1.0])
    mu = np.array([2.0, 5.0, 9.0])
    paired = vmj.sweep(
        vmj.turning_points, paper_model(eps=eps, mu=mu), a0=A0, n=8, solver=vmj.EnergyBalance()
    )
    assert paired.dims == ("point",) and paired.shape == (3,)
    assert set(paired.coords) == {"eps", "mu"}
    for p in range(3):
        one = vmj.turning_points(paper_model(eps=eps[p], mu=mu[p]), A0, 8, vmj.EnergyBalance())
        np.testing.assert_allclose(paired.values.positions[p], one.positions, atol=1e-12 * A0)
    # (2, 1) x (3,) broadcasts to a 2 x 3 product, the same as the grid over those axes
    outer = vmj.sweep(
        vmj.turning_points,
        paper_model(eps=eps[:2, None], mu=mu),
        a0=A0,
        n=8,
        solver=vmj.EnergyBalance(),
    )
    g = vmj.sweep(
        vmj.turning_points,
        vmj.grid(paper_model(), eps=eps[:2], mu=mu),
        a0=A0,
        n=8,
        solver=vmj.EnergyBalance(),
    )
    assert outer.shape == g.shape == (2, 3)
    assert outer.dims == ("point_0", "point_1")
    np.testing.assert_array_equal(outer.values.positions, g.values.positions)


def test_nested_parameter_names():
    g = vmj.grid(paper_model(), F=[5.0, 14.7])
    assert g.dims == ("F",)
    dotted = vmj.grid(paper_model(), **{"friction.F": [5.0, 14.7]})
    np.testing.assert_array_equal(dotted.model.friction.F, g.model.friction.F)
    r = vmj.sweep(vmj.turning_points, g, a0=A0, n=4, solver=vmj.EnergyBalance())
    one = vmj.turning_points(paper_model(F=5.0), A0, 4, vmj.EnergyBalance())
    np.testing.assert_allclose(r.values.positions[0], one.positions, atol=1e-12 * A0)


def test_default_chunk_fills_an_accelerator_and_keeps_cpu_chunks_in_cache():
    class Device:  # what default_chunk reads of a jax.Device
        def __init__(self, platform):
            self.platform = platform

    here = jax.local_devices()  # this machine's: a CPU in CI
    cpu = here[0].platform == "cpu"
    assert default_chunk(here) == (DEFAULT_CHUNK if cpu else ACCELERATOR_CHUNK * len(here))
    assert default_chunk(None) == DEFAULT_CHUNK  # a cluster's workers
    assert default_chunk([Device("gpu")]) == ACCELERATOR_CHUNK >= 64 * DEFAULT_CHUNK
    assert default_chunk([Device("gpu")] * 4) == 4 * ACCELERATOR_CHUNK  # sharded over four
    assert default_chunk([Device("gpu"), Device("cpu")]) == DEFAULT_CHUNK


def test_chunk_plan():
    # at most chunk_size points, at least one chunk per core, chunks of about equal size
    assert chunk_plan(18, 8, 2) == 5 and chunk_plan(18, 8, 1) == 6
    assert chunk_plan(20000, 16384, 2) == 10000  # not 16384 + an overlapping 16384
    assert chunk_plan(1617, 16384, 2) == 809 and chunk_plan(1617, 16384, 1) == 1617
    assert chunk_plan(5, 16384, 8) == 1 and chunk_plan(1, 100, 2) == 1
    assert chunk_plan(5, 16384, 1, multiple=4) == 8  # padded for four devices
    for n in (1, 7, 100, 12345):
        for limit in (1, 3, 64, 16384):
            for lanes in (1, 2, 3, 16):
                c = chunk_plan(n, limit, lanes)
                k = -(-n // c)
                # the fewest rounds of `lanes` chunks side by side that the limit allows, and
                # at most one point of padding per chunk
                rounds = -(-n // limit)  # chunks the limit alone needs
                assert 1 <= c <= limit and -(-k // lanes) == -(-rounds // lanes)
                assert k * c - n < k


def test_one_point_and_size_one_axes():
    one = vmj.sweep(
        vmj.turning_points,
        vmj.grid(paper_model(), eps=[0.5]),
        a0=A0,
        n=4,
        solver=vmj.EnergyBalance(),
    )
    want = vmj.turning_points(paper_model(eps=0.5), A0, 4, vmj.EnergyBalance())
    assert one.shape == (1,) and one.chunks == 1
    np.testing.assert_allclose(one.values.positions[0], want.positions, atol=1e-12 * A0)
    g = vmj.grid(paper_model(), eps=[0.5], mu=[1.0, 2.0], delta=[3.0])
    r = vmj.sweep(vmj.turning_points, g, a0=A0, n=4, solver=vmj.EnergyBalance())
    assert r.shape == (1, 2, 1)
    np.testing.assert_allclose(
        r.values.positions[0, 1, 0],
        vmj.turning_points(paper_model(eps=0.5, mu=2.0), A0, 4, vmj.EnergyBalance()).positions,
        atol=1e-12 * A0,
    )


def test_small_sweeps_use_every_core():
    r = vmj.sweep(
        vmj.turning_points,
        vmj.grid(paper_model(), eps=np.linspace(0, 1, 10)),
        a0=A0,
        n=4,
        solver=vmj.EnergyBalance(),
    )
    assert r.chunks == min(LANES, 10)  # (one chunk fills a GPU)


def test_sweeps_from_several_threads_at_once_keep_their_results_and_threads():
    """The chunks' threads are kept between sweeps (`_on_threads`): sweeps started from four
    threads at once give each its own result, the same as alone, and the threads kept
    afterwards are no more than the sweeps needed side by side."""
    import threading

    from vmj._sweep import _engine

    grids = [
        vmj.grid(paper_model(delta=d), eps=np.linspace(0, 1, 9)) for d in (-2.0, 0.0, 1.0, 3.0)
    ]

    def run(g):
        return vmj.sweep(
            vmj.turning_points, g, a0=A0, n=6, chunk_size=2, solver=vmj.EnergyBalance()
        ).values.amplitudes

    alone = [run(g) for g in grids]
    got = [None] * len(grids)

    def one(i):
        got[i] = run(grids[i])

    threads = [threading.Thread(target=one, args=(i,)) for i in range(len(grids))]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for a, b in zip(alone, got):
        np.testing.assert_array_equal(a, b)
    kept = len(_engine._IDLE)  # (one core: the chunks run in the calling thread, none kept)
    assert (1 if CORES > 1 else 0) <= kept <= len(grids) * CORES
    for _ in range(5):  # one after the other: no new thread
        run(grids[0])
        assert len(_engine._IDLE) == kept

    def broken(done, total):
        raise RuntimeError("a progress callback that fails")

    # raised in a chunk's thread, it reaches the caller, and the thread is kept
    with pytest.raises(RuntimeError, match="progress callback"):
        vmj.sweep(
            vmj.turning_points,
            grids[1],
            a0=A0,
            n=6,
            chunk_size=2,
            progress=broken,
            solver=vmj.EnergyBalance(),
        )
    np.testing.assert_array_equal(run(grids[1]), alone[1])
    assert len(_engine._IDLE) == kept


def test_results_in_pinned_host_memory_are_the_same(monkeypatch):
    """On an accelerator the chunks write their results to its pinned host memory
    (`host_output`); forced here on this machine's device (a CPU's pinned host memory in CI):
    the same sweep, bit for bit, each chunk's result placed there."""
    from vmj._sweep import _sweep as sweep_module

    assert host_output(jax.devices("cpu")[:1], None) is None  # a CPU's own memory is the host's
    g = vmj.grid(paper_model(), eps=np.linspace(0, 1, 7), mu=[0.0, 5.0])
    want = vmj.sweep(vmj.turning_points, g, a0=A0, n=N_SWINGS, chunk_size=4)
    # (the energy balance's stacked turning points come with the points last)
    want_map = vmj.sweep(
        vmj.turning_points, g, a0=A0, n=N_SWINGS, chunk_size=4, solver=vmj.EnergyBalance()
    )
    monkeypatch.setattr(sweep_module, "host_output", lambda d, s: pinned_host(d[0], s))
    got_map = vmj.sweep(
        vmj.turning_points, g, a0=A0, n=N_SWINGS, chunk_size=4, solver=vmj.EnergyBalance()
    )
    for a, b in zip(jax.tree.leaves(got_map.values), jax.tree.leaves(want_map.values)):
        np.testing.assert_array_equal(a, b)
    placed = []
    real = sweep_module._SweepJob.compute
    monkeypatch.setattr(
        sweep_module._SweepJob,
        "compute",
        lambda job, c: placed.append(job.function()(*job.args(job.first(c)))) or real(job, c),
    )
    got = vmj.sweep(vmj.turning_points, g, a0=A0, n=N_SWINGS, chunk_size=4)
    assert got.chunks == want.chunks >= 4 and len(placed) == got.chunks
    assert {x.sharding.memory_kind for x in jax.tree.leaves(placed)} == {"pinned_host"}
    for a, b in zip(jax.tree.leaves(got.values), jax.tree.leaves(want.values)):
        np.testing.assert_array_equal(a, b)


def test_wide_vectors_on_avx512_processors(monkeypatch):
    """A CPU with AVX-512 compiles the chunks for 512-bit vectors (`chunk_options`; forced here
    whatever this machine's processor): the same turning points to rounding, the same counts
    and results; an accelerator, or `XLA_FLAGS` naming the width, leaves XLA's default."""
    from vmj._sweep import _sweep as sweep_module

    monkeypatch.delenv("XLA_FLAGS", raising=False)  # (a width set by the caller decides)
    cpu = jax.devices("cpu")[:1]
    g = vmj.grid(paper_model(), eps=np.linspace(0, 1, 7), mu=[0.0, 5.0])
    monkeypatch.setattr(sweep_module, "_avx512", lambda: False)
    assert chunk_options(cpu) == {}
    narrow = vmj.sweep(vmj.turning_points, g, a0=A0, n=N_SWINGS, chunk_size=4, devices=cpu)
    monkeypatch.setattr(sweep_module, "_avx512", lambda: True)
    assert chunk_options(cpu) == {"xla_cpu_prefer_vector_width": 512}
    assert chunk_options([type("GPU", (), {"platform": "gpu"})()]) == {}
    with monkeypatch.context() as m:
        m.setenv("XLA_FLAGS", "--xla_cpu_prefer_vector_width=256")
        assert chunk_options(cpu) == {}
    sweep_module._KNOWN.clear()  # (compiled anew with the option)
    made, real = [], sweep_module._ChunkFunction
    monkeypatch.setattr(sweep_module, "_ChunkFunction", lambda *a: made.append(a[-1]) or real(*a))
    wide = vmj.sweep(vmj.turning_points, g, a0=A0, n=N_SWINGS, chunk_size=4, devices=cpu)
    assert made == [{"xla_cpu_prefer_vector_width": 512}]
    np.testing.assert_allclose(wide.values.positions, narrow.values.positions, atol=1e-13 * A0)
    np.testing.assert_allclose(wide.values.times, narrow.values.times, rtol=1e-13)
    for name in ("crossed", "count", "stopped", "result"):
        np.testing.assert_array_equal(getattr(wide.values, name), getattr(narrow.values, name))


def test_chunking_gives_identical_results_and_reports_progress(capsys):
    # chunks of 2500 (on two cores) against chunks of at most 480, the last overlapping
    rng = np.random.default_rng(1)
    n = 5000
    model = paper_model(
        delta=rng.uniform(-3, 3, n), eps=rng.uniform(0, 1, n), mu=rng.uniform(0, 10, n)
    )
    whole = vmj.sweep(
        vmj.turning_points, model, a0=A0, n=N_SWINGS, chunk_size=n, solver=vmj.EnergyBalance()
    )
    parts = vmj.sweep(
        vmj.turning_points,
        model,
        a0=A0,
        n=N_SWINGS,
        chunk_size=480,
        progress=True,
        solver=vmj.EnergyBalance(),
    )
    k = n_chunks(n, 480)
    assert whole.chunks == n_chunks(n, n) and parts.chunks == k >= 11
    for a, b in zip(whole.values.__dict__.values(), parts.values.__dict__.values()):
        np.testing.assert_array_equal(a, b)
    err = capsys.readouterr().err
    assert f"{k}/{k} chunks" in err and "points/s" in err and "ETA" in err


def test_results_keep_the_points_on_the_axis_their_computation_puts_them_on():
    # a loop's stacked output (lax.scan: its own axis first, the points after it) comes back
    # without a transpose, a point's own values with the points first; the values as
    # jax.vmap's, over chunks that overlap
    def both(x):
        return {"plain": x, "stacked": jax.lax.scan(lambda c, _: (c + 1, c), x, None, length=3)[1]}

    x = jnp.arange(5.0)
    out, axes = vmap_in_place(both, x)
    assert axes == [0, 1] and out["stacked"].shape == (3, 5)
    np.testing.assert_array_equal(out["stacked"].T, jax.vmap(both)(x)["stacked"])

    def fn(model, a0, n):  # (the energy balance's own loop is inside a conditional, whose
        # batched results have the points first)
        seq = vmj.turning_points(model, a0, n, vmj.EnergyBalance())
        grown = jax.lax.scan(lambda m, _: (m * 1.5, m), model.mu + a0, None, length=n)[1]
        return {"amplitudes": seq.amplitudes, "grown": grown, "count": seq.count}

    delta, mu = np.linspace(-3, 3, 7), np.linspace(0, 9, 7)
    one = jax.local_devices()[:1]  # (several devices split the first axis)
    r = vmj.sweep(fn, paper_model(delta=delta, mu=mu), a0=A0, n=N_SWINGS, chunk_size=4, devices=one)
    ref = jax.vmap(lambda d, m: fn(paper_model(d, 0.0, m), A0, N_SWINGS))(delta, mu)
    assert r.chunks == n_chunks(7, 4) >= 2
    for name in ("amplitudes", "grown", "count"):
        np.testing.assert_array_equal(r.values[name], ref[name])
    grown = r.values["grown"]
    assert grown.shape == (7, N_SWINGS) and grown.strides[0] == grown.itemsize


def _run(code: str, env_extra: dict | None = None) -> dict:
    env = {**os.environ, **(env_extra or {})}
    out = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(code)],
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
        cwd=os.path.dirname(os.path.dirname(__file__)),
    )
    assert out.returncode == 0, out.stderr[-3000:]
    return json.loads(out.stdout.strip().splitlines()[-1])


@pytest.mark.parametrize("retain", [False, True])
def test_million_point_energy_sweep_has_bounded_memory(retain):
    got = _run(f"""
        import json, resource
        import jax
        jax.config.update("jax_enable_x64", True)
        import numpy as np, vmj
        applied = vmj.retain_host_memory() if {retain} else None
        model = vmj.VariableMass(5.0, 4900.0, 3.0, 0.0, 2.0, vmj.Coulomb(14.7))
        g = vmj.grid(model, eps=np.linspace(0, 1, 100), mu=np.linspace(0, 10, 100),
                     delta=np.linspace(-3, 3, 100))
        fn = lambda m, a0, n: vmj.turning_points(m, a0, n, vmj.EnergyBalance()).amplitudes
        vmj.sweep(fn, vmj.grid(model, eps=[0.5]), a0=0.06, n=12)  # imports and a first compile
        before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
        r = vmj.sweep(fn, g, a0=0.06, n=12, chunk_size=65536)
        after = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
        print(json.dumps({{"mb": after - before, "chunks": r.chunks, "shape": r.values.shape,
                           "finite": bool(np.isfinite(r.values).all()), "applied": applied}}))
    """)
    assert got["shape"] == [100, 100, 100, 12] and got["finite"]
    assert got["chunks"] == n_chunks(10**6, 65536) >= 16
    assert got["applied"] in ((None,) if not retain else (True, False))
    # the result itself is 96 MB; an unchunked evaluation keeps several 10^6 x 12 buffers
    assert got["mb"] < 250, got


def test_retain_host_memory_checks_its_limit():
    for bad in (-1, 2**31, 1.5, True, "1G"):
        with pytest.raises(ValueError, match="limit must be an integer number of bytes"):
            vmj.retain_host_memory(bad)
    if platform.libc_ver()[0] == "glibc":
        assert vmj.retain_host_memory(2**30) is True


def test_sharded_over_four_devices_equals_one_device():
    got = _run(
        """
        import json
        import jax
        jax.config.update("jax_enable_x64", True)
        import numpy as np, vmj
        assert len(jax.devices()) == 4
        model = vmj.VariableMass(5.0, 4900.0, 3.0, 0.0, 2.0, vmj.Coulomb(14.7))
        g = vmj.grid(model, eps=np.linspace(0, 1, 5), mu=np.linspace(0, 9, 7), delta=[-3.0, 3.0])
        fn = lambda m, a0, n: vmj.turning_points(m, a0, n, vmj.EnergyBalance())
        four = vmj.sweep(fn, g, a0=0.06, n=12, chunk_size=24)
        one = vmj.sweep(fn, g, a0=0.06, n=12, chunk_size=24, devices=jax.devices()[:1])
        # five points: one chunk padded to eight, two per device
        small = vmj.grid(model, eps=np.linspace(0, 1, 5))
        four_small = vmj.sweep(fn, small, a0=0.06, n=12)
        one_small = vmj.sweep(fn, small, a0=0.06, n=12, devices=jax.devices()[:1])
        # the results in the devices' pinned host memory, as on accelerators
        from vmj._sweep import _sweep
        _sweep.host_output = lambda d, s: _sweep.pinned_host(d[0], s)
        four_pinned = vmj.sweep(fn, g, a0=0.06, n=12, chunk_size=24)
        diff = max(float(np.max(np.abs(np.asarray(a, float) - np.asarray(b, float))))
                   for x, y in ((four, one), (four_small, one_small), (four_pinned, one))
                   for a, b in zip(jax.tree.leaves(x.values), jax.tree.leaves(y.values)))
        print(json.dumps({"devices": [four.devices, one.devices], "diff": diff,
                          "chunks": four.chunks, "small": list(four_small.values.positions.shape)}))
    """,
        {"XLA_FLAGS": "--xla_force_host_platform_device_count=4", "JAX_PLATFORMS": "cpu"},
    )
    assert got["devices"] == [4, 1] and got["chunks"] == 3 and got["small"] == [5, 12]
    assert got["diff"] <= 1e-15


def test_csv_round_trip(exact_grid, tmp_path):
    path = tmp_path / "sweep.csv"
    exact_grid.to_csv(str(path))
    back = vmj.SweepResult.read_csv(str(path))
    assert back.dims == exact_grid.dims and back.shape == exact_grid.shape
    for d in back.dims:
        np.testing.assert_array_equal(back.coords[d], exact_grid.coords[d])
    for name in ("times", "positions", "crossed", "count", "stopped", "result"):
        orig = getattr(exact_grid.values, name)
        np.testing.assert_array_equal(back.values[name], orig)
        assert back.values[name].dtype == orig.dtype
    header = path.read_text().splitlines()[1].split(",")
    assert header[:4] == ["eps", "mu", "delta", "times_1"]


def test_csv_round_trip_paired(tmp_path):
    model = paper_model(eps=np.array([0.1, 0.7]), mu=np.array([1.0, 3.0]))
    r = vmj.sweep(vmj.turning_points, model, a0=A0, n=5, solver=vmj.EnergyBalance())
    r.to_csv(str(tmp_path / "p.csv"))
    back = vmj.SweepResult.read_csv(str(tmp_path / "p.csv"))
    np.testing.assert_array_equal(back.coords["eps"], [0.1, 0.7])
    np.testing.assert_array_equal(back.values["positions"], r.values.positions)


def test_netcdf_round_trip(exact_grid, tmp_path):
    xr = pytest.importorskip("xarray")
    pytest.importorskip("netCDF4")
    ds = exact_grid.to_xarray()
    assert ds.positions.dims == ("eps", "mu", "delta", "k")
    np.testing.assert_array_equal(ds.k, np.arange(1, N_SWINGS + 1))
    path = tmp_path / "sweep.nc"
    exact_grid.to_netcdf(str(path))
    with xr.open_dataset(path) as back:
        np.testing.assert_array_equal(back.positions.values, exact_grid.values.positions)
        np.testing.assert_array_equal(back.crossed.values, exact_grid.values.crossed)
        np.testing.assert_array_equal(back.mu.values, MU)
        sel = back.positions.sel(eps=0.4, mu=2.0, delta=3.0).values
        np.testing.assert_array_equal(sel, exact_grid.values.positions[1, 1, 1])
    exact_grid.to_netcdf(os.devnull)  # a device: through a temporary file (HDF5 failed on it)
    assert not os.path.isfile(os.devnull)


def test_bad_input_raises_value_error():
    m = paper_model()
    with pytest.raises(ValueError, match="'nu' is not a parameter"):
        vmj.grid(m, nu=[1.0])
    with pytest.raises(ValueError, match=r"eps must be finite and in \[0, 1\]"):
        vmj.grid(m, eps=[0.0, 2.0])
    with pytest.raises(ValueError, match="1-D"):
        vmj.grid(m, eps=[[0.0, 1.0]])
    with pytest.raises(ValueError, match="scalar parameters"):
        vmj.grid(paper_model(eps=jnp.array([0.0, 1.0])), mu=[1.0])
    with pytest.raises(ValueError, match="do not broadcast"):
        vmj.sweep(
            vmj.turning_points,
            paper_model(eps=np.zeros(2), mu=np.zeros(3)),
            a0=A0,
            n=2,
            solver=vmj.EnergyBalance(),
        )
    with pytest.raises(ValueError, match="chunk_size"):
        vmj.sweep(
            vmj.turning_points,
            vmj.grid(m, eps=[0.0]),
            a0=A0,
            n=2,
            chunk_size=0,
            solver=vmj.EnergyBalance(),
        )


def test_cli_sweep(tmp_path, capsys):
    from vmj.cli import main

    out, fig = tmp_path / "s.csv", tmp_path / "s.png"
    argv = [
        "sweep",
        "variable-mass",
        "--eps",
        "0:1:3",
        "--mu",
        "0:10:3",
        "--delta",
        "-3:3:2",
        "--set",
        "m0=5,c=4900,FT=14.7,a0=0.06",
        "--method",
        "energy",
        "--out",
        str(out),
        "--plot",
        str(fig),
    ]
    assert main(argv) == 0
    assert "18 points (eps 3 x mu 3 x delta 2)" in capsys.readouterr().out
    back = vmj.SweepResult.read_csv(str(out))
    assert back.dims == ("eps", "mu", "delta")
    np.testing.assert_array_equal(back.coords["delta"], [-3.0, 3.0])
    one = vmj.turning_points(paper_model(-3.0, 0.5, 10.0), A0, N_SWINGS, vmj.EnergyBalance())
    np.testing.assert_allclose(back.values["positions"][1, 2, 0], one.positions, atol=1e-12 * A0)
    assert fig.stat().st_size > 10_000
    bad = argv[:3] + ["0:2:3"] + argv[4:]
    assert main(bad) == 2
    assert "eps must be finite and in [0, 1]" in capsys.readouterr().err
    assert main(["sweep", "variable-mass", "--eps", "0:1:3", "--set", "m0=5,c=4900,FT=1"]) == 2
    assert "--set a0= (initial deflection [m])" in capsys.readouterr().err


@pytest.mark.long  # 25 s: with the long runs, for CI's time
def test_smoothed_chunks_are_sized_from_the_memory_they_need(monkeypatch):
    # The smoothed solve's working memory per point is what XLA's memory analysis says (a few
    # kilobytes: its turning points come from events, not from a stored dense solution). Here
    # the machine is made to look small, a few points' worth of memory, so that the default
    # chunk shrinks to what fits in a quarter of it, and an explicit chunk size that cannot fit
    # at all is refused.
    from vmj._sweep import _sweep as sweep_module

    seen = []

    def spy(job, chunk):
        need = real(job, chunk)
        seen.append(need / chunk)
        return need

    real = sweep_module.chunk_bytes
    monkeypatch.setattr(sweep_module, "chunk_bytes", spy)
    memory = [1e12]
    monkeypatch.setattr(sweep_module, "available_memory", lambda device, enough: memory[0])
    g = vmj.grid(paper_model(), eps=[0.0, 0.5, 1.0, 0.25], mu=[2.0, 9.0])
    vmj.sweep(vmj.turning_points, g, a0=A0, n=N_SWINGS, solver=vmj.Smoothed())
    per_point = seen[-1]
    assert 1e2 < per_point < 1e6  # bytes per point: no memory that grows with the steps
    memory[0] = 2.5 * CORES * per_point / sweep_module.MEMORY_FRACTION
    r = vmj.sweep(vmj.turning_points, g, a0=A0, n=N_SWINGS, solver=vmj.Smoothed())
    fits = int(sweep_module.MEMORY_FRACTION * memory[0] / CORES / seen[-1])
    assert 1 <= fits < 4
    assert r.chunks == n_chunks(8, fits) >= 8 // fits >= 2  # chunks of `fits` points at most
    exact = vmj.sweep(vmj.turning_points, g, a0=A0, n=N_SWINGS)
    np.testing.assert_array_equal(r.values.count, exact.values.count)
    # the turning points before the last (where the smoothed model creeps to its rest)
    before_rest = np.arange(N_SWINGS) < exact.values.count[..., None] - 1
    np.testing.assert_allclose(
        r.values.positions[before_rest], exact.values.positions[before_rest], rtol=0, atol=1e-6 * A0
    )
    memory[0] = 1.5 * CORES * per_point  # not even two chunks of 4 points
    with pytest.raises(
        ValueError,
        match=r"chunk_size=8 needs .* GB of working memory per chunk "
        r".* use chunk_size <= \d+, or leave it",
    ):
        vmj.sweep(vmj.turning_points, g, a0=A0, n=N_SWINGS, solver=vmj.Smoothed(), chunk_size=8)


def test_float32_sweeps_agree_with_float64_to_float32_accuracy():
    # GPUs run float32 fast: the exact and energy-balance sweeps in float32 (a process of its
    # own: JAX reads x64 once) against the same sweeps here in float64
    rng = np.random.default_rng(5)
    eps, mu, delta = rng.uniform(0, 1, 64), rng.uniform(0, 10, 64), rng.uniform(-3, 3, 64)
    got = _run(f"""
        import json, warnings
        import jax
        jax.config.update("jax_enable_x64", False)
        warnings.filterwarnings("ignore", "vmj: JAX is running in float32")
        import numpy as np, vmj
        m = vmj.VariableMass(5.0, 4900.0, {delta.tolist()}, {eps.tolist()}, {mu.tolist()},
                             vmj.Coulomb(14.7))
        x = vmj.sweep(vmj.turning_points, m, a0=0.06, n=12).values
        e = vmj.sweep(vmj.turning_points, m, a0=0.06, n=12, solver=vmj.EnergyBalance()).values
        print(json.dumps({{"dtype": str(x.positions.dtype), "x": x.positions.tolist(),
                           "count": x.count.tolist(), "result": x.result.tolist(),
                           "e": e.positions.tolist(), "e_count": e.count.tolist()}}))
    """)
    assert got["dtype"] == "float32"
    model = paper_model(delta=delta, eps=eps, mu=mu)
    for solver, x, count in (
        (vmj.Exact(), got["x"], got["count"]),
        (vmj.EnergyBalance(), got["e"], got["e_count"]),
    ):
        ref = vmj.sweep(vmj.turning_points, model, a0=A0, n=12, solver=solver).values
        np.testing.assert_array_equal(count, ref.count)
        moved = np.arange(12) < ref.count[:, None]
        big = moved & (np.abs(ref.positions) > 0.01 * A0)
        rel = np.abs(np.asarray(x) / ref.positions - 1)[big]
        # float32 rounding (1.2e-7) grown over 12 swings: measured 1.9e-5 at most
        assert rel.max() < 1e-4, rel.max()
    assert vmj.RESULTS.okay(np.asarray(got["result"])).all()


def test_threads_let_go_of_each_chunk_once_it_is_sunk():
    # a chunk's output kept until the end of the sweep makes every chunk fresh memory, page-
    # faulted into existence; sunk in its thread, it is let go at once
    class Output:
        pass

    refs, alive = {}, []

    class Job:
        def compute(self, c):
            out = Output()
            refs[c] = weakref.ref(out)
            return [out]

    def sink(c, got):
        if c == 19:
            gc.collect()
            alive.append(sum(r() is not None for k, r in refs.items() if k != c))

    run_chunks(
        Job(),
        range(20),
        sink=sink,
        fail=None,
        progress=Progress(20, 20, False),
        threads=1,
        sink_in_thread=True,
    )
    assert alive == [0]


def test_a_sweep_checks_its_points_once_on_the_host():
    # a value that bypassed construction is refused before anything is computed, by name
    good = paper_model(eps=np.array([0.5, 0.7]))
    bad = eqx.tree_at(lambda m: m.eps, good, np.array([0.5, 1.5]))
    with pytest.raises(ValueError, match="eps must be"):
        vmj.sweep(vmj.turning_points, bad, a0=A0, n=4, solver=vmj.EnergyBalance())
    # each point's model is then traced as checked: no host callback in the compiled chunk
    # (and a swept function's own arguments are still checked, as values of the chunk)
    swept = tuple(np.ndim(x) > 0 for x in jax.tree.leaves(good))
    energy = {"a0": A0, "n": 4, "solver": vmj.EnergyBalance()}
    job = _SweepJob(vmj.turning_points, energy, good, swept, (2,), 2, "")
    assert "callback" not in job.function().lower(*job.args(0)).as_text()
    own_a0 = lambda m, n: vmj.turning_points(m, m.eps - 0.6, n, vmj.EnergyBalance())  # noqa: E731
    job = _SweepJob(own_a0, {"n": 4}, good, swept, (2,), 2, "")
    assert "callback" not in job.function().lower(*job.args(0)).as_text()
    with pytest.raises(ValueError, match="^a0 must be finite and > 0"):
        job.compute(0)  # (the first point's a0 is -0.1)


def test_threads_that_sink_their_chunks_report_failures_and_progress():
    class Job:
        def compute(self, c):
            if c in (3, 7):
                raise RuntimeError(f"chunk {c}")
            return [c]

    sunk, counts = [], []
    progress = Progress(10, 10, lambda done, total: counts.append((done, total)))
    # without `fail`, the first failure is raised (after the running chunks end)
    with pytest.raises(RuntimeError, match="chunk [37]"):
        run_chunks(
            Job(),
            range(10),
            sink=lambda c, got: None,
            fail=None,
            progress=progress,
            threads=2,
            sink_in_thread=True,
        )
    # with `fail`, every chunk is tried: the others sunk, the failures handed over, all counted
    failures = {}
    progress = Progress(10, 10, lambda done, total: counts.append((done, total)))
    counts.clear()
    run_chunks(
        Job(),
        range(10),
        sink=lambda c, got: sunk.append((c, got)),
        fail=lambda c, e: failures.setdefault(c, str(e)),
        progress=progress,
        threads=2,
        sink_in_thread=True,
    )
    assert sorted(sunk) == [(c, [c]) for c in range(10) if c not in (3, 7)]
    assert failures == {3: "chunk 3", 7: "chunk 7"}
    assert sorted(counts) == [(k, 10) for k in range(1, 11)]
