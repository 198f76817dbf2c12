"""Torque and drag (downhole.string.torque_drag, `downhole torque-drag`) against hand
calculations, an independent ODE solution and welleng's soft-string model on two wells."""

from __future__ import annotations

import csv
import itertools
import json
import math
import warnings
from pathlib import Path

import numpy as np
import pytest

from downhole.errors import DownholeInputError
from downhole.string.drillstring import DrillString, StringSegment, pipe_section
from downhole.string.torque_drag import CASES, torque_drag
from downhole.system import DrillingSystem
from downhole.well import Arc, Tangent, Vertical, WellPath

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
G = 9.81


def _system(name: str):
    from downhole.scenario import load_scenario
    from downhole.scenario.system import build_system, parse_system

    data, source, _ = load_scenario(EXAMPLES / name)
    sc = parse_system(data, source)
    return build_system(sc, source, sc.model.fidelity)


def _w(seg: StringSegment, mud: float) -> float:
    return G * seg.section.area * (seg.section.density - mud)


def _rel(a, b):
    return abs(a - b) / abs(b)


# ---------------------------------------------------------------------------- hand calculations
def test_vertical_well_hook_load_is_the_buoyed_weight():
    """Vertical: no wall contact; every off-bottom case carries the buoyed weight
    sum g A_i (rho_steel - rho_mud) L_i, drilling carries it less the WOB; torque 0 / TOB."""
    segs = (StringSegment(1500.0, pipe_section(0.127, 0.1086)),
            StringSegment(150.0, pipe_section(0.127, 0.0762), "heavyweight"),
            StringSegment(150.0, pipe_section(0.1651, 0.0714), "collar"))
    string = DrillString(segs, mud_density=1200.0)
    well = WellPath.from_sections([Vertical(1800.0)])
    res = torque_drag(well, string, friction=(0.1, 0.4), wob=60e3, tob=4e3, step=7.0)
    weight = sum(_w(s, 1200.0) * s.length for s in segs)
    for k in range(2):
        for c in ("trip_out", "trip_in", "rotating"):
            assert _rel(res.tension[c][k, 0], weight) < 1e-9
        assert _rel(res.tension["drilling"][k, 0], weight - 60e3) < 1e-9
        assert res.torque["rotating"][k, 0] == pytest.approx(0.0, abs=1e-9)
        assert res.torque["drilling"][k, 0] == pytest.approx(4e3, rel=1e-12)
        assert np.max(np.abs(res.side_force["trip_out"][k])) < 1e-9
    # broomstick: the bit at d (about 1000 m) carries the collars, the heavyweight and d - 300 m
    # of pipe; at d = 200 m, 50 m of heavyweight and the collars
    for target in (1000.0, 200.0):
        j = int(np.argmin(np.abs(res.bit_depth - target)))
        d = res.bit_depth[j]
        expect = (_w(segs[0], 1200.0) * max(d - 300.0, 0.0)
                  + _w(segs[1], 1200.0) * min(max(d - 150.0, 0.0), 150.0)
                  + _w(segs[2], 1200.0) * min(d, 150.0))
        for c in ("trip_out", "trip_in", "rotating"):
            assert _rel(res.hook_load[c][1, j], expect) < 1e-9
        assert _rel(res.hook_load["drilling"][1, j], expect - 60e3) < 1e-9
    assert res.hook_load["trip_out"][0, -1] == pytest.approx(res.tension["trip_out"][0, 0])


