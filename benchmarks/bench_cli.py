"""The `vmj` command as a user meets it: whole processes, wall time.

- `vmj --help` (goal <= 0.3 s) and `vmj table 1`, cold (a fresh compilation cache) and
  repeated (the cache filled), against `python -c "import jax"` (goal: the repeat <= 1.5 x);
- `vmj fit fits/data/table1_mu9_eps0.csv --model variable-mass --fit FT,mu
  --set m0=5,c=4900,delta=3,eps=0 --loss cauchy --json`, first run in a fresh cache (goal
  <= 10 s) and repeated (goal <= 1.5 x), against a whole SciPy script doing the same fit
  (benchmarks/scipy_fit.py: least_squares over an event-driven solve_ivp model), whose answer
  must agree to 1e-4;
- with `--sweep` (for a machine with an accelerator: benchmarks/gpu.sh) `vmj sweep
  variable-mass` of 1617 to 10^6 points on the accelerator, on the CPU and where the command
  chooses, in turns (`sweep`).

Each group is measured in turns (`interleaved`: one run of each per round), so that the
machine's changes of speed during the run reach a figure and its peer alike.

Run: .venv/bin/python benchmarks/bench_cli.py [--quick] [--fit] [--sweep]  (`--fit`: the fit's
timings alone; `--sweep`: the sweep's alone)
"""

import argparse
import json
import os
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _timing import REPEAT, interleaved, machine, ratio, run_process  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
VMJ = [os.path.join(os.path.dirname(sys.executable), "vmj")]
if not os.path.exists(VMJ[0]):  # vmj run from a checkout (benchmarks/gpu.sh): no script installed
    VMJ = [sys.executable, "-m", "vmj.cli"]
FIT = [
    "fit",
    os.path.join(ROOT, "fits", "data", "table1_mu9_eps0.csv"),
    "--model",
    "variable-mass",
    "--fit",
    "FT,mu",
    "--set",
    "m0=5,c=4900,delta=3,eps=0",
    "--loss",
    "cauchy",
    "--json",
]


SWEEP = ["sweep", "variable-mass", "--set", "m0=5,c=4900,FT=14.7,a0=0.06"]


def process(argv, cache=None, fresh=False, out=None, platforms=None):
    """One run of a process as a function: in the compilation cache `cache`, or with `fresh` in
    a new empty one (else one made for the run); its standard output is kept in `out["text"]`;
    `platforms` sets `JAX_PLATFORMS`."""

    def run():
        with tempfile.TemporaryDirectory() as empty:
            env = dict(os.environ)
            if platforms is not None:
                env["JAX_PLATFORMS"] = platforms
            env["VMJ_CACHE_DIR"] = empty if fresh else (cache or empty)
            _, text = run_process(argv, env=env, cwd=ROOT)
            if out is not None:
                out["text"] = text

    return run


def start_up(times):
    """`vmj --help` and `vmj table 1` against `python -c "import jax"`, in turns."""
    with tempfile.TemporaryDirectory() as cache:
        process([*VMJ, "table", "1"], cache=cache)()  # (fills the cache)
        t_jax, t_help, t_table_cold, t_table = interleaved(
            (process([sys.executable, "-c", "import jax"]), 1),
            (process([*VMJ, "--help"]), 1),
            (process([*VMJ, "table", "1"], fresh=True), 1),
            (process([*VMJ, "table", "1"], cache=cache), 1),
            rounds=times,
        )
    print(f"  python -c 'import jax':   {t_jax}")
    print(f"  vmj --help:               {t_help}  (goal <= 0.3 s)")
    print(f"  vmj table 1, cold cache:  {t_table_cold}")
    print(f"  vmj table 1, repeated:    {t_table}")
    ratio("table 1 repeated / import jax", t_table, t_jax, "<= 1.5")


