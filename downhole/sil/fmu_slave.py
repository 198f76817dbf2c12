"""Source of the exported FMU (FMI 2.0 co-simulation, pythonfmu): the plant of a scenario.

This file is copied into the FMU by :func:`downhole.sil.fmu.export_fmu` as ``DownholePlant``'s
script; it is the FMU's only code. The FMU's resources hold data only: the scenario's text
(``scenario.toml``), the data files it names (a survey CSV) and ``fmu.json`` (format, fidelity,
options such as the display units, the downhole version that exported it). Every instance
rebuilds its plant from them with the installed downhole package
(:func:`downhole.sil.fmu.load_fmu_plant`): the scenario is validated as any scenario file is,
and an invalid one fails the instantiation with its one-line message in the FMU log.

Inputs are the plant's command signals (:mod:`downhole.signals`), named ``command_<name>`` (start
value: the scenario's set-points; the prefix keeps a command apart from the observation of the
same name, e.g. ``top_drive_angular_velocity``); outputs are the plant's observation signals
under their registry names, except the plant's simulated time, output as ``sim_time`` (a
variable named ``time`` clashes with the importer's own time column). Every variable carries
its SI unit and description from :mod:`downhole.signals` (the units declared in
``<UnitDefinitions>`` with their SI base-unit exponents), the constant ``bit_radius`` (m, for
the MSE) is exported when the plant's bit is known, and the default experiment runs from 0 to
the scenario's duration at the plant's step.
``do_step`` advances ``round(step_size / dt)`` plant steps holding the inputs (the
communication step must be a whole multiple of the plant's ``dt``, the FMU's default step
size, and at most :data:`~downhole.sil.fmu.MAX_STEP_SECONDS` of simulated time and
:data:`~downhole.sil.fmu.MAX_STEPS_PER_DO_STEP` plant steps: a larger, negative or non-finite
step is an FMI error with the reason in the FMU log, returned before any plant step); a
rejected command (non-finite, out of its range) fails the step with the plant's reason in the
FMU log and is never applied.
"""

import math
from pathlib import Path
from xml.etree.ElementTree import Element, SubElement

from pythonfmu import DefaultExperiment, Fmi2Causality, Fmi2Slave, Fmi2Variability, Real
from pythonfmu.enums import Fmi2Initial, Fmi2Status

from downhole.sil.fmu import MAX_STEP_SECONDS, MAX_STEPS_PER_DO_STEP, TIME_OUTPUT, load_fmu_plant

_BASE = {"kilogram": "kg", "meter": "m", "second": "s", "ampere": "A", "kelvin": "K",
         "mole": "mol", "candela": "cd", "radian": "rad"}


class UnitReal(Real):
    """A Real variable with a ``unit`` (pythonfmu 0.7 writes no units of its own)."""

    def __init__(self, name, unit=None, display_unit=None, **kwargs):
        super().__init__(name, **kwargs)
        self.unit = unit or None
        self.display_unit = display_unit if (unit and display_unit and display_unit != unit) \
            else None

    def to_xml(self):
        node = super().to_xml()
        if self.unit:
            node.find("Real").set("unit", self.unit)
        if self.display_unit:
            node.find("Real").set("displayUnit", self.display_unit)
        return node


def unit_definition(unit: str, display_units=()) -> Element:
    """``<Unit name=...><BaseUnit .../><DisplayUnit .../></Unit>`` of a pint unit string (SI
    base exponents); each display unit with its FMI factor (display = factor * value, pint)."""
    from downhole.units import _registry

    node = Element("Unit", {"name": unit})
    base = _registry().Quantity(1.0, unit).to_base_units()
    attrib = {}
    for name, power in base.units._units.items():
        attrib[_BASE[name]] = str(int(power))
    if float(base.magnitude) != 1.0:
        attrib["factor"] = f"{float(base.magnitude):.16g}"
    SubElement(node, "BaseUnit", attrib)
    for d in sorted(set(display_units)):
        factor = float(_registry().Quantity(1.0, unit).to(d).magnitude)
        SubElement(node, "DisplayUnit", {"name": d, "factor": f"{factor:.16g}"})
    return node


def _signal(name: str, plant=None):
    """``(unit, description)`` of a plant signal: the registry's, else the plant's own unit
    (a design-model state of the DHP ``state`` interface)."""
    from downhole.signals import SIGNALS

    sig = SIGNALS.get(name)
    if sig is not None:
        return sig.unit, sig.description
    unit = (getattr(plant, "units", None) or {}).get(name, "")
    if name in tuple(getattr(plant, "state_names", ()) or ()):
        return unit, f"state {name} of the controller's design model"
    return unit, ""