def test_wob_tob_and_step_take_unit_strings_and_pint_quantities():
    """``wob="20 klbf"``, ``tob`` as a pint quantity and ``step="30 ft"`` give the same loads as
    the SI numbers converted by an independent pint registry; a wrong dimension is refused."""
    import pint

    ureg = pint.UnitRegistry()
    well = WellPath.from_sections([Vertical(500.0), Arc(600.0, 0.7)])
    string = DrillString.uniform(well.total_depth, pipe_section(0.127, 0.108))
    wob = ureg.Quantity(20.0, "kip").to("N").magnitude
    tob = ureg.Quantity(5.0, "kilofoot * force_pound").to("N * m").magnitude
    step = ureg.Quantity(30.0, "ft").to("m").magnitude
    si = torque_drag(well, string, friction=0.25, wob=wob, tob=tob, step=step)
    q = torque_drag(well, string, friction=0.25, wob="20 klbf", tob=ureg.Quantity(5.0, "kft*lbf"),
                    step="30 ft")
    for c in CASES:
        np.testing.assert_allclose(q.tension[c], si.tension[c], rtol=1e-12)
        np.testing.assert_allclose(q.torque[c], si.torque[c], rtol=1e-12, atol=1e-9)
    with pytest.raises(DownholeInputError, match="wob"):
        torque_drag(well, string, wob="20 m")


@pytest.mark.parametrize("inc_deg", [30.0, 60.0, 89.0])
def test_straight_inclined_well_matches_the_closed_form(inc_deg):
    """Straight inclined hole: N = w sin I, T = w L (cos I +- mu sin I), M = mu w sin I L r."""
    inc, mu, length = math.radians(inc_deg), 0.25, 1200.0
    well = WellPath.from_survey([0.0, length], [inc_deg, inc_deg], [40.0, 40.0])
    sec = pipe_section(0.127, 0.1086)
    string = DrillString.uniform(length, sec, mud_density=1100.0)
    res = torque_drag(well, string, friction=mu, wob=50e3, tob=3e3, step=25.0)
    w = _w(string.segments[0], 1100.0)
    up, down = math.cos(inc) + mu * math.sin(inc), math.cos(inc) - mu * math.sin(inc)
    assert _rel(res.tension["trip_out"][0, 0], w * length * up) < 1e-9
    assert _rel(res.tension["trip_in"][0, 0], w * length * down) < 1e-9
    assert _rel(res.tension["rotating"][0, 0], w * length * math.cos(inc)) < 1e-9
    assert _rel(res.tension["drilling"][0, 0], w * length * math.cos(inc) - 50e3) < 1e-9
    torque = mu * w * math.sin(inc) * length * 0.127 / 2
    assert _rel(res.torque["rotating"][0, 0], torque) < 1e-9
    assert _rel(res.torque["drilling"][0, 0], torque + 3e3) < 1e-9
    assert np.allclose(res.side_force["trip_out"][0], w * math.sin(inc), rtol=1e-9)


@pytest.mark.parametrize("example", ["table_5_1.toml", "directional_survey.toml",
                                     "torque_drag.toml"])
def test_rotating_hook_load_is_the_buoyed_weight_over_tvd(example):
    """Rotating off bottom has no axial friction: the hook load is sum w_i (TVD at the bottom of
    segment i - TVD at its top), exactly. DrillingSystem.hanging_weight (Gauss-Legendre over
    each segment's MD, which kinks at survey stations) agrees within its quadrature error."""
    sysm = _system(example)
    res = sysm.torque_drag(friction=0.3, step=10.0, hook_load=False)
    joints = sysm.well.top_depth + sysm.string.boundaries
    tvd = sysm.well.tvd(joints)
    expect = sum(_w(seg, sysm.string.mud_density) * (tvd[i + 1] - tvd[i])
                 for i, seg in enumerate(sysm.string.segments))
    assert _rel(res.tension["rotating"][0, 0], expect) < 1e-9
    assert _rel(res.tension["rotating"][0, 0], sysm.hanging_weight()) < 1e-3


