"""Controllers for the SIL testbed and loading a controller from a file.

Any object with ``reset()`` and ``command(t, observation, reference) -> dict`` is a controller;
it runs unchanged offline (:func:`run_offline`), in the real-time loop and over the network.
:class:`SurfacePI` is a simple bit-speed PI for plants with a ``surface`` or ``lumped``
interface (it honours reference changes); DHP controllers come from
:mod:`downhole.control.dhp` (``state`` interface). :func:`load_controller_file` reads a DHP
controller (``.json``/``.npz``, data only) or, on explicit request (``allow_code=True``, the
command line's ``--allow-code``), a Python file defining ``make_controller()`` or ``controller``.
A Python file is code: it is never executed because a scenario names it.
"""

from __future__ import annotations

import importlib.util
import math
from pathlib import Path

import numpy as np

from downhole.errors import DownholeInputError
from downhole.sim.result import Result

__all__ = [
    "CODE_REFUSED",
    "ManualFill",
    "SurfacePI",
    "controller_choices",
    "load_controller_file",
    "pi_controller_for",
    "plant_stick_slip_frequency",
    "plant_torsional_impedance",
    "run_offline",
]


class SurfacePI:
    """Bit-velocity PI acting on the surface commands.

    Angular: set-point = omega_ref + kp_w (omega_ref - omega_bit) + ki_w int(...), >= 0.
    Axial (``hook_load`` plants): hook load = ``weight`` - WOB command, WOB command =
    ``wob0`` + kp_v (v_ref - v_bit) + ki_v int(...), clipped to [0, ``wob_max``].
    Axial (``top_drive_axial_velocity`` plants): the top feeds at v_ref.

    Parameters
    ----------
    command_names : (str, str)
        The plant's commands.
    weight : float
        Hook load at zero WOB (buoyed string weight), N (``hook_load`` plants).
    wob0, wob_max : float
        Initial and largest WOB command, N.
    kp_w, ki_w : float
        Angular gains (1/1, 1/s).
    kp_v, ki_v : float
        Axial gains (N s/m, N/m).
    dt : float
        Controller step, s (for the integrators).
    """

    def __init__(self, command_names, *, weight: float = 0.0, wob0: float = 120e3,
                 wob_max: float = 300e3, kp_w: float = 0.3, ki_w: float = 0.2,
                 kp_v: float = 2e6, ki_v: float = 1e6, dt: float = 1e-3):
        self.command_names = tuple(command_names)
        self.weight, self.wob0, self.wob_max = float(weight), float(wob0), float(wob_max)
        self.kp_w, self.ki_w, self.kp_v, self.ki_v = map(float, (kp_w, ki_w, kp_v, ki_v))
        self.dt = float(dt)
        self.reset()

    def reset(self) -> None:
        self._iw = 0.0
        self._iv = 0.0

    def command(self, t: float, observation: dict, reference=None) -> dict:
        ref = reference or {}
        w_ref = float(ref.get("reference_angular_velocity",
                              observation.get("reference_angular_velocity", 20.0)))
        v_ref = float(ref.get("reference_axial_velocity",
                              observation.get("reference_axial_velocity", 0.01)))
        ew = w_ref - observation["bit_angular_velocity"]
        self._iw = float(np.clip(self._iw + self.dt * ew, -50.0, 50.0))
        sp = max(0.0, w_ref + self.kp_w * ew + self.ki_w * self._iw)
        ax, tq = self.command_names
        if ax == "hook_load":
            ev = v_ref - observation["bit_axial_velocity"]
            self._iv = float(np.clip(self._iv + self.dt * ev, -self.wob_max / max(self.ki_v, 1e-9),
                                     self.wob_max / max(self.ki_v, 1e-9)))
            wob = float(np.clip(self.wob0 + self.kp_v * ev + self.ki_v * self._iv, 0.0,
                                self.wob_max))
            return {ax: self.weight - wob, tq: sp}
        return {ax: v_ref, tq: sp}


