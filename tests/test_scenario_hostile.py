"""Hostile scenario input (issue 15, item 2): every class gets the one-line error that
``docs/scenarios.md`` promises (file, dotted field, expectation), exit code 2 from the CLI, no
traceback, no hang and nothing written.

The seeded fuzz test over all examples is ``tests/test_scenario_fuzz.py``; this file pins each
class down with explicit cases, checks the quantity grammar and the ranges against independent
conversions, the explicit-Euler step bound against a direct simulation of the linear chain, and
runs a handful of real CLI subprocesses.
"""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from downhole.errors import DownholeInputError, ScenarioError
from downhole.scenario import load_scenario, run_scenario, validate_data
from downhole.units import RANGES, SI_UNITS, UnitError, to_si

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
LBF = 4.4482216152605  # N, exact by definition (0.45359237 kg x 9.80665 m/s^2)
FT = 0.3048            # m, exact

GOOD = textwrap.dedent("""\
    title = "hostile-input base"
    [model]
    fidelity = "lumped4"
    preset = "table_2_1"
    [operation]
    rop = "10 mm/s"
    surface_speed = "10 rad/s"
    [simulation]
    duration = "4 s"
    dt = "0.5 ms"
    record_dt = "10 ms"
    """)


def _alarm(seconds):
    def handler(signum, frame):
        raise TimeoutError(f"still running after {seconds} s")

    signal.signal(signal.SIGALRM, handler)
    signal.alarm(seconds)


@pytest.fixture()
def guard():
    """A watchdog: a hang fails the test instead of blocking the suite."""
    yield _alarm
    signal.alarm(0)


def write(tmp_path, text, name="s.toml"):
    p = tmp_path / name
    p.write_text(text)
    return p


def validate(path):
    data, source, _ = load_scenario(path)
    return validate_data(data, source)


def expect_error(path, field, *fragments):
    with pytest.raises(ScenarioError) as info:
        validate(path)
    msg = str(info.value)
    assert msg.startswith(f"{path}: "), msg
    assert "\n" not in msg
    assert info.value.field == field or info.value.field.startswith(field + "."), msg
    for f in fragments:
        assert f in msg, msg
    return msg


# ------------------------------------------------------------------ quantity grammar
@pytest.mark.parametrize("text, dim, si", [
    ("10 rad/s", "angular_velocity", 10.0),
    ("120 rpm", "angular_velocity", 120 * 2 * math.pi / 60),
    ("30 m/h", "velocity", 30 / 3600),
    ("10 mm/s", "velocity", 0.01),
    ("25 klbf", "force", 25e3 * LBF),
    ("5 kft_lbf", "torque", 5e3 * FT * LBF),
    ("2 N m", "torque", 2.0),
    ("77 MPa", "pressure", 77e6),
    ("0.5 ms", "time", 5e-4),
    ("1200 kg/m^3", "density", 1200.0),
    ("500 kg*m**2", "inertia", 500.0),
    ("1e7 N/m", "stiffness", 1e7),
    ("1e6 N*s/m", "damping", 1e6),
    ("-2.5e-1 m/s", "velocity", -0.25),
    ("5 in", "length", 5 * 0.0254),
    ("30 deg", "angle", math.pi / 6),
    ("9.81 m/s^2", "acceleration", 9.81),
    ("3 1/(m)", "dimensionless", None),    # 1/m is no plain number: a dimension error
    ("7", "dimensionless", 7.0),
    (".5", "dimensionless", 0.5),
])
def test_accepted_quantities_convert_exactly(text, dim, si):
    if si is None:
        with pytest.raises(UnitError, match="cannot be converted"):
            to_si(text, dim)
        return
    assert to_si(text, dim) == pytest.approx(si, rel=1e-12)