def _arc_ode(well_radius, kop, angle, length, w, mu, sign, r, t_bit=0.0, m_bit=0.0):
    """Independent solution of the planar soft-string equations on vertical + build arc +
    tangent: dT/dmd = -(w cos I + sign mu |T I' - w sin I|), dM/dmd = -mu |.| r (rotating)."""
    from scipy.integrate import solve_ivp

    kappa = 1.0 / well_radius
    arc_end = kop + angle / kappa

    def inc(md):
        return 0.0 if md <= kop else min(angle, (md - kop) * kappa)

    def rhs(md, y):
        i = inc(md)
        k = kappa if kop < md < arc_end else 0.0
        n = abs(y[0] * k - w * math.sin(i))
        return [-(w * math.cos(i) + sign * mu * n), -(mu * n * r if sign == 0 else 0.0)]

    y = [t_bit, m_bit]
    bounds = sorted({length, min(arc_end, length), kop, 0.0}, reverse=True)
    for a, b in itertools.pairwise(bounds):
        sol = solve_ivp(rhs, (a, b), y, rtol=1e-11, atol=1e-6, method="DOP853")
        y = sol.y[:, -1]
    return y


@pytest.mark.parametrize("case,sign", [("trip_out", 1), ("trip_in", -1), ("rotating", 0),
                                       ("drilling", 0)])
def test_build_section_matches_an_ode_solution(case, sign):
    """Table 5.1 well (vertical 3000 m, arc R 4000 m over 30 deg): the marching scheme against an
    adaptive ODE solution of the same equations (second-order convergence, 0.1 %)."""
    sysm = DrillingSystem.table_5_1()
    mu, wob, tob = 0.3, 120e3, 6e3
    res = sysm.torque_drag(friction=mu, wob=wob, tob=tob, step=10.0, hook_load=False)
    seg = sysm.string.segments[0]
    w = _w(seg, 0.0)
    on_bottom = case == "drilling"
    t, m = _arc_ode(4000.0, 3000.0, math.radians(30.0), sysm.well.total_depth, w, mu, sign,
                    seg.section.outer_diameter / 2, -wob if on_bottom else 0.0,
                    tob if on_bottom else 0.0)
    assert _rel(res.tension[case][0, 0], t) < 1e-3
    if sign == 0:
        assert _rel(res.torque[case][0, 0], m) < 1e-3


# ------------------------------------------------------------------------------------ welleng
def _welleng_td(well, string, mu, wob, tob, ds=2.0, bit_depth=None, fixed=True):
    """welleng's TorqueDrag on the same well (stations every ds m from our minimum-curvature
    path) and string (unit weight g A rho_steel, buoyancy factor (rho_s - rho_mud)/rho_s)."""
    pytest.importorskip("welleng")
    from welleng.architecture import BHA, WellBore
    from welleng.survey import Survey, SurveyHeader
    from welleng.torque_drag import TorqueDrag

    class Johancsik(TorqueDrag):
        """Two conventions made to match ours (docs/torque-drag.md, "welleng"):
        - welleng takes the inclination change as deeper minus shallower station and adds
          T dI to w sin I: tension then pushes a build section's string to the low side. The
          tension's pull is towards the centre of curvature (the high side of a build), so the
          two terms have opposite signs; we flip dI.
        - welleng zips the per-element torque arms top-down with the other arrays bottom-up;
          we reverse them (matters only for strings with more than one outer diameter)."""

        def get_inc_delta(self):
            super().get_inc_delta()
            self.inc_delta = -self.inc_delta

        def get_weight_buoyed_and_radius(self):
            super().get_weight_buoyed_and_radius()
            self.radius = self.radius[::-1]

    d = well.total_depth if bit_depth is None else float(bit_depth)
    md = np.unique(np.concatenate([np.arange(0.0, d, ds), [d],
                                   well.stations["md"][well.stations["md"] < d]]))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        survey = Survey(md=md, inc=np.degrees(well.inclination(md)),
                        azi=np.degrees(well.azimuth(md)), header=SurveyHeader(), deg=True)
        wb = WellBore("hole", top=0.0, bottom=d, method="bottom_up")
        wb.add_section(length=d, id=0.3, coeff_friction_sliding=mu)
        bha = BHA("string", top=0.0, bottom=d, method="bottom_up")
        left = d
        for seg in reversed(string.segments):
            length = min(seg.length, left)
            sec = seg.section
            bha.add_section(length=length, od=sec.outer_diameter,
                            unit_weight=string.g * sec.area * sec.density,
                            density=sec.density / 1000.0)
            left -= length
            if left <= 1e-9:
                break
        cls = Johancsik if fixed else TorqueDrag
        return cls(survey, wb, bha, fluid_density=string.mud_density / 1000.0, wob=wob,
                   tob=tob)


