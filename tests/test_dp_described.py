"""The DP's 4th-order model derived from a described system (issue 23, item 3: design models
come from the description): `downhole optimize dp` on a file with [well] and [string] optimizes
the lumped4 chain of that string, checked against hand values of the string."""

import math
from pathlib import Path

import pytest

from downhole.control.dp.problem import dp_problem_of, load_dp_scenario
from downhole.errors import ScenarioError
from downhole.scenario.schema import read_scenario
from downhole.scenario.system import lumped_design_model

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "dp_described.toml"


def _pipe(od, id_):
    return math.pi / 4 * (od ** 2 - id_ ** 2)


def test_the_dp_model_is_the_strings():
    data, source, _ = read_scenario(EXAMPLE)
    lumped, bit = lumped_design_model(data, source)
    problem, method = dp_problem_of(data, source, (lumped, bit))
    string, bitp = problem.params()
    assert method == "customized"
    # static axial stiffness of 2820 m of 5" pipe over 180 m of 6 3/4" collars: 1 / sum L/(EA)
    inch = 0.0254
    a_pipe, a_collar = _pipe(0.127, 0.1086), _pipe(6.75 * inch, 2.8125 * inch)
    k_a = 1.0 / (2820.0 / (2.1e11 * a_pipe) + 180.0 / (2.1e11 * a_collar))
    assert string.axial_stiffness == pytest.approx(k_a, rel=1e-9)
    # ground damping: Rayleigh alpha0 times the string's mass
    mass = 7850.0 * (2820.0 * a_pipe + 180.0 * a_collar)
    assert string.axial_damping == pytest.approx(0.05 * mass, rel=1e-9)
    # the chain's mass is below the string's (the first mode, top clamped, moves part of it)
    assert 0.3 * mass < string.mass < mass
    # the bit is the described one: Table 2.1's cutter constants, an 8 1/2" bit
    assert bitp.radius == pytest.approx(4.25 * inch, rel=1e-12)


def test_a_described_file_needs_the_derivation_and_refuses_foreign_keys(tmp_path):
    with pytest.raises(ScenarioError, match="derives the 4th-order model"):
        load_dp_scenario(EXAMPLE)
    p = tmp_path / "x.toml"
    p.write_text(EXAMPLE.read_text().replace("[optimize]\n", "[operation]\nwob = \"10 kN\"\n"
                                             "[optimize]\n"))
    data, source, _ = read_scenario(p)
    with pytest.raises(ScenarioError, match="operation"):
        dp_problem_of(data, source, lumped_design_model(data, source))


def test_cli_optimizes_the_described_string(tmp_path, capsys):
    import json

    from downhole.cli import main

    out = tmp_path / "dp"
    assert main(["optimize", "dp", str(EXAMPLE), "--out", str(out), "--no-progress"]) == 0
    sol = json.loads((out / "solution.json").read_text())
    text = json.dumps(sol)
    assert "lumped" in text  # the derived parameters are stored with the problem
    from downhole.control.dp import load_solution

    s = load_solution(out)
    assert s.x2[-1] == pytest.approx(0.01) and s.x4[-1] == pytest.approx(10.0)
