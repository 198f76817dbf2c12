"""SIL plant adapters: any downhole plant as a fixed list of named scalar signals.

The real-time runtime, the UDP link, the FMU and the Gymnasium environment all need a plant
whose observations and commands are a *fixed*, ordered list of named floats.
:class:`SilPlant` wraps a plant of the :class:`~downhole.sim.plant.Plant` contract
(``reset(start=..., set_point=...) -> obs``, ``step(command) -> obs``:
:class:`~downhole.string.fem.DirectionalPlant` (lumped, neutral and directional models),
:class:`~downhole.control.dhp.directional.DirectionalStatePlant`; the HIL string takes the
same two calls) and adds:

- ``observation_names`` / ``command_names`` / ``units`` (the layout announced on the link);
- a vector ``"state"`` observation (the DHP design state) flattened into its state names
  (``x_1``, ``alpha_1``, ..., ``omega_6``), so a DHP controller reads them by name;
- ``default_command()`` (the open-loop command when the controller is off) and
  ``safe_command()`` (the safe state of the controller-timeout action);
- ``command_ranges``: the admissible range of every command (:data:`COMMAND_RANGES`); the
  runtime and the UDP link reject (count, never apply) a non-finite or out-of-range command,
  and :meth:`SilPlant.check_command` says why.

Interfaces (``interface`` of :func:`build_plant`):

``"surface"``
    PI top drive and force-driven hook: commands ``hook_load`` (N) and
    ``top_drive_angular_velocity`` (set-point, rad/s). Safe state: hook load = buoyed string
    weight (no weight on bit), set-point 0.
``"state"``
    The DHP set-up of Ch. 6: torque-driven top drive and slack-off force, observations add the
    24-state design model's state. Commands ``slack_off_force`` (N) and ``surface_torque``
    (N m). Safe state: slack-off 0 (hook carries the whole string), torque 0.
``"lumped"``
    The lumped chain (velocity-driven top): ``top_drive_axial_velocity`` (m/s) and
    ``top_drive_angular_velocity`` (rad/s). Safe state: both 0.
``"neutral"``
    The neutral-type wave model of Ch. 3 with the same two commands (the axial one relative to
    the hanging equilibrium, so 0 holds the string still). Default: the nominal commands of
    10 mm/s and 20 rad/s; safe state: both 0.
"""

from __future__ import annotations

import numpy as np

from downhole.errors import DownholeInputError
from downhole.signals import SIGNALS, range_reason
from downhole.sim.plant import plant_bit_radius

__all__ = [
    "COMMAND_RANGES",
    "REFERENCE_RANGES",
    "SIGNAL_UNITS",
    "SilPlant",
    "build_plant",
    "check_range",
    "resolve_ranges",
]

#: Units of the signals the adapters expose (others: ""), from :mod:`downhole.signals`.
SIGNAL_UNITS = {name: SIGNALS[name].unit for name in (
    "time", "bit_axial_position", "bit_axial_velocity", "bit_angle", "bit_angular_velocity",
    "depth_of_cut", "wob", "tob", "hook_load", "surface_torque", "top_drive_axial_velocity",
    "top_drive_angular_velocity", "force_b", "torque_b", "force_c", "torque_c", "top_drive_angle",
    "reference_angular_velocity", "last_node_axial_velocity", "last_node_angular_velocity",
    "slack_off_force", "reference_axial_velocity", "top_drive_set_point")}

#: Admissible range ``(low, high)`` of every command signal, from the one signal registry
#: (:mod:`downhole.signals`): finite and physically sane bounds for a drilling rig (they catch a
#: wrong unit, a corrupted or hostile packet, an absurd set-point; they are not the rig's
#: operating envelope). The HIL rig sends the measured bit velocities as its commands.
COMMAND_RANGES = {
    name: (SIGNALS[name].low, SIGNALS[name].high)
    for name in ("hook_load", "top_drive_angular_velocity", "top_drive_axial_velocity",
                 "slack_off_force", "surface_torque", "bit_axial_velocity",
                 "bit_angular_velocity")
}