WELLENG_TENSION = {"trip_out": "pickup", "trip_in": "slackoff", "rotating": "rotating",
                   "drilling": "drilling"}


@pytest.mark.parametrize("example", ["table_5_1.toml", "directional_survey.toml"])
@pytest.mark.parametrize("mu", [0.1, 0.3])
def test_agrees_with_welleng_on_two_wells(example, mu):
    """Hook load (4 cases), surface torque and the tension profile agree with welleng within
    1 % (measured: < 0.03 %) on the Table 5.1 well and the J-shaped survey well."""
    sysm = _system(example)
    wob, tob = 90e3, 7e3
    res = sysm.torque_drag(friction=mu, wob=wob, tob=tob, step=5.0, hook_load=False)
    wl = _welleng_td(sysm.well, sysm.string, mu, wob, tob)
    for case, key in WELLENG_TENSION.items():
        assert _rel(res.tension[case][0, 0], wl.tension[key][0]) < 0.01, case
        ours = np.interp(wl.survey.md, res.md, res.tension[case][0])
        big = np.abs(wl.tension[key]) > 0.1 * np.max(np.abs(wl.tension[key]))
        assert np.max(np.abs(ours[big] / wl.tension[key][big] - 1)) < 0.01, case
    assert _rel(res.torque["rotating"][0, 0], wl.torque["rotating"][0]) < 0.01
    assert _rel(res.torque["drilling"][0, 0], wl.torque["drilling"][0]) < 0.01


@pytest.mark.parametrize("bit_depth", [1800.0, 2400.0])
def test_hook_load_curve_agrees_with_welleng_at_intermediate_bit_depths(bit_depth):
    """The broomstick's hook load with the bit part-way in (the string's bottom part: collars,
    heavyweight, the rest of the pipe) against welleng run on that shorter string."""
    sysm = _system("directional_survey.toml")
    res = sysm.torque_drag(friction=(0.2,), wob=50e3, tob=5e3, step=5.0)
    j = int(np.argmin(np.abs(res.bit_depth - bit_depth)))
    assert res.bit_depth[j] == pytest.approx(bit_depth)
    wl = _welleng_td(sysm.well, sysm.string, 0.2, 50e3, 5e3, bit_depth=bit_depth)
    for case, key in WELLENG_TENSION.items():
        assert _rel(res.hook_load[case][0, j], wl.tension[key][0]) < 0.01, case
    assert _rel(res.surface_torque["rotating"][0, j], wl.torque["rotating"][0]) < 0.01
    assert _rel(res.surface_torque["drilling"][0, j], wl.torque["drilling"][0]) < 0.01


def test_welleng_as_published_differs_in_build_sections_only():
    """welleng 0.30 as published: identical where the inclination does not change (a tangent
    turning in azimuth, one pipe size), but in a build it adds T dI to w sin I (pick-up hook
    load about 3 % and rotating torque about 50 % higher on the Table 5.1 well)."""
    md = np.linspace(0.0, 3000.0, 1501)
    string = DrillString.uniform(3000.0, pipe_section(0.127, 0.1086), mud_density=1100)
    # a turn at constant inclination: stations at 60 deg every few metres, azimuth 0 -> 90 deg
    flat = WellPath.from_survey(md, np.full(md.size, 60.0), np.linspace(0.0, 90.0, md.size))
    res = torque_drag(flat, string, friction=0.3, wob=40e3, tob=2e3, step=5.0, hook_load=False)
    wl = _welleng_td(flat, string, 0.3, 40e3, 2e3, fixed=False)
    for case, key in WELLENG_TENSION.items():
        assert _rel(res.tension[case][0, 0], wl.tension[key][0]) < 0.01, case
    assert _rel(res.torque["rotating"][0, 0], wl.torque["rotating"][0]) < 0.01
    t51 = DrillingSystem.table_5_1()
    res = t51.torque_drag(friction=0.3, wob=100e3, tob=5e3, step=5.0, hook_load=False)
    wl = _welleng_td(t51.well, t51.string, 0.3, 100e3, 5e3, fixed=False)
    assert wl.tension["pickup"][0] / res.tension["trip_out"][0, 0] - 1 > 0.02
    assert wl.torque["rotating"][0] / res.torque["rotating"][0, 0] - 1 > 0.4


