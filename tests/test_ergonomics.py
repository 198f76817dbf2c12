"""Python ergonomics: Result.to_pandas and Result.plot, the named state-space model of
``linear_model``, and the MSE present in every kind of Result (DHP closed loop, SIL)."""

import math

import numpy as np
import pytest

from downhole.params import get_preset
from downhole.sim.result import Result, load_result


def _teale_mse(res, window, radius):
    """Teale's MSE by hand, in its textbook form with N in rev/s: WOB/A + 2 pi N TOB/(A ROP),
    means over the window (N TOB averaged as a product: the power at the bit)."""
    t = res.time
    sel = (t >= window[0]) & (t <= window[1])
    area = math.pi * radius ** 2
    n_rev = res["bit_angular_velocity"][sel] / (2 * math.pi)         # rev/s
    rop = res["bit_axial_velocity"][sel].mean()
    return (res["wob"][sel].mean() / area
            + 2 * math.pi * (n_rev * res["tob"][sel]).mean() / (area * rop))


# ---------------------------------------------------------------------------------- Result
def _small_result():
    t = np.linspace(0.0, 1.0, 11)
    return Result(t, {"bit_angular_velocity": 2.0 + np.sin(t), "wob": 1e4 * t,
                      "node_angular_velocity": np.column_stack([t, 2 * t])},
                  units={"node_angular_velocity": "rad/s"}, attrs={"model": "test"})


def test_to_pandas_is_indexed_by_time_with_one_column_per_signal():
    import pandas as pd

    r = _small_result()
    df = r.to_pandas()
    assert isinstance(df, pd.DataFrame)
    assert df.index.name == "time" and np.array_equal(df.index.values, r.time)
    assert list(df.columns) == ["bit_angular_velocity", "wob", "node_angular_velocity[0]",
                                "node_angular_velocity[1]"]
    assert np.array_equal(df["wob"].values, r["wob"])
    assert np.array_equal(df["node_angular_velocity[1]"].values, 2 * r.time)
    assert df.attrs["units"]["wob"] == "N"  # from downhole.signals
    assert df.attrs["units"]["node_angular_velocity[0]"] == "rad/s"
    assert df.attrs["result"]["model"] == "test"
    # selecting by time works as for any time-indexed frame
    assert df.loc[0.5, "wob"] == pytest.approx(5e3)


def test_to_pandas_after_a_netcdf_round_trip(tmp_path):
    r = _small_result()
    r.save(tmp_path / "r.nc")
    df = load_result(tmp_path / "r.nc").to_pandas()
    assert np.allclose(df["bit_angular_velocity"].values, 2.0 + np.sin(r.time))


