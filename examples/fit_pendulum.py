"""Identify viscous damping and Coulomb friction of the measured pendulum record 80P.txt
(shipped with fits as package data).

Run: .venv/bin/python examples/fit_pendulum.py [PNG]   (default out/fit_80P.png;
docs/figures/fit_80P.png for the site)
"""

import os
import sys
import warnings
from importlib.resources import files

import jax

jax.config.update("jax_enable_x64", True)

import fits  # noqa: E402

record = fits.read_record(files("fits") / "data" / "80P.txt", series=True)
print(f"{len(record)} turning points extracted (noise {record.noise:.3g} deg, "
      f"clock {record.signal.clock})")
with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    result = fits.fit(record, "oscillator", ("omega", "zeta", "xF", "a0", "offset"))
print(result.report())
out = sys.argv[1] if len(sys.argv) > 1 else os.path.join("out", "fit_80P.png")
os.makedirs(os.path.dirname(out) or ".", exist_ok=True)
fits.plot_fit(result, out)
print("figure written to", out)
