"""The benchmark's cases and its versioned suites (``standard``, ``smoke``).

A :class:`Case` fixes everything about one run: the system (:mod:`downhole.compare.systems`),
the operating point (speed set-point, and WOB through a force-driven hook or ROP through a
velocity-driven one), the rock (epsilon scale), the sensors (noise) and the actuator (delay),
the start (``rest``, ``steady``, or ``stick_slip``: a developed cycle under the stiff PI, then
the hand-over) and the durations. ``scores.json`` carries each case's :meth:`Case.definition`
(with the system's full description) beside its scores, and the suite's name and version.

A suite's version changes whenever one of its cases (or a system) changes, so that scores with
the same suite name and version are comparable.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

from downhole.errors import DownholeInputError

__all__ = ["NOISE", "SUITES", "SUITE_VERSIONS", "Case", "get_suite"]

#: Sensor noise of the cases with ``noise=True``: standard deviations (signal units) of white
#: Gaussian noise on every measurement a controller may read.
NOISE = {"surface_torque": 200.0, "hook_load": 2e3, "top_drive_angular_velocity": 0.05,
         "bit_angular_velocity": 0.2, "bit_axial_velocity": 5e-4, "wob": 2e3, "tob": 100.0}


@dataclass(frozen=True)
class Case:
    """One benchmark case (see the module docstring).

    Parameters
    ----------
    id : str
    system : str
        Key of :data:`downhole.compare.systems.SYSTEMS`.
    speed : float
        Speed set-point (rad/s).
    wob : float
        ``hook="force"``: weight on bit through the hook (N; hook load = buoyed weight - wob);
        ``"velocity"``: the static WOB of the rest start.
    hook : {"force", "velocity"}
    rop : float, optional
        ``hook="velocity"``: block velocity = ROP set-point (m/s).
    epsilon_scale : float
        Intrinsic specific energy of the rock relative to the bit's nominal.
    noise : bool
        Sensor noise :data:`NOISE` on.
    delay : float
        Actuator delay, s (0.02 in the noisy cases).
    start : {"rest", "steady", "stick_slip"}
    pre_time : float
        ``stick_slip``: seconds of stiff PI before the hand-over.
    duration : float
        Seconds under the controller.
    n_elements : int
        FEM elements.
    dt : float
        Plant step, s.
    seed : int
        Noise seed.
    region : str
        What the stiff PI does there (``"stick-slip"`` or ``"smooth"``): the operating point's
        label, measured when the suite was made (documentation, not a score).
    """

    id: str
    system: str
    speed: float
    wob: float
    hook: str = "force"
    rop: float | None = None
    epsilon_scale: float = 1.0
    noise: bool = False
    delay: float = 0.0
    start: str = "rest"
    pre_time: float = 0.0
    duration: float = 30.0
    n_elements: int = 60
    dt: float = 1e-3
    seed: int = 0
    region: str = ""

    def __post_init__(self):
        from downhole.compare.systems import SYSTEMS

        if self.system not in SYSTEMS:
            raise DownholeInputError(f"case {self.id}: unknown system {self.system!r}; known: "
                                     f"{sorted(SYSTEMS)}")
        if self.hook not in ("force", "velocity"):
            raise DownholeInputError(f"case {self.id}: hook must be 'force' or 'velocity'")
        if self.hook == "velocity" and not (self.rop and self.rop > 0):
            raise DownholeInputError(f"case {self.id}: a velocity-driven hook needs rop > 0")
        if self.start not in ("rest", "steady", "stick_slip"):
            raise DownholeInputError(f"case {self.id}: start must be rest, steady or "
                                     f"stick_slip, got {self.start!r}")
        if self.start == "stick_slip" and not self.pre_time > 0:
            raise DownholeInputError(f"case {self.id}: a stick_slip start needs pre_time > 0")
        for name in ("speed", "duration", "dt", "epsilon_scale"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise DownholeInputError(f"case {self.id}: {name} must be > 0, got {v!r}")
        for name in ("delay", "pre_time", "wob"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
                raise DownholeInputError(f"case {self.id}: {name} must be >= 0, got {v!r}")

    # ------------------------------------------------------------------ derived
    @property
    def handover_time(self) -> float:
        """When the controller takes over, s (0 unless the start is a developed cycle)."""
        return self.pre_time if self.start == "stick_slip" else 0.0

    @property
    def delay_steps(self) -> int:
        return int(round(self.delay / self.dt))

    def noise_levels(self) -> dict:
        return dict(NOISE) if self.noise else {}

    def drilling_system(self):
        """The case's :class:`~downhole.system.DrillingSystem`."""
        from downhole.compare.systems import build_system

        return build_system(self.system, self.epsilon_scale)

    def reference_rop(self) -> float:
        """The ROP reference: the set-point (velocity hook) or the steady ROP of the bit law at
        the case's WOB and speed with the approximated depth of cut (force hook), m/s."""
        if self.hook == "velocity":
            return float(self.rop)
        return steady_rop(self.drilling_system().bit, self.speed, self.wob)

    def definition(self) -> dict:
        """JSON-able definition: every field, the derived reference and the system's full
        description."""
        from downhole.compare.systems import describe_system

        d = asdict(self)
        d["reference_rop"] = self.reference_rop()
        d["noise_levels"] = self.noise_levels()
        d["system_description"] = describe_system(self.drilling_system())
        return d


