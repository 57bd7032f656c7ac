"""fits: identification of dry friction, rope friction and damping from measured decay.

    import jax
    jax.config.update("jax_enable_x64", True)
    import fits

    record = fits.read_record("80P.txt", series=True)       # raw signal -> turning points
    result = fits.fit(record, "oscillator", free=("omega", "zeta", "xF", "a0", "offset"))
    print(result.report())

See docs/fits.md.
"""

from ._clock import recover_clock
from ._decrement import decrement
from ._extract import extract_turning_points
from ._fit import LOSSES, OPTIMIZERS, FitResult, fit, fit_batch
from ._io import read_decays, read_record
from ._record import (
    EDGE_RELEASE,
    HELD_RELEASE,
    ROWS_AS_HALF_SWINGS,
    Record,
    read_peaks,
    record_from_sequence,
)
from ._report import paper_records, plot_fit
from ._result import text_report
from ._sensor import sensor_start
from ._signal import Signal, read_signal
from ._space import FORWARDS
from ._text import MAX_ROWS, TIME_UNITS

__all__ = [
    "Record",
    "Signal",
    "read_peaks",
    "read_signal",
    "read_record",
    "read_decays",
    "record_from_sequence",
    "extract_turning_points",
    "recover_clock",
    "sensor_start",
    "MAX_ROWS",
    "EDGE_RELEASE",
    "HELD_RELEASE",
    "ROWS_AS_HALF_SWINGS",
    "TIME_UNITS",
    "decrement",
    "fit",
    "fit_batch",
    "FitResult",
    "FORWARDS",
    "LOSSES",
    "OPTIMIZERS",
    "paper_records",
    "plot_fit",
    "text_report",
]
