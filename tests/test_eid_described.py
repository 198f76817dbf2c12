"""The EID's design model derived from a described system (issue 23, item 3): `downhole design
eid` on a file with [well] and [string] designs on that string's neutral-type model, checked
against hand values of the string."""

import math
from pathlib import Path

import pytest

from downhole.errors import ScenarioError
from downhole.scenario.schema import read_scenario
from downhole.scenario.system import neutral_design_model

FIRST_RUN = Path(__file__).resolve().parents[1] / "examples" / "first_run.toml"
EID = """
[controller]
type = "eid"
internal_model_gain = [10.0, 1.0]
filter_bandwidth = [20.0, 2.0]

[reference]
type = "constant"
axial_velocity = "10 mm/s"
angular_velocity = "12 rad/s"
"""


def _file(tmp_path, extra=EID):
    p = tmp_path / "eid.toml"
    p.write_text(FIRST_RUN.read_text() + extra)
    return p


def test_the_design_model_is_the_strings_neutral_model(tmp_path):
    data, source, _ = read_scenario(_file(tmp_path))
    model, options, ref = neutral_design_model(data, source)
    inch = 0.0254
    # the line is the 2820 m of 5" pipe; the 180 m of 6 3/4" collars are the lumped bottom
    assert model.params.length == pytest.approx(2820.0, rel=1e-12)
    assert model.tau1 == pytest.approx(2820.0 / math.sqrt(2.1e11 / 7850.0), rel=1e-9)
    assert model.tau2 == pytest.approx(2820.0 / math.sqrt(8.08e10 / 7850.0), rel=1e-9)
    collar = math.pi / 4 * ((6.75 * inch) ** 2 - (2.8125 * inch) ** 2)
    assert model.params.bit_mass == pytest.approx(7850.0 * collar * 180.0, rel=1e-9)
    assert options == {"internal_model_gain": (10.0, 1.0), "filter_bandwidth": (20.0, 2.0)}
    assert ref.sample([0.0, 5.0]).ravel().tolist() == pytest.approx([0.01, 0.01, 12.0, 12.0])


def test_a_design_needs_the_eid_and_a_representable_string(tmp_path):
    data, source, _ = read_scenario(_file(tmp_path, EID.replace('"eid"', '"pi"')))
    with pytest.raises(ScenarioError, match="controller"):
        neutral_design_model(data, source)
    data, source, _ = read_scenario(_file(tmp_path, EID + "\n[optimize]\nhorizon = 20.0\n"))
    with pytest.raises(ScenarioError, match="optimize"):
        neutral_design_model(data, source)