@pytest.mark.parametrize("text", [
    "1 s * 10**10**8", "2**1000 m", "10**10 m", "1 m**99", "1 m^5", "1 (m)*(m)", "1 m * 3",
    "nan", "NaN m", "inf s", "-inf N", "1e400 m", "1.2.3 m", "1e5e5", "m", "", "   ",
    "__import__('os').system('true')", "1 m; 2 m", "1 m + 2 m", "1 m,2", "1 ((((m))))",
    "1 m)", "1 (m", "1 m//s", "1 m**", "1 kg*", "x" * 65, "1 " + "m*" * 40 + "m",
])
def test_rejected_quantity_strings_fail_fast(text, guard):
    guard(5)  # '1 s * 10**10**8' burnt minutes of CPU in pint before the grammar check
    with pytest.raises(UnitError):
        to_si(text, "time" if "s" in text else "length")


def test_overlong_string_names_the_limit():
    with pytest.raises(UnitError, match="at most 64"):
        to_si("1" + "0" * 70 + " m", "length")


# ------------------------------------------------------------------ ranges
def test_ranges_cover_every_dimension_and_hold_engineering_values():
    assert set(RANGES) == set(SI_UNITS)
    for dim, (lo, hi) in RANGES.items():
        assert lo < hi and math.isfinite(lo) and math.isfinite(hi), dim
    # values real scenarios use sit well inside
    for text, dim in [("12 km", "length"), ("3 MN", "force"), ("60 kN*m", "torque"),
                      ("787 t", "mass"), ("210 GPa", "pressure"), ("2500 kg/m^3", "density"),
                      ("200 rpm", "angular_velocity"), ("24 h", "time")]:
        to_si(text, dim)


@pytest.mark.parametrize("value, dim, fragment", [
    ("1e12 m", "length", "0 to 100000 m"),
    ("1e300 N*m", "torque", "-1e+08 to 1e+08 N*m"),
    (1e300, "torque", "-1e+08 to 1e+08 N*m"),
    (-5.0, "mass", "0 to 1e+09 kg"),
    ("-1 kg/m^3", "density", "0 to 100000 kg/m**3"),
    (10**400, "force", "admissible range"),
    (float("nan"), "time", "finite"),
    (float("inf"), "velocity", "finite"),
])
def test_out_of_range_values_name_the_admissible_range(value, dim, fragment):
    with pytest.raises(UnitError) as info:
        to_si(value, dim)
    assert fragment in str(info.value)


def test_absurd_scenario_values_name_field_and_range(tmp_path):
    p = write(tmp_path, GOOD.replace('[operation]', '[bit]\nradius = "1e12 m"\n[operation]'))
    expect_error(p, "bit.radius", "admissible range of a length", "100000 m")
    p = write(tmp_path, GOOD.replace('surface_speed = "10 rad/s"',
                                     'surface_speed = "1e300 rad/s"'))
    expect_error(p, "operation.surface_speed", "admissible range")
    p = write(tmp_path, GOOD.replace('duration = "4 s"', 'duration = "1e9 s"'))
    expect_error(p, "simulation.duration", "0 to 1e+06 s")


def test_directional_survey_md_of_1e12_m(tmp_path):
    base = (EXAMPLES / "directional_fem_stickslip.toml").read_text()
    p = write(tmp_path, base + "\n[well]\nmd = [0, 500, 1e12]\ninclination = [0, 0, 10]\n"
                               "azimuth = [0, 0, 0]\n")
    expect_error(p, "well.md", "station 3", "0 to 100000 m")
    (tmp_path / "w.csv").write_text("md,inc,azi\n0,0,0\n500,0,0\n1e12,10,0\n")
    p = write(tmp_path, base + '\n[well]\nsurvey = "w.csv"\n')
    expect_error(p, "well.survey", "line 4, column 'md'", "1e+12 m, is beyond any well drilled")
    (tmp_path / "w.csv").write_text("md,inc,azi\n0,0,0\n500,nan,0\n1000,10,0\n")
    with pytest.raises(ScenarioError) as info:
        validate(p)
    assert info.value.field == "well.survey"