def test_a_well_crossing_north_is_the_rotated_well_turning_through_south():
    """Loads depend on the path, not on where azimuth 0 is: a right turn through north
    (350 -> 20 deg) gives the loads of the same turn through south (170 -> 200 deg); the
    azimuth difference is never taken as almost a full turn (welleng issue 312)."""
    md = [0.0, 500.0, 1000.0, 1500.0, 2000.0, 2500.0]
    inc = [0.0, 0.0, 30.0, 55.0, 60.0, 60.0]
    azi = np.array([350.0, 350.0, 350.0, 5.0, 20.0, 20.0])
    string = DrillString.uniform(2500.0, pipe_section(0.127, 0.1086), mud_density=1100)
    a = torque_drag(WellPath.from_survey(md, inc, azi), string, friction=0.3, step=5.0,
                    hook_load=False)
    b = torque_drag(WellPath.from_survey(md, inc, azi - 180.0), string, friction=0.3, step=5.0,
                    hook_load=False)
    for c in CASES:
        assert np.allclose(a.tension[c], b.tension[c], rtol=1e-9)
        assert np.allclose(a.side_force[c], b.side_force[c], rtol=1e-7, atol=1e-6)


# ------------------------------------------------------------------------------ survey quantities
def test_dogleg_build_turn_and_vertical_section():
    well = WellPath.from_sections([Vertical(600.0), Arc(573.0, math.radians(60.0),
                                                        azimuth=math.radians(45.0)),
                                   Tangent(800.0)])
    mid = np.array([900.0])
    # a 573 m radius arc is 3 deg/30 m (2.9998), all build, no turn; 100 ft = 30.48 m
    assert well.dogleg_severity(mid)[0] == pytest.approx(math.degrees(30.0 / 573.0), rel=1e-9)
    assert well.dogleg_severity(mid, 30.48)[0] == pytest.approx(math.degrees(30.48 / 573.0),
                                                                rel=1e-9)
    assert np.degrees(well.build_rate(mid))[0] * 30 == pytest.approx(
        math.degrees(30.0 / 573.0), rel=1e-9)
    assert well.turn_rate(mid)[0] == pytest.approx(0.0, abs=1e-12)
    dist, az = well.closure()
    assert math.degrees(az) == pytest.approx(45.0, abs=1e-9)
    # closure: R (1 - cos 60) + 800 sin 60 of horizontal departure
    assert dist == pytest.approx(573.0 * 0.5 + 800.0 * math.sin(math.radians(60)), rel=1e-9)
    assert well.vertical_section(well.total_depth) == pytest.approx(dist, rel=1e-12)
    assert well.vertical_section(well.total_depth, math.radians(135.0)) == pytest.approx(
        0.0, abs=1e-6)


def test_build_and_turn_rates_integrate_to_the_station_changes():
    """Along each minimum-curvature interval of the J-shaped survey the point rates integrate
    to the change of inclination and azimuth between the stations."""
    well = _system("directional_survey.toml").well
    st = well.stations
    for a, b, ia, ib, aa, ab in zip(st["md"][:-1], st["md"][1:], st["inclination"][:-1],
                                    st["inclination"][1:], st["azimuth"][:-1],
                                    st["azimuth"][1:]):
        if ia < 1e-9 and ib < 1e-9:
            continue
        x, wq = np.polynomial.legendre.leggauss(40)
        md = 0.5 * (a + b) + 0.5 * (b - a) * x
        assert 0.5 * (b - a) * np.dot(wq, well.build_rate(md)) == pytest.approx(ib - ia,
                                                                                abs=1e-8)
        if ia > 1e-9:
            turn = (ab - aa + math.pi) % (2 * math.pi) - math.pi
            assert 0.5 * (b - a) * np.dot(wq, well.turn_rate(md)) == pytest.approx(turn,
                                                                                   abs=1e-8)


