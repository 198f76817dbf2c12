"""Parameter sweeps and Monte Carlo over scenario parameters, locally or on a Dask cluster.

>>> from downhole.sweep import run_sweep                                   # doctest: +SKIP
>>> ds = run_sweep("examples/sweep_stability_map.toml",
...                ["operation.surface_speed=1:12:12", "operation.rop=2:20:10 mm/s"],
...                ["stick_slip_severity", "bit_bounce_fraction"], processes=2)
>>> stability_map(ds, "map.png")

See ``docs/sweeps.md``.
"""

from downhole.sweep.plots import REGIMES, classify_regimes, plot_sweep, stability_map
from downhole.sweep.runner import (
    failed_cases,
    load_sweep,
    load_sweep_file,
    run_cases,
    run_sweep,
    save_sweep,
)
from downhole.sweep.spec import METRICS, ParamSpec, parse_param

__all__ = [
    "METRICS",
    "REGIMES",
    "ParamSpec",
    "classify_regimes",
    "failed_cases",
    "load_sweep",
    "load_sweep_file",
    "parse_param",
    "plot_sweep",
    "run_cases",
    "run_sweep",
    "save_sweep",
    "stability_map",
]
