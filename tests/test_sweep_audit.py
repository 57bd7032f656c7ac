"""Sweeps at scale, from an audit: stores interrupted or shared, results that do not fit in
memory, sweeps without an axis, bad values in long axes, what a store's refusal names, and the
metadata of the exports. Small grids (35 points, 6 swings): every sweep here shares one
compiled chunk per chunk size."""

import numpy as np
import pytest

import vmj
from vmj._sweep._store import ChunkStore

N = 6  #: swings
A0 = 0.06  #: release amplitude [m]


@pytest.fixture(scope="module")
def model():
    return vmj.VariableMass(
        m0=5.0, c=4900.0, delta=3.0, eps=0.0, mu=2.0, friction=vmj.Coulomb(14.7)
    )


@pytest.fixture(scope="module")
def g(model):
    return vmj.grid(model, eps=np.linspace(0, 1, 5), mu=np.linspace(0, 10, 7))


@pytest.fixture(scope="module")
def reference(g):
    """The sweep in memory, in chunks of 8 points (as the stored sweeps below)."""
    return vmj.sweep(vmj.turning_points, g, a0=A0, n=N, chunk_size=8)


def _same(a, b):
    """Every field equal to the last bit (`a`: a DecaySequence; `b`: one, or a dict of fields
    as read back from a store)."""
    fields = ("times", "positions", "crossed", "count", "stopped", "result")
    got = b if isinstance(b, dict) else {f: getattr(b, f) for f in fields}
    return all(np.array_equal(np.asarray(getattr(a, f)), np.asarray(got[f])) for f in fields)


# -- stores ----------------------------------------------------------------------------------
def test_a_store_interrupted_before_its_arrays_were_made_resumes(
    g, reference, tmp_path, monkeypatch
):
    """Killed between the store's metadata and its fields' arrays, a store could not be
    resumed (`KeyError: 'times'` from the first chunk's write)."""
    path = str(tmp_path / "s.zarr")

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    with monkeypatch.context() as m:
        m.setattr(ChunkStore, "create_sweep_arrays", interrupted)
        with pytest.raises(KeyboardInterrupt):
            vmj.sweep(vmj.turning_points, g, a0=A0, n=N, chunk_size=8, store=path)
    r = vmj.sweep(vmj.turning_points, g, a0=A0, n=N, chunk_size=8, store=path, resume=True)
    assert (r.computed, r.resumed) == (r.chunks, 0)
    assert _same(reference.values, r.values)
    assert _same(reference.values, vmj.SweepResult.read_zarr(path).values)


def test_a_store_created_meanwhile_by_another_process_is_a_clear_refusal(g, tmp_path, monkeypatch):
    """Two processes starting the same new store at once: the second one's creation found the
    first one's files and failed with Zarr's `FileExistsError` and a traceback. (The race is
    made here by hiding the store from the check that comes before the creation.)"""
    path = str(tmp_path / "s.zarr")
    vmj.sweep(vmj.turning_points, g, a0=A0, n=N, chunk_size=8, store=path)
    monkeypatch.setattr(ChunkStore, "existing", classmethod(lambda cls, *a, **k: None))
    with pytest.raises(ValueError, match="created by another process.*resume=True"):
        vmj.sweep(vmj.turning_points, g, a0=A0, n=N, chunk_size=8, store=path)


def test_an_incomplete_store_says_so(g, tmp_path):
    """A store whose creation did not reach its metadata (killed, or another process creating
    it now) was called 'not a vmj store'."""
    path = str(tmp_path / "s.zarr")
    ChunkStore.create(path, kind="sweep", definition={}, described={}, plan={"n_chunks": 1})
    import zarr

    group = zarr.open_group(path, mode="r+")
    del group.attrs["vmj"]
    with pytest.raises(ValueError, match="incomplete.*delete it"):
        vmj.sweep(vmj.turning_points, g, a0=A0, n=N, store=path, resume=True)


