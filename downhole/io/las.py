"""LAS 2.0 files of simulation results (time-indexed logs), via lasio: the reader, and the writer
re-exported from :mod:`downhole.sim.las` (where it lives beside the Result it writes, so that
:meth:`Result.to_las <downhole.sim.result.Result.to_las>` needs no import of this package).
"""

from __future__ import annotations

import os

import numpy as np

from downhole.errors import DownholeInputError
from downhole.sim.las import _PARAM_ATTRS, NULL, write_las

__all__ = ["write_las", "read_las", "NULL"]


def read_las(path: str | os.PathLike):
    """Read a time-indexed LAS file written by :func:`write_las` back into a Result."""
    import lasio

    from downhole.sim.result import Result

    las = lasio.read(str(path))
    if las.curves[0].mnemonic.upper() != "TIME":
        raise DownholeInputError(f"{path}: the first curve is {las.curves[0].mnemonic!r}, "
                                 "expected the TIME index of a downhole LAS file")
    t = np.asarray(las.curves[0].data, float)
    channels, units = {}, {}
    for c in las.curves[1:]:
        name = c.descr.split(":", 1)[0] if ":" in c.descr else c.mnemonic.lower()
        channels[name] = np.asarray(c.data, float)
        units[name] = c.unit
    attrs = {"source": str(path)}
    for attr, (mnemonic, _) in _PARAM_ATTRS.items():  # the run's metadata written by write_las
        if mnemonic in las.params:
            value = las.params[mnemonic].value
            attrs[attr] = value.strip() if isinstance(value, str) else value
    radius = attrs.get("bit_radius")
    if not isinstance(radius, (int, float)):
        attrs.pop("bit_radius", None)
    return Result(t, channels, units=units, attrs=attrs)