#: Admissible bit-velocity references (set-points given to the controller), from the registry.
REFERENCE_RANGES = {
    "axial": (SIGNALS["reference_axial_velocity"].low, SIGNALS["reference_axial_velocity"].high),
    "angular": (SIGNALS["reference_angular_velocity"].low,
                SIGNALS["reference_angular_velocity"].high),
}


def check_range(name: str, value, ranges: dict) -> str | None:
    """None when ``value`` is a finite number within ``ranges[name]``, else the reason.

    Parameters
    ----------
    name : str
        Command or reference name (its unit, if declared in :mod:`downhole.signals`, is named
        in the reason).
    value : object
        The value, in the signal's SI unit.
    ranges : dict
        ``{name: (low, high)}``, SI.

    Returns
    -------
    str or None
        A one-line reason, or None when admissible.

    Raises
    ------
    KeyError
        If ``name`` has no entry in ``ranges``.
    """
    lo, hi = ranges[name]
    return range_reason(name, value, lo, hi, SIGNALS[name].unit if name in SIGNALS else "")


def resolve_ranges(names, overrides: dict | None, what: str) -> dict:
    """``{name: (low, high)}`` for ``names`` from :data:`COMMAND_RANGES` and ``overrides``.

    Parameters
    ----------
    names : iterable of str
        Command names.
    overrides : dict or None
        ``{name: (low, high)}`` (SI) replacing or adding to :data:`COMMAND_RANGES`.
    what : str
        What the names are (e.g. ``"commands"``), used in the error message.

    Returns
    -------
    dict
        ``{name: (low, high)}`` as floats, SI, for every name.

    Raises
    ------
    DownholeInputError
        If a name has no range (the message names ``what``).
    """
    ranges = dict(COMMAND_RANGES)
    ranges.update(overrides or {})
    missing = [k for k in names if k not in ranges]
    if missing:
        raise DownholeInputError(f"{what} {missing} have no declared admissible range "
                                 f"(COMMAND_RANGES or command_ranges=)")
    return {k: (float(ranges[k][0]), float(ranges[k][1])) for k in names}


#: Plant signals renamed in the layout: the directional plants call their top-drive speed
#: set-point ``reference_angular_velocity``, which in the SIL layout is the *bit* reference.
_RENAME = {"reference_angular_velocity": "top_drive_set_point"}