def test_survey_quantities_agree_with_welleng():
    pytest.importorskip("welleng")
    from welleng.survey import Survey, SurveyHeader

    well = _system("directional_survey.toml").well
    st = well.stations
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        s = Survey(md=st["md"], inc=np.degrees(st["inclination"]),
                   azi=np.degrees(st["azimuth"]), header=SurveyHeader(), deg=True)
    mid = 0.5 * (st["md"][:-1] + st["md"][1:])
    assert np.allclose(well.dogleg_severity(mid), s.dls[1:], atol=1e-9)
    assert np.allclose(st["tvd"], s.tvd, atol=1e-6)
    az = well.closure()[1]
    assert np.allclose(well.vertical_section(st["md"]),
                       s.get_vertical_section(az, deg=False), atol=1e-6)


# ------------------------------------------------------------------------------ hostile input
@pytest.mark.parametrize("kw,match", [
    ({"friction": -0.1}, "friction factor"), ({"friction": float("nan")}, "friction factor"),
    ({"friction": ()}, "at least one"), ({"friction": 11.0}, "at most 10"),
    ({"wob": -1.0}, "wob"), ({"tob": float("inf")}, "tob"), ({"step": 0.0}, "step"),
    ({"step": 1e-4}, "more than"), ({"friction": "x"}, "number")])
def test_bad_arguments_are_refused(kw, match):
    well = WellPath.from_sections([Vertical(1000.0)])
    string = DrillString.uniform(1000.0, pipe_section(0.12, 0.06))
    with pytest.raises(DownholeInputError, match=match):
        torque_drag(well, string, **kw)


def test_string_must_reach_the_surface():
    well = WellPath.from_sections([Vertical(1000.0)])
    with pytest.raises(DownholeInputError, match="from surface to the bit"):
        torque_drag(well, DrillString.uniform(800.0, pipe_section(0.12, 0.06)))


# ------------------------------------------------------------------------------------ the CLI
def _main(args):
    from downhole.cli import main

    return main([str(a) for a in args])


def test_cli_writes_the_table_and_figures(tmp_path):
    out = tmp_path / "td"
    assert _main(["torque-drag", EXAMPLES / "directional_survey.toml", "--out", out,
                  "--friction", "0.15,0.35"]) == 0
    for name in ("torque_drag.csv", "summary.json", "broomstick.png", "profiles.png",
                 "survey.png"):
        assert (out / name).stat().st_size > 0, name
    assert not (out / "INCOMPLETE").exists()
    with open(out / "torque_drag.csv", newline="") as fh:
        rows = list(csv.reader(fh))
    header = rows[0]
    assert header[:3] == ["md [m]", "tvd [m]", "north [m]"]
    assert all(h.endswith("]") for h in header)
    data = np.array(rows[1:], float)
    col = {h: data[:, k] for k, h in enumerate(header)}
    sysm = _system("directional_survey.toml")
    summ = json.loads((out / "summary.json").read_text())
    res = sysm.torque_drag(friction=(0.15, 0.35), wob=summ["wob_N"], tob=summ["tob_N_m"])
    assert col["md [m]"][-1] == pytest.approx(2700.0)
    assert col["tension_trip_out_mu0.35 [N]"][0] == pytest.approx(res.tension["trip_out"][1, 0],
                                                                  rel=1e-8)
    # the last row's hook load (bit at total depth) is the profile's top tension
    assert col["hook_load_trip_in_mu0.15 [N]"][-1] == pytest.approx(
        col["tension_trip_in_mu0.15 [N]"][0], rel=1e-8)
    assert col["surface_torque_drilling_mu0.35 [N*m]"][-1] == pytest.approx(
        col["torque_drilling_mu0.35 [N*m]"][0], rel=1e-8)
    assert summ["cases"]["trip_out"]["mu0.35"]["hook_load_N"] == pytest.approx(
        col["tension_trip_out_mu0.35 [N]"][0], rel=1e-8)
    # the set-points: WOB from [operation] rop = 10 mm/s (steady state), TOB from the bit law
    from downhole.scenario.system import steady_bit_state

    _, wob, tob = steady_bit_state(sysm.bit, 10.0, rop=0.01)
    assert summ["wob_N"] == pytest.approx(wob) and summ["tob_N_m"] == pytest.approx(tob)


