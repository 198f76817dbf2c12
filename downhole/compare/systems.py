"""The drilling systems of the controller benchmark, each a
:class:`~downhole.system.DrillingSystem`.

Every system is described in full here (well sections or survey stations, string segments, bit
preset, rig), so that a suite version fixes them; :func:`describe_system` turns one into the
JSON-able description that ``scores.json`` carries with each case.

``ch2``
    Chapter 2's vertical string in physical form: the 4th-order lumped model's "plausible"
    geometry (preset ``plausible_lumped``: 2500 m of 5" drill pipe over 200 m of 6 3/4"
    collars) with the Table 2.1 bit, in a 2700 m vertical well.
``ch3``
    Chapter 3's vertical string (Table 3.1, corrected): 1000 m of the 120/60 mm pipe over a BHA
    of 8" collars carrying the table's 30 t bit mass (103 m), Table 3.1 bit.
``table_5_1``
    The Table 5.1 directional well and string (:meth:`DrillingSystem.table_5_1`: 2000 m
    vertical, 1000 m vertical, 30 deg arc of radius 4000 m; 120/60 mm pipe; wall friction 0.5).
``j_survey``
    The J-shaped survey well of ``examples/directional_survey.toml`` (vertical to 1500 m, build
    at 3 deg/30 m to 45 deg with a slight turn, hold to 2700 m MD; stations copied below) with
    its string: 2400 m of 5" pipe, 150 m of 5" heavyweight, 6.5" collars to the bit, a near-bit
    stabilizer, 1200 kg/m^3 mud; wall friction 0.3.
``horizontal_3000``
    A 3000 m (MD) horizontal well: 600 m vertical, a 90 deg build of radius 600 m (942.5 m,
    2.86 deg/30 m) and a 1457.5 m horizontal lateral; 2850 m of 5" pipe over
    150 m of 6.5" collars, 1200 kg/m^3 mud, wall friction 0.25.
"""

from __future__ import annotations

import math
from functools import cache

from downhole.errors import DownholeInputError
from downhole.params import get_preset
from downhole.params.rig import Hook, TopDrive
from downhole.string.drillstring import DrillString, Stabilizer, StringSegment, pipe_section
from downhole.system import DrillingSystem, Rig
from downhole.well.path import Arc, Tangent, Vertical, WellPath

__all__ = ["J_SURVEY_STATIONS", "SYSTEMS", "build_system", "describe_system"]

INCH = 0.0254

#: Survey stations (MD m, inclination deg, azimuth deg) of examples/directional_survey_well.csv.
J_SURVEY_STATIONS = ((0.0, 0.0, 0.0), (500.0, 0.0, 0.0), (1000.0, 0.0, 0.0), (1500.0, 0.0, 0.0),
                     (1650.0, 15.0, 30.0), (1800.0, 30.0, 32.0), (1950.0, 45.0, 35.0),
                     (2100.0, 45.0, 35.0), (2400.0, 45.0, 35.0), (2700.0, 45.0, 35.0))

#: The rig of every case: Table 5.1's top drive (J = 500 kg m^2, a stiff PI Kp = 1e4 N m s/rad,
#: Ki = 2e3 N m/rad) and the default hook servo.
def _rig() -> Rig:
    return Rig(TopDrive(inertia=500.0, kp=1e4, ki=2e3), Hook())


def _ch2() -> DrillingSystem:
    pipe = pipe_section(0.127, 0.1086)
    collar = pipe_section(0.171, 0.0714)
    string = DrillString((StringSegment(2500.0, pipe), StringSegment(200.0, collar, "collar")))
    return DrillingSystem.vertical(string, get_preset("table_2_1").bit, rig=_rig(),
                                   friction=0.0)


def _ch3() -> DrillingSystem:
    p = get_preset("table_3_1").string
    collar = pipe_section(8 * INCH, 2.8125 * INCH)
    bha_length = round(p.bit_mass / (collar.density * collar.area), 1)
    string = DrillString((StringSegment(float(p.length), p.pipe),
                          StringSegment(bha_length, collar, "collar")))
    return DrillingSystem.vertical(string, get_preset("table_3_1").bit, rig=_rig(),
                                   friction=0.0)