def test_survey_csv_that_is_a_fifo_is_refused_without_blocking(tmp_path, guard):
    base = (EXAMPLES / "directional_fem_stickslip.toml").read_text()
    os.mkfifo(tmp_path / "w.csv")
    p = write(tmp_path, base + '\n[well]\nsurvey = "w.csv"\n')
    guard(10)
    expect_error(p, "well.survey", "FIFO")


# ------------------------------------------------------------------ the file itself
def test_directory_fifo_and_devices_are_refused_before_opening(tmp_path, guard):
    guard(10)  # opening a FIFO for reading blocks until a writer comes: it must not be opened
    os.mkfifo(tmp_path / "pipe.toml")
    for path, what in [(tmp_path, "a directory"), (tmp_path / "pipe.toml", "a FIFO"),
                       (Path("/dev/zero"), "a device"), (tmp_path / "missing.toml", "not found")]:
        with pytest.raises(ScenarioError, match=what) as info:
            load_scenario(path)
        assert str(info.value).startswith(f"{path}: ")


def test_oversized_file_is_refused(tmp_path):
    p = tmp_path / "big.toml"
    p.write_text(GOOD + "# " + "x" * (1 << 20) + "\n")
    with pytest.raises(ScenarioError, match="bytes"):
        load_scenario(p)


@pytest.mark.parametrize("blob, fragment", [
    (GOOD.encode().replace(b"hostile", b"hos\xfftile"), "not UTF-8 text: byte 0xff"),
    (GOOD.encode().replace(b"hostile", b"hos\x00tile"), "NUL character at line 1"),
    (GOOD.encode() + b"seed = " + b"9" * 5000 + b"\n", "not valid TOML"),
    (GOOD.encode() + b"x = " + b"[" * 5000 + b"]" * 5000 + b"\n", "not valid TOML"),
])
def test_bytes_that_are_no_scenario(tmp_path, blob, fragment):
    p = tmp_path / "s.toml"
    p.write_bytes(blob)
    with pytest.raises(ScenarioError, match=fragment):
        load_scenario(p)


@pytest.mark.parametrize("line, field, fragment", [
    ('description = "a\\u0000b"', "description", "control character"),
    ("description = 1e308", "description", "out of range"),
    ("description = nan", "description", "finite"),
    ("description = [1.0, -inf]", "description.1", "finite"),
    ('description = "1e400"', "description", "finite"),
    ('description = "' + "x" * 5000 + '"', "description", "at most 4096"),
])
def test_values_no_field_accepts(tmp_path, line, field, fragment):
    p = write(tmp_path, line + "\n" + GOOD)
    with pytest.raises(ScenarioError) as info:
        load_scenario(p)
    assert info.value.field == field and fragment in str(info.value)


# ------------------------------------------------------------------ shapes and types
@pytest.mark.parametrize("old, new, field", [
    ('surface_speed = "10 rad/s"', "surface_speed = [[0]]", "operation.surface_speed"),
    ('surface_speed = "10 rad/s"', 'surface_speed = [[0, "1 rad/s", 2]]',
     "operation.surface_speed"),
    ('surface_speed = "10 rad/s"', 'surface_speed = [[0, ["1 rad/s"]]]',
     "operation.surface_speed"),
    ('surface_speed = "10 rad/s"', 'surface_speed = [[0, "nan"]]',
     "operation.surface_speed"),
    ('surface_speed = "10 rad/s"', "surface_speed = []", "operation.surface_speed"),
    ('surface_speed = "10 rad/s"', "surface_speed = true", "operation.surface_speed"),
    ('fidelity = "lumped4"', 'fidelity = ["lumped4"]', "model.fidelity"),
    ('duration = "4 s"', 'duration = "4 s * 10**10**8"', "simulation.duration"),
])
def test_wrong_shapes_and_types_name_the_field(tmp_path, old, new, field, guard):
    guard(10)
    p = write(tmp_path, GOOD.replace(old, new))
    expect_error(p, field)