def test_a_different_model_is_refused_naming_the_parameter(model, g, tmp_path):
    """The refusal said only `model (stored VariableMass (parameters af1fe81f), now
    VariableMass (parameters e75bbd42))`, not which parameter differs."""
    path = str(tmp_path / "s.zarr")
    vmj.sweep(vmj.turning_points, g, a0=A0, n=N, chunk_size=8, store=path)
    heavier = vmj.grid(
        vmj.VariableMass(6.0, 4900.0, 3.0, 0.0, 2.0, vmj.Coulomb(14.7)),
        eps=g.coords["eps"],
        mu=g.coords["mu"],
    )
    with pytest.raises(ValueError, match=r"m0 \(stored 5, now 6\)") as e:
        vmj.sweep(vmj.turning_points, heavier, a0=A0, n=N, chunk_size=8, store=path, resume=True)
    assert "eps" not in str(e.value) and "mu " not in str(e.value)
    finer = vmj.grid(model, eps=g.coords["eps"], mu=np.linspace(0, 11, 7))
    with pytest.raises(
        ValueError, match=r"mu \(stored 7 values in \[0, 10\].*now 7 values in \[0, 11\]"
    ):
        vmj.sweep(vmj.turning_points, finer, a0=A0, n=N, chunk_size=8, store=path, resume=True)


# -- memory, degenerate sweeps, bad values ---------------------------------------------------
def test_a_result_larger_than_memory_is_refused_before_computing(g, monkeypatch):
    """A result that did not fit was allocated anyway (NumPy's overcommitted `np.empty`), and
    the process was killed part-way through the sweep, or raised NumPy's MemoryError."""
    monkeypatch.setattr(vmj._checks, "ROOM_CHECKED_FROM", 0)
    # 35 points x 111 bytes (6 swings: times and positions 2 x 48, crossed 6, count 4,
    # stopped 1, result 4) = 3885 bytes; 3000 bytes free
    monkeypatch.setattr(vmj._host, "available_memory", lambda device, enough: 3000)
    computed = []
    with pytest.raises(
        ValueError,
        match=r"result, 35 points x 111 bytes: about 3.89e-06 GB, more than the 3e-06 GB",
    ) as e:
        vmj.sweep(vmj.turning_points, g, a0=A0, n=N, progress=lambda d, t: computed.append(d))
    assert "stop_time" in str(e.value)
    assert computed == []
    monkeypatch.setattr(vmj._host, "available_memory", lambda device, enough: 3885)
    assert vmj.sweep(vmj.turning_points, g, a0=A0, n=N).shape == (5, 7)


def test_a_sweep_without_an_array_parameter_is_a_clear_error(model):
    """A model of scalars only raised JAX's `vmap wrapped function must be passed at least one
    argument containing an array`."""
    with pytest.raises(ValueError, match="no array parameter.*vmj.grid"):
        vmj.sweep(vmj.turning_points, model, a0=A0, n=N)


def test_a_bad_value_in_a_long_axis_is_named_with_its_index(model):
    """NumPy's summary of a long array (`[0. 0.0002 ... 1.]`) left the bad value out of the
    message."""
    eps = np.linspace(0, 1, 5000)
    eps[1234] = np.nan
    with pytest.raises(ValueError, match=r"eps must be .* \(got nan at index 1234 of 5000"):
        vmj.grid(model, eps=eps)
    mu = np.full((40, 50), 2.0)
    mu[17, 3], mu[20, 0] = -1.0, -2.0
    paired = vmj.VariableMass(5.0, 4900.0, 3.0, 0.0, 2.0, vmj.Coulomb(14.7))
    with pytest.raises(ValueError, match=r"got -1.0 at index \(17, 3\) of \(40, 50\); 2 bad"):
        vmj.sweep(vmj.turning_points, _with(paired, mu=mu), a0=A0, n=N)


def _with(model, **fields):
    import equinox as eqx

    names = list(fields)
    return eqx.tree_at(lambda m: [getattr(m, k) for k in names], model, list(fields.values()))


