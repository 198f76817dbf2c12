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
from pathlib import Path

import numpy as np

from downhole.errors import DownholeInputError
from downhole.sim.result import Result

__all__ = ["SurfacePI", "pi_controller_for", "load_controller_file", "run_offline",
           "CODE_REFUSED"]


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


#: The one-line refusal of a Python controller file without the opt-in (``{path}`` filled in).
CODE_REFUSED = ("controller file {path} is Python code: it runs only on explicit request "
                "(--allow-code on the command line, allow_code=True from Python)")


def load_controller_file(path, plant=None, *, allow_code: bool = False):
    """Load a controller from ``path``.

    - ``*.json`` / ``*.npz``: a saved DHP controller (:func:`downhole.control.dhp.load_controller`;
      data only, no code is executed);
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
        Missing file, unknown suffix, a Python file without ``allow_code``, or a module without
        either name.
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