def test_wrong_shapes_in_directional_tables(tmp_path):
    base = (EXAMPLES / "directional_fem_stickslip.toml").read_text()
    for extra, field in [("[well]\nsections = 5\n", "well.sections"),
                         ("[well]\nmd = [0, 500]\ninclination = [0]\nazimuth = [0, 0]\n",
                          "well.md"),
                         ("[[string.segments]]\nouter_diameter = [1, 2]\ninner_diameter = 0\n",
                          "string.segments[1].outer_diameter")]:
        p = write(tmp_path, base + "\n" + extra)
        with pytest.raises(ScenarioError) as info:
            validate(p)
        assert info.value.field.startswith(field), str(info.value)


def test_every_reader_refuses_hostile_files(tmp_path, guard):
    """SIL, DP, DHP design, EID design and sweep readers go through the same checks."""
    from downhole.cli.design_eid import load_eid_scenario
    from downhole.control.dp import load_problem
    from downhole.scenario.dhp import load_dhp_scenario
    from downhole.sil.scenario import load_sil_scenario
    from downhole.sweep import load_sweep_file

    guard(30)
    os.mkfifo(tmp_path / "pipe.toml")
    readers = [load_sil_scenario, load_problem, load_dhp_scenario, load_eid_scenario,
               load_sweep_file]
    (tmp_path / "bad.toml").write_bytes(b'name = "\xff"\n')
    for reader in readers:
        for path, fragment in [(tmp_path / "pipe.toml", "FIFO"), (tmp_path, "directory"),
                               (tmp_path / "bad.toml", "not UTF-8")]:
            with pytest.raises(DownholeInputError, match=fragment):
                reader(path)
    sil = (EXAMPLES / "sil_open_loop.toml").read_text().replace('dt = "1 ms"', 'dt = "nan"')
    assert '"nan"' in sil
    with pytest.raises(ScenarioError, match="simulation.dt"):
        load_sil_scenario(write(tmp_path, sil, "sil.toml"))
    dp = (EXAMPLES / "dp_customized.toml").read_text().replace("horizon = 20.0",
                                                               "horizon = inf")
    with pytest.raises(ScenarioError, match="horizon: expected a finite number"):
        load_problem(write(tmp_path, dp, "dp.toml"))


# ------------------------------------------------------------------ explicit Euler step bound
def _linear_euler_growth(field, dt, steps):
    """Forward Euler of one linear chain field (top spring to a fixed top drive, no bit), built
    from the update rule q += dt v, v += dt M^-1 (-K q - C v): the energy norm's growth from
    ``steps`` to ``2 steps`` steps, starting from an alternating displacement."""
    n = field.n
    k = field.stiffness_matrix()
    c = np.diag(np.asarray(field.c_abs, float))
    c[0, 0] += field.c_top
    for i, cl in enumerate(field.c_link):
        c[i, i] += cl
        c[i + 1, i + 1] += cl
        c[i, i + 1] -= cl
        c[i + 1, i] -= cl
    m = np.asarray(field.mass, float)
    step = np.block([[np.eye(n), dt * np.eye(n)],
                     [-dt * k / m[:, None], np.eye(n) - dt * c / m[:, None]]])
    x = np.concatenate([(-1.0) ** np.arange(n), np.zeros(n)])
    power = np.linalg.matrix_power(step, steps)

    def energy(x):
        q, v = x[:n], x[n:]
        return math.sqrt(float(q @ (k @ q) + v @ (m * v)))

    x1 = power @ x
    return energy(power @ x1) / energy(x1)