# -- what the exports say of their origin -----------------------------------------------------
def test_exports_say_what_produced_them_and_the_units_of_their_coordinates(model, tmp_path):
    """The Dataset (and so the NetCDF file) had no attributes at all: neither the model, the
    solver nor the units of the swept parameters."""
    xr = pytest.importorskip("xarray")
    fg = vmj.grid(
        vmj.VariableMass(5.0, 4900.0, 0.1, 0.0, 2.0, model.friction), F=[10.0, 14.7], mu=[0.0, 2.0]
    )  # (a nested parameter: friction.F)
    path = str(tmp_path / "s.zarr")
    r = vmj.sweep(vmj.turning_points, fg, a0=A0, n=N, solver=vmj.EnergyBalance(), store=path)
    want = {
        "model": "VariableMass(friction=Coulomb)",
        "function": "vmj._integrate.turning_points",
        "solver_arguments": "a0=0.06, n=6, solver=EnergyBalance()",
        "fixed_parameters": "m0=5 kg, c=4900 N/m, delta=0.1 kg/s, eps=0",  # (not 0.10000000000000001)
        "vmj_version": vmj.__version__,
    }
    ds = r.to_xarray()
    assert {k: ds.attrs[k] for k in want} == want
    assert (ds["F"].attrs["units"], ds["mu"].attrs["units"]) == ("N", "kg/s")
    r.to_netcdf(str(tmp_path / "s.nc"))
    with xr.open_dataset(str(tmp_path / "s.nc")) as back:
        assert {k: back.attrs[k] for k in want} == want
        assert back["mu"].attrs["units"] == "kg/s"
    with xr.open_zarr(path, consolidated=False) as lazy:
        assert (lazy["F"].attrs["units"], lazy["mu"].attrs["units"]) == ("N", "kg/s")
    assert vmj.SweepResult.read_zarr(path).attrs == r.attrs
    r.to_csv(str(tmp_path / "s.csv"))
    assert vmj.SweepResult.read_csv(str(tmp_path / "s.csv")).attrs == r.attrs


def test_cli_store_messages_use_the_command_line_spelling(tmp_path, capsys):
    """A store made with another --chunk-size was refused as 'chunk_size (stored 8, now
    default)', and a resumed run's summary did not say that its chunks were read back."""
    from vmj.cli import main

    store = str(tmp_path / "s.zarr")
    base = ["sweep", "variable-mass", "--eps", "0:1:5", "--mu", "0:10:7", "--n", str(N)]
    base += ["--set", "m0=5,c=4900,FT=14.7,a0=0.06,delta=3", "--store", store]
    assert main(base + ["--chunk-size", "8"]) == 0
    assert capsys.readouterr().out.split("; ")[-1] == f"stored in {store}\n"
    assert main(base + ["--resume"]) == 2
    assert "--chunk-size (stored 8, now default)" in capsys.readouterr().err
    assert main(base + ["--resume", "--chunk-size", "8"]) == 0
    assert capsys.readouterr().out.split("; ")[-1] == (
        f"stored in {store} (6 of 6 chunks were in it already)\n"
    )


def test_attrs_are_made_when_asked_for_and_pickled_made(g):
    """The attributes cost 0.2-1 ms to make (equinox's attribute lookups, a solver's repr):
    made for every sweep, they were a tenth of a warm 35-point sweep."""
    import pickle

    r = vmj.sweep(lambda m, a0, n: vmj.turning_points(m, a0, n).positions, g, a0=A0, n=N)
    assert callable(r._attrs)
    back = pickle.loads(pickle.dumps(r))
    assert back.attrs == r.attrs and back.attrs["function"].endswith("<lambda>")
    assert back.attrs["units"] == {"eps": "1", "mu": "kg/s"}  # (a bare array: no field units)