def test_plot_returns_the_figure_and_saves_when_given_a_path(tmp_path):
    import matplotlib.pyplot as plt
    from matplotlib.figure import Figure

    from downhole.sim import SurfaceInputs, simulate
    from downhole.sim.lumped_model import lumped_model

    res = simulate(lumped_model("table_2_1", order=4), SurfaceInputs.velocity(0.01, 2.0),
                   duration=1.0, dt=5e-4)
    fig = res.plot()
    assert isinstance(fig, Figure) and len(fig.axes) >= 3
    plt.close(fig)
    before = len(plt.get_fignums())
    fig = res.plot(tmp_path / "o.png", title="t")
    assert isinstance(fig, Figure)
    assert (tmp_path / "o.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert len(plt.get_fignums()) == before  # saved figures are not left open in pyplot
    fig.savefig(tmp_path / "again.png")      # ... but stay usable
    assert (tmp_path / "again.png").stat().st_size > 0


# ---------------------------------------------------------------------------------- linear_model
@pytest.fixture(scope="module")
def fem6():
    from downhole.string.fem import fem_model

    return fem_model(n_elements=6)


def test_linear_model_is_a_named_state_space_that_unpacks_like_the_old_pair(fem6):
    from downhole.string.zoh import StateSpace, zoh

    ss = fem6.linear_model(1e-3)
    assert isinstance(ss, StateSpace)
    A, B, names, _ = fem6.continuous_linear_model()
    Ad, Bd = zoh(A, B, 1e-3)
    A_d, B_d = ss                                  # the old tuple interface
    assert np.array_equal(A_d, Ad) and np.array_equal(B_d, Bd)
    assert ss[0] is ss.A and ss[1] is ss.B and len(ss) == 2
    n = fem6.n_nodes
    assert ss.dt == 1e-3 and ss.A.shape == (4 * n, 4 * n) and ss.B.shape == (4 * n, 2)
    assert ss.state_names == tuple(names) and ss.state_names[:2] == ("x_1", "alpha_1")
    assert ss.input_names == ("slack_off_force", "surface_torque")
    assert np.array_equal(ss.C, np.eye(4 * n)) and not ss.D.any()
    assert ss.output_names == ss.state_names
    with pytest.raises(Exception):
        ss.dt = 2.0  # frozen


def test_state_space_refuses_inconsistent_shapes():
    from downhole.errors import DownholeInputError
    from downhole.string.zoh import StateSpace

    with pytest.raises(DownholeInputError, match="inconsistent shapes"):
        StateSpace(np.eye(2), np.ones((3, 1)), np.eye(2), np.zeros((2, 1)), 0.1)
    with pytest.raises(DownholeInputError, match="input_names has 2 names, expected 1"):
        StateSpace.full_state(np.eye(2), np.ones((2, 1)), 0.1, ("a", "b"), ("u", "v"))


def test_to_control_matches_python_controls_own_zoh(fem6):
    control = pytest.importorskip("control")
    ss = fem6.linear_model(1e-3)
    sys = ss.to_control()
    assert sys.dt == 1e-3
    assert sys.state_labels == list(ss.state_names)
    assert sys.input_labels == ["slack_off_force", "surface_torque"]
    # an independent discretization of the continuous model: python-control's c2d (zoh)
    A, B, _, _ = fem6.continuous_linear_model()
    ref = control.c2d(control.ss(A, B, np.eye(A.shape[0]), 0), 1e-3, method="zoh")
    assert np.allclose(sys.A, ref.A, rtol=1e-9, atol=1e-12)
    assert np.allclose(sys.B, ref.B, rtol=1e-9, atol=1e-15)


# ---------------------------------------------------------------------------------- MSE
def test_mse_is_finite_in_a_dhp_closed_loop_result():
    from downhole.control.dhp import (
        BitReference,
        PenaltyWeights,
        design_dhp,
        lumped_affine_model,
        lumped_true_plant,
        run_on_plant,
    )

    model = lumped_affine_model("table_2_1", dt=1e-3)
    w = PenaltyWeights(bit_velocity=(1000.0, 1000.0), bit_position=(1.0, 1.0), r=(1.0, 0.1))
    ctrl = design_dhp(model, BitReference.step(0.01, 20.0), horizon=3.0, weights=w)
    plant, adapter = lumped_true_plant("table_2_1", dt=1e-3, depth_of_cut="approximate")
    res = run_on_plant(ctrl, plant, 3.0, adapter=adapter, record_every=5)
    radius = get_preset("table_2_1").bit.radius
    assert res.attrs["bit_radius"] == radius
    s = res.summary((1.5, 3.0))
    assert math.isfinite(s["mse"]) and s["mse"] > 0
    assert s["mse"] == pytest.approx(_teale_mse(res, (1.5, 3.0), radius), rel=1e-12)


def test_mse_is_finite_in_an_in_process_sil_result():
    from downhole.sil import RealTimeRunner, build_plant, pi_controller_for

    plant = build_plant("lumped")
    rt = RealTimeRunner(plant, pi_controller_for(plant), paced=False, record_every=1)
    res = rt.run(4.0)
    radius = get_preset("table_2_1").bit.radius
    assert res.attrs["bit_radius"] == radius
    s = res.summary()
    assert math.isfinite(s["mse"]) and s["mse"] > 0
    w = (res.time[0] + 0.5 * (res.time[-1] - res.time[0]), res.time[-1])
    assert s["mse"] == pytest.approx(_teale_mse(res, w, radius), rel=1e-12)


def test_plant_bit_radius_finds_the_bit_through_wrappers():
    from downhole.sim.plant import plant_bit_radius

    class Bit:
        radius = 0.1

    class Model:
        bit = Bit()

    class Inner:
        model = Model()

    class Outer:
        plant = Inner()

    assert plant_bit_radius(Outer()) == 0.1
    assert plant_bit_radius(object()) is None

    class Loop:
        pass

    a = Loop()
    a.plant = a  # a cycle ends the search
    assert plant_bit_radius(a) is None


def test_a_las_round_trip_keeps_the_bit_radius_and_the_mse(tmp_path):
    from downhole.io import read_las
    from downhole.sim import SurfaceInputs, simulate
    from downhole.sim.lumped_model import lumped_model

    res = simulate(lumped_model("table_2_1", order=4), SurfaceInputs.velocity(0.01, 10.0),
                   duration=4.0, dt=5e-4)
    res.to_las(tmp_path / "r.las")
    back = read_las(tmp_path / "r.las")
    assert back.attrs["bit_radius"] == 0.15 and back.attrs["model"] == res.attrs["model"]
    # the LAS file keeps 10 significant digits
    assert back.summary()["mse"] == pytest.approx(res.summary()["mse"], rel=1e-8)
    # written in oilfield units (the radius in inches, 5.905511811 in): read back in SI
    res.to_las(tmp_path / "ft.las", units="oilfield")
    back = read_las(tmp_path / "ft.las")
    assert back.attrs["bit_radius"] == pytest.approx(0.15, rel=1e-9)
    assert back.summary()["mse"] == pytest.approx(res.summary()["mse"], rel=1e-8)