def steady_rop(bit, speed: float, wob: float) -> float:
    """ROP (m/s) at which the bit law gives ``wob`` at ``speed`` with d = 2 pi v / omega."""
    from scipy.optimize import brentq

    from downhole.bit.law import bit_forces_py

    def f(v):
        return bit_forces_py(2 * math.pi * v / speed, v, speed, bit)[0] - wob

    if f(1.0) < 0:
        raise DownholeInputError(f"WOB {wob:g} N is not reached at any ROP up to 1 m/s")
    return float(brentq(f, 1e-12, 1.0, xtol=1e-14, rtol=1e-12))


def _c(**kw) -> Case:
    return Case(**kw)


_NOISY = dict(noise=True, delay=0.02)

# The standard suite. Operating points: "stick-slip" where the stiff PI sticks, "smooth" where
# it does not (labels measured with suite version 1; see docs/compare-controllers.md).
_STANDARD = (
    # Ch. 2 vertical string, 2700 m
    _c(id="ch2-ss-rest", system="ch2", speed=5.0, wob=100e3, start="rest", duration=30.0,
       region="stick-slip"),
    _c(id="ch2-ss-cycle-noisy", system="ch2", speed=5.0, wob=100e3, start="stick_slip",
       pre_time=15.0, duration=30.0, region="stick-slip", seed=1, **_NOISY),
    _c(id="ch2-smooth-steady", system="ch2", speed=15.0, wob=60e3, start="steady",
       duration=20.0, region="smooth"),
    # Ch. 3 vertical string, 1134 m; velocity-driven hook (ROP set-point) as in Ch. 3
    _c(id="ch3-rop-ss-rest", system="ch3", speed=5.0, wob=50e3, hook="velocity", rop=8e-3,
       start="rest", duration=20.0, region="stick-slip"),
    _c(id="ch3-rop-smooth-steady-noisy", system="ch3", speed=20.0, wob=50e3, hook="velocity",
       rop=10e-3, start="steady", duration=20.0, region="smooth", seed=2, **_NOISY),
    _c(id="ch3-wob-ss-cycle", system="ch3", speed=5.0, wob=60e3, start="stick_slip",
       pre_time=10.0, duration=20.0, region="stick-slip"),
    # Table 5.1 directional well, 5094 m
    _c(id="t51-ss-rest", system="table_5_1", speed=10.0, wob=120e3, start="rest",
       duration=30.0, n_elements=107, region="stick-slip"),
    _c(id="t51-ss-cycle-noisy", system="table_5_1", speed=10.0, wob=120e3, start="stick_slip",
       pre_time=20.0, duration=30.0, n_elements=107, region="stick-slip", seed=3, **_NOISY),
    _c(id="t51-ss-eps50", system="table_5_1", speed=10.0, wob=120e3, epsilon_scale=0.5,
       start="stick_slip", pre_time=20.0, duration=30.0, n_elements=107, region="stick-slip"),
    _c(id="t51-ss-eps300", system="table_5_1", speed=10.0, wob=150e3, epsilon_scale=3.0,
       start="stick_slip", pre_time=20.0, duration=30.0, n_elements=107, region="stick-slip"),
    _c(id="t51-smooth-steady", system="table_5_1", speed=20.0, wob=60e3, start="steady",
       duration=20.0, n_elements=107, region="smooth"),
    # J-shaped survey well, 2700 m MD
    _c(id="j-ss-cycle", system="j_survey", speed=6.0, wob=100e3, start="stick_slip",
       pre_time=15.0, duration=30.0, region="stick-slip"),
    _c(id="j-smooth-steady-noisy", system="j_survey", speed=15.0, wob=60e3, start="steady",
       duration=20.0, region="smooth", seed=4, **_NOISY),
    # 3000 m horizontal well
    _c(id="hz-ss-cycle-noisy", system="horizontal_3000", speed=6.0, wob=60e3,
       start="stick_slip", pre_time=15.0, duration=30.0, region="stick-slip", seed=5,
       **_NOISY),
    _c(id="hz-smooth-steady", system="horizontal_3000", speed=15.0, wob=40e3, start="steady",
       duration=20.0, region="smooth"),
)

# The smoke suite: one short stick-slip case on the short Ch. 3 string, with sensor noise and
# the actuator delay (seconds to run).
_SMOKE = (
    _c(id="smoke-ch3-ss-noisy", system="ch3", speed=5.0, wob=60e3, start="stick_slip",
       pre_time=4.0, duration=8.0, n_elements=20, region="stick-slip", seed=7, **_NOISY),
)

#: Suite name -> cases.
SUITES = {"standard": _STANDARD, "smoke": _SMOKE}
#: Suite name -> version (bump on any change of its cases or systems).
SUITE_VERSIONS = {"standard": 1, "smoke": 1}


def get_suite(name: str) -> tuple:
    """The cases of suite ``name``."""
    try:
        return SUITES[name]
    except KeyError:
        raise DownholeInputError(f"unknown suite {name!r}; known: {sorted(SUITES)}") from None