def sweep(times, accelerator):
    """`vmj sweep variable-mass` of the README (1617 points written to a CSV file, estimated
    0.02 s), of 91809 points (estimated 1.1 s) and of 1009899 points (12 s; these two write
    nothing), whole processes in turns: on the accelerator (`JAX_PLATFORMS=accelerator`, none
    on a CPU-only machine), on the CPU, and where the command chooses (`JAX_PLATFORMS` unset:
    the CPU below an estimated 5 s); each repeated, its cache filled (the README's sweep in a
    fresh cache: 5.26 s on an H200 machine's GPU, 3.60 s on its CPU, docs/performance.md)."""
    sizes = {
        "1617 points": ["--eps", "0:1:11", "--mu", "0:10:21", "--delta", "-3:3:7", "--out"],
        "91809 points": ["--eps", "0:1:101", "--mu", "0:10:101", "--delta", "-3:3:9"],
        "1009899 points": ["--eps", "0:1:101", "--mu", "0:10:101", "--delta", "-3:3:99"],
    }
    where = {"the command's choice": None, "JAX_PLATFORMS=cpu": "cpu"}
    if accelerator:
        where[f"JAX_PLATFORMS={accelerator}"] = accelerator
    with tempfile.TemporaryDirectory() as tmp:
        runs = []
        for size, axes in sizes.items():
            cmd = [*VMJ, *SWEEP, *axes]
            if cmd[-1] == "--out":
                cmd.append(os.path.join(tmp, "sweep.csv"))
            for name, platforms in where.items():
                cache = os.path.join(tmp, f"{len(runs)}")
                os.mkdir(cache)
                process(cmd, cache=cache, platforms=platforms)()  # (fills the cache)
                runs.append((f"{size}, {name}, repeated", cmd, cache, platforms))
        timings = interleaved(
            *[
                (process(cmd, cache=cache, platforms=platforms), 1)
                for _, cmd, cache, platforms in runs
            ],
            rounds=times,
        )
    print("  vmj sweep variable-mass (the README's --set)")
    for (label, *_), t in zip(runs, timings):
        print(f"    {label + ':':52s} {t}")
    if accelerator:
        found = dict(zip([label for label, *_ in runs], timings))
        for size in sizes:
            ratio(
                f"{size}, repeated, {accelerator} / cpu",
                found[f"{size}, JAX_PLATFORMS={accelerator}, repeated"],
                found[f"{size}, JAX_PLATFORMS=cpu, repeated"],
            )


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="fewer repetitions (a smoke run)")
    ap.add_argument("--fit", action="store_true", help="only `vmj fit` and its SciPy peer")
    ap.add_argument("--sweep", action="store_true", help="only `vmj sweep`, accelerator and CPU")
    args = ap.parse_args()
    import jax  # (for the machine line and the accelerator's name; the timed processes are separate)

    platform = jax.devices()[0].platform
    accelerator = {"gpu": "cuda"}.get(platform, platform) if platform != "cpu" else None
    print(machine())
    times = 2 if args.quick else REPEAT
    print("whole processes, wall time")
    if args.sweep:
        sweep(times, accelerator)
        return
    if not args.fit:
        start_up(times)

    vmj_out, scipy_out = {}, {}
    with tempfile.TemporaryDirectory() as cache:
        process([*VMJ, *FIT], cache=cache)()  # (fills the cache)
        t_fit_cold, t_fit, t_scipy = interleaved(
            (process([*VMJ, *FIT], fresh=True), 1),
            (process([*VMJ, *FIT], cache=cache, out=vmj_out), 1),
            (
                process(
                    [sys.executable, os.path.join(ROOT, "benchmarks", "scipy_fit.py")],
                    out=scipy_out,
                ),
                1,
            ),
            rounds=times,
        )
    vmj_fit = json.loads(vmj_out["text"])["params"]
    scipy_fit = json.loads(scipy_out["text"])["params"]
    worst = max(abs(vmj_fit[k] / scipy_fit[k] - 1) for k in ("FT", "mu"))
    print(f"  vmj fit, fresh cache:     {t_fit_cold}  (goal <= 10 s)")
    print(f"  vmj fit, repeated:        {t_fit}")
    print(f"  SciPy script, same fit:   {t_scipy}")
    print(
        f"  answers: vmj FT = {vmj_fit['FT']:.5f} N, mu = {vmj_fit['mu']:.5f} kg/s; SciPy "
        f"FT = {scipy_fit['FT']:.5f} N, mu = {scipy_fit['mu']:.5f} kg/s (agree to {worst:.0e})"
    )
    ratio("vmj fit repeated / SciPy", t_fit, t_scipy, "<= 1.5")


if __name__ == "__main__":
    main()
