"""Hybrid FEM + wave-segment directional model (seed Sec. 5.2): FEM for the top (AB) and curved
(CD) parts, a lossless wave (delay) line for the straight, uniform, contact-free part BC.

The line is :class:`downhole.sim.wave.WaveSegment` (one implementation shared with Ch. 3):
force on B = Z (2 b_in - v_B), on C = Z (2 a_in - v_C), Z_axial = A sqrt(rho E),
Z_torsional = J sqrt(rho G) (seed Eq. 5.18 swaps them; docs/seed-errata.md), plus the static preload
of the hanging line (its weight). The kernels treat -Z v as an implicit damper on B and C. Damping
of the line (docs/seed-errata.md): the Rayleigh alpha0 part is lumped as end dashpots alpha0 rho A
L/2 (and alpha0 rho J L/2) at B and C; optionally the beta0 part as ``n_lags`` first-order lags on
each incoming wave with time constant sqrt(beta0 tau / n_lags), which reproduce the low-frequency
Kelvin-Voigt attenuation exp(-omega^2 beta0 tau / 2); the pure delay is shortened by the lags' group
delay (n_lags * T) so that the arrival time stays tau.

Presets: the seed's state counts (4 states per FEM node): ``hybrid24`` (2 + 4 nodes),
``hybrid68`` (4 + 13 nodes, the Ch. 6 plant: (2+1)(2-1)+1 = 4 on AB, (3+1)(4-1)+1 = 13 on CD)
and ``hybrid108`` (7 + 20 nodes).
"""

from __future__ import annotations

import math

import numpy as np

from downhole.errors import DownholeInputError
from downhole.params import BitParams
from downhole.sim.wave import WaveSegment
from downhole.string.drillstring import DrillString
from downhole.string.fem import (
    MAX_ELEMENT_ANGLE,
    MAX_ELEMENT_LENGTH,
    DirectionalModel,
    _apply_stabilizers,
    _assemble_chain,
    _check_int,
    _check_mesh_sizes,
    _count_keys,
    _damping,
    _derived_md,
    _mesh,
    table_5_1_setup,
)
from downhole.well import WellPath

__all__ = ["HYBRID_PRESETS", "hybrid_model", "line_with_rig"]

#: Seed state counts -> (nodes on AB, nodes on CD).
HYBRID_PRESETS = {"hybrid24": (2, 4), "hybrid68": (4, 13), "hybrid108": (7, 20)}


def _chain_md(well, string, lo, hi, top_md, n_nodes, name):
    """Node depths of a FEM chain from lo to hi: ``n_nodes`` spread over the survey stations and
    string joints, or (None) the mesh derived from the description."""
    keys = _count_keys(well, string, lo, hi, top_md)
    if n_nodes - 1 < keys.size - 1:
        raise DownholeInputError(
            f"{name} = {n_nodes} nodes are too few for {lo:g}..{hi:g} m, which the survey "
            f"stations and string joints split into {keys.size - 1} sections: give {name} >= "
            f"{keys.size} (scenario key model.hybrid.{name}), or leave {name} and the preset "
            "unset for the mesh derived from the description")
    return _mesh(keys, n_nodes - 1)