class SilPlant:
    """A plant with a fixed, named scalar layout (see the module docstring).

    Parameters
    ----------
    plant : object
        ``reset() -> dict`` and ``step(command: dict) -> dict``, attribute ``dt``.
    command_names : sequence of str
        Names of the commands the plant takes (signals of :mod:`downhole.signals`).
    default_command, safe_command : dict
        Open-loop command and the safe state (same keys as ``command_names``).
    name : str
        Description (for Result metadata).
    state_names : sequence of str, optional
        Names of the entries of a vector observation ``"state"`` (flattened into the layout).
    info : dict, optional
        Extra description (``model``, ``interface``, ...) kept as :attr:`info`; the plant's
        bit radius is added as ``bit_radius`` (m) when known.
    command_ranges : dict, optional
        ``{name: (low, high)}`` overriding :data:`COMMAND_RANGES` (every command needs one).

    Raises
    ------
    DownholeInputError
        A command without a declared range, or a default / safe command outside it.
    """

    def __init__(self, plant, command_names, default_command: dict, safe_command: dict,
                 name: str = "", state_names=None, info: dict | None = None,
                 command_ranges: dict | None = None):
        self.plant = plant
        self.dt = float(plant.dt)
        self.command_names = tuple(command_names)
        for d, what in ((default_command, "default_command"), (safe_command, "safe_command")):
            if set(d) != set(self.command_names):
                raise DownholeInputError(f"{what} keys {sorted(d)} differ from the commands "
                                         f"{self.command_names}")
        #: admissible ``(low, high)`` of every command (see :data:`COMMAND_RANGES`)
        self.command_ranges = resolve_ranges(self.command_names, command_ranges, "commands")
        self._default = {k: float(default_command[k]) for k in self.command_names}
        self._safe = {k: float(safe_command[k]) for k in self.command_names}
        for d, what in ((self._default, "default (open-loop)"), (self._safe, "safe")):
            why = self.check_command(d)
            if why is not None:
                raise DownholeInputError(f"{name or 'plant'}: the {what} command is not "
                                         f"admissible: {why}")
        self.name = name
        self.state_names = tuple(state_names or ())
        self.info = dict(info or {})
        radius = plant_bit_radius(plant)
        if radius is not None:  # recorded in the Result's attributes, for the MSE
            self.info.setdefault("bit_radius", radius)
        #: The start of a bare ``reset()`` (the runtime's): ``{"start": "steady"}``, ... of
        #: :meth:`downhole.sim.plant.Plant.reset`; empty: from rest.
        self.default_start: dict = {}
        #: extra command names handed to the plant when present (HIL: the rig's bit velocities)
        self.passthrough: tuple = ()
        obs = plant.reset()
        self.observation_names = self._names(obs)
        self.units = {n: SIGNAL_UNITS.get(n, "") for n in
                      (*self.observation_names, *self.command_names)}
        self._last = self._flatten(obs)

    def _names(self, obs) -> tuple:
        names = []
        for k, v in obs.items():
            if k == "state":
                if len(self.state_names) != np.size(v):
                    raise DownholeInputError("state_names do not match the plant's state size")
                names.extend(self.state_names)
            elif np.ndim(v) == 0:
                names.append(_RENAME.get(k, k))
        if "time" in names:
            names.remove("time")
            names.insert(0, "time")
        return tuple(names)

    def _flatten(self, obs: dict) -> dict:
        # the hot path of every SIL step: plain floats skip the NumPy dimension check
        out = {_RENAME.get(k, k): float(v) for k, v in obs.items()
               if k != "state" and (type(v) is float or np.ndim(v) == 0)}
        if "state" in obs:
            out.update(zip(self.state_names, np.asarray(obs["state"], float).tolist()))
        out.setdefault("time", 0.0)
        return out

    def check_command(self, command: dict) -> str | None:
        """None when every command is present, finite and within :attr:`command_ranges`.

        Parameters
        ----------
        command : dict
            Command name -> value (SI).

        Returns
        -------
        str or None
            The reason for the first offending signal, or None when admissible.
        """
        for k in self.command_names:
            if k not in command:
                return f"{k} is missing"
            why = check_range(k, command[k], self.command_ranges)
            if why is not None:
                return why
        return None

    def default_command(self) -> dict:
        """The open-loop command (used while the controller is off)."""
        return dict(self._default)

    def safe_command(self) -> dict:
        """The safe state the controller-timeout action ramps to."""
        return dict(self._safe)

    @property
    def last_observation(self) -> dict:
        return self._last

    def reset(self, **start) -> dict:
        """Reset the plant and return the first observation.

        Parameters
        ----------
        **start
            ``start=``, ``set_point=``, ... of :meth:`downhole.sim.plant.Plant.reset`; none: the
            plant's :attr:`default_start` (empty: from rest).

        Returns
        -------
        dict
            The flattened observation, signal name -> value (SI).
        """
        self._last = self._flatten(self.plant.reset(**(start or self.default_start)))
        return dict(self._last)

    def step(self, command: dict) -> dict:
        """Advance one ``dt`` holding ``command`` (every command name required).

        Parameters
        ----------
        command : dict
            Command name -> value (SI); extra :attr:`passthrough` names are handed on when present.

        Returns
        -------
        dict
            The flattened observation after the step (the plant's own dict; do not modify it).

        Raises
        ------
        DownholeInputError
            If a command name is missing.
        """
        try:
            cmd = {k: float(command[k]) for k in self.command_names}
        except KeyError as exc:
            raise DownholeInputError(f"command lacks {exc.args[0]!r}; expected "
                                     f"{self.command_names}") from None
        for k in self.passthrough:
            if k in command:
                cmd[k] = float(command[k])
        self._last = self._flatten(self.plant.step(cmd))
        return self._last

    def vector(self, obs: dict | None = None, out: np.ndarray | None = None) -> np.ndarray:
        """Observation values in layout order.

        Parameters
        ----------
        obs : dict, optional
            Flattened observation (default: the last one).
        out : ndarray, optional
            Array of length ``len(observation_names)`` to fill in place.

        Returns
        -------
        ndarray
            The values (SI) in the order of :attr:`observation_names`, NaN for missing ones.
        """
        obs = self._last if obs is None else obs
        if out is None:
            out = np.empty(len(self.observation_names))
        for i, n in enumerate(self.observation_names):
            out[i] = obs.get(n, np.nan)
        return out


