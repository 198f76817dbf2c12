"""Source of the exported FMU (FMI 2.0 co-simulation, pythonfmu): a plant of the Plant contract.

This file is copied into the FMU by :func:`downhole.sil.fmu.export_fmu` (a SIL scenario, as
``scenario.toml`` beside it) or :func:`downhole.sil.fmu.export_plant_fmu` (any plant object of
the :class:`~downhole.sim.plant.Plant` contract at any fidelity, pickled as ``plant.pkl``, with
its start mode in ``start.json``) as ``DownholePlant``'s script.

Inputs are the plant's command signals (:mod:`downhole.signals`), named ``command_<name>`` (start
value: the plant's default command; the prefix keeps a command apart from the observation of the
same name, e.g. ``top_drive_angular_velocity``); outputs are the plant's observation signals
under their registry names. ``do_step`` advances ``round(step_size / dt)`` plant steps holding
the inputs (the communication step must be a whole multiple of the plant's ``dt``, the FMU's
default step size); a rejected command (non-finite, out of its range) fails the step with the
plant's reason in the FMU log and is never applied. The FMU imports downhole from the Python
environment that runs it (the pickled plant needs the downhole version that exported it).
"""

import json
import pickle
from pathlib import Path

from pythonfmu import DefaultExperiment, Fmi2Causality, Fmi2Slave, Fmi2Variability, Real
from pythonfmu.enums import Fmi2Status


def _load_plant(resources: Path):
    """``(plant, settings)`` from the FMU's resources (settings: ``start``, ``set_point``,
    ``command_start``)."""
    if (resources / "plant.pkl").is_file():
        with open(resources / "plant.pkl", "rb") as fh:
            plant = pickle.load(fh)
        start = json.loads((resources / "start.json").read_text())
        return plant, start

    from downhole.sil.scenario import build_from_scenario, load_sil_scenario

    sc = load_sil_scenario(resources / "scenario.toml")
    plant, _ = build_from_scenario(sc, with_controller=False)
    return plant, {"start": "rest", "set_point": None, "command_start": {}}


class DownholePlant(Fmi2Slave):
    """downhole drill-string plant (see the resources: scenario.toml or plant.pkl)."""

    author = "downhole"
    description = "downhole drill-string plant: inputs = command_<signal>, outputs = signals"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self._plant, settings = _load_plant(Path(self.resources))
        self._reset = {"start": settings["start"], "set_point": settings["set_point"]}
        self._dt = float(self._plant.dt)
        self.default_experiment = DefaultExperiment(start_time=0.0, step_size=self._dt)
        self._in = [f"command_{c}" for c in self._plant.command_names]
        start_values = dict(self._plant.default_command(), **settings.get("command_start", {}))
        for c, v in start_values.items():
            setattr(self, f"command_{c}", float(v))
            self.register_variable(Real(f"command_{c}", causality=Fmi2Causality.input,
                                        variability=Fmi2Variability.continuous))
        self._out = list(self._plant.observation_names)
        self._set_outputs(self._plant.reset(**self._reset))
        for n in self._out:
            self.register_variable(Real(n, causality=Fmi2Causality.output,
                                        variability=Fmi2Variability.continuous))

    def _set_outputs(self, obs):
        for n in self._out:
            setattr(self, n, float(obs.get(n, 0.0)))

    def exit_initialization_mode(self):
        self._set_outputs(self._plant.reset(**self._reset))

    def do_step(self, current_time, step_size):
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
        except Exception as exc:  # noqa: BLE001 - the reason goes to the importer's log
            self.log(f"t = {current_time:g} s: {type(exc).__name__}: {exc}", Fmi2Status.error)
            return False
        self._set_outputs(obs)
        return True