# -- results larger than memory: streamed to the store ----------------------------------------
def test_a_store_sweep_larger_than_memory_streams_to_disk(tmp_path):
    """With `store=` the whole result was held in memory as well (and refused when it did not
    fit): a 10^6-point energy-balance sweep (221 MB of DecaySequence) grew the peak RSS by
    1.26 GB per 3e6 points. Now each chunk is written and dropped; `values` are read lazily
    from the store. The limit imposed is 64 MB of free memory (the result is 3.5 times it);
    the bound asserted, half the result, leaves room for the chunks in flight (measured: 54-92
    MB of growth at 0.3-3 x 10^6 points, whatever the result's size).

    A reduction over the stored values runs within memory smaller than the field it reduces
    (a guard, not a defect: it did before): the mean of `positions` (96 MB) over eps, with the
    address space capped at what the process had mapped plus 64 MB, where loading the field
    whole fails (measured: the mean also ran with 32 MB; its peak RSS grows by 49-51 MB at
    10^6 points, 59-63 MB at 4 x 10^6, see docs/sweeps.md)."""
    import json
    import subprocess
    import sys
    import textwrap

    code = textwrap.dedent(f"""
        import json
        import jax
        jax.config.update("jax_enable_x64", True)
        import numpy as np, vmj
        def hwm():
            for line in open("/proc/self/status"):
                if line.startswith("VmHWM"):
                    return int(line.split()[1]) / 1024
        model = vmj.VariableMass(5.0, 4900.0, 3.0, 0.0, 2.0, vmj.Coulomb(14.7))
        g = vmj.grid(model, eps=np.linspace(0, 1, 100), mu=np.linspace(0, 10, 100),
                     delta=np.linspace(-3, 3, 100))
        kw = dict(a0=0.06, n=12, solver=vmj.EnergyBalance())
        small = vmj.grid(model, eps=[0.5, 0.6])
        vmj.sweep(vmj.turning_points, small, store={str(tmp_path / "warm.zarr")!r}, **kw)
        import vmj._sweep._sweep as sweeping
        sweeping.available_memory = lambda device, enough=None: 64e6  # (the chunks' sizing)
        open("/proc/self/clear_refs", "w").write("5")  # (resets VmHWM)
        before = hwm()
        r = vmj.sweep(vmj.turning_points, g, store={str(tmp_path / "big.zarr")!r}, **kw)
        grew = hwm() - before
        got = {{"mb": grew, "lazy": hasattr(r.values.positions, "compute"),
               "shape": list(r.values.positions.shape),
               "stopped": int(r.values.stopped.sum().compute()),
               "corner": float(r.values.positions[99, 99, 99, 11].compute())}}
        import resource
        mapped = [l for l in open("/proc/self/status") if l.startswith("VmSize")][0]
        cap = int(mapped.split()[1]) * 1024 + 64 * 2**20
        resource.setrlimit(resource.RLIMIT_AS, (cap, resource.getrlimit(resource.RLIMIT_AS)[1]))
        got["mean"] = float(r.values.positions.mean(axis=0).compute()[99, 99, 11])
        try:
            np.asarray(r.values.positions)
            got["whole"] = "loaded"
        except MemoryError:
            got["whole"] = "MemoryError"
        print(json.dumps(got))
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-3000:]
    got = json.loads(out.stdout.strip().splitlines()[-1])
    assert got["lazy"] and got["shape"] == [100, 100, 100, 12]
    assert got["mb"] < 221 / 2, got
    one = vmj.turning_points(
        vmj.VariableMass(5.0, 4900.0, 3.0, 1.0, 10.0, vmj.Coulomb(14.7)),
        A0,
        12,
        vmj.EnergyBalance(),
    )
    assert got["corner"] == float(one.positions[11])  # (the same compiled arithmetic: exact)
    assert got["stopped"] > 0
    assert got["whole"] == "MemoryError"  # (the cap is below the field's 96 MB)
    edge = vmj.grid(
        vmj.VariableMass(5.0, 4900.0, 3.0, 0.0, 10.0, vmj.Coulomb(14.7)), eps=np.linspace(0, 1, 100)
    )
    want = vmj.sweep(vmj.turning_points, edge, a0=A0, n=12, solver=vmj.EnergyBalance())
    # summed in another order: 100 terms of magnitude <= a0, each sum's rounding <= 99 x 2^-53
    # x the sum of magnitudes, twice, over 100
    bound = 2 * 99 * 2.0**-53 * A0
    assert abs(got["mean"] - float(np.mean(want.values.positions[:, 11]))) <= bound


def test_store_results_are_lazy_and_equal_the_in_memory_sweep(g, reference, tmp_path):
    """What `vmj.sweep(..., store=)` returns is read from the store (not a copy kept in
    memory), equal to the in-memory sweep to the last bit; the exports stream it."""
    path = str(tmp_path / "s.zarr")
    r = vmj.sweep(vmj.turning_points, g, a0=A0, n=N, chunk_size=8, store=path)
    assert all(hasattr(leaf, "compute") for leaf in (r.values.times, r.values.count))
    assert _same(reference.values, r.values)
    assert _same(reference.values, vmj.SweepResult.read_zarr(path).values)
    r.to_csv(str(tmp_path / "lazy.csv"))
    reference.to_csv(str(tmp_path / "memory.csv"))
    assert (tmp_path / "lazy.csv").read_text() == (tmp_path / "memory.csv").read_text()


def test_read_zarr_reads_the_markers_and_checks_each_chunk_when_read(g, reference, tmp_path):
    """Opening a store read every chunk of every field to check it (a 4 x 10^6-point
    energy-balance store, 884 MB of values: 4.9 s of CPU before anything was asked for, the
    time of reading it all; a store far larger than memory took as long as reading all of
    it). Now opening reads the completion markers and checksums only; a chunk of a field is checked against
    its own checksum when it is read, and one that does not match raises, naming it. A
    damaged field leaves the others readable, and resuming computes the chunk again."""
    path = str(tmp_path / "s.zarr")
    vmj.sweep(vmj.turning_points, g, a0=A0, n=N, chunk_size=8, store=path)
    # garbage in chunk 2 of positions (the sweep's chunks are 6 points: points 12-17)
    (data,) = (tmp_path / "s.zarr" / "positions" / "c" / "2").iterdir()
    raw = bytearray(data.read_bytes())
    raw[8:16] = bytes(b ^ 0xFF for b in raw[8:16])
    data.write_bytes(bytes(raw))
    back = vmj.SweepResult.read_zarr(path)  # (raised: "unfinished sweep: 1 of 6 chunks")
    np.testing.assert_array_equal(back.values["count"], reference.values.count)
    np.testing.assert_array_equal(back.values["positions"][0], reference.values.positions[0])
    with pytest.raises(
        ValueError,
        match=r"s.zarr': the field 'positions' of chunk 2 \(points 12 to 17\) does not match "
        r"its checksum .*resume=True\) computes it again",
    ):
        back.values["positions"].sum().compute()
    again = vmj.sweep(vmj.turning_points, g, a0=A0, n=N, chunk_size=8, store=path, resume=True)
    assert (again.resumed, again.computed) == (5, 1)
    assert _same(reference.values, vmj.SweepResult.read_zarr(path).values)


def test_a_checked_field_cuts_any_part_from_whole_checked_chunks(g, reference, tmp_path):
    """What dask may ask a stored field for (its parts, slices fused with later indexing: an
    integer, a step, a negative step, an empty range) equals the same part of the in-memory
    field, each chunk read whole and checked (exact: the same bytes)."""
    from vmj._sweep._store import _markers

    path = str(tmp_path / "s.zarr")
    vmj.sweep(vmj.turning_points, g, a0=A0, n=N, chunk_size=8, store=path)
    st = ChunkStore.read_only(path, kind="sweep")
    j = [f[0] for f in st.meta["fields"]].index("positions")
    field = vmj._sweep._store._CheckedField(st, "positions", _markers(st._checksum)[:, j])
    flat = np.asarray(reference.values.positions).reshape(35, N)
    keys = [
        (5,),
        (-1, slice(1, 3)),
        (slice(3, 20, 4),),
        (slice(None), 2),
        (slice(30, 2, -5), slice(None, None, 2)),
        (Ellipsis, 0),
        (slice(7, 7),),
        (np.int64(12), 3),
        slice(10, 30),
    ]
    for key in keys:
        got, want = field[key], flat[key]
        assert got.shape == want.shape and np.array_equal(got, want), key


def test_a_memory_error_while_checking_a_store_is_not_taken_for_damage(
    g, reference, tmp_path, monkeypatch
):
    """A chunk that could not be read for want of memory counted as damaged: `read_zarr` under
    a 600 MB address-space limit called a sound 884 MB store 'unfinished: 1 of 246 chunks
    ... do not match their checksum', and resuming would have computed such chunks again.
    Now the MemoryError is raised."""
    import zarr

    path = str(tmp_path / "s.zarr")
    vmj.sweep(vmj.turning_points, g, a0=A0, n=N, chunk_size=8, store=path)
    read = zarr.Array.__getitem__

    def short_of_memory(self, key):
        if self.basename == "times":
            raise MemoryError("(simulated)")
        return read(self, key)

    monkeypatch.setattr(zarr.Array, "__getitem__", short_of_memory)
    with pytest.raises(MemoryError):
        vmj.sweep(vmj.turning_points, g, a0=A0, n=N, chunk_size=8, store=path, resume=True)
    with pytest.raises(MemoryError):
        np.asarray(vmj.SweepResult.read_zarr(path).values["times"])
    monkeypatch.undo()
    assert _same(reference.values, vmj.SweepResult.read_zarr(path).values)


def test_a_store_of_another_format_is_refused_as_such(g, tmp_path):
    """A store written by another version of vmj (here: format 1, one checksum per chunk over
    all its fields) was called 'not a vmj store' on resuming, and read with the wrong
    layout by `read_zarr`."""
    import zarr

    path = str(tmp_path / "s.zarr")
    vmj.sweep(vmj.turning_points, g, a0=A0, n=N, chunk_size=8, store=path)
    group = zarr.open_group(path, mode="r+")
    group.attrs["vmj"] = {**group.attrs["vmj"], "format": 1}
    refusal = r"written by another version of vmj \(store format 1; this version reads format 2\)"
    with pytest.raises(ValueError, match=refusal + ": delete it to start over"):
        vmj.sweep(vmj.turning_points, g, a0=A0, n=N, chunk_size=8, store=path, resume=True)
    with pytest.raises(ValueError, match=refusal + r": read it with that version"):
        vmj.SweepResult.read_zarr(path)


def test_columns_too_large_for_memory_are_refused_with_their_size(
    g, reference, tmp_path, monkeypatch
):
    """`columns()` of a result read from a store loaded every field whole whatever the memory
    (the 4 x 10^6-point energy-balance store, 884 MB of values: the peak RSS grew by 1562 MB,
    the fields read in blocks and concatenated). Now the columns are refused before anything
    is read where they need more than the free memory, with their size and what to do; where
    they fit, each field is read block by block into its columns (1049 MB)."""
    path = str(tmp_path / "s.zarr")
    lazy = vmj.sweep(vmj.turning_points, g, a0=A0, n=N, chunk_size=8, store=path)
    got, want = lazy.columns(), reference.columns()
    assert list(got) == list(want)
    assert all(np.array_equal(got[k], want[k]) for k in want)
    monkeypatch.setattr(vmj._checks, "ROOM_CHECKED_FROM", 0)
    # 35 points x (index 24 + eps, mu 16 + fields 111) = 35 x 151 = 5285 bytes; 5000 free
    monkeypatch.setattr(vmj._host, "available_memory", lambda device, enough: 5000)
    read = []
    monkeypatch.setattr(vmj._sweep._store._CheckedField, "_chunk", lambda *a: read.append(a))
    with pytest.raises(
        ValueError,
        match=r"SweepResult.columns\(\) of 35 points x 151 bytes: about 5.29e-06 GB, more than "
        r"the 5e-06 GB free on cpu; write them to a file block by block with to_csv",
    ):
        lazy.columns()
    assert read == []  # (refused before anything was read)
    # 24 + 16 bytes a point of an in-memory result (its fields are the result's own)
    monkeypatch.setattr(vmj._host, "available_memory", lambda device, enough: 1000)
    with pytest.raises(ValueError, match=r"of 35 points x 40 bytes"):
        vmj.SweepResult(
            reference.values, reference.dims, reference.coords, reference.shape
        ).columns()


def test_paired_points_in_a_store_are_labelled_by_point(tmp_path):
    """A store of paired points kept its coordinates in their own dimensions `eps_0`,
    `delta_0`, unrelated to the fields' `point`: `xarray.open_zarr` could not tell which point
    had which parameters."""
    xr = pytest.importorskip("xarray")
    paired = vmj.VariableMass(
        5.0,
        4900.0,
        delta=[3.0, -3.0, 1.0],
        eps=[0.0, 1.0, 0.5],
        mu=2.0,
        friction=vmj.Coulomb(14.7),
    )
    path = str(tmp_path / "p.zarr")
    r = vmj.sweep(vmj.turning_points, paired, a0=A0, n=N, store=path)
    with xr.open_zarr(path, consolidated=False) as ds:
        assert ds["eps"].dims == ("point",) and "eps" in ds.coords and "delta" in ds.coords
        np.testing.assert_array_equal(ds["eps"].values, [0.0, 1.0, 0.5])
        np.testing.assert_array_equal(ds["delta"].values, [3.0, -3.0, 1.0])
    back = vmj.SweepResult.read_zarr(path)
    assert back.dims == ("point",)
    np.testing.assert_array_equal(back.coords["eps"], r.coords["eps"])


@pytest.mark.filterwarnings("error:endian-ness")
def test_cli_store_is_not_refused_as_results_in_memory_and_its_exports_stream(
    tmp_path, capsys, monkeypatch
):
    """`vmj sweep ... --store` refused a sweep whose results exceeded the limit of results
    held in memory (1 GiB without --force), although with a store they are on disk; its
    summary and exports (--out, --netcdf) read the store as the in-memory run does."""
    pytest.importorskip("xarray")
    import vmj.cli._sweep as cli_sweep
    from vmj.cli import main

    monkeypatch.setattr(cli_sweep, "MAX_BYTES", 1000)  # (35 points: about 5 kB of results)
    base = ["sweep", "variable-mass", "--eps", "0:1:5", "--mu", "0:10:7", "--n", str(N)]
    base += ["--set", "m0=5,c=4900,FT=14.7,a0=0.06,delta=3", "--chunk-size", "8"]
    assert main(base) == 2
    assert "GiB of results in memory (--store PATH.zarr" in capsys.readouterr().err
    memory = [str(tmp_path / "m.csv"), str(tmp_path / "m.nc")]
    stored = [str(tmp_path / "s.csv"), str(tmp_path / "s.nc")]
    assert main(base + ["--force", "--out", memory[0], "--netcdf", memory[1]]) == 0
    summary_memory = capsys.readouterr().out.split("; ")[1:3]
    store = ["--store", str(tmp_path / "s.zarr"), "--out", stored[0], "--netcdf", stored[1]]
    assert main(base + store) == 0
    assert capsys.readouterr().out.split("; ")[1:3] == summary_memory  # stopped, failed
    assert open(stored[0]).read() == open(memory[0]).read()
    import xarray as xr

    with xr.open_dataset(memory[1]) as a, xr.open_dataset(stored[1]) as b:
        xr.testing.assert_identical(a, b)


def energy_amplitudes(m, a0, n):
    return vmj.turning_points(m, a0, n, vmj.EnergyBalance()).amplitudes


def test_a_sensitivity_over_a_grid_names_its_function(g):
    """Its `function` attribute (the exports', a store's) was the internal
    `vmj._sweep._sensitivity._PointSensitivity`, not the function differentiated."""
    r = vmj.sensitivity(energy_amplitudes, g, ("F", "mu"), a0=A0, n=N)
    assert r.attrs["function"].startswith("vmj.sensitivity(")
    assert r.attrs["function"].endswith(
        "test_sweep_audit.energy_amplitudes, wrt=(F, mu), mode=forward)"
    )


def test_value_fields_and_dimensionless_parameters_carry_their_units(model, g, tmp_path):
    """The exports gave no unit to the value fields (turning-point times [s], positions [m];
    the stick-slip cycle's dimensionless ones), nor to the dimensionless parameters that only
    the command line's help called dimensionless (VariableMass eps; StickSlip eps, Omega):
    each is now declared by its model or solution type."""
    xr = pytest.importorskip("xarray")
    r = vmj.sweep(vmj.turning_points, g, a0=A0, n=N, solver=vmj.EnergyBalance())
    assert r.attrs["units"] == {"eps": "1", "mu": "kg/s", "times": "s", "positions": "m"}
    ds = r.to_xarray()
    assert (ds["times"].attrs["units"], ds["positions"].attrs["units"]) == ("s", "m")
    assert ds["eps"].attrs["units"] == "1" and "units" not in ds["count"].attrs
    r.to_netcdf(str(tmp_path / "s.nc"))
    with xr.open_dataset(str(tmp_path / "s.nc")) as back:
        assert back["positions"].attrs["units"] == "m"
    path = str(tmp_path / "s.zarr")
    vmj.sweep(vmj.turning_points, g, a0=A0, n=N, solver=vmj.EnergyBalance(), store=path)
    with xr.open_zarr(path, consolidated=False) as lazy:
        assert (lazy["times"].attrs["units"], lazy["eps"].attrs["units"]) == ("s", "1")
    cycles = vmj.sweep(
        vmj.limit_cycle, vmj.grid(vmj.StickSlip(3.0, 0.7), eps=[3.0, 5.0], Omega=[0.5, 0.7])
    )
    units = cycles.attrs["units"]
    assert (units["eps"], units["Omega"], units["period"], units["positions"]) == ("1",) * 4
    assert "count" not in units and "reversals" not in units
