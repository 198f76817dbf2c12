"""``downhole export``: a Result (NetCDF) to CSV and/or LAS 2.0; a sweep dataset to CSV."""

from __future__ import annotations

from pathlib import Path

import typer
from rich.console import Console

from downhole._atomic import atomic_path, check_output_path
from downhole.cli import app, fail
from downhole.cli._units import UNIT_OPTION, UNITS_OPTION, resolve_units

console = Console()


@app.command()
def export(
    result: Path = typer.Argument(..., help="result.nc written by `downhole simulate` (or a "
                                            "sweep.nc for --csv)"),
    csv: Path | None = typer.Option(None, "--csv", help="write the channels as CSV"),
    las: Path | None = typer.Option(None, "--las", help="write a time-indexed LAS 2.0 file"),
    channel: list[str] | None = typer.Option(None, "--channel", help="only these channels "
                                                "(repeat; LAS only)"),
    well: str = typer.Option("downhole simulation", "--well", help="LAS ~Well WELL entry"),
    units: str = UNITS_OPTION,
    unit: list[str] | None = UNIT_OPTION,
):
    """Export a simulation result to CSV (time column + channels, each header with its unit)
    and/or LAS 2.0 with curve units, in the display units of --units/--unit."""
    import xarray as xr

    from downhole.errors import DownholeInputError

    if csv is None and las is None:
        fail("nothing to do: give --csv FILE and/or --las FILE")
    display = resolve_units(units, unit)
    for option, path in (("--csv", csv), ("--las", las)):
        if path is not None:
            check_output_path(path, option=option, kind="file")
    if not result.is_file():
        raise DownholeInputError(f"{result}: file not found")
    try:
        with xr.open_dataset(result, engine="h5netcdf") as ds:
            ds = ds.load()
    except (OSError, ValueError) as exc:
        raise DownholeInputError(f"{result}: not a NetCDF file written by downhole ({exc})"
                                 ) from None
    if "time" not in ds.dims:
        if "sweep_mode" not in ds.attrs:
            raise DownholeInputError(f"{result}: neither a simulation result (no time "
                                     "dimension) nor a sweep dataset")
        if las is not None:
            raise DownholeInputError("a sweep dataset has no time axis: export it with --csv")
        frame = _sweep_frame(ds, display)
        with atomic_path(csv) as tmp:
            frame.to_csv(tmp, index=False)
        console.print(f"written {csv} ({ds.attrs.get('n_cases', '?')} cases)")
        return
    from downhole.sim.result import Result

    res = Result.from_dataset(ds)
    if csv is not None:
        res.to_csv(csv, units=display)  # atomic (temporary file, fsync, rename)
        console.print(f"written {csv}")
    if las is not None:
        res.to_las(las, well=well, channels=channel or None, units=display)  # atomic
        console.print(f"written {las}")


def _sweep_frame(ds, display):
    """A sweep dataset as one row per case: parameters and metrics in the display units, each
    header with its unit (``mean_wob [klbf]``); text columns (``error``) as they are."""
    frame = ds.to_dataframe().reset_index()
    cols = {}
    for col in frame.columns:
        values = frame[col].to_numpy()
        if col in ds.variables and values.dtype.kind in "fiu":
            si = str(ds[col].attrs.get("units", ""))
            if col == "case" and not si:
                cols[col] = values
                continue
            values, unit = display.convert(col, values.astype(float), si)
            cols[f"{col} [{unit or '-'}]"] = values
        else:
            cols[col] = values
    import pandas as pd

    return pd.DataFrame(cols)