def hybrid_model(preset: str | None = None, *, n_ab: int | None = None,
                 n_cd: int | None = None,
                 max_element_length: float = MAX_ELEMENT_LENGTH,
                 max_element_angle: float = MAX_ELEMENT_ANGLE,
                 well: WellPath | None = None,
                 string: DrillString | None = None, bit: BitParams | None = None,
                 md_b: float | None = None, md_c: float | None = None,
                 damping: str = "rayleigh", rayleigh_alpha: float | None = None,
                 rayleigh_beta: float | None = None, modal_ratio: float = 0.03,
                 n_lags: int = 0, friction: float | None = None, v_eps: float = 1e-3,
                 mass: str = "consistent", name: str | None = None) -> DirectionalModel:
    """Build a hybrid FEM + wave-segment model.

    Parameters
    ----------
    preset : {"hybrid24", "hybrid68", "hybrid108"} or None
        Node counts of the seed's models; ``n_ab``/``n_cd`` override. Default (None): the
        counts given, and where none is given the mesh derived from the description (as
        :func:`~downhole.string.fem.fem_model` without ``n_elements``: a node at every string
        joint and at every survey station where the path turns, elements no longer than
        ``max_element_length`` and turning by at most ``max_element_angle``).
    n_ab, n_cd : int, optional
        FEM nodes on AB (string top to B, >= 2) and on CD (C to bit, >= 2).
    max_element_length, max_element_angle : float or quantity
        Of the derived mesh: default 50 m and 2 deg.
    well, string, bit : optional
        Default: Table 5.1 (AB vertical 2000 m, BC vertical 1000 m, CD arc R = 4000 m, 30 deg).
    md_b, md_c : float, optional
        Measured depths of B and C; default Table 5.1's 2000 and 3000 m. BC must be straight,
        vertical (no contact) and of one uniform segment.
    damping : {"rayleigh", "modal"}
        FEM damping; with Rayleigh the line gets the end dashpots and lags described above.
    rayleigh_alpha, rayleigh_beta, friction : float, optional
        As :func:`~downhole.string.fem.fem_model` (friction: Table 5.1's 0.5 on its well, else
        0).
    n_lags : int
        First-order lags per incoming wave approximating beta0 (default 0 = lossless line with
        the alpha0 end dashpots only: against a 1000-element FEM with Table 5.1 damping this is
        closer (bit speed 4.5 % RMS for 68 states) than 1 lag (6.8 %) or 3 lags (8.0 %),
        because beta0 acts mostly above the frequencies that matter here).

    Returns
    -------
    DirectionalModel
        ``kind == "hybrid"``; ``n_states`` = 4 (n_ab + n_cd).

    Raises
    ------
    DownholeInputError
        Unknown preset, too few nodes (the message names the count that works), BC curved /
        inclined / non-uniform, line shorter than its lags.

    Examples
    --------
    >>> hybrid_model("hybrid68").n_states
    68
    >>> m = hybrid_model()            # derived: AB 0..2000 m, CD 3000 m..bit
    >>> (m.info["n_ab"], m.info["n_cd"])
    (41, 43)
    """
    well0, string0, bit0, p = table_5_1_setup()
    seed_well = well is None
    well = well or well0
    string = string or (string0 if well is well0 else
                        DrillString.uniform(well.total_depth, p.pipe, g=p.g))
    bit = bit or bit0
    if preset is not None:
        if preset not in HYBRID_PRESETS:
            raise DownholeInputError(
                f"unknown hybrid preset {preset!r}; known: {', '.join(HYBRID_PRESETS)}")
        pa, pc = HYBRID_PRESETS[preset]
        n_ab = pa if n_ab is None else n_ab
        n_cd = pc if n_cd is None else n_cd
    if n_ab is not None:
        n_ab = _check_int("n_ab (nodes on AB)", n_ab, 2)
    if n_cd is not None:
        n_cd = _check_int("n_cd (nodes on CD)", n_cd, 2)
    n_lags = _check_int("n_lags", n_lags, 0)
    h, angle = _check_mesh_sizes(max_element_length, max_element_angle)
    if string.length > well.total_depth + 1e-6:
        raise DownholeInputError(f"string length {string.length:g} m exceeds the well's total "
                                 f"depth {well.total_depth:g} m")
    top_md = well.total_depth - string.length
    md_b = p.length_ab if md_b is None else float(md_b)
    md_c = p.length_ab + p.length_bc if md_c is None else float(md_c)
    if not (top_md < md_b < md_c < well.total_depth):
        raise DownholeInputError(
            f"need string top ({top_md:g} m) < md_b ({md_b:g} m) < md_c ({md_c:g} m) < bit "
            f"({well.total_depth:g} m)")
    probe = np.linspace(md_b, md_c, 21)[1:-1]
    if np.max(well.curvature(probe)) > 1e-9:
        raise DownholeInputError(
            f"section BC ({md_b:g}..{md_c:g} m) is curved; the wave segment needs a straight "
            "section (move B/C or model it with FEM)")
    if np.max(np.sin(well.inclination(probe))) > 1e-6:
        raise DownholeInputError(
            f"section BC ({md_b:g}..{md_c:g} m) is inclined: its wall contact (w sin(inc)) "
            "cannot be carried by a lossless wave segment; use FEM there")
    seg_idx = np.unique(string.segment_at(probe - top_md))
    if seg_idx.size != 1:
        raise DownholeInputError(
            f"section BC ({md_b:g}..{md_c:g} m) spans {seg_idx.size} string segments; the wave "
            "segment needs a uniform pipe")
    pipe = string.segments[int(seg_idx[0])].section
    alpha = p.rayleigh_alpha if rayleigh_alpha is None else float(rayleigh_alpha)
    beta = p.rayleigh_beta if rayleigh_beta is None else float(rayleigh_beta)
    mu = (p.wellbore_friction if seed_well else 0.0) if friction is None else float(friction)
    md_ab = (_derived_md(well, string, top_md, md_b, top_md, h, angle) if n_ab is None else
             _chain_md(well, string, top_md, md_b, top_md, n_ab, "n_ab"))
    md_cd = (_derived_md(well, string, md_c, well.total_depth, top_md, h, angle)
             if n_cd is None else
             _chain_md(well, string, md_c, well.total_depth, top_md, n_cd, "n_cd"))
    n_ab, n_cd = md_ab.size, md_cd.size
    chains = [_assemble_chain(well, string, md_ab, top_md, mass),
              _assemble_chain(well, string, md_cd, top_md, mass)]
    md = np.concatenate([md_ab, md_cd])
    n = md.size
    iB, iC = n_ab - 1, n_ab

    def cat(key):
        a, b = chains[0][key], chains[1][key]
        if key in ("Ma", "Ka", "Mt", "Kt"):
            out = np.concatenate([a, b], axis=1)
            out[1, iB] = 0.0  # no element between B and C: the wave segment joins them
            return out
        return np.concatenate([a, b], axis=0)

    Ma, Ka, Mt, Kt = cat("Ma"), cat("Ka"), cat("Mt"), cat("Kt")
    elem = cat("elem")
    elem[iB] = 0.0
    grav = cat("grav")
    radius = cat("radius")
    _apply_stabilizers(string, md, radius, well.total_depth)
    Ca, Ct, Cd = _damping(Ma, Ka, Mt, Kt, damping, alpha, beta, modal_ratio)
    L = md_c - md_b
    tau_a = L / pipe.axial_wave_speed
    tau_t = L / pipe.torsional_wave_speed
    if damping == "rayleigh":
        for C, rho_x in ((Ca, pipe.linear_mass), (Ct, pipe.linear_inertia)):
            dash = alpha * rho_x * L / 2.0
            if Cd is None:
                C[0, iB] += dash
                C[0, iC] += dash
        lag_beta = beta
    else:
        lag_beta = 0.0
    lag_tau = [1.0, 1.0]
    segs = []
    nl = n_lags if lag_beta > 0 else 0
    for k, (tau, c, Z) in enumerate(((tau_a, pipe.axial_wave_speed, pipe.axial_impedance),
                                     (tau_t, pipe.torsional_wave_speed,
                                      pipe.torsional_impedance))):
        if nl > 0:
            T = math.sqrt(lag_beta * tau / nl)
            if nl * T >= 0.9 * tau:
                raise DownholeInputError(
                    f"{nl} lags of {T:.3g} s do not fit in the {tau:.3g} s delay of BC; "
                    "use fewer lags (n_lags) or a longer BC")
            lag_tau[k] = T
            segs.append(WaveSegment(c * (tau - nl * T), c, Z))
        else:
            segs.append(WaveSegment(L, c, Z))
    wb = float(string.buoyed_weight_per_length(0.5 * (md_b + md_c) - top_md))
    line_weight = wb * float(well.tvd(md_c) - well.tvd(md_b))
    wave = {"segments": tuple(segs), "length": L, "EA": pipe.area * pipe.young_modulus,
            "line_weight": line_weight, "n_lags": nl, "lag_tau": tuple(lag_tau),
            "tau": (tau_a, tau_t), "impedance": (pipe.axial_impedance, pipe.torsional_impedance)}
    return DirectionalModel(
        name=name or f"hybrid {4 * n} states ({n_ab}+{n_cd} nodes)", kind="hybrid", well=well,
        string=string, bit=bit, node_md=md, Ma=Ma, Ka=Ka, Ca=Ca, Mt=Mt, Kt=Kt, Ct=Ct, Cdense=Cd,
        gravity=grav, elem=elem, radius=radius, mu=mu, v_eps=float(v_eps), node_b=iB,
        node_c=iC, wave=wave,
        info={"damping": damping, "rayleigh_alpha": alpha, "rayleigh_beta": beta,
              "modal_ratio": modal_ratio, "mass": mass, "n_ab": n_ab, "n_cd": n_cd,
              "n_lags": nl})