@pytest.mark.parametrize("order", [4, 12])
def test_euler_bound_is_where_the_linear_chain_turns_unstable(order):
    from downhole.scenario import euler_stable_dt
    from downhole.sim.lumped_model import lumped_model

    model = lumped_model("table_2_1", order=order)
    bound, mode = euler_stable_dt(model)
    assert mode["field"] in ("axial", "torsional") and 0 < mode["damping_ratio"] < 1
    # closed form of the limiting mode: dt = 2 zeta / omega
    assert bound == pytest.approx(2 * mode["damping_ratio"] / mode["frequency"], rel=1e-9)
    field = getattr(model, mode["field"])
    a = mode["damping_ratio"] * mode["frequency"]
    steps = int(8 * mode["frequency"] ** 2 / a ** 2)  # long enough for +-10 % to show
    assert _linear_euler_growth(field, 0.9 * bound, steps) < 1.0
    assert _linear_euler_growth(field, 1.1 * bound, steps) > 1.0


def _lumped12_scenario(dt, duration):
    return {"model": {"fidelity": "lumped12", "preset": "table_2_1"},
            "operation": {"rop": "10 mm/s", "surface_speed": "10 rad/s"},
            "simulation": {"duration": duration, "dt": dt, "integrator": "euler",
                           "record_dt": dt}}


def test_euler_dt_just_below_the_bound_runs_and_well_above_is_refused():
    from downhole.scenario import euler_stable_dt
    from downhole.sim.lumped_model import lumped_model

    bound, _ = euler_stable_dt(lumped_model("table_2_1", order=12))
    dt = float(f"{0.95 * bound:.3g}")
    res = run_scenario(_lumped12_scenario(dt, 2000 * dt))
    assert np.all(np.isfinite(res.dataset["bit_angular_velocity"].values))
    with pytest.raises(ScenarioError) as info:
        validate_data(_lumped12_scenario(0.05, 60.0), "<dict>")
    msg = str(info.value)
    assert info.value.field == "simulation.dt"
    assert f"stable only for dt < {bound:.4g} s" in msg and "newmark" in msg
    # the refused step really diverges (the Python API runs it unchecked)
    from downhole.errors import SimulationDiverged
    from downhole.sim import simulate

    with pytest.raises(SimulationDiverged):
        simulate(lumped_model("table_2_1", order=12), duration=60.0, dt=0.05, record_dt=0.05)
    # newmark takes that step
    data = _lumped12_scenario(0.05, 60.0)
    data["simulation"]["integrator"] = "newmark"
    validate_data(data, "<dict>")


def test_undamped_string_with_euler_is_refused(tmp_path):
    p = write(tmp_path, GOOD.replace('preset = "table_2_1"',
                                     'preset = "table_2_1"\nstring = { torsional_damping = 0 }')
              .replace("[simulation]", '[simulation]\nintegrator = "euler"'))
    expect_error(p, "simulation.dt", "undamped", "newmark")


def test_step_count_is_bounded(tmp_path):
    p = write(tmp_path, GOOD.replace('duration = "4 s"', 'duration = "9 days"')
              .replace('dt = "0.5 ms"', 'dt = "1 us"').replace('record_dt = "10 ms"',
                                                                 'record_dt = "1 s"'))
    expect_error(p, "simulation.dt", "steps; at most")


# ------------------------------------------------------------------ the real CLI
def _cli(args, cwd, timeout=120):
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[1]))
    code = "import sys; from downhole.cli import main; sys.exit(main(sys.argv[1:]))"
    return subprocess.run([sys.executable, "-c", code, *args], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=timeout)


