"""`map_chunks`: a function of a list of items, evaluated chunk by chunk in threads or on a Dask
cluster, with a resumable store: the same machinery as [`vmj.sweep`][] for work that is not a
sweep over model parameters (batched fits of many records, bootstrap replicates)."""

from __future__ import annotations

import math
import pickle
import sys
from collections.abc import Callable, Sequence

from .._checks import check_int
from .._version import __version__
from ._engine import CORES, Progress, cluster, failure_message, run_chunks, threads_of
from ._store import ChunkStore, check_resume, describe_fn, digest
from ._sweep import SweepError, chunk_plan

__all__ = ["map_chunks"]

#: the most items per chunk unless a chunk_size is given
DEFAULT_ITEMS = 256


class _MapJob:
    def __init__(self, fn, items, chunk, token):
        self.fn, self.items, self.chunk, self.token = fn, items, chunk, token

    def compute(self, c: int) -> list:
        part = self.items[c * self.chunk : (c + 1) * self.chunk]
        got = list(self.fn(part))
        if len(got) != len(part):
            raise ValueError(
                f"fn returned {len(got)} results for a chunk of {len(part)} items "
                f"(one result per item is needed)"
            )
        return got


def map_chunks(
    fn: Callable,
    items: Sequence,
    *,
    chunk_size: int | None = None,
    progress=None,
    client=None,
    store=None,
    resume: bool = False,
) -> list:
    """`fn` over consecutive chunks of `items`: `fn(items[i:j])` returns one result per item,
    and the results come back in the order of the items.

    **Arguments:**

    - `fn`: a function of a list of items (e.g. records to fit) returning a list of as many
      picklable results (e.g. `functools.partial(fits.fit_batch, model="variable-mass")`).
    - `items`: a sequence of picklable items.
    - `chunk_size`: the most items per call of `fn` (default 256); the items are split into
      at least one chunk per core (per worker thread of a cluster), of about equal size.
    - `progress`, `client`, `resume`: as in [`vmj.sweep`][].
    - `store`: a path of a Zarr store: each finished chunk's results are written to it
      (pickled, with a checksum and a completion marker) as it completes; a rerun with
      `resume=True` computes only the chunks not yet in it. The store records the function,
      the items and `chunk_size`, and refuses a different one. Read only stores you wrote:
      they hold pickles.

    **Returns:** the list of results. With a client or a store, a chunk that raises does not
    stop the others; [`vmj.SweepError`][] then names the failed chunks, and its `result` is
    the list with `None` for their items.
    """
    items = list(items)
    if not items:
        raise ValueError("items must not be empty")
    if chunk_size is not None:
        chunk_size = check_int("chunk_size", chunk_size, 1)
    check_resume(resume, store, "work")
    n = len(items)
    definition = {
        "fn": digest(fn),
        "items": digest(items),
        "chunk_size": chunk_size,
        "vmj": __version__,
    }
    described = {
        "fn": f"{describe_fn(fn)} (code {definition['fn'][:8]})",
        "items": f"{n} items ({definition['items'][:8]})",
        "chunk_size": "default" if chunk_size is None else str(chunk_size),
        "versions": f"vmj {definition['vmj']}",
    }
    token = digest(definition)
    with cluster(client) as cl:
        lanes = threads_of(cl) if cl is not None else CORES
        st = None
        if store is not None:
            st = ChunkStore.existing(
                store, kind="map", definition=definition, described=described, resume=resume
            )
        if st is not None:
            chunk = int(st.meta["chunk"])
        else:
            chunk = chunk_plan(n, chunk_size or DEFAULT_ITEMS, lanes)
        n_chunks = math.ceil(n / chunk)
        if store is not None and st is None:
            st = ChunkStore.create(
                store,
                kind="map",
                definition=definition,
                described=described,
                plan={"n": n, "chunk": chunk, "n_chunks": n_chunks},
            )
        out: list = [None] * n

        def place(c, blob):
            out[c * chunk : (c + 1) * chunk] = pickle.loads(blob)

        todo = st.remaining(None, place) if st is not None and resume else list(range(n_chunks))
        resumed = n_chunks - len(todo)

        def sink(c, got):
            out[c * chunk : (c + 1) * chunk] = got
            if st is not None:
                st.write(c, pickle.dumps(got, protocol=5))

        failures = {}

        def fail(c, exc):
            message = failure_message(exc)
            failures[c] = (c * chunk, min((c + 1) * chunk, n) - 1, -1, message)
            if st is not None:
                st.fail(c, -1, message)

        show = progress if progress is not None else (sys.stderr.isatty() and n_chunks > 1)
        bar = Progress(n_chunks, n, show, already=resumed, label="map", unit="items")
        run_chunks(
            _MapJob(fn, items, chunk, token),
            todo,
            sink=sink,
            progress=bar,
            client=cl,
            threads=lanes,
            fail=fail if (cl is not None or st is not None) else None,
            store=st,
        )
    if failures:
        lo, hi, _, message = failures[min(failures)]
        raise SweepError(
            f"{len(failures)} of {n_chunks} chunks failed (the first: items {lo} "
            f"to {hi}: {message})",
            failures,
            out,
        )
    return out