class DownholePlant(Fmi2Slave):
    """downhole drill-string plant, rebuilt from the scenario in the resources."""

    author = "downhole"
    description = "downhole drill-string plant: inputs = command_<signal>, outputs = signals"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        from downhole.sim.plant import plant_bit_radius

        self._plant, settings, system = load_fmu_plant(Path(self.resources))

        def shown(name, unit):  # the display unit of a signal (None: its SI unit)
            return system.unit_of(name, unit) if (system is not None and unit) else None

        self._reset = {"start": settings["start"], "set_point": settings["set_point"]}
        self._dt = float(self._plant.dt)
        self.default_experiment = DefaultExperiment(
            start_time=0.0, stop_time=float(settings["stop_time"]),
            step_size=self._dt)
        self._in = [f"command_{c}" for c in self._plant.command_names]
        start_values = dict(self._plant.default_command(), **settings["command_start"])
        for c, v in start_values.items():
            setattr(self, f"command_{c}", float(v))
            unit, desc = _signal(c)
            self.register_variable(UnitReal(f"command_{c}", unit=unit,
                                            display_unit=shown(c, unit),
                                            description=f"command: {desc}" if desc else
                                            f"command {c}",
                                            causality=Fmi2Causality.input,
                                            variability=Fmi2Variability.continuous))
        #: (FMU variable name, observation key)
        self._out = [(TIME_OUTPUT if n == "time" else n, n)
                     for n in self._plant.observation_names]
        self._set_outputs(self._plant.reset(**self._reset))
        for var, n in self._out:
            unit, desc = _signal(n, self._plant)
            self.register_variable(UnitReal(var, unit=unit, display_unit=shown(n, unit),
                                            description=desc or n,
                                            causality=Fmi2Causality.output,
                                            variability=Fmi2Variability.continuous))
        radius = plant_bit_radius(self._plant)
        if radius is not None:
            self.bit_radius = radius
            self.register_variable(UnitReal("bit_radius", unit="m",
                                            display_unit=system.kind_unit("diameter")
                                            if system is not None else None,
                                            description="bit radius (for the mechanical "
                                            "specific energy)",
                                            causality=Fmi2Causality.local,
                                            variability=Fmi2Variability.constant,
                                            initial=Fmi2Initial.exact))

    def to_xml(self, model_options=None):
        root = super().to_xml(model_options or {})
        units = sorted({v.unit for v in self.vars.values() if getattr(v, "unit", None)})
        if units:
            defs = Element("UnitDefinitions")
            for u in units:
                defs.append(unit_definition(u, [v.display_unit for v in self.vars.values()
                                                if getattr(v, "unit", None) == u
                                                and getattr(v, "display_unit", None)]))
            children = list(root)
            at = children.index(root.find("CoSimulation")) + 1  # the FMI 2.0 element order
            root.insert(at, defs)
        return root

    def _set_outputs(self, obs):
        for var, n in self._out:
            setattr(self, var, float(obs.get(n, 0.0)))

    def exit_initialization_mode(self):
        self._set_outputs(self._plant.reset(**self._reset))

    def do_step(self, current_time, step_size):
        if not (isinstance(step_size, (int, float)) and math.isfinite(step_size)
                and step_size > 0):
            self.log(f"doStep refused: the communication step {step_size!r} s is not a "
                     "positive finite number",
                     Fmi2Status.error)
            return False
        limit = min(MAX_STEP_SECONDS, MAX_STEPS_PER_DO_STEP * self._dt)
        if step_size > limit * (1.0 + 1e-12):
            self.log(f"doStep refused: a communication step of {step_size:g} s exceeds the "
                     f"limit of {limit:g} s per doStep (at most {MAX_STEP_SECONDS:g} s of "
                     f"simulated time and {MAX_STEPS_PER_DO_STEP} plant steps of dt = "
                     f"{self._dt:g} s); use communication steps of at most {limit:g} s",
                     Fmi2Status.error)
            return False
        n = round(step_size / self._dt)
        if n < 1 or abs(n * self._dt - step_size) > 1e-9 * max(1.0, step_size):
            self.log(f"step size {step_size!r} s is not a whole multiple of the plant's dt = "
                     f"{self._dt!r} s", Fmi2Status.error)
            return False
        cmd = {c[8:]: float(getattr(self, c)) for c in self._in}
        obs = None
        try:
            for _ in range(n):
                obs = self._plant.step(cmd)
        except Exception as exc:
            self.log(f"t = {current_time:g} s: {type(exc).__name__}: {exc}", Fmi2Status.error)
            return False
        self._set_outputs(obs)
        return True
