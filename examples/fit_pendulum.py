"""Identify viscous damping and Coulomb friction of the measured pendulum record 80P.txt.

Run: .venv/bin/python examples/fit_pendulum.py  (writes docs/figures/fit_80P.png)
"""

import os
import warnings

import jax

jax.config.update("jax_enable_x64", True)

import fits  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
record = fits.read_record(os.path.join(HERE, "data", "80P.txt"), series=True)
print(f"{len(record)} turning points extracted (noise {record.noise:.3g} deg, "
      f"clock {record.signal.clock})")
with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    result = fits.fit(record, "oscillator", ("omega", "zeta", "xF", "a0", "offset"))
print(result.report())
out = os.path.join(HERE, "..", "docs", "figures", "fit_80P.png")
fits.plot_fit(result, out)
print("figure written to", os.path.normpath(out))
