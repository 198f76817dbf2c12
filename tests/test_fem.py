"""Directional FEM: quarter-wave frequencies, static hook load, energy balance, linear export."""

import math

import numpy as np
import pytest

from downhole.control.affine import from_directional
from downhole.control.topdrive import Hook, TopDrive
from downhole.errors import DownholeInputError
from downhole.sim.kernel import CHANNELS
from downhole.string.drillstring import DrillString, pipe_section
from downhole.string.fem import _Packed, _static_axial, fem_model
from downhole.well import Arc, Tangent, Vertical, WellPath

PIPE = pipe_section(0.127, 0.1086, young_modulus=2.1e11, shear_modulus=8.1e10)


def _vertical(L=1000.0, **kw):
    well = WellPath.from_sections([Vertical(L)])
    return well, DrillString.uniform(L, PIPE, **kw)


@pytest.mark.parametrize("field,speed", [("axial", PIPE.axial_wave_speed),
                                         ("torsional", PIPE.torsional_wave_speed)])
def test_fixed_free_frequencies_converge_to_quarter_wave(field, speed):
    L = 1000.0
    well, ds = _vertical(L)
    exact = np.array([(2 * n - 1) * speed / (4 * L) for n in (1, 2, 3)])
    errs = []
    for ne in (10, 40, 160):
        f = fem_model(well, ds, n_elements=ne, md_b=300, md_c=600).natural_frequencies(
            field, 3, top="fixed", bottom="free")
        errs.append(np.max(np.abs(f - exact) / exact))
    assert errs[0] > errs[1] > errs[2]
    assert errs[2] < 2e-4
    assert errs[1] / errs[2] == pytest.approx(16, rel=0.1)  # second-order convergence


@pytest.mark.parametrize("sections", [[Vertical(1500)],
                                      [Vertical(500), Arc(600, math.pi / 4), Tangent(400)]])
def test_static_hook_load_is_buoyed_weight_minus_wob(sections):
    well = WellPath.from_sections(sections)
    ds = DrillString.uniform(well.total_depth, PIPE, mud_density=1300.0)
    m = fem_model(well, ds, n_elements=60, md_b=200, md_c=400)
    wob = 50e3
    u = _static_axial(m, wob)
    top_tension = -m.Ka[1, 0] * (u[1] - u[0]) + m.gravity[0]  # element 0 + top node's own load
    w_b = 9.81 * PIPE.area * (PIPE.density - 1300.0)
    W = w_b * float(well.tvd(well.total_depth))
    assert m.buoyed_weight == pytest.approx(W, rel=1e-9)
    assert top_tension == pytest.approx(W - wob, rel=1e-9)
    # the bit element carries the WOB in compression
    bit_tension = -m.Ka[1, -2] * (u[-1] - u[-2]) - m.gravity[-1]
    assert bit_tension == pytest.approx(-wob, rel=1e-6)


def test_undamped_run_conserves_energy():
    well, ds = _vertical(800.0)
    m = fem_model(well, ds, n_elements=40, rayleigh_alpha=0.0, rayleigh_beta=0.0, friction=0.0,
                  md_b=200, md_c=400)
    dt = 1e-3
    td = TopDrive(mode="torque", speed=3000.0)
    hook = Hook(mode="force", wob=0.0)
    pk = _Packed(m, dt, td, hook, "delayed")
    st = pk.initial_state()
    H = m.buoyed_weight + 30e3  # lift off bottom: no bit force, free flight of a linear system
    n = m.n_nodes

    def tri(d, o, x):
        y = d * x
        y[:-1] += o[:-1] * x[1:]
        y[1:] += o[:-1] * x[:-1]
        return y

    fa = m.gravity.copy()
    fa[0] -= H
    ft = np.zeros(n)
    ft[0] = 3000.0

    def energy(s):
        ua, va, ut, vt = s[0], s[1], s[3], s[4]
        mt = pk.mats
        return (0.5 * va @ tri(mt[0], mt[1], va) + 0.5 * ua @ tri(mt[2], mt[3], ua) - fa @ ua
                + 0.5 * vt @ tri(mt[6], mt[7], vt) + 0.5 * ut @ tri(mt[8], mt[9], ut) - ft @ ut)

    e0 = energy(st["state"])
    rec = np.zeros((10, len(CHANNELS)))
    cmd = np.tile([H, 3000.0], (501, 1))
    drift, kin = [], []
    for k in range(10):
        pk.run(st, cmd, rec, 500, k)
        s = st["state"]
        drift.append(energy(s) - e0)
        kin.append(0.5 * s[1] @ tri(pk.mats[0], pk.mats[1], s[1])
                   + 0.5 * s[4] @ tri(pk.mats[6], pk.mats[7], s[4]))
    assert np.all(rec[:, CHANNELS.index("wob")] == 0.0)  # the bit stayed off bottom
    assert max(abs(x) for x in drift) < 0.01 * max(kin)


def test_linear_model_matches_the_newmark_kernel():
    well, ds = _vertical(600.0)
    m = fem_model(well, ds, n_elements=12, friction=0.0, md_b=200, md_c=400)
    A_d, B_d = m.linear_model(1e-3, top_drive_inertia=500.0)
    n = m.n_nodes
    assert B_d[2 * n, 0] > 0  # Eq. 4.14 corrected: B = [0; +M^-1] (slack-off pushes down)
    z = np.zeros(4 * n)
    u = np.array([-20e3, 2000.0])  # hook load 20 kN above hanging weight; 2 kN m
    traj = []
    for _ in range(1500):
        z = A_d @ z + B_d @ u
        traj.append(z[2 * n + 2 * (n - 1) + 1])
    dt = 1e-4
    pk = _Packed(m, dt, TopDrive(mode="torque", speed=2000.0), Hook(wob=0.0), "delayed")
    st = pk.initial_state()
    rec = np.zeros((15, len(CHANNELS)))
    pk.run(st, np.tile([m.buoyed_weight + 20e3, 2000.0], (15001, 1)), rec, 1000, 0)
    kern = rec[:, CHANNELS.index("bit_angular_velocity")]
    ref = np.array(traj)[99::100]
    assert np.max(np.abs(kern - ref)) < 0.01 * np.max(np.abs(ref))


