"""Result export: LAS 2.0 read back by lasio (curves, units, index, parameters) and CSV."""

from __future__ import annotations

import numpy as np
import pytest

lasio = pytest.importorskip("lasio")

from downhole.cli import main
from downhole.io import read_las, write_las
from downhole.sim import Result, SurfaceInputs, simulate
from downhole.sim.lumped_model import lumped_model


@pytest.fixture(scope="module")
def result():
    return simulate(lumped_model("table_2_1", order=4), SurfaceInputs.velocity(0.01, 10.0),
                    duration=3.0, dt=1e-3, integrator="newmark", record_dt=0.01)


def test_las_round_trip_with_lasio(result, tmp_path):
    path = result.to_las(tmp_path / "run.las", well="test well")
    las = lasio.read(str(path))
    assert las.version["VERS"].value == 2.0
    assert str(las.version["WRAP"].value).upper() == "NO"
    assert las.well["WELL"].value == "test well"
    mnems = [c.mnemonic for c in las.curves]
    assert mnems[0] == "TIME" and las.curves["TIME"].unit == "s"
    units = {c.mnemonic: c.unit for c in las.curves}
    assert units["WOB"] == "N" and units["TOB"] == "N*m"
    assert units["BIT_ANGULAR_VELOCITY"] == "rad/s" and units["BIT_AXIAL_VELOCITY"] == "m/s"
    t = result.time
    np.testing.assert_allclose(las["TIME"], t, rtol=1e-9, atol=1e-12)
    assert las.well["STRT"].value == pytest.approx(0.0)
    assert las.well["STOP"].value == pytest.approx(t[-1])
    assert las.well["STEP"].value == pytest.approx(0.01)
    for ch in ("wob", "tob", "bit_angular_velocity", "bit_axial_velocity", "depth_of_cut"):
        np.testing.assert_allclose(las[ch.upper()], result[ch], rtol=1e-9,
                                   atol=1e-9 * np.abs(result[ch]).max())
    assert las.params["DT"].value == pytest.approx(1e-3) and las.params["DT"].unit == "s"
    assert las.params["INTEG"].value == "newmark"
    # the summary metrics travel as parameters; compare with Result.summary()
    assert las.params["MEAN_ROP"].value == pytest.approx(result.summary()["mean_rop"], rel=1e-7)
    # every 1-D channel is there
    assert len(las.curves) == 1 + sum(result.dataset[c].ndim == 1 for c in result.channels)


def test_read_las_gives_back_a_result_and_nan_is_null(tmp_path):
    t = np.linspace(0, 1, 11)
    wob = np.linspace(0, 5e4, 11)
    wob[3] = np.nan
    res = Result(t, {"wob": wob, "custom_signal": t**2}, units={"custom_signal": "m**2"})
    write_las(res, tmp_path / "x.las", summary=False)
    text = (tmp_path / "x.las").read_text()
    assert "-999.25" in text and "CUSTOM_SIGNAL.m**2" in text.replace(" ", "")
    back = read_las(tmp_path / "x.las")
    assert np.isnan(back["wob"][3])
    np.testing.assert_allclose(np.delete(back["wob"], 3), np.delete(wob, 3), rtol=1e-9)
    np.testing.assert_allclose(back["custom_signal"], t**2, rtol=1e-9, atol=1e-15)
    assert back.units("custom_signal") == "m**2"


def test_write_las_rejects_unknown_channels(result, tmp_path):
    from downhole.errors import DownholeInputError

    with pytest.raises(DownholeInputError, match=r"channels \['nope'\] are not in the result"):
        write_las(result, tmp_path / "x.las", channels=["wob", "nope"])


def test_cli_export_csv_and_las(result, tmp_path, capsys):
    import pandas as pd

    nc = result.save(tmp_path / "result.nc")
    rc = main(["export", str(nc), "--csv", str(tmp_path / "r.csv"), "--las",
               str(tmp_path / "r.las"), "--channel", "wob", "--channel", "tob"])
    assert rc == 0
    df = pd.read_csv(tmp_path / "r.csv")
    # the CLI names each column's unit (SI by default, see docs/units.md)
    np.testing.assert_allclose(df["time [s]"], result.time)
    np.testing.assert_allclose(df["wob [N]"], result["wob"], rtol=1e-12)
    las = lasio.read(str(tmp_path / "r.las"))
    assert [c.mnemonic for c in las.curves] == ["TIME", "WOB", "TOB"]
    assert main(["export", str(nc)]) == 2
    assert "give --csv FILE and/or --las FILE" in capsys.readouterr().err
    assert main(["export", str(tmp_path / "missing.nc"), "--csv", "x.csv"]) == 2
    assert "missing.nc: file not found" in capsys.readouterr().err