def line_with_rig(well: WellPath, string: DrillString, bit: BitParams, line, top_md: float,
                  bottom_mass: float, bottom_inertia: float, rayleigh_alpha: float,
                  weight: float, rayleigh_beta: float = 0.0, n_lags: int = 2
                  ) -> DirectionalModel:
    """The neutral model of a described system under the rig: the hybrid model with no FEM
    chains, a wave line from the top node (B = node 0, where the top drive and the hook act,
    as on every fidelity's top node) to the lumped bottom (C = node 1: collars and BHA, or the
    bottom ``lump_length``, rigid, the bit below it). The line's Rayleigh damping is the hybrid
    model's: the alpha0 part lumped as a dashpot on the bottom node (so a steady rotation costs
    alpha0 J omega at the top at every fidelity), the beta0 part as ``n_lags`` first-order lags on each incoming wave (without
    them a force-driven top leaves the line's axial modes undamped and the delayed depth of cut
    drives them: bit bounce that the FEM's beta0 damping removes).

    Parameters
    ----------
    well, string, bit : WellPath, DrillString, BitParams
        The description.
    line : StringSegment
        The uniform pipe of the line and its length (``DrillingSystem.neutral_split``).
    top_md : float
        Measured depth of the string's top, m.
    bottom_mass, bottom_inertia : float
        The lumped bottom, kg and kg m^2.
    rayleigh_alpha : float
        Mass-proportional damping, 1/s.
    weight : float
        The string's buoyed hanging weight, N (the line carries its share, the bottom node the
        rest).
    rayleigh_beta : float
        Stiffness-proportional damping, s (0: the seed's lossless line).
    n_lags : int
        Lag stages per incoming wave that carry it (with ``rayleigh_beta`` > 0).

    Returns
    -------
    DirectionalModel
        Kind ``"neutral"``, two nodes.
    """
    pipe, length = line.section, float(line.length)
    md = np.array([top_md, well.total_depth])
    Ma = np.array([[0.0, bottom_mass], [0.0, 0.0]])
    Mt = np.array([[0.0, bottom_inertia], [0.0, 0.0]])
    Ka, Kt = np.zeros((2, 2)), np.zeros((2, 2))
    # the line's alpha0 dashpot at the bottom node, so that the torque and force the line
    # carries at the top (the recorded surface torque and hook load) include it, as the FEM's
    Ca = np.array([[0.0, 1.0], [0.0, 0.0]]) * rayleigh_alpha * (
        pipe.linear_mass * length + bottom_mass)
    Ct = np.array([[0.0, 1.0], [0.0, 0.0]]) * rayleigh_alpha * (
        pipe.linear_inertia * length + bottom_inertia)
    wb = float(string.buoyed_weight_per_length(0.5 * length))
    line_weight = wb * float(well.tvd(top_md + length) - well.tvd(top_md))
    nl = int(n_lags) if rayleigh_beta > 0 else 0
    segs, lag_tau = [], [1.0, 1.0]
    for k, (c, z) in enumerate(((pipe.axial_wave_speed, pipe.axial_impedance),
                                (pipe.torsional_wave_speed, pipe.torsional_impedance))):
        tau = length / c
        if nl > 0:
            lag_tau[k] = math.sqrt(rayleigh_beta * tau / nl)
            if nl * lag_tau[k] >= 0.9 * tau:
                raise DownholeInputError(f"{nl} lags of {lag_tau[k]:.3g} s do not fit in the "
                                         f"{tau:.3g} s delay of the neutral line")
        segs.append(WaveSegment(c * (tau - nl * lag_tau[k]), c, z))
    wave = {"segments": tuple(segs), "length": length, "EA": pipe.area * pipe.young_modulus,
            "line_weight": line_weight, "n_lags": nl, "lag_tau": tuple(lag_tau),
            "tau": (length / pipe.axial_wave_speed, length / pipe.torsional_wave_speed),
            "impedance": (pipe.axial_impedance, pipe.torsional_impedance)}
    return DirectionalModel(
        name="neutral line with the rig", kind="neutral", well=well, string=string, bit=bit,
        node_md=md, Ma=Ma, Ka=Ka, Ca=Ca, Mt=Mt, Kt=Kt, Ct=Ct, Cdense=None,
        gravity=np.array([0.0, weight - line_weight]), elem=np.zeros((2, 8)),
        radius=np.zeros(2), mu=0.0, v_eps=1e-3, node_b=0, node_c=1, wave=wave,
        info={"damping": "rayleigh", "rayleigh_alpha": rayleigh_alpha,
              "rayleigh_beta": rayleigh_beta, "modal_ratio": 0.03, "mass": "lumped", "n_ab": 1,
              "n_cd": 1, "n_lags": nl})
