"""Controllers from outside the package: a Gymnasium policy, a controller file, a saved DHP."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from downhole.control.base import Controller
from downhole.errors import DownholeInputError

__all__ = ["GymPolicy", "gym_policy", "load_controller_spec"]


class GymPolicy(Controller):
    """A Gymnasium policy ``policy(obs) -> action`` of ``downhole/Drilling-v0`` as a controller.

    The observation vector and the action map are the environment's (:mod:`downhole.gym`):
    obs = [v_bit / v_s, omega_bit / w_s, WOB / 1e5, TOB / 1e4, omega_td / w_s, v_ref / v_s,
    omega_ref / w_s] (float32), action in [-1, 1]^2 mapped to WOB 0..``wob_max`` (hook load =
    ``weight`` - WOB) and speed 0..``omega_max``; the action is held for ``control_dt`` s. A
    policy that returns ``(action, state)`` (stable-baselines' ``predict``) is accepted.

    Parameters
    ----------
    policy : callable
    weight : float
        Hook load at zero WOB (the string's buoyed weight), N.
    control_dt, wob_max, omega_max : float
        As in :class:`downhole.gym.DrillingEnv`.
    """

    needs = ("bit_axial_velocity", "bit_angular_velocity", "wob", "tob",
             "top_drive_angular_velocity")
    commands = ("hook_load", "top_drive_angular_velocity")

    def __init__(self, policy, *, weight: float, control_dt: float = 0.05,
                 wob_max: float = 250e3, omega_max: float = 40.0):
        if not callable(policy):
            raise DownholeInputError(f"a Gymnasium policy must be callable obs -> action, got "
                                     f"{type(policy).__name__}")
        self.policy = policy
        self.weight, self.control_dt = float(weight), float(control_dt)
        self.wob_max, self.omega_max = float(wob_max), float(omega_max)
        self.reset()

    def reset(self) -> None:
        self._next = 0.0
        self._held = None

    def command(self, t, observation, reference=None) -> dict:
        from downhole.gym import V_S, W_S

        if self._held is not None and t < self._next - 1e-9:
            return self._held
        ref = reference or {}
        v_ref = float(ref.get("reference_axial_velocity", 0.0))
        w_ref = float(ref.get("reference_angular_velocity", 0.0))
        o = observation
        vec = np.array([o["bit_axial_velocity"] / V_S, o["bit_angular_velocity"] / W_S,
                        o["wob"] / 1e5, o["tob"] / 1e4, o["top_drive_angular_velocity"] / W_S,
                        v_ref / V_S, w_ref / W_S], dtype=np.float32)
        action = self.policy(vec)
        if isinstance(action, tuple):
            action = action[0]
        a = np.clip(np.asarray(action, float).reshape(-1), -1.0, 1.0)
        if a.size != 2 or not np.all(np.isfinite(a)):
            raise DownholeInputError(f"the policy must return 2 finite actions, got {action!r}")
        frac = (a + 1.0) / 2.0
        self._held = {"hook_load": self.weight - float(frac[0]) * self.wob_max,
                      "top_drive_angular_velocity": float(frac[1]) * self.omega_max}
        self._next = t + self.control_dt
        return self._held


def gym_policy(policy, *, label: str = "gym-policy", **options):
    """A factory ``(system, case) -> GymPolicy`` for :func:`downhole.compare.compare_controllers`
    (the weight at zero WOB is the case's FEM's buoyed weight); ``options`` go to
    :class:`GymPolicy`."""
    def factory(system, case):
        weight = system.build("fem", n_elements=case.n_elements).buoyed_weight
        return GymPolicy(policy, weight=weight, **options)

    factory.__name__ = label
    factory.label = label
    factory.description = f"Gymnasium policy {getattr(policy, '__name__', type(policy).__name__)}"
    return factory


def load_controller_spec(path, *, allow_code: bool = False):
    """The controller in ``path`` for the benchmark: a saved DHP (``.json``/``.npz``; a
    factory that runs it from the surface on the cases of the string it was trained on,
    :func:`downhole.compare.observed.dhp_for_case`, and is ``n/a`` elsewhere with the reason) or, with ``allow_code``, a Python file defining
    ``make_controller(plant)`` (called with None) or ``controller``
    (:func:`downhole.sil.controllers.load_controller_file`).

    Raises
    ------
    DownholeInputError
        One line naming the file and what is wrong with it.
    """
    from downhole.sil.controllers import load_controller_file

    p = Path(path)
    if p.suffix in (".json", ".npz") and not p.exists():
        raise DownholeInputError(f"controller file {p} does not exist")
    try:
        ctrl = load_controller_file(p, None, allow_code=allow_code)
    except DownholeInputError:
        raise
    except Exception as exc:
        msg = str(exc).splitlines()[0] if str(exc) else ""
        raise DownholeInputError(f"controller file {p}: {type(exc).__name__}: {msg}") from None
    if p.suffix in (".json", ".npz"):
        from downhole.compare.observed import dhp_for_case

        return dhp_for_case(ctrl, label=p.stem)
    ctrl.label = getattr(ctrl, "label", None) or p.stem
    if not isinstance(getattr(ctrl, "label", None), str):
        ctrl.label = p.stem
    return ctrl
