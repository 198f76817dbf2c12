"""LAS 2.0 export of simulation results (time-indexed logs), via lasio.

Drilling data tools (log viewers, Techlog, Petrel, lasio/welly scripts) read LAS. A
:class:`~downhole.sim.Result` becomes a time-indexed LAS 2.0 file: the index curve ``TIME`` (s),
one curve per 1-D channel with its unit in the curve header (``WOB .N``, ``TOB .N*m``), the run's
scalar metadata (dt, model, integrator, ...) in the ``~Parameter`` section and the summary
metrics as parameters too.

:meth:`Result.to_las <downhole.sim.result.Result.to_las>` calls :func:`write_las`. The writer
lives beside the Result (as its CSV and netCDF writers do) so that the Result does not import the
I/O package; :mod:`downhole.io.las` re-exports it and holds the reader,
:func:`~downhole.io.las.read_las`.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np

from downhole._atomic import atomic_path
from downhole.errors import DownholeInputError

__all__ = ["NULL", "write_las"]

#: Null value written for NaN samples (the LAS convention).
NULL = -999.25

#: Parameters copied from Result.attrs into ~Parameter when present: attr -> (mnemonic, unit).
_PARAM_ATTRS = {"dt": ("DT", "s"), "model": ("MODEL", ""), "integrator": ("INTEG", ""),
                "depth_of_cut": ("DOC", ""), "input_mode": ("INPUT", ""),
                "bit_radius": ("BITRAD", "m"), "n_blades": ("NBLADES", ""),
                "downhole_version": ("DHVER", ""), "title": ("TITLE", "")}


def _mnemonic(name: str) -> str:
    m = "".join(c if (c.isalnum() or c == "_") else "_" for c in name.upper())
    return m or "CURVE"


def write_las(result, path: str | os.PathLike, well: str = "downhole simulation",
              channels: list[str] | None = None, company: str = "", field: str = "",
              summary: bool = True, units=None) -> Path:
    """Write ``result`` as a time-indexed LAS 2.0 file.

    Parameters
    ----------
    result : Result
    path : path-like
        Output file (written to an exclusive temporary file in its folder, then renamed).
    well : str
        ``WELL`` entry of the ~Well section.
    channels : list of str, optional
        Channels to write (default: every 1-D channel).
    company, field : str
        ``COMP`` and ``FLD`` entries.
    summary : bool
        Also write the summary metrics (second half of the run) as ~Parameter entries.
    units : str or UnitSystem, optional
        Display units of the curves and parameters (:func:`downhole.units.display_units`,
        e.g. ``"oilfield"``: WOB in klbf, torques in kft*lbf, speeds in rpm, ROP in ft/h);
        default: the stored SI units.

    Returns
    -------
    pathlib.Path
    """
    import lasio

    from downhole.units import convert, display_units

    disp = display_units(units or "si")
    names = [n for n in result.channels if result.dataset[n].ndim == 1]
    if channels is not None:
        unknown = [c for c in channels if c not in result.channels]
        if unknown:
            raise DownholeInputError(f"channels {unknown} are not in the result; it has "
                                     f"{', '.join(result.channels)}")
        multi = [c for c in channels if result.dataset[c].ndim != 1]
        if multi:
            raise DownholeInputError(f"channels {multi} are not 1-D time series; LAS holds one "
                                     "value per time sample")
        names = list(channels)
    t = np.asarray(result.time, float)
    if t.size == 0:
        raise DownholeInputError("the result has no samples; nothing to write")
    las = lasio.LASFile()
    las.well["WELL"].value = well
    las.well["COMP"].value = company
    las.well["FLD"].value = field
    las.well["NULL"].value = NULL
    import datetime

    for key, descr in (("STRT", "START TIME"), ("STOP", "STOP TIME"), ("STEP", "STEP")):
        las.well[key].unit = "s"
        las.well[key].descr = descr
    las.well["DATE"].value = datetime.date.today().isoformat()
    las.append_curve("TIME", t, unit="s", descr="simulated time")
    seen = {"TIME"}
    for n in names:
        mnem = _mnemonic(n)
        if mnem in seen:
            raise DownholeInputError(f"channel names {n!r} and another map to the same LAS "
                                     f"mnemonic {mnem!r}")
        seen.add(mnem)
        da = result.dataset[n]
        unit = str(da.attrs.get("units", "")).replace(" ", "")
        desc = str(da.attrs.get("description", "")) or n
        values, unit = disp.convert(n, da.values, unit)
        unit = "" if unit == "-" else unit
        values = np.where(np.isfinite(values), values, NULL)
        las.append_curve(mnem, values, unit=unit, descr=f"{n}: {desc}")
    attrs = result.attrs
    for key, (mnem, unit) in _PARAM_ATTRS.items():
        if key in attrs:
            value = attrs[key]
            if isinstance(value, (np.generic,)):
                value = value.item()
            if key == "bit_radius" and isinstance(value, (int, float)):
                # a radius reads like a diameter: inches, not feet, in oilfield units
                unit = disp.kind_unit("diameter")
                value = convert(float(value), "m", unit)
            las.params.append(lasio.HeaderItem(mnem, unit=unit, value=value, descr=key))
    if summary:
        try:
            s = result.summary()
        except Exception:
            s = {}
        from downhole.signals import metric_unit

        for k, v in s.items():
            if isinstance(v, float) and math.isfinite(v):
                v, unit = disp.convert(k, v, metric_unit(k))
                las.params.append(lasio.HeaderItem(_mnemonic(k), unit=unit.replace("-", ""),
                                                   value=float(f"{v:.8g}"),
                                                   descr=f"summary: {k} (second half)"))
    las.other = ("Written by downhole from a simulation Result. Time-indexed (not depth): the "
                 "index curve TIME is the simulated time in seconds.")
    path = Path(path)
    # an exclusive, non-following temporary with a random name (never a fixed "path.part" that
    # a planted link could redirect), filled through its descriptor, then renamed
    with atomic_path(path) as tmp:
        fd = os.open(tmp, os.O_WRONLY | os.O_TRUNC | getattr(os, "O_NOFOLLOW", 0))
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            las.write(fh, version=2.0, wrap=False, fmt="%.10g")
    return path
