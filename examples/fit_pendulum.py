"""Identify the restoring law, the dissipation laws and the sensor of the measured pendulum record
80P.txt (shipped with fits as package data) with the `pendulum` model: every law set the record
can identify is fitted and the one preferred by BIC is reported, with the others in the model
comparison; the plain oscillator fit is shown beside it for its residual autocorrelation.

Run: .venv/bin/python examples/fit_pendulum.py [PNG]   (default out/fit_80P.png;
docs/figures/fit_80P.png for the site); about 5 minutes on 2 cores. `VMJ_EXAMPLES_QUICK=1` (the
test suite's smoke run) fits the sine law set with every law alone, without the comparison and
the profile intervals.
"""

import os
import sys
import warnings
from importlib.resources import files

import jax

jax.config.update("jax_enable_x64", True)

import fits  # noqa: E402

FREE = ("omega", "zeta", "xF", "cq", "b2", "a0", "offset", "asym")
QUICK = os.environ.get("VMJ_EXAMPLES_QUICK") == "1"

record = fits.read_record(files("fits") / "data" / "80P.txt", series=True)
print(
    f"{len(record)} turning points extracted (noise {record.noise:.3g} deg); clock: "
    f"{record.clock['message']}"
)
with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    plain = fits.fit(record, "oscillator", ("omega", "zeta", "xF", "a0", "offset"), intervals=False)
    result = fits.fit(record, "pendulum", FREE, compare=not QUICK, intervals=not QUICK)
print(
    f"plain oscillator fit: rms {plain.rms:.4f} deg, residual lag-1 autocorrelation "
    f"{plain.diagnostics['lag1']:.3f}"
)
print(result.report())
print("law sets by BIC:")
for label, entry in sorted(
    ((k, v) for k, v in result.model_comparison.items() if isinstance(v, dict)),
    key=lambda kv: kv[1]["bic"],
):
    print(f"  {label:34s} BIC {entry['bic']:10.1f}")
out = sys.argv[1] if len(sys.argv) > 1 else os.path.join("out", "fit_80P.png")
os.makedirs(os.path.dirname(out) or ".", exist_ok=True)
fits.plot_fit(result, out)
print("figure written to", out)