def _design_model(design: str):
    from downhole.control.dhp.directional import directional_affine_model
    from downhole.string.hybrid import hybrid_model

    return directional_affine_model(hybrid_model(design).design_model())


def build_plant(model: str = "hybrid68", *, interface: str = "surface", dt: float = 1e-3,
                depth_of_cut: str = "delayed", wob: float = 120e3,
                top_drive_speed: float = 10.0, design: str = "hybrid24", n_elements: int = 23,
                lumped_preset: str = "table_2_1", order: int = 4,
                axial_velocity: float = 0.01, surface_torque: float = 0.0,
                design_model=None, bit=None) -> SilPlant:
    """Build a :class:`SilPlant`.

    Parameters
    ----------
    model : {"hybrid24", "hybrid68", "hybrid108", "fem", "lumped", "neutral"}
        The plant (``fem``: Table 5.1 FEM with ``n_elements`` elements).
    interface : {"surface", "state"}
        See the module docstring (``lumped`` models always use the lumped interface).
    dt : float
        Step, s.
    depth_of_cut : {"delayed", "approximate"}
        Depth-of-cut model (default ``"delayed"``).
    wob : float
        ``surface``: initial (static) weight on bit, N; the default hook load is the buoyed
        weight minus this.
    top_drive_speed : float
        ``surface`` / ``lumped``: default top-drive speed set-point, rad/s.
    design : str
        ``state``: the hybrid preset whose design FEM the DHP controller was trained on.
    n_elements : int
        ``fem``: number of finite elements (default 23).
    lumped_preset : str
        ``lumped``: the lumped preset (default ``"table_2_1"``).
    order : {4, 12}
        ``lumped``: order of the lumped model (default 4).
    axial_velocity : float
        ``lumped``: default top-drive axial velocity, m/s.
    surface_torque : float
        ``state``: default (open-loop) surface torque, N m (the default slack-off is ``wob``).
    design_model : ControlAffineModel, optional
        ``state``: use this design model instead of building it from ``design``.
    bit : BitParams, optional
        The bit (default: the model's preset's, Tables 2.1, 3.1, 5.1).

    Returns
    -------
    SilPlant
        The plant with its command layout, open-loop (default) and safe commands.

    Raises
    ------
    DownholeInputError
        Unknown model or interface.
    """
    if model == "lumped":
        from downhole.string.fem import DirectionalPlant
        from downhole.string.lumped import lumped_model

        if bit is None:
            lm = lumped_model(lumped_preset, order=order)
        else:
            from downhole.params import get_preset

            lm = lumped_model(get_preset(lumped_preset).string, bit, order=order)
        p = DirectionalPlant(lm, dt=dt, mode="velocity", depth_of_cut=depth_of_cut)
        names = p.command_names
        return SilPlant(p, names, {names[0]: axial_velocity, names[1]: top_drive_speed},
                        {names[0]: 0.0, names[1]: 0.0}, name=f"lumped {lumped_preset} order "
                        f"{order}", info={"model": "lumped", "interface": "lumped"})
    if model == "neutral":
        from downhole.string.fem import DirectionalPlant
        from downhole.string.neutral import NOMINAL_U_A, NOMINAL_U_T, neutral_model

        if bit is None:
            nm = neutral_model("table_3_1")
        else:
            from downhole.params import get_preset

            nm = neutral_model(get_preset("table_3_1").string, bit)
        p = DirectionalPlant(nm, dt=dt, depth_of_cut=depth_of_cut)
        names = p.command_names
        return SilPlant(p, names, {names[0]: NOMINAL_U_A - p.model.hang_command,
                                   names[1]: NOMINAL_U_T},
                        {names[0]: 0.0, names[1]: 0.0}, name="neutral table_3_1",
                        info={"model": "neutral", "interface": "neutral"})
    from downhole.string.fem import fem_model
    from downhole.string.hybrid import HYBRID_PRESETS, hybrid_model

    kw = {} if bit is None else {"bit": bit}
    if model in HYBRID_PRESETS:
        dmodel = hybrid_model(model, **kw)
    elif model == "fem":
        dmodel = fem_model(n_elements=n_elements, **kw)
    else:
        raise DownholeInputError(f"unknown plant model {model!r}; expected one of "
                                 f"{(*HYBRID_PRESETS, 'fem', 'lumped', 'neutral')}")
    info = {"model": model, "interface": interface, "n_states": dmodel.n_states}
    if interface == "surface":
        from downhole.control.topdrive import Hook, TopDrive
        from downhole.string.fem import DirectionalPlant

        p = DirectionalPlant(dmodel, dt, top_drive=TopDrive(speed=top_drive_speed),
                             hook=Hook(wob=wob), depth_of_cut=depth_of_cut)
        hl0 = dmodel.buoyed_weight - wob
        return SilPlant(p, ("hook_load", "top_drive_angular_velocity"),
                        {"hook_load": hl0, "top_drive_angular_velocity": top_drive_speed},
                        {"hook_load": dmodel.buoyed_weight, "top_drive_angular_velocity": 0.0},
                        name=dmodel.name, info=info)
    if interface == "state":
        from downhole.control.dhp.directional import DirectionalStatePlant

        dm = design_model if design_model is not None else _design_model(design)
        p = DirectionalStatePlant(dmodel, dm, dt, depth_of_cut=depth_of_cut)
        info["design"] = design
        sp = SilPlant(p, ("slack_off_force", "surface_torque"),
                      {"slack_off_force": wob, "surface_torque": surface_torque},
                      {"slack_off_force": 0.0, "surface_torque": 0.0},
                      name=dmodel.name, state_names=dm.state_names, info=info)
        sp.units.update(zip(dm.state_names, dm.state_units()))  # m, rad, m/s, rad/s by kind
        return sp
    raise DownholeInputError(f"interface must be 'surface' or 'state', got {interface!r}")