def _table_5_1() -> DrillingSystem:
    return DrillingSystem.table_5_1(rig=_rig())


def _j_survey() -> DrillingSystem:
    md, inc, azi = zip(*J_SURVEY_STATIONS)
    well = WellPath.from_survey(md, inc, azi, degrees=True)
    pipe = pipe_section(5 * INCH, 4.276 * INCH)
    hw = pipe_section(5 * INCH, 3 * INCH)
    collar = pipe_section(6.5 * INCH, 2.8125 * INCH)
    rest = well.total_depth - 2400.0 - 150.0
    string = DrillString((StringSegment(2400.0, pipe), StringSegment(150.0, hw, "heavyweight"),
                          StringSegment(rest, collar, "collar")),
                         (Stabilizer(2.0, 8.5 * INCH),), mud_density=1200.0)
    return DrillingSystem(well=well, string=string, bit=get_preset("table_5_1").bit, rig=_rig(),
                          friction=0.3)


def _horizontal_3000() -> DrillingSystem:
    well = WellPath.from_sections([Vertical(600.0), Arc(600.0, math.pi / 2),
                                   Tangent(3000.0 - 600.0 - 600.0 * math.pi / 2)])
    pipe = pipe_section(5 * INCH, 4.276 * INCH)
    collar = pipe_section(6.5 * INCH, 2.8125 * INCH)
    string = DrillString((StringSegment(2850.0, pipe), StringSegment(150.0, collar, "collar")),
                         (Stabilizer(2.0, 8.5 * INCH),), mud_density=1200.0)
    return DrillingSystem(well=well, string=string, bit=get_preset("table_5_1").bit, rig=_rig(),
                          friction=0.25)


#: System key -> builder.
SYSTEMS = {"ch2": _ch2, "ch3": _ch3, "table_5_1": _table_5_1, "j_survey": _j_survey,
           "horizontal_3000": _horizontal_3000}


@cache
def _base(key: str) -> DrillingSystem:
    try:
        return SYSTEMS[key]()
    except KeyError:
        raise DownholeInputError(f"unknown benchmark system {key!r}; known: "
                                 f"{sorted(SYSTEMS)}") from None


def build_system(key: str, epsilon_scale: float = 1.0) -> DrillingSystem:
    """The benchmark system ``key`` with the bit's intrinsic specific energy epsilon scaled by
    ``epsilon_scale`` (the rock is harder or softer than the nominal)."""
    from dataclasses import replace

    base = _base(key)
    if epsilon_scale == 1.0:
        return base
    bit = base.bit.model_copy(update={"epsilon": base.bit.epsilon * float(epsilon_scale)})
    return replace(base, bit=bit)


def _section(s) -> dict:
    return {"outer_diameter": s.outer_diameter, "inner_diameter": s.inner_diameter,
            "young_modulus": s.young_modulus, "shear_modulus": s.shear_modulus,
            "density": s.density}


def describe_system(system: DrillingSystem) -> dict:
    """A JSON-able description of ``system``: well stations, string, bit, rig and constants."""
    st = system.well.stations
    well = {"total_depth": system.well.total_depth,
            "stations": {k: [float(x) for x in v] for k, v in st.items()}}
    string = {"segments": [{"kind": s.kind, "length": s.length, **_section(s.section)}
                           for s in system.string.segments],
              "stabilizers": [{"distance_from_bit": s.distance_from_bit,
                               "outer_diameter": s.outer_diameter}
                              for s in system.string.stabilizers],
              "mud_density": system.string.mud_density, "g": system.string.g}
    td, hk = system.rig.top_drive, system.rig.hook
    rig = {"top_drive": {"inertia": td.inertia, "kp": td.kp, "ki": td.ki,
                         "soft_gain": td.soft_gain, "soft_tau": td.soft_tau},
           "hook": {"servo_stiffness": hk.servo_stiffness, "servo_damping": hk.servo_damping,
                    "block_mass": hk.block_mass}}
    return {"well": well, "string": string, "bit": system.bit.model_dump(mode="json"),
            "rig": rig, "friction": system.friction, "rayleigh_alpha": system.rayleigh_alpha,
            "rayleigh_beta": system.rayleigh_beta}
