"""LAS 2.0 files of simulation results (time-indexed logs), via lasio: the reader, and the writer
re-exported from :mod:`downhole.sim.las` (where it lives beside the Result it writes, so that
:meth:`Result.to_las <downhole.sim.result.Result.to_las>` needs no import of this package).
"""

from __future__ import annotations

import os

import numpy as np

from downhole.errors import DownholeInputError
from downhole.sim.las import _PARAM_ATTRS, NULL, write_las

__all__ = ["NULL", "read_las", "write_las"]


def read_las(path: str | os.PathLike):
    """Read a time-indexed LAS file written by :func:`write_las` back into a Result.

    Curves of declared signals written in other units (e.g. oilfield) are converted back to SI;
    the run's metadata (e.g. ``bit_radius``, back in m) is restored as attributes.

    Parameters
    ----------
    path : str or os.PathLike
        LAS file.

    Returns
    -------
    Result
        Channels in SI, with attribute ``source`` = ``path``.

    Raises
    ------
    DownholeInputError
        If the first curve is not the TIME index, or a curve's unit does not convert to its
        signal's SI unit.
    """
    import lasio

    from downhole.sim.result import Result

    las = lasio.read(str(path))
    if las.curves[0].mnemonic.upper() != "TIME":
        raise DownholeInputError(f"{path}: the first curve is {las.curves[0].mnemonic!r}, "
                                 "expected the TIME index of a downhole LAS file")
    t = np.asarray(las.curves[0].data, float)
    channels, units = {}, {}
    from downhole.signals import SIGNALS
    from downhole.units import convert

    for c in las.curves[1:]:
        name = c.descr.split(":", 1)[0] if ":" in c.descr else c.mnemonic.lower()
        data = np.asarray(c.data, float)
        sig = SIGNALS.get(name)
        if sig is not None and c.unit and c.unit.replace(" ", "") != sig.unit.replace(" ", ""):
            # written in display units (e.g. --units oilfield): back to SI
            try:
                data = convert(data, c.unit, sig.unit)
            except Exception as exc:
                raise DownholeInputError(
                    f"{path}: curve {c.mnemonic} has unit {c.unit!r}, which does not convert "
                    f"to {sig.unit or 'a plain number'} ({exc})") from None
        channels[name] = data
        units[name] = sig.unit if sig is not None else c.unit
    attrs = {"source": str(path)}
    for attr, (mnemonic, _) in _PARAM_ATTRS.items():  # the run's metadata written by write_las
        if mnemonic in las.params:
            value = las.params[mnemonic].value
            attrs[attr] = value.strip() if isinstance(value, str) else value
    radius = attrs.get("bit_radius")
    if not isinstance(radius, (int, float)):
        attrs.pop("bit_radius", None)
    else:  # written in the display unit of a diameter (in, mm, m): back to metres
        unit = (las.params["BITRAD"].unit or "m").strip() or "m"
        try:
            attrs["bit_radius"] = float(convert(float(radius), unit, "m"))
        except Exception:
            attrs.pop("bit_radius", None)
    return Result(t, channels, units=units, attrs=attrs)