BASE = (EXAMPLES / "directional_survey.toml").read_text()


def test_cli_oilfield_units_are_the_si_run_converted_by_pint(tmp_path):
    """``--units oilfield``: every CSV column is the SI run's column converted by an independent
    pint registry (ft, klbf, kft*lbf, lbf/ft, deg/100ft), headers naming the units; summary.json
    names the system."""
    import pint

    ureg = pint.UnitRegistry()
    si, oil = tmp_path / "si", tmp_path / "oil"
    scen = EXAMPLES / "directional_survey.toml"
    assert _main(["torque-drag", scen, "--out", si, "--friction", "0.2"]) == 0
    assert _main(["torque-drag", scen, "--out", oil, "--friction", "0.2", "--units",
                  "oilfield"]) == 0

    def table(path):
        with open(path / "torque_drag.csv", newline="") as fh:
            rows = list(csv.reader(fh))
        data = np.array([[float(x) if x else np.nan for x in r] for r in rows[1:]])
        return rows[0], data

    hs, ds = table(si)
    ho, do = table(oil)
    assert len(hs) == len(ho)
    to = {"m": "ft", "N": "kip", "N*m": "kip*ft", "N/m": "lbf/ft", "deg": "deg"}
    for k, (a, b) in enumerate(zip(hs, ho)):
        base, unit = a[:-1].split(" [")
        assert b.startswith(base + " ["), (a, b)
        if a.startswith("dls "):  # both DLS columns are kept as they are
            np.testing.assert_allclose(do[:, k], ds[:, k], rtol=1e-9)
            continue
        if unit == "deg/30m":  # build and turn rates: deg per 30 m -> deg per 100 ft
            assert b.endswith("[deg/100ft]")
            ref = (ureg.Quantity(ds[:, k], "deg") / ureg.Quantity(30.0, "m")).to(
                "deg/ft").magnitude * 100.0
        else:
            ref = ureg.Quantity(ds[:, k], unit).to(to[unit]).magnitude
        np.testing.assert_allclose(do[:, k], ref, rtol=1e-8, atol=1e-9, err_msg=a)
    assert "tension_trip_out_mu0.2 [klbf]" in ho and "torque_rotating_mu0.2 [kft*lbf]" in ho
    summ = json.loads((oil / "summary.json").read_text())
    assert summ["units"]["system"] == "oilfield"