def pi_controller_for(plant, **kw) -> SurfacePI:
    """A :class:`SurfacePI` matching a :class:`~downhole.sil.plants.SilPlant`'s commands."""
    names = plant.command_names
    if names[1] != "top_drive_angular_velocity":
        raise DownholeInputError(f"the PI needs a speed-controlled top drive (interface "
                                 f"'surface' or 'lumped'); this plant takes {names}")
    weight = plant.safe_command().get("hook_load", 0.0)
    d = plant.default_command()
    kw.setdefault("wob0", weight - d["hook_load"] if "hook_load" in d else 0.0)
    return SurfacePI(names, weight=weight, dt=plant.dt, **kw)


class ManualFill:
    """A controller that sets only some of the plant's commands, completed by the runner's
    open-loop (manual) command: e.g. Z-torque sets the top-drive speed and the axial command
    follows the driller's set-point (ROP or WOB) instead of the last value of the previous
    controller.

    Parameters
    ----------
    controller : object
        ``reset()`` and ``command(t, observation, reference)``.
    runner : RealTimeRunner
        Whose :attr:`manual_command` fills the commands the controller does not return.
    """

    def __init__(self, controller, runner):
        self.inner = controller
        self.runner = runner
        self.needs = tuple(getattr(controller, "needs", ()) or ())
        self.commands = tuple(runner.plant.command_names)

    def reset(self) -> None:
        self.inner.reset()

    def command(self, t: float, observation: dict, reference=None) -> dict:
        out = dict(self.runner.manual_command)
        out.update(self.inner.command(t, observation, reference))
        return out


def plant_torsional_impedance(plant) -> float | None:
    """Characteristic torsional impedance of the top of ``plant``'s string, N m s/rad, or None
    when the plant does not say.

    A directional (FEM / hybrid) plant: J sqrt(rho G) of the top pipe section. A lumped chain:
    sqrt(k J) of its top element (stiffness to the top drive times inertia), which is the same
    quantity for an element cut from a uniform pipe (k = G J_p / L, J = rho J_p L).
    """
    inner = getattr(plant, "plant", plant)
    model = getattr(inner, "model", None)
    string = getattr(model, "string", None)
    try:
        return float(string.segments[0].section.torsional_impedance)
    except (AttributeError, IndexError, TypeError):
        pass
    tors = getattr(model, "torsional", None)
    try:
        k, j = float(tors.k_top), float(np.asarray(tors.mass)[0])
    except (AttributeError, IndexError, TypeError, ValueError):
        return None
    return math.sqrt(k * j) if k > 0 and j > 0 else None


def plant_stick_slip_frequency(plant) -> float | None:
    """The first torsional natural frequency of ``plant``'s string with the top clamped, rad/s
    (SoftSpeed's w_s), or None when the plant does not say: a lumped chain's first torsional
    mode, a FEM string's (a hybrid model has no modal analysis of its own)."""
    from downhole.errors import DownholeInputError as _Refused

    inner = getattr(plant, "plant", plant)
    model = getattr(inner, "model", None)
    nf = getattr(model, "natural_frequencies", None)
    if nf is None:
        return None
    try:
        if hasattr(model, "torsional") and not hasattr(model, "string"):  # lumped chain
            w = float(np.asarray(nf()["torsional"])[0])
        else:
            w = float(np.asarray(nf("torsional", 1, top="fixed"))[-1])
    except (_Refused, AttributeError, IndexError, KeyError, TypeError, ValueError):
        return None
    return w if math.isfinite(w) and w > 0 else None


