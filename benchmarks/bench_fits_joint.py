"""A joint pendulum fit of several raw records on their samples against one record's fit:
`fits/data/80P.txt` whole, and its rows split into three consecutive parts (rows 0-1504,
1505-3010, 3011-end: 40, 40 and 58 turning points) fitted jointly with omega, zeta, xF, cq
and b2 shared (`fits.fit(..., "pendulum", residuals="series")`, intervals and the shared
parameters' test included). One run each, in a fresh process (compilations included); wall
and CPU time of the fit, and per stage the Levenberg-Marquardt solves (calls, chunks of the
batch size, jobs, the batch's steps per call) and their wall time.

Run: .venv/bin/python benchmarks/bench_fits_joint.py [--single | --joint]
(both, each in its own process, without an argument)
"""

import collections
import os
import subprocess
import sys
import tempfile
import time
import warnings

HERE = os.path.dirname(os.path.abspath(__file__))
DATA = os.path.join(HERE, "..", "fits", "data", "80P.txt")
SHARED = ("omega", "zeta", "xF", "cq", "b2")
PARTS = ((0, 1505), (1505, 3011), (3011, None))  #: rows of the data after its 2 header lines


def parts(directory) -> list:
    with open(DATA) as f:
        lines = f.read().splitlines()
    head, rows = lines[:2], lines[2:]
    out = []
    for i, (a, b) in enumerate(PARTS):
        path = os.path.join(directory, f"80P-part{i}.txt")
        with open(path, "w") as f:
            f.write("\n".join(head + rows[a:b]) + "\n")
        out.append(path)
    return out


def measure(joint: bool) -> None:
    sys.path.insert(0, HERE)
    from _timing import machine, set_up_jax

    set_up_jax()
    import fits
    import fits._fit as F
    import fits._solve as S
    from fits._pendulum import FREE

    stage = ["turning points"]
    solves = collections.defaultdict(lambda: [0, 0, 0, 0.0, []])
    plain = S._solve

    def counted(space, items, shape, optimizer=None):
        t = time.perf_counter()
        out = plain(space, items, shape, optimizer)
        s = solves[stage[0]]
        s[0] += 1
        s[1] += -(-len(items) // shape.B)
        s[2] += len(items)
        s[3] += time.perf_counter() - t
        s[4].append(max(o["steps"] for o in out))
        return out

    S._solve = F._solve = counted
    for name, label in (
        ("_series_stage", "samples"),
        ("_check_shared", "records alone"),
        ("_profiles", "profiles"),
    ):
        inner = getattr(F, name)

        def staged(*args, _inner=inner, _label=label, **kwargs):
            before, stage[0] = stage[0], _label
            try:
                return _inner(*args, **kwargs)
            finally:
                stage[0] = before

        setattr(F, name, staged)
    with tempfile.TemporaryDirectory() as tmp:
        paths = parts(tmp) if joint else [DATA]
        records = [fits.read_record(p, series=True) for p in paths]
        t0, c0 = time.perf_counter(), time.process_time()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = fits.fit(
                records if joint else records[0],
                "pendulum",
                FREE,
                shared=SHARED if joint else (),
                residuals="series",
            )
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    what = "3 parts jointly" if joint else "80P.txt alone"
    print(f"{what}: {wall:.0f} s wall, {cpu:.0f} s CPU ({machine()})")
    for label, (calls, chunks, jobs, seconds, steps) in solves.items():
        print(
            f"  {label}: {calls} solves, {chunks} chunks, {jobs} jobs, {seconds:.0f} s; "
            f"steps {steps}"
        )
    print(f"  {res.label}: " + ", ".join(f"{k} {v:.6g}" for k, v in res.params.items()))
    test = res.diagnostics.get("shared")
    if test and test.get("tested"):
        print(f"  shared test: F {test['F']:.6g} on {test['df']}, p {test['p']:.3g}")


if __name__ == "__main__":
    if "--single" in sys.argv or "--joint" in sys.argv:
        measure("--joint" in sys.argv)
    else:
        for flag in ("--single", "--joint"):
            subprocess.run([sys.executable, __file__, flag], check=True)
