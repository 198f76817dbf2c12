"""Neutral-model scenarios through ``downhole simulate`` (open loop and EID) and ``downhole design
eid`` on the same files; bad fields give exit 2 naming the file and the dotted field."""

import json
import warnings
from pathlib import Path

import numpy as np
import pytest

from downhole.cli import main
from downhole.sim.result import load_result

warnings.filterwarnings("ignore", category=UserWarning)
EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


@pytest.mark.parametrize("name", ["neutral_open_loop", "eid_nominal", "eid_tracking"])
def test_examples_run_through_simulate(name, tmp_path):
    out = tmp_path / name
    assert main(["simulate", str(EXAMPLES / f"{name}.toml"), "--out", str(out)]) == 0
    for f in ("result.nc", "summary.json", "overview.png"):
        assert (out / f).exists(), f
    res = load_result(out / "result.nc")
    assert res.attrs["scenario"] == (EXAMPLES / f"{name}.toml").read_text()
    t, v, w = res.time, res["bit_axial_velocity"], res["bit_angular_velocity"]
    if name == "eid_tracking":
        # Eqs. 3.34/3.35 tracked once the start-up transient is over (epsilon 67.5 MPa, noise).
        # The start-up ramp passes the regenerative region of the delayed depth of cut: the bit
        # bounces (+/-1 m/s) for 30-80 s, a chaotic transient whose length moves with round-off
        # (docs/reproduce.md); the tracking after it is the claim checked here.
        late = t > 100
        assert np.sqrt(np.mean((v[late] - res["reference_axial_velocity"][late]) ** 2)) < 1e-3
        assert np.sqrt(np.mean((w[late] - res["reference_angular_velocity"][late]) ** 2)) < 1.0
        assert res.attrs["controller"] == "eid"
    else:
        # docs/seed-errata.md: the open-loop commands give 10 mm/s, 20 rad/s; the EID regulates to
        # the same
        assert abs(v[t > 15].mean() - 0.01) < 2e-5 and abs(w[t > 15][-1] - 20.0) < 0.05
    s = json.loads((out / "summary.json").read_text())
    assert s["mean_rop"] > 0


def test_design_then_simulate_a_saved_design(tmp_path):
    assert main(["design", "eid", str(EXAMPLES / "eid_nominal.toml"), "--out",
                 str(tmp_path / "eid")]) == 0
    gains = np.load(tmp_path / "eid" / "eid_gains.npz")
    assert np.allclose(gains["A_F"], -gains["B_F"])  # F(s) = bf/(s + bf): unit DC gain
    assert (tmp_path / "eid" / "roots.png").exists()
    assert '"stable": true' in (tmp_path / "eid" / "report.md").read_text()
    sc = tmp_path / "saved.toml"
    sc.write_text('[model]\nfidelity = "neutral"\n[controller]\ntype = "eid"\nfile = "eid"\n'
                  '[reference]\naxial_velocity = "8 mm/s"\nangular_velocity = 25.0\n'
                  '[simulation]\nduration = "20 s"\ndt = "0.5 ms"\n')
    assert main(["simulate", str(sc), "--out", str(tmp_path / "run")]) == 0
    res = load_result(tmp_path / "run" / "result.nc")
    t = res.time
    assert abs(res["bit_axial_velocity"][t > 15].mean() - 0.008) < 1e-4
    assert gains["Kp"][0, 0] < 0  # the saved gains were used (not re-designed on the fly)


BAD = [
    ('[model]\nfidelity = "neutral"\n[bit]\nepsilon = "-5 MPa"\n[simulation]\nduration = 1.0\n',
     "bit.epsilon"),
    ('[model]\nfidelity = "neutral"\n[model.string]\nlength = 0\n[simulation]\nduration = 1.0\n',
     "model.string.length"),
    ('[model]\nfidelity = "neutral"\n[controller]\ntype = "eid"\nobserver_gain = [1.0]\n'
     '[simulation]\nduration = 1.0\n', "controller.observer_gain"),
    ('[model]\nfidelity = "neutral"\n[controller]\ntype = "eid"\n[reference]\ntype = "sine"\n'
     '[simulation]\nduration = 1.0\n', "reference.type"),
    ('[model]\nfidelity = "neutral"\n[simulation]\nduration = 1.0\n[simulation.noise]\n'
     'axial_velocity = "1 rad/s"\n', "simulation.noise.axial_velocity"),
    ('[model]\nfidelity = "neutral"\n[simulation]\nduration = 1.0\ndt = 0.5\n', "simulation.dt"),
    ('[model]\nfidelity = "neutral"\n[operation]\nrpm = 3\n[simulation]\nduration = 1.0\n',
     "operation.rpm"),
    ('[model]\nfidelity = "neutral"\n[controller]\ntype = "eid"\nfile = "nowhere"\n'
     '[simulation]\nduration = 1.0\n', "controller.file"),
    ('[model]\nfidelity = "neutral"\n[operation]\naxial_command = 1.1\n', "simulation"),
    ('[model]\nfidelity = "neutral"\n[controller]\ntype = "eid"\n[operation]\n'
     'axial_command = 1.1\n[simulation]\nduration = 1.0\n', "operation"),
    ('[model]\nfidelity = "neutral"\npreset = "table_2_1"\n[simulation]\nduration = 1.0\n',
     "model.preset"),
]


@pytest.mark.parametrize("text,field", BAD)
def test_bad_fields_exit_2_naming_file_and_field(text, field, tmp_path, capsys):
    sc = tmp_path / "bad.toml"
    sc.write_text(text)
    out = tmp_path / "out"
    assert main(["simulate", str(sc), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert str(sc) in err and f"{field}:" in err, err
    assert not out.exists()


def test_design_eid_rejects_a_saved_design_reference(tmp_path, capsys):
    sc = tmp_path / "d.toml"
    sc.write_text('[model]\nfidelity = "neutral"\n[controller]\ntype = "eid"\nfile = "x"\n')
    assert main(["design", "eid", str(sc), "--out", str(tmp_path / "o")]) == 2
    assert "controller.file" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()
    sc.write_text('[model]\nfidelity = "neutral"\n[controller]\ntype = "eid"\n'
                  'filter_bandwidth = [1, -2]\n')
    assert main(["design", "eid", str(sc), "--out", str(tmp_path / "o")]) == 2
    assert "controller.filter_bandwidth" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()
