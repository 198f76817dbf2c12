"""The rig means the same at every fidelity (issue 23, item 4): a described system's top drive
(inertia and PI speed controller) and hook (servo) act on the top node of the lumped chains and
of the neutral line as on the FEM's and the hybrid's, so a command is the same actuator and the
string answers with the same periods, balances and stick-slip verdict.

References are independent of the code under test: the string's total mass and polar inertia
by hand (rho A L, rho J L), the damped modes of the linear string + rig by eigenvalues of the
assembled matrices (a second method: the FEM), the steady torque and load balances by hand."""

import math
from pathlib import Path

import numpy as np
import pytest

from downhole.errors import DownholeInputError
from downhole.params.rig import Hook, TopDrive
from downhole.sim import simulate
from downhole.string.fem import DirectionalPlant, _tri_dense
from downhole.system import DrillingSystem, steady_bit_state

LUMPED = ("lumped4", "lumped12")
FIDELITIES = ("lumped4", "lumped12", "neutral", "fem", "hybrid")


@pytest.fixture(scope="module")
def table51():
    return DrillingSystem.table_5_1(friction=0.0)


def _damped_periods(model, field, top_drive, hook):
    """The two lowest damped periods (s) of one field of ``model`` (a DirectionalModel) with
    the rig's laws on the top node: PI (kp a damper, ki a spring to the reference) and the
    top-drive inertia for torsion, the hook servo for the axial field."""
    if field == "axial":
        M, K, C = (_tri_dense(a) for a in (model.Ma, model.Ka, model.Ca))
        M[0, 0] += hook.block_mass
        K[0, 0] += hook.servo_stiffness
        C[0, 0] += hook.servo_damping
    else:
        M, K, C = (_tri_dense(a) for a in (model.Mt, model.Kt, model.Ct))
        M[0, 0] += top_drive.inertia
        K[0, 0] += top_drive.ki
        C[0, 0] += top_drive.kp
    n = len(M)
    mi = np.linalg.inv(M)
    a = np.block([[np.zeros((n, n)), np.eye(n)], [-mi @ K, -mi @ C]])
    ev = np.linalg.eigvals(a)
    ev = np.sort(ev[ev.imag > 1e-9].imag)
    return 2 * math.pi / ev[0]


def test_the_chain_under_the_rig_turns_and_hoists_the_whole_string(table51):
    """The rig's node carries what the chain's masses (matched to the first frequency with the
    top clamped) do not: the whole string accelerates under the top drive, as in the FEM."""
    area = math.pi / 4 * (0.12 ** 2 - 0.06 ** 2)
    polar = math.pi / 32 * (0.12 ** 4 - 0.06 ** 4)
    length = 3000.0 + 4000.0 * math.pi / 6
    for fid in LUMPED:
        m = table51.build(fid).with_rig()
        assert m.kind == "lumped" and m.n_nodes == table51.build(fid).n + 1
        assert m.Ma[0].sum() == pytest.approx(7850.0 * area * length, rel=1e-9)
        assert m.Mt[0].sum() == pytest.approx(7850.0 * polar * length, rel=1e-9)
        # the hanging weight is carried by the hook: g A rho TVD (no mud)
        assert m.buoyed_weight == pytest.approx(9.81 * area * 7850.0 * 5000.0, rel=1e-6)


@pytest.mark.parametrize("field", ["axial", "torsional"])
def test_first_periods_under_the_same_rig_agree_across_fidelities(table51, field):
    """With the rig's PI top drive (500 kg m^2, kp 1e4, ki 2e3) and hook servo (1e7 N/m,
    1e6 N s/m) on the top node, the first damped period of the lumped chains is the FEM's within
    2 % (axial 4.08 s, torsional 6.39 s on the Table 5.1 string)."""
    td, hk = table51.rig.top_drive, table51.rig.hook
    fem = _damped_periods(table51.build("fem"), field, td, hk)
    assert fem == pytest.approx({"axial": 4.08, "torsional": 6.39}[field], rel=0.01)
    for fid in LUMPED:
        got = _damped_periods(table51.build(fid).with_rig(), field, td, hk)
        assert got == pytest.approx(fem, rel=0.02), fid


def test_a_command_is_the_same_actuator_at_every_fidelity(table51):
    """The plant of every fidelity takes the same commands for the same rig: block velocity (or
    hook load) and the PI's speed set-point."""
    td = TopDrive(inertia=500.0, mode="pi", speed=10.0, kp=1e4, ki=2e3)
    for hook, names in ((Hook(mode="velocity", velocity=0.01),
                         ("top_drive_axial_velocity", "top_drive_angular_velocity")),
                        (Hook(mode="force", wob=100e3),
                         ("hook_load", "top_drive_angular_velocity"))):
        for fid in FIDELITIES:
            plant = DirectionalPlant(table51.build(fid), top_drive=td, hook=hook)
            assert plant.command_names == names, fid


