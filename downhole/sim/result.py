"""The Result of a simulation: labeled time series with units, metadata, summary metrics, plots.

A :class:`Result` wraps an :class:`xarray.Dataset` whose variables are named channels over the
``time`` coordinate. It saves to NetCDF (h5netcdf) with units and the scenario (TOML text) in
the attributes, loads back, summarizes itself with drilling metrics and plots itself.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import xarray as xr

from downhole._atomic import atomic_path, write_netcdf_atomic
from downhole.signals import SIGNALS, STANDARD_CHANNELS

__all__ = ["CHANNEL_UNITS", "Result", "load_result"]

#: Units and descriptions of the standard channels (a view of :data:`downhole.signals.SIGNALS`).
CHANNEL_UNITS: dict[str, tuple[str, str]] = {
    n: (SIGNALS[n].unit, SIGNALS[n].description)
    for n in STANDARD_CHANNELS + ("reference_axial_velocity", "reference_angular_velocity")
}

REQUIRED_CHANNELS = STANDARD_CHANNELS


class Result:
    """Labeled time series of one run.

    Parameters
    ----------
    time : array_like
        Sample times, s.
    channels : dict of str to array_like
        Named signals, each of the same length as ``time``.
    units : dict of str to str, optional
        Units of channels not declared in :mod:`downhole.signals` (declared ones take the
        registry's unit unless given here).
    attrs : dict, optional
        Metadata (``scenario`` TOML text, ``model``, ``dt``, ``downhole_version``, ...).

    Examples
    --------
    >>> import numpy as np
    >>> r = Result(np.arange(3.0), {"bit_angular_velocity": np.ones(3)})
    >>> float(r["bit_angular_velocity"][-1])
    1.0
    """

    def __init__(self, time, channels: dict, units: dict | None = None, attrs: dict | None = None):
        time = np.asarray(time, dtype=float)
        data_vars = {}
        units = dict(units or {})
        for name, values in channels.items():
            values = np.asarray(values, dtype=float)
            if values.shape[0] != time.shape[0]:
                raise ValueError(f"channel {name!r} has {values.shape[0]} samples, "
                                 f"time has {time.shape[0]}")
            sig = SIGNALS.get(name)
            unit, desc = (sig.unit, sig.description) if sig else (units.get(name, ""), "")
            dims = ("time",) if values.ndim == 1 else ("time",) + tuple(
                f"{name}_dim{i}" for i in range(1, values.ndim))
            data_vars[name] = xr.Variable(dims, values,
                                          attrs={"units": units.get(name, unit),
                                                 "description": desc})
        from downhole import __version__

        meta = {"downhole_version": __version__}
        meta.update({k: _attr(v) for k, v in (attrs or {}).items()})
        self.dataset = xr.Dataset(data_vars, coords={"time": ("time", time, {"units": "s"})},
                                  attrs=meta)

    # --- access -------------------------------------------------------------------------------
    @classmethod
    def from_dataset(cls, ds: xr.Dataset) -> Result:
        """Wrap an existing :class:`xarray.Dataset` (no copy, no checks).

        Parameters
        ----------
        ds : xarray.Dataset
            Channels over the ``time`` coordinate, with ``units`` attributes (as written by
            :meth:`save`).

        Returns
        -------
        Result
        """
        obj = cls.__new__(cls)
        obj.dataset = ds
        return obj

    @property
    def time(self) -> np.ndarray:
        return self.dataset["time"].values

    @property
    def channels(self) -> list[str]:
        return list(self.dataset.data_vars)

    @property
    def attrs(self) -> dict:
        return dict(self.dataset.attrs)

    def __getitem__(self, name: str) -> np.ndarray:
        if name == "time":
            return self.time
        if name not in self.dataset:
            raise KeyError(f"no channel {name!r}; channels: {', '.join(self.channels)}")
        return self.dataset[name].values

    def __contains__(self, name: str) -> bool:
        return name == "time" or name in self.dataset

    def units(self, name: str) -> str:
        """Unit string of channel ``name`` (``""`` if it has none).

        Parameters
        ----------
        name : str
            Channel name.

        Returns
        -------
        str
            The ``units`` attribute of the channel, e.g. ``"N"`` or ``"rad/s"``.

        Raises
        ------
        KeyError
            If there is no channel ``name``.
        """
        return self.dataset[name].attrs.get("units", "")

    def window(self, t_start: float | None = None, t_end: float | None = None) -> Result:
        """A Result restricted to ``t_start <= t <= t_end``.

        Parameters
        ----------
        t_start : float, optional
            Start time, s (default: the first sample).
        t_end : float, optional
            End time, s (default: the last sample).

        Returns
        -------
        Result
            A view of the samples in the window (bounds inclusive).
        """
        t = self.time
        lo = t[0] if t_start is None else t_start
        hi = t[-1] if t_end is None else t_end
        return Result.from_dataset(self.dataset.sel(time=slice(lo, hi)))

    # --- io -----------------------------------------------------------------------------------
    def save(self, path: str | os.PathLike) -> Path:
        """Write NetCDF (h5netcdf engine), atomically.

        Serialized in memory, written to a temporary file in the same folder, fsynced and
        renamed (:func:`downhole._atomic.write_netcdf_atomic`), so a failed or killed write never
        leaves a half-written file under ``path``; a full disk raises one clean
        :class:`OSError`.

        Parameters
        ----------
        path : str or os.PathLike
            Destination file; its folder must exist.

        Returns
        -------
        pathlib.Path
            ``path``.
        """
        return write_netcdf_atomic(path, self.dataset)

    def summary(self, window: tuple[float, float] | None = None) -> dict:
        """Drilling metrics over ``window`` (default: second half of the run).

        See :func:`downhole.analysis.metrics.summarize` for the definitions.

        Parameters
        ----------
        window : (float, float), optional
            ``(t_start, t_end)``, s.

        Returns
        -------
        dict
            Metric name -> value in SI (None where undefined).
        """
        from downhole.analysis.metrics import summarize

        return summarize(self, window)

    def plot(self, path: str | os.PathLike | None = None, title: str | None = None,
             units=None):
        """Overview figure of the run.

        Velocities, rotary speeds and stick-slip, WOB/TOB, hook load and surface torque, depth, in
        the display ``units``. With ``path`` the figure is also saved (atomically, PNG at 120 dpi)
        and released from pyplot's figure manager, so that a loop that saves many plots keeps no
        figures open; the returned figure stays usable (``fig.savefig``, ``fig.axes``).

        Parameters
        ----------
        path : str or os.PathLike, optional
            PNG file to write.
        title : str, optional
            Figure title.
        units : str or UnitSystem, optional
            ``"si"``, ``"oilfield"``, ``"metric"`` or a :class:`~downhole.units.UnitSystem`
            (default SI with kN, kN m and rpm).

        Returns
        -------
        matplotlib.figure.Figure
        """
        from downhole.analysis.plots import plot_overview

        fig = plot_overview(self, None, title, **({} if units is None else {"units": units}))
        if path is not None:
            import matplotlib.pyplot as plt

            with atomic_path(path) as tmp:
                fig.savefig(tmp, dpi=120, bbox_inches="tight")
            plt.close(fig)
        return fig

    def to_pandas(self):
        """The channels as a :class:`pandas.DataFrame` indexed by ``time`` (s), one column per
        signal; a 2-D channel (per node, ...) gives one column per component, named
        ``NAME[i]``. Column units are in ``df.attrs["units"]`` and the Result's metadata in
        ``df.attrs["result"]``."""
        import pandas as pd

        cols: dict[str, np.ndarray] = {}
        units: dict[str, str] = {}
        for name in self.channels:
            values = self.dataset[name].values
            if values.ndim == 1:
                cols[name] = values
                units[name] = self.units(name)
            else:
                flat = values.reshape(values.shape[0], -1)
                for i in range(flat.shape[1]):
                    cols[f"{name}[{i}]"] = flat[:, i]
                    units[f"{name}[{i}]"] = self.units(name)
        df = pd.DataFrame(cols, index=pd.Index(self.time, name="time"))
        df.attrs["units"] = units
        df.attrs["result"] = self.attrs
        return df

    def to_csv(self, path: str | os.PathLike, units=None) -> Path:
        """Write the 1-D channels as CSV with a ``time`` column (atomically).

        Parameters
        ----------
        path : str or os.PathLike
            Destination file; its folder must exist.
        units : str or UnitSystem, optional
            A system name such as ``"oilfield"`` or a :class:`~downhole.units.UnitSystem`: the
            values are in those display units and every header names its unit, ``wob [klbf]``.
            Without, the columns are the channel names and the values SI.

        Returns
        -------
        pathlib.Path
            ``path``.
        """
        one_d = [n for n in self.channels if self.dataset[n].ndim == 1]
        if units is None:
            with atomic_path(path) as tmp:
                self.dataset[one_d].to_dataframe().to_csv(tmp)
            return Path(path)
        import pandas as pd

        from downhole.units import display_units

        disp = display_units(units)
        cols = {}
        for n in one_d:
            values, unit = disp.convert(n, self.dataset[n].values, self.units(n))
            cols[f"{n} [{unit or '-'}]"] = values
        frame = pd.DataFrame(cols, index=pd.Index(self.time, name="time [s]"))
        with atomic_path(path) as tmp:
            frame.to_csv(tmp)
        return Path(path)

    def to_las(self, path: str | os.PathLike, **kwargs) -> Path:
        """Write the 1-D channels as a time-indexed LAS 2.0 file, atomically.

        Parameters
        ----------
        path : str or os.PathLike
            Destination file; its folder must exist.
        **kwargs
            ``well``, ``channels``, ``company``, ``field``, ``summary``, ``units``; see
            :func:`downhole.sim.las.write_las` (also :func:`downhole.io.write_las`).

        Returns
        -------
        pathlib.Path
            ``path``.
        """
        from downhole.sim.las import write_las

        return write_las(self, path, **kwargs)  # atomic (temporary file, fsync, rename)

    def __repr__(self) -> str:
        t = self.time
        span = f"{t[0]:.3g}..{t[-1]:.3g} s" if t.size else "empty"
        return f"Result({len(t)} samples, {span}, channels={self.channels})"


def _attr(v):
    if isinstance(v, bool):
        return int(v)
    if isinstance(v, (dict, list, tuple)):
        import json

        return json.dumps(v)
    return v


def load_result(path: str | os.PathLike) -> Result:
    """Load a Result saved by :meth:`Result.save`.

    Parameters
    ----------
    path : str or os.PathLike
        NetCDF file.

    Returns
    -------
    Result
        The run, fully loaded in memory (the file is closed).
    """
    with xr.open_dataset(path, engine="h5netcdf") as ds:
        return Result.from_dataset(ds.load())
