"""One description of a drilling system, from which every model fidelity is built.

A :class:`DrillingSystem` holds the well (sections or survey), the drill string (sections, mud),
the bit (law and parameters), the rig (top drive, hook) and the wellbore and damping constants.
:meth:`DrillingSystem.build` turns it into the model of a chosen fidelity
(:data:`FIDELITIES`): the seed's 4th- and 12th-order lumped chains, the neutral-type wave model,
the FEM and the hybrid FEM + wave-segment model, so that one physical string runs at every
fidelity.

How the reduced models are derived (``docs/architecture.md``, "One description, every
fidelity"):

* **FEM** and **hybrid** mesh the description itself.
* **lumped4 / lumped12**: per field (axial, torsional) the chain's stiffness to the top drive is
  the string's static stiffness, top clamped and load at the bit (1/k = sum L_i / (E_i A_i),
  resp. L_i / (G_i J_i)); its mass (inertia) is chosen so that the chain's first natural
  frequency, top clamped, equals the string's (from a fine FEM of the description). The
  absolute damper carries the string's mass-proportional (Rayleigh alpha) damping force, so the
  steady forces match; a damper to the top drive adds what the first mode's damping ratio
  (alpha / (2 w1) + beta w1 / 2) still needs. The hook carries the string's buoyed weight.
* **neutral**: the string above the BHA (collars, "bha" segments; or, without a BHA, the
  bottom ``lump_length`` of the string) is the wave segment and must be one uniform pipe; the
  rest is lumped into the bit mass and inertia. The top dampers are the rig's: the top drive's
  proportional gain (N m s/rad) and the hook servo's damping (N s/m).

Features a fidelity cannot represent raise :class:`~downhole.errors.DownholeInputError` naming
the feature: wall contact (a deviated well with friction) in the lumped and neutral models, an
inclined or curved wave segment in the hybrid model, several pipe sections in the neutral line.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from functools import partial

import numpy as np

from downhole.errors import DownholeInputError
from downhole.errors import positive_number as _positive
from downhole.params import BitParams, LumpedParams
from downhole.params.rig import Hook, TopDrive
from downhole.params.strings import NeutralStringParams
from downhole.string.drillstring import DrillString, StringSegment
from downhole.units import si_or_number
from downhole.well.path import WellPath

__all__ = ["BUILD_OPTIONS", "FIDELITIES", "DrillingSystem", "LumpedDerivation", "Rig",
           "steady_bit_state", "wave_points"]

#: The heaviest string a rig can hold, N (1,000 t; the largest land and offshore rigs are rated
#: 1,000-1,400 short tons): a described string heavier than this is a mistake of units or
#: lengths, refused with both named.
MAX_STRING_WEIGHT = 1.0e7

#: Model fidelities a description can be built at.
FIDELITIES = ("lumped4", "lumped12", "neutral", "fem", "hybrid")

_BHA_KINDS = ("collar", "bha")

#: The options of :meth:`DrillingSystem.build` per fidelity and their defaults: the keys (and
#: defaults) of the scenario tables ``[model.<fidelity>]`` (tested against the schema).
BUILD_OPTIONS = {
    "lumped4": {"reference_elements": 400},
    "lumped12": {"reference_elements": 400},
    "neutral": {},
    "fem": {"n_elements": None, "max_element_length": 50.0,
            "max_element_angle": math.radians(2.0), "mass": "consistent"},
    "hybrid": {"preset": None, "n_ab": None, "n_cd": None, "n_lags": 0,
               "max_element_length": 50.0, "max_element_angle": math.radians(2.0),
               "mass": "consistent"},
}


def wave_points(well: WellPath, string: DrillString) -> tuple[float, float]:
    """Default measured depths (B, C) of the hybrid model's wave segment for ``string`` hanging
    in ``well`` (bit at total depth): B at two thirds and C at the end of the vertical part
    above the kick-off point (the station before the first inclined one), or at two thirds and
    90 % of the string when the well is vertical.

    Parameters
    ----------
    well : WellPath
        The well (bit at its total depth).
    string : DrillString
        The string hanging in it.

    Returns
    -------
    tuple of (float, float)
        Measured depths of B and C, m.
    """
    st = well.stations
    top = well.total_depth - string.length
    below = st["md"] > top + 1e-9
    dev = np.nonzero(below & (np.sin(st["inclination"]) > 1e-6))[0]
    if dev.size == 0:
        return top + 2.0 / 3.0 * string.length, top + 0.9 * string.length
    kop = max(float(st["md"][dev[0] - 1]) if dev[0] > 0 else top, top)
    return top + 2.0 / 3.0 * (kop - top), kop


def steady_bit_state(bit, surface_speed: float, rop: float | None = None,
                     wob: float | None = None) -> tuple[float, float, float]:
    """``(rop, wob, tob)`` of steady cutting at ``surface_speed`` with the approximate depth of
    cut d = 2 pi v / omega (Eq. 2.11): from the ROP, or the ROP that gives ``wob``.

    Raises
    ------
    DownholeInputError
        When no ROP up to 1 m/s reaches ``wob``.
    """
    from scipy.optimize import brentq

    from downhole.bit.law import bit_forces_py

    def forces(v):
        d = 2 * math.pi * v / max(surface_speed, bit.omega_floor)
        return bit_forces_py(d, v, surface_speed, bit)

    if rop is None:
        hi = 1.0
        if forces(hi)[0] < wob:
            raise DownholeInputError(f"operation.wob = {wob:g} N is not reached at any ROP up "
                                     f"to {hi:g} m/s with this bit at {surface_speed:g} rad/s")
        rop = brentq(lambda v: forces(v)[0] - wob, 1e-12, hi, xtol=1e-14, rtol=1e-12)
    w, t = forces(rop)
    return float(rop), float(w), float(t)


@dataclass(frozen=True)
class Rig:
    """The rig's side of the string's top boundary: top drive and hook.

    Attributes
    ----------
    top_drive : TopDrive
        Inertia and speed controller (PI gains: the proportional gain is also the neutral
        model's torsional top damper).
    hook : Hook
        Hook / drawworks (its servo damping is the neutral model's axial top damper).
    """

    top_drive: TopDrive = field(default_factory=TopDrive)
    hook: Hook = field(default_factory=Hook)


@dataclass(frozen=True)
class LumpedDerivation:
    """How a lumped chain was matched to the string (per field: axial, torsional).

    Attributes
    ----------
    stiffness : tuple of float
        Static stiffness, top clamped, load at the bit: N/m and N m/rad.
    first_frequency : tuple of float
        First natural frequency of the string (and of the chain), top clamped, Hz.
    mass : tuple of float
        Chain mass (kg) and inertia (kg m^2).
    string_mass : tuple of float
        The string's total mass and polar inertia.
    damping_ratio : tuple of float
        First-mode damping ratio of the string's Rayleigh damping.
    """

    stiffness: tuple
    first_frequency: tuple
    mass: tuple
    string_mass: tuple
    damping_ratio: tuple


@dataclass(frozen=True)
class DrillingSystem:
    """A well, a drill string, a bit and a rig: the one description of a drilling system.

    Parameters
    ----------
    well : WellPath
        Trajectory; the bit sits at its total depth.
    string : DrillString
        Segments from surface to bit, stabilizers, mud density.
    bit : BitParams
        Bit law and parameters.
    rig : Rig
        Top drive and hook.
    friction : float
        Wellbore (soft-string) friction coefficient; 0 (default) disables wall contact.
    rayleigh_alpha, rayleigh_beta : float
        String damping alpha0 M + beta0 K (1/s and s).
    lump_length : float
        Without a BHA in the string: length (m) at the bottom lumped into the bit for the neutral
        model.
    wave_section : tuple of float, optional
        Measured depths (B, C) of the hybrid model's wave segment; default: see
        :meth:`wave_points`.

    Examples
    --------
    >>> sysm = DrillingSystem.table_5_1()
    >>> [f for f in FIDELITIES]
    ['lumped4', 'lumped12', 'neutral', 'fem', 'hybrid']
    >>> sysm.build("fem", n_elements=107).n_states     # the seed's 432-state FEM
    432
    >>> sysm.build("fem").n_states     # derived from the description: 102 elements <= 50 m
    412
    """

    well: WellPath
    string: DrillString
    bit: BitParams
    rig: Rig = field(default_factory=Rig)
    friction: float = 0.0
    rayleigh_alpha: float = 0.05
    rayleigh_beta: float = 0.03
    lump_length: float = 10.0
    wave_section: tuple | None = None

    def __post_init__(self):
        if not isinstance(self.well, WellPath):
            raise DownholeInputError(f"well must be a WellPath, got {type(self.well).__name__}")
        if not isinstance(self.string, DrillString):
            raise DownholeInputError(f"string must be a DrillString, got "
                                     f"{type(self.string).__name__}")
        if not isinstance(self.bit, BitParams):
            raise DownholeInputError(f"bit must be BitParams, got {type(self.bit).__name__}")
        object.__setattr__(self, "lump_length", si_or_number(self.lump_length, "length",
                                                             "lump_length"))
        if isinstance(self.wave_section, (tuple, list)):
            object.__setattr__(self, "wave_section", tuple(
                si_or_number(x, "length", "wave_section") for x in self.wave_section))
        _positive("friction", self.friction, allow_zero=True)
        _positive("rayleigh_alpha", self.rayleigh_alpha, allow_zero=True)
        _positive("rayleigh_beta", self.rayleigh_beta, allow_zero=True)
        _positive("lump_length", self.lump_length)
        if self.string.length > self.well.total_depth + 1e-6:
            raise DownholeInputError(f"string length {self.string.length:g} m exceeds the well's "
                                     f"total depth {self.well.total_depth:g} m")
        weight = sum(seg.length * float(self.string.buoyed_weight_per_length(s0 + 0.5 * seg.length))
                     for seg, s0 in zip(self.string.segments, self.string.boundaries[:-1]))
        if weight > MAX_STRING_WEIGHT:
            raise DownholeInputError(
                f"the string weighs {weight / 1e3:,.0f} kN ({weight / 4448.2216:,.0f} klbf) in "
                f"the mud, beyond any rig's hook capacity ({MAX_STRING_WEIGHT / 1e3:,.0f} kN, "
                f"{MAX_STRING_WEIGHT / 4448.2216:,.0f} klbf): check the string's segment lengths "
                f"({self.string!r}) and the well's depth units ({self.well.total_depth:,.0f} m "
                "deep; a survey in feet read as metres?)")

    # ------------------------------------------------------------------ presets
    @classmethod
    def table_5_1(cls, **changes) -> DrillingSystem:
        """The seed's Table 5.1 well, string and bit (corrected), with its top drive."""
        from downhole.params import get_preset
        from downhole.string.fem import table_5_1_setup

        well, string, bit, p = table_5_1_setup()
        rig = Rig(TopDrive(inertia=p.top_drive_inertia, kp=p.top_drive_kp, ki=p.top_drive_ki))
        base = dict(well=well, string=string, bit=bit or get_preset("table_5_1").bit, rig=rig,
                    friction=p.wellbore_friction, rayleigh_alpha=p.rayleigh_alpha,
                    rayleigh_beta=p.rayleigh_beta, wave_section=(p.length_ab,
                                                                 p.length_ab + p.length_bc))
        base.update(changes)
        return cls(**base)

    @classmethod
    def vertical(cls, string: DrillString, bit: BitParams | None = None,
                 **changes) -> DrillingSystem:
        """A vertical well exactly as deep as ``string`` is long."""
        from downhole.params import get_preset
        from downhole.well.path import Vertical

        well = WellPath.from_sections([Vertical(string.length)])
        return cls(well=well, string=string, bit=bit or get_preset("table_5_1").bit, **changes)

    # ------------------------------------------------------------------ geometry
    @property
    def top_md(self) -> float:
        """Measured depth of the top of the string, m."""
        return self.well.total_depth - self.string.length

    def _deviated_length(self) -> float:
        md = np.linspace(self.top_md, self.well.total_depth, 2001)
        inc = np.asarray(self.well.inclination(md), float)
        return float(np.sum(np.sin(inc[:-1]) > 1e-6) * (md[1] - md[0]))

    def _needs_contact(self, fidelity: str) -> None:
        dev = self._deviated_length()
        if self.friction > 0 and dev > 0:
            raise DownholeInputError(
                f"fidelity {fidelity!r} cannot represent wall contact: the well is deviated over "
                f"{dev:.0f} m with friction {self.friction:g}; set friction = 0 (no contact) or "
                "choose fidelity 'fem' or 'hybrid'")

    def wave_points(self) -> tuple[float, float]:
        """Measured depths (B, C) of the hybrid model's wave segment.

        ``wave_section`` when given; otherwise :func:`wave_points` of the well and string: B at
        two thirds and C at the end of the vertical part above the kick-off point (Table 5.1:
        2000 and 3000 m), or at two thirds and 90 % of a vertical string."""
        if self.wave_section is not None:
            return float(self.wave_section[0]), float(self.wave_section[1])
        return wave_points(self.well, self.string)

    # ------------------------------------------------------------------ builders
    def build(self, fidelity: str, **options):
        """The model of this system at ``fidelity``.

        Parameters
        ----------
        fidelity : {"lumped4", "lumped12", "neutral", "fem", "hybrid"}
        **options
            The keywords of the scenario tables ``[model.<fidelity>]``, with the same names and
            defaults (:data:`BUILD_OPTIONS`): ``fem``: ``n_elements`` (default None: the mesh
            derived from the description, a node at every string joint and survey station
            where the path turns, elements <= ``max_element_length`` = 50 m and turning by <=
            ``max_element_angle`` = 2 deg), ``max_element_length``, ``max_element_angle``,
            ``mass`` and the other keywords of :func:`~downhole.string.fem.fem_model`;
            ``hybrid``: ``preset`` (default None: derived mesh; or ``"hybrid24"``,
            ``"hybrid68"``, ``"hybrid108"``), ``n_ab``, ``n_cd``, ``n_lags``,
            ``max_element_length``, ``max_element_angle``, ``mass``; ``lumped*``:
            ``reference_elements`` (FEM used for the first natural frequency, default 400).
            ``fem`` and ``hybrid`` also take ``friction``, ``rayleigh_alpha``,
            ``rayleigh_beta`` (overriding the description's), ``md_b``/``md_c`` and ``damping``.

        Returns
        -------
        ChainModel, NeutralModel or DirectionalModel

        Raises
        ------
        DownholeInputError
            Unknown fidelity, unknown option, or a feature the fidelity cannot represent.
        """
        if fidelity not in FIDELITIES:
            raise DownholeInputError(f"fidelity must be one of {FIDELITIES}, got {fidelity!r}")
        known = self._options(fidelity)
        for key in options:
            if key not in known:
                import difflib

                near = difflib.get_close_matches(key, known, 1, 0.5)
                hint = f" (did you mean {near[0]!r}?)" if near else ""
                raise DownholeInputError(
                    f"unknown option {key!r} for fidelity {fidelity!r}{hint}; it takes "
                    f"{', '.join(known) or 'no options'}")
        return getattr(self, f"_build_{fidelity}")(**options)

    @staticmethod
    def _options(fidelity: str) -> list[str]:
        """The keywords :meth:`build` takes at ``fidelity``: :data:`BUILD_OPTIONS`, and at
        ``fem`` / ``hybrid`` every other keyword of the builder (``friction``, ``damping``,
        ``md_b``, ...)."""
        names = list(BUILD_OPTIONS[fidelity])
        if fidelity in ("fem", "hybrid"):
            import inspect

            from downhole.string.fem import fem_model
            from downhole.string.hybrid import hybrid_model

            fn = fem_model if fidelity == "fem" else hybrid_model
            names += [k for k in inspect.signature(fn).parameters
                      if k not in names and k not in ("well", "string", "bit")]
        return names

    def _fem_common(self) -> dict:
        return dict(friction=self.friction, rayleigh_alpha=self.rayleigh_alpha,
                    rayleigh_beta=self.rayleigh_beta)

    def _build_fem(self, **options):
        from downhole.string.fem import fem_model

        b, c = self.wave_points()
        kw = dict(self._fem_common(), md_b=b, md_c=c)
        kw.update(options)
        return fem_model(self.well, self.string, self.bit, **kw)

    def _build_hybrid(self, preset: str | None = None, **options):
        from downhole.string.hybrid import hybrid_model

        b, c = self.wave_points()
        kw = dict(self._fem_common(), md_b=b, md_c=c)
        kw.update(options)
        return hybrid_model(preset, well=self.well, string=self.string, bit=self.bit, **kw)

    # ---- lumped
    def lumped_derivation(self, reference_elements: int = 400) -> LumpedDerivation:
        """Static stiffness, first natural frequency and damping of the string, per field (see the
        module docstring), from which the lumped chains are matched."""
        from downhole.string.fem import _check_int, _count_keys, fem_model

        reference_elements = _check_int("reference_elements", reference_elements, 1)
        sections = _count_keys(self.well, self.string, self.top_md, self.well.total_depth,
                               self.top_md).size - 1
        if reference_elements < sections:
            raise DownholeInputError(
                f"reference_elements = {reference_elements} is too few: the survey stations and "
                f"string joints split the string into {sections} sections, each needs an "
                f"element; give reference_elements >= {sections} (scenario key "
                "model.lumped4.reference_elements or model.lumped12.reference_elements)")
        ref = fem_model(self.well, self.string, self.bit, n_elements=reference_elements,
                        friction=0.0, rayleigh_alpha=self.rayleigh_alpha,
                        rayleigh_beta=self.rayleigh_beta)
        segs = self.string.segments
        k_a = 1.0 / sum(s.length / (s.section.young_modulus * s.section.area) for s in segs)
        k_t = 1.0 / sum(s.length / (s.section.shear_modulus * s.section.polar_moment)
                        for s in segs)
        f_a = float(ref.natural_frequencies("axial", 1, top="fixed")[0])
        f_t = float(ref.natural_frequencies("torsional", 1, top="fixed")[0])
        m_a = k_a / (2 * math.pi * f_a) ** 2
        m_t = k_t / (2 * math.pi * f_t) ** 2
        mass = sum(s.section.linear_mass * s.length for s in segs)
        inertia = sum(s.section.linear_inertia * s.length for s in segs)
        zeta = tuple(self.rayleigh_alpha / (2 * w) + self.rayleigh_beta * w / 2
                     for w in (2 * math.pi * f_a, 2 * math.pi * f_t))
        return LumpedDerivation((k_a, k_t), (f_a, f_t), (m_a, m_t), (mass, inertia), zeta)

    def hanging_weight(self) -> float:
        """Axial buoyed weight of the hanging string (hook load off bottom, no contact), N:
        g A (rho_steel - rho_mud) integrated over true vertical depth, segment by segment
        (Gauss-Legendre on each, exact for straight sections)."""
        x, wq = np.polynomial.legendre.leggauss(64)
        total, top = 0.0, self.top_md
        for a, b, seg in zip(self.string.boundaries[:-1], self.string.boundaries[1:],
                             self.string.segments):
            md = top + 0.5 * (a + b) + 0.5 * (b - a) * x
            cos_inc = np.cos(np.asarray(self.well.inclination(md), float))
            w = self.string.g * seg.section.weight_factor * seg.section.area * (
                seg.section.density - self.string.mud_density)
            total += w * 0.5 * (b - a) * float(np.dot(wq, cos_inc))
        return total

    def torque_drag(self, friction=(0.1, 0.2, 0.3), wob: float = 0.0,
                    tob: float | None = None, step: float = 10.0, hook_load: bool = True,
                    surface_speed: float | None = None):
        """Soft-string torque and drag of this string in this well at the friction factors
        ``friction``: :func:`downhole.string.torque_drag.torque_drag`.

        The drilling case has ``wob`` (N) and ``tob`` (N m) at the bit; ``tob`` defaults to the
        bit law's torque at that WOB and ``surface_speed`` (default: the top drive's set-point
        ``rig.top_drive.speed``) in steady cutting (:func:`steady_bit_state`), as
        ``downhole torque-drag`` does with the scenario's ``[operation]``; ``tob = 0`` drops it.
        The defaults of ``friction`` and ``step`` are the scenario keys
        ``torque_drag.friction_factors`` and ``torque_drag.step``."""
        from downhole.string.torque_drag import torque_drag

        wob = si_or_number(wob, "force", "wob")
        if tob is None:
            speed = self.rig.top_drive.speed if surface_speed is None else si_or_number(
                surface_speed, "angular_velocity", "surface_speed")
            tob = steady_bit_state(self.bit, speed, wob=wob)[2] if wob > 0 else 0.0
        return torque_drag(self.well, self.string, friction=friction, wob=wob, tob=tob,
                           step=step, hook_load=hook_load)

    def _lumped(self, order: int, reference_elements: int = 400):
        from downhole.sim.lumped_model import lumped_model

        self._needs_contact(f"lumped{order}")
        der = self.lumped_derivation(reference_elements)
        (k_a, k_t), (m_a, m_t) = der.stiffness, der.mass
        c_a = self.rayleigh_alpha * der.string_mass[0]
        c_t = self.rayleigh_alpha * der.string_mass[1]
        params = LumpedParams(mass=m_a, inertia=m_t, axial_stiffness=k_a, axial_damping=c_a,
                              torsional_stiffness=k_t, torsional_damping=c_t,
                              gravity_prebalance=True, g=self.string.g)
        model = lumped_model(params, self.bit, order=order)
        if order == 12:
            # scale the split chain's masses so that its first frequency is the string's too
            scale = []
            for fld, f1 in ((model.axial, der.first_frequency[0]),
                            (model.torsional, der.first_frequency[1])):
                w_chain = float(_chain_frequencies(fld)[0])
                scale.append((w_chain / (2 * math.pi * f1)) ** 2)
            params = params.model_copy(update=dict(mass=m_a * scale[0], inertia=m_t * scale[1]))
            model = lumped_model(params, self.bit, order=order)
        else:
            # a damper to the top drive brings the first mode's damping ratio to the string's
            fields = []
            for fld, zeta, k, m in ((model.axial, der.damping_ratio[0], k_a, m_a),
                                    (model.torsional, der.damping_ratio[1], k_t, m_t)):
                extra = max(0.0, 2 * zeta * math.sqrt(k * m) - float(fld.c_abs[0]))
                fields.append(replace(fld, c_top=extra))
            model = replace(model, axial=fields[0], torsional=fields[1])
        model = replace(model, weight=self.hanging_weight(), name=f"lumped{order}:system")
        return replace(model, with_rig=partial(self._chain_with_rig, model, der.string_mass))

    def _chain_with_rig(self, chain, string_mass):
        from downhole.string.fem import chain_with_rig

        return chain_with_rig(chain, self.well, self.string, self.top_md, *string_mass)

    def _build_lumped4(self, **options):
        return self._lumped(4, **options)

    def _build_lumped12(self, **options):
        return self._lumped(12, **options)

    # ---- neutral
    def neutral_split(self) -> tuple[StringSegment, float, float, float]:
        """The neutral model's line and lumped bottom: ``(line segment, lumped mass kg, lumped
        polar inertia kg m^2, line length m)``."""
        segs = list(self.string.segments)
        bha = [s for s in segs if s.kind in _BHA_KINDS]
        n_bha = 0
        while n_bha < len(segs) and segs[-1 - n_bha].kind in _BHA_KINDS:
            n_bha += 1
        if bha and n_bha != len(bha):
            raise DownholeInputError("the neutral model lumps the BHA at the bottom: collars and "
                                     "'bha' segments must be the bottom segments of the string")
        line = segs[:len(segs) - n_bha]
        if not line:
            raise DownholeInputError("the neutral model needs pipe above the BHA; the string is "
                                     "all collars/BHA")
        if len(line) > 1:
            raise DownholeInputError(
                f"the neutral model's wave segment is one uniform pipe; this string has "
                f"{len(line)} sections above the BHA ({', '.join(s.kind for s in line)}): use "
                "fidelity 'fem' or 'hybrid'")
        pipe = line[0]
        lumped = segs[len(segs) - n_bha:]
        length = pipe.length
        if not lumped:
            if self.lump_length >= pipe.length:
                raise DownholeInputError(f"lump_length {self.lump_length:g} m is not shorter "
                                         f"than the string ({pipe.length:g} m)")
            length = pipe.length - self.lump_length
            lumped = [StringSegment(self.lump_length, pipe.section, pipe.kind)]
        m_b = sum(s.section.linear_mass * s.length for s in lumped)
        i_b = sum(s.section.linear_inertia * s.length for s in lumped)
        return StringSegment(length, pipe.section, pipe.kind), m_b, i_b, length

    def _build_neutral(self):
        from downhole.string.neutral import neutral_model

        self._needs_contact("neutral")
        line, m_b, i_b, length = self.neutral_split()
        # the model's static hook load is (M_S + m_b) g: M_S makes it the string's buoyed weight
        string_mass = self.hanging_weight() / self.string.g - m_b
        params = NeutralStringParams(
            length=length, pipe=line.section, alpha_axial=self.rig.hook.servo_damping,
            alpha_torsional=self.rig.top_drive.kp, string_mass=string_mass, bit_mass=m_b,
            bit_inertia=i_b, g=self.string.g)
        model = neutral_model(params, self.bit)
        return replace(model, with_rig=partial(self._line_with_rig, line, m_b, i_b))

    def _line_with_rig(self, line, m_b, i_b):
        from downhole.string.hybrid import line_with_rig

        return line_with_rig(self.well, self.string, self.bit, line, self.top_md, m_b, i_b,
                             self.rayleigh_alpha, self.hanging_weight(),
                             rayleigh_beta=self.rayleigh_beta)


def _chain_frequencies(fld) -> np.ndarray:
    """Undamped natural frequencies (rad/s) of one chain field, top clamped."""
    k = fld.stiffness_matrix()
    m = np.diag(1.0 / np.sqrt(np.asarray(fld.mass, float)))
    return np.sqrt(np.sort(np.linalg.eigvalsh(m @ k @ m)))