def controller_choices(plant, scenario_controller=None, scenario_label: str | None = None) -> dict:
    """The controllers an operator can switch ``plant`` to: ``{name: (label, factory)}``, where
    ``factory()`` builds a fresh controller.

    - ``scenario``: the scenario's own controller (DHP, a file), when it is not the PI;
    - ``pi``: :class:`SurfacePI` (a speed-controlled top drive: interfaces ``surface``,
      ``lumped``);
    - ``ztorque``: :class:`~downhole.control.ztorque.ZTorque` with the impedance of the top of
      the string (:func:`plant_torsional_impedance`), when the plant observes the surface
      torque and takes a top-drive speed command;
    - ``softspeed``: :class:`~downhole.control.softspeed.SoftSpeed` (P = Z, I = J w_s^2, J the
      package's top-drive inertia) where, in addition, the stick-slip frequency is known
      (:func:`plant_stick_slip_frequency`).

    The speed set-point of each is the reference ``reference_angular_velocity`` (the driller's
    surface rpm).
    """
    out: dict = {}
    if scenario_controller is not None and not isinstance(scenario_controller, SurfacePI):
        out["scenario"] = (scenario_label or type(scenario_controller).__name__,
                           lambda: scenario_controller)
    names = tuple(plant.command_names)
    speed = len(names) == 2 and names[1] == "top_drive_angular_velocity"
    if speed:
        out["pi"] = ("PI (bit speed)", lambda: pi_controller_for(plant))
    z = plant_torsional_impedance(plant)
    if (speed and z is not None and "surface_torque" in plant.observation_names):
        from downhole.control.ztorque import ZTorque

        out["ztorque"] = (f"Z-torque (Z = {z:.0f} N m s/rad)",
                          lambda: ZTorque(z, dt=plant.dt))
        ws = plant_stick_slip_frequency(plant)
        if ws is not None:
            from downhole.control.softspeed import SoftSpeed
            from downhole.params.rig import DEFAULT_TOP_DRIVE_INERTIA

            out["softspeed"] = (f"SoftSpeed (w_s = {ws:.3g} rad/s)",
                                lambda: SoftSpeed(impedance=z, frequency=ws,
                                                  inertia=DEFAULT_TOP_DRIVE_INERTIA,
                                                  dt=plant.dt))
    return out


#: The one-line refusal of a Python controller file without the opt-in (``{path}`` filled in).
CODE_REFUSED = ("controller file {path} is Python code: it runs only on explicit request "
                "(--allow-code on the command line, allow_code=True from Python)")


def load_controller_file(path, plant=None, *, allow_code: bool = False):
    """Load a controller from ``path``.

    - ``*.json`` / ``*.npz``: a saved DHP controller (:func:`downhole.control.dhp.load_controller`: data only, no code
      is executed, every field checked);
    - ``*.py``: a module defining ``make_controller(plant)`` (called with the SilPlant, or None)
      or a ``controller`` object. Importing it executes it, so it is loaded only with
      ``allow_code=True``.

    Parameters
    ----------
    path : path-like
        The controller file.
    plant : SilPlant, optional
        Passed to ``make_controller(plant)``.
    allow_code : bool, keyword-only
        Allow executing a Python file (the command line's ``--allow-code``). Default False.

    Raises
    ------
    DownholeInputError
        Missing file, unknown suffix, a Python file without ``allow_code``, a module without
        either name, or a saved DHP controller that :func:`downhole.control.dhp.load_controller` refuses.
    """
    path = Path(path)
    if path.suffix in (".json", ".npz"):
        from downhole.control.dhp import load_controller

        return load_controller(path)
    if path.suffix != ".py":
        raise DownholeInputError(f"controller file {path}: expected .py, .json or .npz")
    if allow_code is not True:
        raise DownholeInputError(CODE_REFUSED.format(path=path))
    if not path.exists():
        raise DownholeInputError(f"controller file {path} does not exist")
    spec = importlib.util.spec_from_file_location(f"_downhole_user_ctrl_{path.stem}", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    if hasattr(mod, "make_controller"):
        ctrl = mod.make_controller(plant)
    elif hasattr(mod, "controller"):
        ctrl = mod.controller
    else:
        raise DownholeInputError(f"controller file {path} defines neither make_controller(plant) "
                                 "nor controller")
    if not (hasattr(ctrl, "command") and hasattr(ctrl, "reset")):
        raise DownholeInputError(f"controller from {path} lacks reset() / command(t, obs, ref)")
    return ctrl


def run_offline(plant, controller, duration: float, *, reference: dict | None = None,
                record_every: int = 10) -> Result:
    """The same closed loop as the real-time runner, unpaced and without a link.

    Step ``k``: command from the observation at ``k dt``, held over the step. Recorded
    channels match :class:`~downhole.sil.runtime.RealTimeRunner`'s.
    """
    from downhole.sil.runtime import RealTimeRunner

    rt = RealTimeRunner(plant, controller, reference=reference, paced=False,
                        record_every=record_every)
    return rt.run(duration)