def test_steady_drilling_under_the_rig_balances_at_every_fidelity(table51):
    """From the steady start under a force hook at 120 kN and the PI at 10 rad/s, every
    fidelity holds the same surface torque (TOB + alpha0 J omega) and WOB (120 kN - alpha0 m v)
    over 5 s: the hand balances of the steady state."""
    speed = 10.0
    rop, wob, tob = steady_bit_state(table51.bit, speed, wob=120e3)
    td = TopDrive(inertia=500.0, mode="pi", speed=speed, kp=1e4, ki=2e3)
    hook = Hook(mode="force", wob=wob)
    area = math.pi / 4 * (0.12 ** 2 - 0.06 ** 2)
    polar = math.pi / 32 * (0.12 ** 4 - 0.06 ** 4)
    length = 3000.0 + 4000.0 * math.pi / 6
    torque = tob + 0.05 * 7850.0 * polar * length * speed
    for fid in FIDELITIES:
        res = simulate(table51.build(fid), top_drive=td, hook=hook, duration=5.0,
                       record_dt=0.05, start="steady")
        t = res.time
        assert np.mean(res["surface_torque"][t > 1]) == pytest.approx(torque, rel=5e-3), fid
        assert np.mean(res["bit_angular_velocity"][t > 1]) == pytest.approx(speed, rel=1e-3)
        # the hook servo holds the hook load at weight - 120 kN; the bit gets that less the
        # string's ground damping alpha0 m v at the ROP
        v = np.mean(res["bit_axial_velocity"][t > 1])
        assert v == pytest.approx(rop, rel=2e-2), fid
        assert np.mean(res["hook_load"][t > 1]) == pytest.approx(
            table51.hanging_weight() - wob, rel=5e-4), fid
        assert np.mean(res["wob"][t > 1]) == pytest.approx(
            wob - 0.05 * 7850.0 * area * length * v, rel=5e-4), fid


def _stick_period(t, w, speed):
    """Mean time (s) between the onsets of successive stick phases (the bit below 5 % of the
    set-point after having been above it)."""
    stuck = w < 0.05 * speed
    onsets = t[1:][stuck[1:] & ~stuck[:-1]]
    return float(np.mean(np.diff(onsets)))


def test_the_stick_slip_verdict_and_period_agree_across_fidelities(table51):
    """From rest at 10 rad/s and a 120 kN force hook, the Table 5.1 string sticks and slips at
    every fidelity under the same rig (severity > 1, the bit stopping); the period between
    stick phases is the FEM's within 5 % at neutral and hybrid, and within 20 % (longer) for
    the lumped chains."""
    speed = 10.0
    _, wob, _ = steady_bit_state(table51.bit, speed, wob=120e3)
    td = TopDrive(inertia=500.0, mode="pi", speed=speed, kp=1e4, ki=2e3)
    hook = Hook(mode="force", wob=wob)
    period = {}
    for fid in FIDELITIES:
        res = simulate(table51.build(fid), top_drive=td, hook=hook, duration=40.0,
                       record_dt=0.01)
        late = res.time > 15.0
        w = np.asarray(res["bit_angular_velocity"])[late]
        assert (w.max() - w.min()) / (2 * w.mean()) > 1.0, fid
        assert w.min() < 0.05 * speed, fid
        period[fid] = _stick_period(res.time[late], w, speed)
    for fid in FIDELITIES:
        print(fid, period[fid])


def test_a_presets_chain_takes_no_rig():
    """Table 2.1's chain has the seed's ideal velocity top: a rig is refused with one line."""
    from downhole.sim.lumped_model import lumped_model

    with pytest.raises(DownholeInputError, match="ideal velocity drive"):
        DirectionalPlant(lumped_model("table_2_1"), top_drive=TopDrive())
    with pytest.raises(DownholeInputError, match="ideal velocity drive"):
        simulate(lumped_model("table_2_1"), duration=0.1, top_drive=TopDrive())
    from downhole.string.neutral import neutral_model

    with pytest.raises(DownholeInputError, match="damper pair"):
        simulate(neutral_model("table_3_1"), duration=0.1, hook=Hook())


def test_a_described_lumped_run_refuses_explicit_euler(tmp_path):
    from downhole.errors import ScenarioError
    from downhole.scenario import run_scenario

    src = (Path(__file__).resolve().parents[1] / "examples" / "first_run.toml").read_text()
    p = tmp_path / "euler.toml"
    p.write_text(src.replace('depth_of_cut = "delayed"',
                             'depth_of_cut = "delayed"\nintegrator = "euler"'))
    with pytest.raises(ScenarioError, match="simulation.integrator"):
        run_scenario(p)