def _cli_case(name, tmp_path):
    def ex(n):
        return (EXAMPLES / n).read_text()

    if name == "simulate-fifo":
        os.mkfifo(tmp_path / "s.toml")
        return ["simulate", "s.toml", "--out", "out"], "is a FIFO"
    if name == "simulate-utf8":
        (tmp_path / "s.toml").write_bytes(ex("fig2.3.toml").encode() + b"# \xc3\x28\n")
        return ["simulate", "s.toml", "--out", "out"], "not UTF-8"
    if name == "simulate-arithmetic":
        write(tmp_path, GOOD.replace('"4 s"', '"1 s * 10**10**8"'))
        return ["simulate", "s.toml", "--out", "out"], "simulation.duration"
    if name == "sil-nan":
        write(tmp_path, ex("sil_open_loop.toml").replace('dt = "1 ms"', 'dt = "nan"'))
        return ["sil", "s.toml", "--out", "out.nc", "--unpaced"], "simulation.dt"
    if name == "sil-controller-directory":
        (tmp_path / "d").mkdir()
        return ["sil-controller", "--port", "9", "--scenario", "d"], "is a directory"
    if name == "export-fmu-torque":
        write(tmp_path, ex("sil_open_loop.toml") + '\n[reference]\naxial_velocity = "1e300 m/s"\n')
        return ["export-fmu", "s.toml", "--out", "out.fmu"], "reference.axial_velocity"
    if name == "optimize-dp-inf":
        write(tmp_path, ex("dp_customized.toml").replace("step = 0.25", "step = inf"))
        return ["optimize", "dp", "s.toml", "--out", "out"], "step: expected a finite"
    if name == "design-dhp-nul":
        (tmp_path / "s.toml").write_bytes(ex("dhp_lumped.toml").encode() + b"\x00")
        return ["design", "dhp", "s.toml", "--out", "out"], "NUL character"
    if name == "design-eid-length":
        write(tmp_path, ex("eid_nominal.toml").replace(
            'preset = "table_3_1"', 'preset = "table_3_1"\nstring = { length = "1e12 m" }'))
        return ["design", "eid", "s.toml", "--out", "out"], "model.string.length"
    if name == "sweep-huge":
        write(tmp_path, ex("sweep_montecarlo.toml").replace('duration = "40 s"',
                                                            'duration = "9e9 s"'))
        return ["sweep", "s.toml", "--out", "out", "--processes", "1"], "simulation.duration"
    raise AssertionError(name)


CLI_CASES = ["simulate-fifo", "simulate-utf8", "simulate-arithmetic", "sil-nan",
             "sil-controller-directory", "export-fmu-torque", "optimize-dp-inf",
             "design-dhp-nul", "design-eid-length", "sweep-huge"]


@pytest.mark.parametrize("name", CLI_CASES)
def test_cli_refuses_hostile_scenarios_in_one_line(name, tmp_path):
    args, fragment = _cli_case(name, tmp_path)
    before = sorted(os.listdir(tmp_path))
    proc = _cli(args, tmp_path)
    err = proc.stderr.strip()
    assert proc.returncode == 2, (proc.returncode, err)
    assert "Traceback" not in proc.stderr and len(err.splitlines()) == 1, err
    assert err.startswith("error: ") and fragment in err, err
    assert sorted(os.listdir(tmp_path)) == before  # nothing written


def test_sil_lumped_plant_step_is_checked_against_the_euler_bound(tmp_path):
    from downhole.scenario import euler_stable_dt
    from downhole.sil.scenario import parse_sil_scenario
    from downhole.sim.lumped_model import lumped_model

    bound, _ = euler_stable_dt(lumped_model("table_2_1", order=12))
    model = {"fidelity": "lumped12", "interface": "surface"}
    parse_sil_scenario({"model": model, "simulation": {"dt": 0.9 * bound}, "controller":
                        {"type": "none"}})
    with pytest.raises(ScenarioError, match=r"simulation.dt: .* stable only for dt <"):
        parse_sil_scenario({"model": model, "simulation": {"dt": 0.01}, "controller":
                            {"type": "none"}})
    with pytest.raises(ScenarioError, match="model.preset"):
        parse_sil_scenario({"model": {**model, "preset": "table_5_1"},
                            "controller": {"type": "none"}})
