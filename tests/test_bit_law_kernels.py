"""Every kernel's bit forces against the one bit law (downhole.bit.law), for both laws.

The lumped chain kernel (explicit Euler and Newmark, delayed and approximated depth of cut), the
neutral kernel, the directional FEM and hybrid kernel, the DP kernels, the DHP design model, the
EID's linearized bit/rock gains and the SIL rig model must all use the law named in
``BitParams.law``: their WOB and TOB at a frozen state equal the law's, and a run with
``law = "aarsnes"`` differs from a Detournay run.
"""

import importlib
import math

import numpy as np
import pytest

from downhole.bit import bit_forces, bit_forces_py, law, solve_bit_node
from downhole.params import get_preset

BIT_21 = get_preset("table_2_1").bit
LAWS = ("detournay", "aarsnes")


def _with_law(bit, name):
    return bit.model_copy(update={"law": name})


def _recorded_matches_law(res, bit, *, skip_first=False):
    """Every recorded (d, v, omega) row: the kernel's WOB/TOB equal the law's."""
    d = np.asarray(res["depth_of_cut"])
    v = np.asarray(res["bit_axial_velocity"])
    w = np.asarray(res["bit_angular_velocity"])
    wob = np.asarray(res["wob"])
    tob = np.asarray(res["tob"])
    rows = range(1 if skip_first else 0, d.size)
    assert np.isfinite(wob).all() and np.isfinite(tob).all()
    ew = np.array([bit_forces_py(d[i], v[i], w[i], bit)[0] for i in rows])
    et = np.array([bit_forces_py(d[i], v[i], w[i], bit)[1] for i in rows])
    np.testing.assert_allclose(wob[list(rows)], ew, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(tob[list(rows)], et, rtol=1e-12, atol=1e-9)
    assert (d > 0).any(), "the run never drilled: the comparison would be empty"
    return wob, tob


@pytest.mark.parametrize("name", LAWS)
@pytest.mark.parametrize("integrator,doc", [("euler", "delayed"), ("newmark", "delayed"),
                                            ("euler", "approximate")])
def test_lumped_runs_of_the_kernel_use_the_law(name, integrator, doc):
    from downhole.sim import SurfaceInputs, simulate
    from downhole.sim.lumped_model import lumped_model

    bit = _with_law(BIT_21, name)
    res = simulate(lumped_model("table_2_1", bit=bit), SurfaceInputs.velocity(0.01, 10.0),
                   duration=2.0, dt=5e-4, integrator=integrator, depth_of_cut=doc,
                   record_dt=0.01)
    _recorded_matches_law(res, bit)


def test_neutral_kernel_uses_the_law():
    from downhole.sim import simulate
    from downhole.string.neutral import neutral_model

    for name in LAWS:
        m = neutral_model("table_3_1")
        bit = _with_law(m.bit, name)
        res = simulate(m.with_bit(bit), duration=1.0, record_dt=0.01)
        _recorded_matches_law(res, bit)


@pytest.mark.parametrize("name", LAWS)
def test_fem_kernel_uses_the_law(name):
    from downhole.sim import simulate
    from downhole.string.fem import fem_model

    m0 = fem_model(n_elements=20)
    bit = _with_law(m0.bit, name)
    m = fem_model(bit=bit, n_elements=20)
    for doc in ("delayed", "approximate"):
        res = simulate(m, duration=1.0, depth_of_cut=doc)
        _recorded_matches_law(res, bit)


@pytest.mark.parametrize("name", LAWS)
@pytest.mark.parametrize("field", [0, 1])
def test_fem_implicit_bit_node_solve_satisfies_the_law(name, field):
    # the FEM kernel's exact implicit bit force: den x + h F(x) = r with F the law's force
    p = _with_law(BIT_21, name).kernel_params()
    rng = np.random.default_rng(7 + field)
    h = 5e-4
    for _ in range(200):
        den = 10.0 ** rng.uniform(2, 6)
        x0 = rng.normal(0.0, 0.02 if field == 0 else 5.0)
        if field == 0:
            c0, c1 = rng.uniform(-1e-3, 4e-3), rng.uniform(0.0, 1.0)  # d = c0 + c1 v
        else:
            c0, c1 = rng.uniform(1e-4, 4e-3), rng.normal(0.0, 0.01)   # d, v fixed
        r = den * rng.normal(0.0, 0.02 if field == 0 else 5.0) + h * 3e4
        x = solve_bit_node(field, den, r, h, x0, c0, c1, p)
        if field == 0:
            f = bit_forces(c0 + c1 * x, x, 0.0, p)[0]
        else:
            f = bit_forces(c0, c1, x, p)[1]
        assert den * x + h * f == pytest.approx(r, rel=1e-9, abs=1e-9 * (abs(r) + h * 1e5))


def test_fem_run_by_scenario_with_the_aarsnes_law():
    from downhole.scenario import run_scenario

    def run(name):
        data = {"title": "bit law", "model": {"fidelity": "fem", "preset": "table_5_1",
                                              "fem": {"n_elements": 20}},
                "bit": {"law": name},
                "simulation": {"duration": "1 s", "dt": "1 ms", "depth_of_cut": "delayed",
                               "record_dt": "10 ms"}}
        return run_scenario(data)

    res = {name: run(name) for name in LAWS}
    bit = get_preset("table_5_1").bit
    for name in LAWS:
        _recorded_matches_law(res[name], _with_law(bit, name))
    assert not np.allclose(res["aarsnes"]["tob"], res["detournay"]["tob"])


def test_lumped_run_by_scenario_with_the_aarsnes_law():
    # steady drilling at 10 mm/s, 10 rad/s (approximated depth of cut: the bit settles on the
    # set-points, d = 6.28 mm > d*): both laws press with sigma l a = 24.3 kN on the wear flats,
    # so the steady WOB is the same and the steady TOB differs by the friction torques' factor,
    # gamma mu a F_c (Aarsnes) against 1/2 gamma mu a F_c (Detournay)
    from downhole.scenario import run_scenario

    def run(name):
        data = {"title": "bit law", "model": {"fidelity": "lumped4", "preset": "table_2_1"},
                "bit": {"law": name},
                "operation": {"mode": "velocity", "rop": "10 mm/s", "surface_speed": "10 rad/s"},
                "simulation": {"duration": "150 s", "dt": "0.5 ms", "record_dt": "10 ms",
                               "depth_of_cut": "approximate", "integrator": "euler"}}
        return run_scenario(data)

    res = {name: run(name) for name in LAWS}
    for name in LAWS:
        _recorded_matches_law(res[name], _with_law(BIT_21, name))
        assert res[name]["bit_angular_velocity"][-1] == pytest.approx(10.0, rel=1e-4)
        assert res[name]["bit_axial_velocity"][-1] == pytest.approx(0.01, rel=1e-4)
        # W = zeta eps a d + sigma l a at d = 2 pi mm
        assert res[name]["wob"][-1] == pytest.approx(46445.3 + 24300.0, rel=1e-4)
    mu = 0.5 + 0.3 * math.exp(-0.9 * 10.0)
    dtob = 0.5 * mu * 0.15 * 45e6 * 3.6e-3 * 0.15  # 911.3 N m
    assert res["aarsnes"]["tob"][-1] - res["detournay"]["tob"][-1] == pytest.approx(dtob,
                                                                                   rel=1e-3)


@pytest.mark.parametrize("name", LAWS)
def test_dp_kernels_use_the_law(name):
    from downhole.control.dp import kernels as dp

    bit = _with_law(BIT_21, name)
    p = bit.kernel_params()
    g2 = np.linspace(0.0, 0.02, 7)
    g4 = np.linspace(0.0, 20.0, 9)
    wob, tob = dp.node_bit_loads(g2, g4, p)
    for i, v in enumerate(g2):
        for j, w in enumerate(g4):
            d = law.approx_depth_of_cut(v, w, p)
            assert (wob[i * 9 + j], tob[i * 9 + j]) == pytest.approx(bit_forces(d, v, w, p),
                                                                    rel=1e-12, abs=1e-9)
    fs, ts = dp.steady_loads(0.01, 10.0, 1e3, 5e2, p)
    ew, et = bit_forces(2 * math.pi * 1e-3, 0.01, 10.0, p)
    assert (fs, ts) == pytest.approx((ew + 10.0, et + 5e3), rel=1e-12)
    # the implicit dampers: slopes of WOB along the approximated depth and of TOB at fixed d
    for v, w in [(0.01, 10.0), (0.004, 2.0), (0.002, 0.7)]:
        cv, cw = dp._slopes(v, w, p)
        hv, hw = 1e-9, 1e-6
        fd_v = (bit_forces(law.approx_depth_of_cut(v + hv, w, p), v + hv, w, p)[0]
                - bit_forces(law.approx_depth_of_cut(v - hv, w, p), v - hv, w, p)[0]) / (2 * hv)
        d = law.approx_depth_of_cut(v, w, p)
        fd_w = (bit_forces(d, v, w + hw, p)[1] - bit_forces(d, v, w - hw, p)[1]) / (2 * hw)
        assert cv == pytest.approx(max(fd_v, 0.0), rel=1e-5)
        assert cw == pytest.approx(max(fd_w, 0.0), rel=1e-5, abs=1e-6)


@pytest.mark.parametrize("name", LAWS)
def test_dhp_design_model_uses_the_law(name):
    from downhole.control.dhp.drilling import bit_forces_batch

    bit = _with_law(BIT_21, name)
    v = np.array([0.0, 0.004, 0.01, 0.02])
    w = np.array([0.2, 2.0, 10.0, 15.0])
    out = bit_forces_batch(v, w, bit)
    for i in range(v.size):
        d = 2 * math.pi * v[i] / max(w[i], bit.omega_floor)
        assert out[i, 2] == pytest.approx(d, rel=1e-14)
        assert tuple(out[i, :2]) == pytest.approx(bit_forces_py(d, v[i], w[i], bit), rel=1e-12)


def test_eid_bit_rock_gains_are_the_law_slopes():
    from downhole.control.eid.stability import _bit_rock_gains
    from downhole.string.neutral import neutral_model

    m = neutral_model("table_3_1")
    b = m.bit
    kw, kt, c, tn = _bit_rock_gains(m, 0.01, 20.0)
    n = b.n_blades
    # by hand (wear flats saturated at d = 2 pi 0.01 / 20 = 3.1 mm > d*): n zeta eps a, n eps a^2/2
    assert kw == pytest.approx(n * b.zeta * b.epsilon * b.radius, rel=1e-14)
    assert kt == pytest.approx(n * 0.5 * b.epsilon * b.radius**2, rel=1e-14)
    assert c == pytest.approx(0.01 / 20.0) and tn == pytest.approx(2 * math.pi / (n * 20.0))
    # below d* the law's wear-flat slope sigma l a / d* enters the axial gain
    kw_lo, _, _, _ = _bit_rock_gains(m, 0.001, 20.0)
    full = b.sigma * b.wear_length * b.radius
    assert kw_lo == pytest.approx(n * (b.zeta * b.epsilon * b.radius + full / b.d_star),
                                  rel=1e-12)


def test_sil_rig_model_uses_the_law():
    from downhole.sil import hil

    for name in LAWS:
        p = _with_law(BIT_21, name).kernel_params()
        st = np.array([0.0, 0.01, 0.0, 10.0, 0.0, 0.0])
        # no coupling: only the bit acts
        par = hil.RigParams(mass=1e3, inertia=50.0, k_a=0.0, c_a=0.0, k_t=0.0, c_t=0.0)
        st1 = st.copy()
        hil._rig_step(st1, 0.0, 0.0, 1e-6, par, p)
        d = law.approx_depth_of_cut(0.01, 10.0, p)
        wob, tob = bit_forces(d, 0.01, 10.0, p)
        sa, sw = law.bit_force_slopes(d, 0.01, 10.0, p, True)
        # one implicit step: dv = -dt WOB / (m + dt dWOB/dv), dw = -dt TOB / (J + dt dTOB/dw)
        assert 0.01 - st1[1] == pytest.approx(1e-6 * wob / (1e3 + 1e-6 * sa), rel=1e-9)
        assert 10.0 - st1[3] == pytest.approx(1e-6 * tob / (50.0 + 1e-6 * sw), rel=1e-9)


MODULES = ["downhole.sim.kernel", "downhole.sim.lumped_model", "downhole.string.neutral",
           "downhole.string._reference_fd", "downhole.control.dp.kernels",
           "downhole.control.dhp.drilling", "downhole.control.dhp.directional", "downhole.sil.hil",
           "downhole.sim.reference_numpy"]


@pytest.mark.parametrize("module", MODULES)
def test_no_module_holds_its_own_copy_of_the_law(module):
    mod = importlib.import_module(module)
    for name in ("bit_forces", "approx_depth_of_cut", "bit_force_slopes", "solve_bit_node",
                 "bit_wob", "rock_depth", "rock_advance", "rock_depth_at", "rock_advance_to"):
        if hasattr(mod, name):
            src = law if not name.startswith("rock") else importlib.import_module(
                "downhole.bit.rock_surface")
            assert getattr(mod, name) is getattr(src, name), f"{module}.{name} is a copy"
    for copy in ("bit_constants", "wear_flat_force", "wob_and_slope", "tob_and_slope",
                 "rock_depth_fast", "rock_advance_fast"):
        assert not hasattr(mod, copy), f"{module}.{copy}: a second bit law / rock memory"