def rig_plant(model, dt: float, *, inertia: float, kp: float, ki: float, speed: float,
              wob: float, servo_stiffness: float = 1e7, servo_damping: float = 1e6,
              block_mass: float = 0.0, depth_of_cut: str = "delayed",
              name: str = "described") -> SilPlant:
    """The surface-interface SIL plant of a described system's model at any fidelity: the rig's
    PI top drive and force hook on the model's top node (a lumped chain and the neutral line
    run under the rig's node, docs/scenarios.md), commands ``hook_load`` and
    ``top_drive_angular_velocity``.

    Parameters
    ----------
    model : ChainModel, NeutralModel or DirectionalModel
        ``DrillingSystem.build(fidelity)``.
    dt : float
        Step, s.
    inertia, kp, ki : float
        The top drive: kg m^2, N m s/rad, N m/rad.
    speed : float
        The PI's open-loop set-point, rad/s.
    wob : float
        The force hook's WOB at the open-loop hook load, N.
    servo_stiffness, servo_damping, block_mass : float
        The hook servo (N/m, N s/m) and the block, kg.
    depth_of_cut : {"delayed", "approximate"}
        The bit's depth-of-cut model.
    name : str
        The plant's name.

    Returns
    -------
    SilPlant
    """
    from downhole.control.topdrive import Hook, TopDrive
    from downhole.string.fem import DirectionalPlant

    p = DirectionalPlant(model, dt, top_drive=TopDrive(inertia=inertia, mode="pi", speed=speed,
                                                       kp=kp, ki=ki),
                         hook=Hook(mode="force", wob=wob, servo_stiffness=servo_stiffness,
                                   servo_damping=servo_damping, block_mass=block_mass),
                         depth_of_cut=depth_of_cut)
    dflt = p.default_command()
    weight = dflt["hook_load"] + wob
    return SilPlant(p, ("hook_load", "top_drive_angular_velocity"),
                    {"hook_load": dflt["hook_load"], "top_drive_angular_velocity": speed},
                    {"hook_load": weight, "top_drive_angular_velocity": 0.0}, name=name,
                    info={"model": "described", "interface": "surface",
                          "n_states": 4 * p._pk.model.n_nodes})