@pytest.mark.parametrize("edit,args,expect", [
    (None, ["--friction", "0.1,x"], "--friction"),
    (None, ["--friction", "-0.2"], "between 0 and 10"),
    ("\n[torque_drag]\nfriction_factors = [0.1, -1]\n", [], "torque_drag.friction_factors"),
    ("\n[torque_drag]\nstep = \"0 m\"\n", [], "torque_drag.step"),
    ("\n[torque_drag]\nbogus = 1\n", [], "torque_drag.bogus"),
    ("\n[torque_drag]\nwob = \"900 MN\"\n", [], "torque_drag.wob: 900 MN = 900,000 kN is above 700 kN"),
    ("\n[torque_drag]\nwob = \"0 N\"\n", [], "torque_drag.wob"),
    ("\n[torque_drag]\nfriction_factors = [true]\n", [], "expected numbers"),
    ("\n[torque_drag]\nvertical_section_azimuth = \"1e9 deg\"\n", [],
     "torque_drag.vertical_section_azimuth"),
])
def test_cli_bad_input_one_line_exit_2_nothing_written(tmp_path, capsys, edit, args, expect):
    scen = EXAMPLES / "directional_survey.toml"
    if edit is not None:
        scen = tmp_path / "directional_survey.toml"
        scen.write_text(BASE + edit)
        (tmp_path / "directional_survey_well.csv").write_text(
            (EXAMPLES / "directional_survey_well.csv").read_text())
    out = tmp_path / "out"
    assert _main(["torque-drag", scen, "--out", out, *args]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error:") and expect in err and "\n" not in err, err
    assert not out.exists()


def test_cli_refuses_a_preset_scenario_a_short_string_and_a_file_as_out(tmp_path, capsys):
    out = tmp_path / "out"
    assert _main(["torque-drag", EXAMPLES / "stickslip-lumped.toml", "--out", out]) == 2
    assert "describes the system" in capsys.readouterr().err
    short = tmp_path / "short.toml"
    short.write_text((EXAMPLES / "table_5_1.toml").read_text().replace(
        'kind = "pipe"                  # the whole well',
        'kind = "pipe"\nlength = "4000 m"'))
    assert _main(["torque-drag", short, "--out", out]) == 2
    assert "string.segments" in capsys.readouterr().err
    assert _main(["torque-drag", tmp_path / "missing.toml", "--out", out]) == 2
    capsys.readouterr()
    assert not out.exists()
    f = tmp_path / "file"
    f.write_text("x")
    assert _main(["torque-drag", EXAMPLES / "table_5_1.toml", "--out", f]) == 2
    assert "expected a folder" in capsys.readouterr().err
    assert f.read_text() == "x"


def test_profiles_of_one_case_and_friction():
    res = DrillingSystem.table_5_1().torque_drag(friction=(0.1, 0.3), hook_load=False)
    prof = res.at("rotating", 0.3)
    assert np.array_equal(prof["tension"], res.tension["rotating"][1])
    assert res.bit_depth.size == 0
    with pytest.raises(DownholeInputError, match="was not computed"):
        res.at("rotating", 0.2)
    with pytest.raises(DownholeInputError, match="case must be one of"):
        res.at("sliding", 0.1)


def test_many_nodes_spread_the_hook_load_depths(monkeypatch, tmp_path):
    """Above MAX_BIT_DEPTHS nodes the hook-load curves use evenly spread nodes with the total
    depth; the CSV leaves the other rows' hook-load cells empty."""
    import downhole.string.torque_drag as tdm
    from downhole.analysis.torque_drag import torque_drag_table, write_csv

    monkeypatch.setattr(tdm, "MAX_BIT_DEPTHS", 40)
    sysm = DrillingSystem.table_5_1()
    res = sysm.torque_drag(friction=0.2, step=20.0)
    assert res.bit_depth.size == 40 and res.bit_depth[-1] == pytest.approx(res.md[-1])
    assert np.all(np.isin(res.bit_depth, res.md))
    assert res.hook_load["trip_out"][0, -1] == pytest.approx(res.tension["trip_out"][0, 0])
    cols = torque_drag_table(res, sysm.well)
    hl = cols["hook_load_trip_out_mu0.2 [N]"]
    assert np.sum(np.isfinite(hl)) == 41 and hl[0] == 0.0
    write_csv(tmp_path / "t.csv", cols)
    with open(tmp_path / "t.csv", newline="") as fh:
        rows = list(csv.reader(fh))
    k = rows[0].index("hook_load_trip_out_mu0.2 [N]")
    assert sum(r[k] == "" for r in rows[1:]) == res.md.size - 41


def test_the_table_module_names_the_same_cases():
    from downhole.analysis import torque_drag as table

    assert table.CASES == CASES
    from downhole.string.torque_drag import CASE_LABELS

    assert table.CASE_LABELS == CASE_LABELS
