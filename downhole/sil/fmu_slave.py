"""Source of the exported FMU (FMI 2.0 co-simulation, pythonfmu): the scenario's plant.

This file is copied into the FMU by :func:`downhole.sil.fmu.export_fmu` as ``DownholePlant``'s
script, with the scenario as ``scenario.toml`` beside it. Inputs are the plant's surface
commands, named ``command_<name>`` (start value: the scenario's open-loop command); outputs
are the plant's named signals. ``do_step`` advances ``round(step_size / dt)`` plant steps
holding the inputs (the communication step must be a multiple of the scenario's dt). The FMU
imports downhole from the Python environment that runs it.
"""

from pathlib import Path

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real


class DownholePlant(Fmi2Slave):
    """downhole drill-string plant (see the scenario.toml resource)."""

    author = "downhole"
    description = "downhole drill-string plant: inputs = surface commands, outputs = signals"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        from downhole.sil.scenario import build_from_scenario, load_sil_scenario

        sc = load_sil_scenario(Path(self.resources) / "scenario.toml")
        self._plant, _ = build_from_scenario(sc, with_controller=False)
        self._dt = self._plant.dt
        self._in = [f"command_{c}" for c in self._plant.command_names]
        for c, v in self._plant.default_command().items():
            setattr(self, f"command_{c}", float(v))
            self.register_variable(Real(f"command_{c}", causality=Fmi2Causality.input,
                                        variability=Fmi2Variability.continuous))
        self._out = [n for n in self._plant.observation_names]
        self._set_outputs(self._plant.reset())
        for n in self._out:
            self.register_variable(Real(n, causality=Fmi2Causality.output,
                                        variability=Fmi2Variability.continuous))

    def _set_outputs(self, obs):
        for n in self._out if hasattr(self, "_out") else obs:
            setattr(self, n, float(obs.get(n, 0.0)))

    def exit_initialization_mode(self):
        self._set_outputs(self._plant.reset())

    def do_step(self, current_time, step_size):
        n = int(round(step_size / self._dt))
        if n < 1 or abs(n * self._dt - step_size) > 1e-9 * max(1.0, step_size):
            return False
        cmd = {c[8:]: float(getattr(self, c)) for c in self._in}
        obs = None
        for _ in range(n):
            obs = self._plant.step(cmd)
        self._set_outputs(obs)
        return True
