#!/usr/bin/env bash
# The issue's GPU measurements in one run, on a machine whose Python has JAX with CUDA (no
# virtual environment needed: vmj runs from the checkout): the exact and the energy-balance
# sweeps in float64 and float32, each against its same-run peer (SciPy's event loop, NumPy in
# place: both on the host), the whole-process `vmj fit` and `vmj sweep` on the GPU and on the
# CPU, then vmj's solver, sweep and fit tests on the GPU.
#
# Run from the repository root: bash benchmarks/gpu.sh [SECONDS]  (PYTHON=... picks the
# interpreter, default python3; SECONDS bounds the whole run, default 540: the tests get what the
# benchmarks leave). Logs go to $OUT (default out/gpu).
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

for flags in "" "--float32"; do
  $PY benchmarks/run.py energy exact -- $flags 2>&1 | tee -a "$LOG/bench.txt"
done
# a GPU fills at far more lanes than the issue's 4096 points
$PY benchmarks/bench_exact.py --points 65536 2>&1 | tee -a "$LOG/bench.txt"
# the `vmj fit` of bench_cli.py, whole processes: JAX's default device (the GPU), then the CPU
for platforms in "" cpu; do
  echo "== vmj fit, JAX_PLATFORMS='$platforms' ==" | tee -a "$LOG/bench.txt"
  JAX_PLATFORMS=$platforms $PY benchmarks/bench_cli.py --quick --fit 2>&1 | tee -a "$LOG/bench.txt"
done
# the README's `vmj sweep`, whole processes: JAX's default device (the GPU) against the CPU
echo "== vmj sweep ==" | tee -a "$LOG/bench.txt"
$PY benchmarks/bench_cli.py --quick --sweep 2>&1 | tee -a "$LOG/bench.txt"

left=$((BUDGET - SECONDS))
echo "== tests on the GPU ($left s left) =="
if [ "$left" -gt 30 ]; then
  timeout "$left" $PY -m pytest -q -n 8 --dist loadfile -m "not long and not slow" -p no:cacheprovider \
    tests/test_variable_mass.py tests/test_sweep.py tests/test_oscillator.py tests/test_rope.py \
    tests/test_stickslip.py tests/test_linear.py tests/test_ode.py tests/test_roots.py \
    tests/test_sensitivity.py tests/test_compiled.py tests/test_bad_input.py \
    tests/test_fits_engine.py 2>&1 | tee "$LOG/tests.txt"
fi