def test_control_affine_export_has_the_interface_shapes():
    m = fem_model(n_elements=5)
    cam = from_directional(m, 1e-3)
    assert cam.n_states == 24 and cam.n_inputs == 2
    A_d, B_d = m.linear_model(1e-3)
    assert np.allclose(cam.A_d, A_d) and np.allclose(cam.B_d, B_d)
    z = np.zeros(24)
    z[cam.index("axial_velocity", "bit")] = 0.01 / cam.state_scale[cam.index("axial_velocity",
                                                                               "bit")]
    z[cam.index("angular_velocity", "bit")] = 0.5
    h = cam.nonlinear(z)
    assert h[cam.index("axial_velocity", "bit")] < 0  # WOB decelerates the bit


def test_fem_bad_input():
    with pytest.raises(DownholeInputError, match="n_elements must be >= 1"):
        fem_model(n_elements=0)
    with pytest.raises(DownholeInputError, match="too few"):
        fem_model(n_elements=2)
    well, ds = _vertical(500.0)
    with pytest.raises(DownholeInputError, match="exceeds the well"):
        fem_model(well, DrillString.uniform(900.0, PIPE), n_elements=10)


def test_modal_damping_gives_the_requested_ratio_in_every_mode():
    # damped eigenvalues of the assembled first-order system: zeta_i = -Re(lambda)/|lambda|
    ratio = 0.04
    m = fem_model(n_elements=12, damping="modal", modal_ratio=ratio, friction=0.0)
    for M, K, C in ((m.Ma, m.Ka, m.Cdense[0]), (m.Mt, m.Kt, m.Cdense[1])):
        from downhole.string.fem import _tri_dense

        Md, Kd = _tri_dense(M), _tri_dense(K)
        n = Md.shape[0]
        Minv = np.linalg.inv(Md)
        A = np.block([[np.zeros((n, n)), np.eye(n)], [-Minv @ Kd, -Minv @ C]])
        lam = np.linalg.eigvals(A)
        osc = lam[np.abs(lam.imag) > 1e-6]      # the free-free rigid mode has lambda = 0
        zeta = -osc.real / np.abs(osc)
        assert zeta.size == 2 * (n - 1)
        assert np.allclose(zeta, ratio, rtol=1e-6)
    with pytest.raises(DownholeInputError, match="damping must be"):
        fem_model(n_elements=12, damping="viscous")


def test_modal_damping_kernel_matches_exact_zoh():
    # the dense (modal) path of the Newmark kernel against expm of the same linear model
    well, ds = _vertical(600.0)
    m = fem_model(well, ds, n_elements=12, friction=0.0, damping="modal", modal_ratio=0.05,
                  md_b=200, md_c=400)
    A_d, B_d = m.linear_model(1e-3, top_drive_inertia=500.0)
    n = m.n_nodes
    z = np.zeros(4 * n)
    u = np.array([-20e3, 2000.0])
    traj = []
    for _ in range(1500):
        z = A_d @ z + B_d @ u
        traj.append(z[2 * n + 2 * (n - 1) + 1])
    pk = _Packed(m, 1e-4, TopDrive(mode="torque", speed=2000.0), Hook(wob=0.0), "delayed")
    st = pk.initial_state()
    rec = np.zeros((15, len(CHANNELS)))
    pk.run(st, np.tile([m.buoyed_weight + 20e3, 2000.0], (15001, 1)), rec, 1000, 0)
    kern = rec[:, CHANNELS.index("bit_angular_velocity")]
    ref = np.array(traj)[99::100]
    assert np.max(np.abs(kern - ref)) < 0.01 * np.max(np.abs(ref))


def test_velocity_hook_servo_drives_the_block_and_balances_the_string():
    from downhole.sim import simulate

    L = 1000.0
    well, ds = _vertical(L)
    m = fem_model(well, ds, n_elements=40, friction=0.0, md_b=300, md_c=600)
    v = 0.005
    r = simulate(m, duration=30.0, dt=1e-3, hook=Hook(mode="velocity", velocity=v, wob=50e3),
                             record_dt=1e-3)
    t = r.time
    sel = t >= 15.0
    # the servo moves the block at the commanded velocity
    assert r["top_drive_axial_velocity"][sel].mean() == pytest.approx(v, rel=1e-3)
    # axial force balance of the whole string (inertia averages out): hook load + WOB = weight
    assert (r["hook_load"][sel] + r["wob"][sel]).mean() == pytest.approx(m.buoyed_weight,
                                                                        rel=5e-3)
    # quasi-static compliance: the string shortens by dWOB L / (E A) relative to the block
    vt = r["top_drive_axial_velocity"]
    x_top = np.concatenate([[0.0], np.cumsum(0.5 * (vt[1:] + vt[:-1]) * np.diff(t))])
    e = r["bit_axial_position"] - x_top
    expected = (50e3 - r["wob"][sel].mean()) * L / (PIPE.area * PIPE.young_modulus)
    assert e[sel].mean() - e[0] == pytest.approx(expected, rel=0.1)
    with pytest.raises(DownholeInputError, match="force hook"):
        simulate(m, {"top_drive_axial_velocity": 0.01}, duration=0.1, dt=1e-3)
