"""Run every benchmark (benchmarks/bench_*.py), each in a fresh process, one after the other.

Each prints its times and its ratios against a reference measured in the same run. Used by
`make bench`. Usage: .venv/bin/python benchmarks/run.py [NAME ...] [-- extra args]
(NAME: e.g. `exact` for bench_exact.py; default: all).
"""

import glob
import os
import subprocess
import sys
import time


def main() -> int:
    here = os.path.dirname(os.path.abspath(__file__))
    args = sys.argv[1:]
    extra = []
    if "--" in args:
        k = args.index("--")
        args, extra = args[:k], args[k + 1 :]
    scripts = sorted(glob.glob(os.path.join(here, "bench_*.py")))
    if args:
        wanted = {f"bench_{a}.py" for a in args}
        unknown = wanted - {os.path.basename(s) for s in scripts}
        if unknown:
            print(f"run.py: no such benchmark: {', '.join(sorted(unknown))}", file=sys.stderr)
            return 2
        scripts = [s for s in scripts if os.path.basename(s) in wanted]
    status = 0
    for script in scripts:
        print(f"== {os.path.basename(script)} ==", flush=True)
        t0 = time.perf_counter()
        rc = subprocess.run([sys.executable, script, *extra]).returncode
        print(f"   ({time.perf_counter() - t0:.0f} s, exit {rc})\n", flush=True)
        status = status or rc
    return status


if __name__ == "__main__":
    sys.exit(main())
