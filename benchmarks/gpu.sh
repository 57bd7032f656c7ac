#!/usr/bin/env bash
# The issue's GPU measurements in one run, on a machine whose Python has JAX with CUDA (no
# virtual environment needed: vmj runs from the checkout): vmj's tests on the GPU, then the
# exact and the energy-balance sweeps in float64 and float32, each against its same-run peer
# (SciPy's event loop, NumPy in place: both on the host), and the whole-process `vmj fit` and
# `vmj sweep` on the GPU and on the CPU.
#
# Run from the repository root: bash benchmarks/gpu.sh [SECONDS]  (PYTHON=... picks the
# interpreter, default python3; SECONDS bounds the whole run, default 540: the tests take at
# most TEST_SECONDS of it, default 200, and a benchmark starts only while it has its time).
# Logs go to $OUT (default out/gpu).
set -u
PY=${PYTHON:-python3}
BUDGET=${1:-540}
LOG=${OUT:-out/gpu}
mkdir -p "$LOG"
export PYTHONPATH=$PWD${PYTHONPATH:+:$PYTHONPATH} PYTHONUNBUFFERED=1
export XLA_PYTHON_CLIENT_PREALLOCATE=false # the benchmarks start a second JAX process

nvidia-smi --query-gpu=name,memory.total,driver_version,clocks.sm,clocks.max.sm --format=csv
$PY - <<'EOF' || exit 1
import importlib, jax
jax.config.update("jax_enable_x64", True)
print("python", __import__("sys").version.split()[0], "devices", jax.devices())
for name in ("jax", "jaxlib", "equinox", "diffrax", "optimistix", "lineax", "numpy", "scipy"):
    print(f"  {name} {importlib.import_module(name).__version__}")
import vmj
m = vmj.VariableMass(5.0, 4900.0, 3.0, 0.0, 2.0, vmj.Coulomb(14.7))
print("smoke:", vmj.turning_points(m, 0.06, 12).positions[:3])
g = vmj.grid(m, eps=[0.0, 0.5, 1.0], mu=[0.0, 5.0])
print("sweep:", vmj.sweep(vmj.turning_points, g, a0=0.06, n=12).values.positions[0, 0, :3])
EOF

# vmj's tests on the GPU first (a failure there is worth more than a figure): every file but
# the documentation's snippets and the cluster's (processes and servers of their own), spread
# over 16 workers, for at most TEST_SECONDS (default 200); each test's outcome is written to
# $LOG/tests.txt as it ends, so that a run cut short still names its failures
timeout "${TEST_SECONDS:-200}" $PY -m pytest -v --tb=short -rf -n 16 --dist load \
  -m "not long and not slow" -p no:cacheprovider -p no:benchmark \
  $(ls tests/test_*.py | grep -v -e test_docs.py -e test_distributed.py) >"$LOG/tests.txt" 2>&1
echo "== tests on the GPU (exit $?) =="
grep -E "FAILED|ERROR |[0-9]+ (passed|failed)" "$LOG/tests.txt" | tail -40

# the benchmarks, each while BUDGET leaves it the time it takes here
left() { [ $((BUDGET - SECONDS)) -gt "$1" ]; }
for flags in "" "--float32"; do
  left 60 && $PY benchmarks/run.py energy exact -- $flags 2>&1 | tee -a "$LOG/bench.txt"
done
# a GPU fills at far more lanes than the issue's 4096 points
left 60 && $PY benchmarks/bench_exact.py --points 65536 2>&1 | tee -a "$LOG/bench.txt"
# the `vmj fit` of bench_cli.py, whole processes: JAX_PLATFORMS unset (the command runs on the
# CPU), then cpu
for platforms in "" cpu; do
  left 40 || break
  echo "== vmj fit, JAX_PLATFORMS='$platforms' ==" | tee -a "$LOG/bench.txt"
  JAX_PLATFORMS=$platforms $PY benchmarks/bench_cli.py --quick --fit 2>&1 | tee -a "$LOG/bench.txt"
done
# `vmj sweep`, whole processes: on the GPU, on the CPU and where the command chooses
left 120 && echo "== vmj sweep ==" | tee -a "$LOG/bench.txt" &&
  $PY benchmarks/bench_cli.py --quick --sweep 2>&1 | tee -a "$LOG/bench.txt"
echo "== done in $SECONDS s =="
