"""Full-state controllers on the benchmark's rig: the surface observer supplies the state, the
rig's own actuators realize the commands.

The benchmark's plant (:func:`~downhole.compare.runner.case_plant`) is a rig: a top drive under
its stiff speed PI (speed set-point in) and a force-driven hook (hook load in) or a block
velocity servo. DHP (Ch. 4) is designed on a torque-driven top drive and a slack-off force and
needs its design model's full state; :func:`observed_dhp` runs it through

- :func:`~downhole.control.observer.dhp_from_surface`: the Kalman filter on the DHP's design
  FEM estimates the state from the top-drive velocities and angle (the block position is
  integrated from the block velocity), nothing downhole;
- :class:`RigActuators`: the slack-off force becomes the hook load ``W - S`` (``W`` the plant's
  buoyed weight) and the surface torque a speed set-point: the rig's PI gives the motor torque
  ``T = kp (w_sp - w) + ki e`` with ``e`` the integral of ``w_sp - w``, so the set-point
  ``w_sp = (T - ki e + kp w) / kp`` (``e`` advanced with the set-point) makes the drive apply
  the torque DHP asked for (within the drive's speed range, ``downhole.signals``; the hook load
  within its range: a hook cannot push, so the slack-off is at most the weight ``W``). The
  adapter's integral starts from the surface torque it first reads (the drive in equilibrium,
  ``T = T_surface``).

EID (Ch. 3) sets the block velocity; on a force-driven hook :class:`VelocityServo` realizes it
as the hook load the rig's block-velocity servo would apply,
``H = H_0 - k (x_ref - x_top) - c (v_cmd - v_top)`` (``k``, ``c`` the hook's servo gains,
``x_ref - x_top`` integrated from the command and the measured block velocity), i.e. the top
boundary EID is designed for (the neutral model's top damper is the servo damping ``c``).

The angles and the block position the observer reads start at zero when the controller starts
(its clock and its reference start then too).
"""

from __future__ import annotations

import math

from downhole.control.base import Controller
from downhole.errors import DownholeInputError

__all__ = ["DHP_SIGNALS", "RigActuators", "VelocityServo", "builtin_dhp", "design_fem",
           "dhp_for_case", "observed_dhp"]

#: Surface signals the actuator adapter reads on top of its inner controller's.
RIG_SIGNALS = ("surface_torque", "top_drive_angular_velocity", "time")


class _Wrapper(Controller):
    """A controller around ``inner``: its step ``dt`` is passed on to ``inner``."""

    @property
    def dt(self):
        return self._dt

    @dt.setter
    def dt(self, value):
        if value is not None:
            self._dt = float(value)
            if hasattr(self.inner, "dt"):
                self.inner.dt = self._dt


class RigActuators(_Wrapper):
    """A controller that sets ``slack_off_force`` and ``surface_torque`` on a rig that takes
    ``hook_load`` and ``top_drive_angular_velocity`` (see the module docstring).

    Parameters
    ----------
    inner : Controller
        Sets ``slack_off_force`` (N) and ``surface_torque`` (N m).
    weight : float
        Hook load at zero slack-off (the plant's buoyed weight), N.
    kp, ki : float
        The rig's top-drive PI gains (N m s/rad, N m/rad).
    speed : float
        The speed set-point held before the controller starts (rad/s): the adapter's integral
        at a hand-over assumes the PI was running on it.
    dt : float
        Step, s.
    hook_servo : (float, float, float), optional
        On a velocity-driven hook: its servo's hook load at zero error (N), stiffness (N/m) and
        damping (N s/m). The adapter then sets the block velocity at which the servo applies
        the hook load ``W - S``: ``v_cmd = v + (H_0 - H - k e) / (c + k dt)``, ``e`` the servo's
        position error (started from the hook load it first reads), the inverse of
        :class:`VelocityServo` (within the block velocity's range, ``downhole.signals``).
    """

    def __init__(self, inner, *, weight: float, kp: float, ki: float, speed: float, dt: float,
                 hook_servo=None):
        for name, v in (("weight", weight), ("kp", kp), ("ki", ki), ("dt", dt)):
            if not (math.isfinite(v) and v > 0):
                raise DownholeInputError(f"RigActuators: {name} must be > 0, got {v!r}")
        inner_cmds = tuple(getattr(inner, "commands", ()) or ())
        if set(inner_cmds) != {"slack_off_force", "surface_torque"}:
            raise DownholeInputError(f"RigActuators: the inner controller must set "
                                     f"slack_off_force and surface_torque, it sets "
                                     f"{list(inner_cmds)}")
        self.inner = inner
        self.weight, self.kp, self.ki = float(weight), float(kp), float(ki)
        self.speed, self._dt = float(speed), float(dt)
        self.hook_servo = None if hook_servo is None else tuple(float(x) for x in hook_servo)
        if self.hook_servo is not None and not (len(self.hook_servo) == 3 and all(
                math.isfinite(x) and x > 0 for x in self.hook_servo[1:])):
            raise DownholeInputError(f"RigActuators: hook_servo must be (hook load, stiffness "
                                     f"> 0, damping > 0), got {hook_servo!r}")
        axial = "hook_load" if self.hook_servo is None else "top_drive_axial_velocity"
        self.commands = (axial, "top_drive_angular_velocity")
        extra = RIG_SIGNALS + (() if self.hook_servo is None else ("hook_load",))
        inner_needs = tuple(getattr(inner, "needs", ()) or ())
        self.needs = inner_needs + tuple(s for s in extra if s not in inner_needs)
        self.label = getattr(inner, "label", type(inner).__name__)
        from downhole.signals import signal

        sig = signal("top_drive_angular_velocity")
        self._w_range = (float(sig.low), float(sig.high))
        sig = signal("hook_load")
        self._h_range = (float(sig.low), float(sig.high))
        sig = signal("top_drive_axial_velocity")
        self._v_range = (float(sig.low), float(sig.high))

    def reset(self) -> None:
        self.inner.reset()
        self._e = None
        self._ex = None

    def command(self, t, observation, reference=None) -> dict:
        if not hasattr(self, "_e"):
            self.reset()
        w = float(observation["top_drive_angular_velocity"])
        if self._e is None:
            # the PI's integral state now: the drive in equilibrium (motor torque = surface
            # torque) under the set-point held so far (none at the plant's start)
            w_prev = self.speed if float(observation.get("time", 0.0)) > 0.0 else w
            self._e = (float(observation["surface_torque"]) - self.kp * (w_prev - w)) / self.ki
        cmd = self.inner.command(t, observation, reference)
        torque = float(cmd["surface_torque"])
        # T = kp (w_sp - w) + ki (e + dt (w_sp - w))  ->  w_sp
        w_sp = w + (torque - self.ki * self._e) / (self.kp + self.ki * self._dt)
        w_sp = min(max(w_sp, self._w_range[0]), self._w_range[1])   # the drive's speed range
        self._e += self._dt * (w_sp - w)
        # a hook holds, it cannot push: the slack-off force is at most the string's weight
        hook = min(max(self.weight - float(cmd["slack_off_force"]), self._h_range[0]),
                   self._h_range[1])
        if self.hook_servo is None:
            return {"hook_load": hook, "top_drive_angular_velocity": w_sp}
        h0, k, c = self.hook_servo
        v = float(observation["top_drive_axial_velocity"])
        if self._ex is None:  # the servo's error now, the block settled on the top's velocity
            self._ex = (h0 - float(observation["hook_load"])) / k
        # H = H_0 - k (e + dt (v_cmd - v)) - c (v_cmd - v)  ->  v_cmd
        v_cmd = v + (h0 - hook - k * self._ex) / (c + k * self._dt)
        v_cmd = min(max(v_cmd, self._v_range[0]), self._v_range[1])   # the drawworks' range
        self._ex += self._dt * (v_cmd - v)
        return {"top_drive_axial_velocity": v_cmd, "top_drive_angular_velocity": w_sp}


class VelocityServo(_Wrapper):
    """A controller that sets ``top_drive_axial_velocity`` on a rig that takes ``hook_load``:
    the block-velocity servo in software (see the module docstring); the other commands pass.

    Parameters
    ----------
    inner : Controller
        Sets ``top_drive_axial_velocity`` (m/s, down).
    hook_load0 : float
        The servo's hook load at zero error (the plant's buoyed weight - the case's WOB), N.
    stiffness, damping : float
        The servo's gains (the rig's hook), N/m and N s/m.
    dt : float
    """

    def __init__(self, inner, *, hook_load0: float, stiffness: float, damping: float,
                 dt: float):
        for name, v in (("stiffness", stiffness), ("damping", damping), ("dt", dt)):
            if not (math.isfinite(v) and v > 0):
                raise DownholeInputError(f"VelocityServo: {name} must be > 0, got {v!r}")
        inner_cmds = tuple(getattr(inner, "commands", ()) or ())
        if "top_drive_axial_velocity" not in inner_cmds:
            raise DownholeInputError(f"VelocityServo: the inner controller must set "
                                     f"top_drive_axial_velocity, it sets {list(inner_cmds)}")
        self.inner = inner
        self.h0, self.k, self.c = float(hook_load0), float(stiffness), float(damping)
        self._dt = float(dt)
        self.commands = tuple("hook_load" if c == "top_drive_axial_velocity" else c
                              for c in inner_cmds)
        inner_needs = tuple(getattr(inner, "needs", ()) or ())
        self.needs = inner_needs + tuple(s for s in ("top_drive_axial_velocity", "hook_load")
                                         if s not in inner_needs)
        self.label = getattr(inner, "label", type(inner).__name__)
        from downhole.signals import signal

        sig = signal("hook_load")
        self._h_range = (float(sig.low), float(sig.high))

    def reset(self) -> None:
        self.inner.reset()
        self._e = None

    def command(self, t, observation, reference=None) -> dict:
        if not hasattr(self, "_e"):
            self.reset()
        v = float(observation["top_drive_axial_velocity"])
        if self._e is None:   # the servo's error from the hook load now (command = velocity)
            self._e = (self.h0 - float(observation["hook_load"])) / self.k
        cmd = dict(self.inner.command(t, observation, reference))
        v_cmd = float(cmd.pop("top_drive_axial_velocity"))
        self._e += self._dt * (v_cmd - v)
        hook = self.h0 - self.k * self._e - self.c * (v_cmd - v)
        cmd["hook_load"] = min(max(hook, self._h_range[0]), self._h_range[1])  # cannot push
        return {c: float(cmd[c]) for c in self.commands}


def design_fem(system, *, min_elements: int = 5):
    """The coarse FEM of ``system`` that DHP and its observer are designed on: 5 elements (the
    24 states of Ch. 4) or one per well/string section where it has more.

    Parameters
    ----------
    system : DrillingSystem
        The case's system.
    min_elements : int
        Fewest elements tried; raised until the mesh takes every section.

    Returns
    -------
    DirectionalModel
        The design FEM.
    """
    n = min_elements
    while True:
        try:
            return system.build("fem", n_elements=n)
        except DownholeInputError as exc:
            if "too few" not in str(exc) or n > 200:
                raise
            n += 1


class _FromReference:
    """The DHP observer started at the controller's reference state: the estimate at the start
    is the design model's state at the reference's first step (the string deformed as when
    drilling at the reference, bit forces of the bit law there), and the measured top-drive
    angle and block position are taken relative to their values at the start, plus the
    reference's top angle and position (the frame of the DHP's reference)."""

    def __init__(self, est, x0):
        self.est, self.x0 = est, x0
        self.dt = getattr(est, "dt", None)

    def reset(self):
        self.est.reset()
        self.est.kf.reset(self.x0)
        self.est._pos = float(self.x0[0])
        self._angle0 = None

    def update(self, observation, command):
        a = float(observation["top_drive_angle"])
        if self._angle0 is None:
            self._angle0 = a
        seen = dict(observation)
        seen["top_drive_angle"] = a - self._angle0 + float(self.x0[1])
        return self.est.update(seen, command)


def _start_estimate(dhp, kf, n, bitp):
    """The observer's state at the DHP reference's first step (see :class:`_FromReference`)."""
    import numpy as np

    from downhole.bit.law import approx_depth_of_cut, bit_forces

    z = np.asarray(dhp.reference_nd[0], float)[:n] * np.asarray(dhp.state_scale, float)[:n]
    iv, iw = kf.bit_indices
    v, w = float(z[iv]), float(z[iw])
    wob, tob = bit_forces(approx_depth_of_cut(v, w, bitp), v, w, bitp)
    rest = np.array([wob, tob]) - kf.bit_jacobian @ np.array([v, w])
    return np.concatenate([z, rest])


#: What a DHP on the rig reads: the observer's surface signals and the adapter's.
DHP_SIGNALS = ("top_drive_axial_velocity", "top_drive_angular_velocity", "top_drive_angle",
               *RIG_SIGNALS)

#: The built-in DHP's training (docs/compare-controllers.md): a step to the case's reference
#: (ROP, speed) from t = 0, 6 s horizon (past it the stationary gain), 50 samples per step,
#: the default weights and input limits (slack-off -50..300 kN, torque +/-60 kN m).
BUILTIN_DHP_HORIZON = 6.0
BUILTIN_DHP_SAMPLES = 50

_DESIGNS: dict = {}


def _design_for(system, dt):
    dm = design_fem(system)
    from downhole.control.dhp.directional import directional_affine_model

    return dm, directional_affine_model(dm, dt)


def builtin_dhp(system, case):
    """The built-in DHP of ``case`` (benchmark factory): trained on the coarse FEM of the case's
    system (:func:`design_fem`) for a step to the case's reference (see
    :data:`BUILTIN_DHP_HORIZON`), run from the surface through :func:`observed_dhp`. One
    training per system, rock and reference (cached in the process).

    Parameters
    ----------
    system : DrillingSystem
        The case's system.
    case : Case
        The benchmark case (reference, rock, step, rig).

    Returns
    -------
    controller
        The observed, actuator-adapted DHP.
    """
    from downhole.control.dhp import BitReference, DHPSettings, design_dhp

    key = (case.system, case.epsilon_scale, case.speed, case.reference_rop(), case.dt)
    if key not in _DESIGNS:
        dm, des = _design_for(system, case.dt)
        dhp = design_dhp(des, BitReference.step(case.reference_rop(), case.speed),
                         horizon=BUILTIN_DHP_HORIZON,
                         settings=DHPSettings(n_samples=BUILTIN_DHP_SAMPLES))
        _DESIGNS[key] = (dm, des, dhp)
    dm, des, dhp = _DESIGNS[key]
    return _on_rig(dhp, dm, des, system, case)


def _on_rig(dhp, dm, des, system, case):
    import copy

    weight = system.build("fem", n_elements=case.n_elements).buoyed_weight
    servo = None
    if case.hook == "velocity":
        hk = system.rig.hook
        servo = (weight - case.wob, hk.servo_stiffness, hk.servo_damping)
    return observed_dhp(copy.deepcopy(dhp), dm, des, case, weight=weight,
                        top_drive=system.rig.top_drive, hook_servo=servo)


def _design_of(system, n_nodes: int, name: str, weight: float, label: str):
    """The design FEM of ``system`` a DHP with this design (node count, model name, hanging hook
    load) was trained on: a coarse FEM of the system (``n_nodes - 1`` elements) or the design
    FEM of its ``hybrid24`` model (the Ch. 4 24-state FEM); (None, reason) when neither is."""
    cands = []
    try:
        cands.append(system.build("fem", n_elements=n_nodes - 1))
    except DownholeInputError:
        pass
    if name.startswith("hybrid"):
        try:
            cands.append(system.build("hybrid", preset="hybrid24").design_model())
        except DownholeInputError:
            pass
    for dm in cands:
        if dm.name == name and dm.design_model().n_nodes == n_nodes \
                and abs(dm.buoyed_weight - weight) <= 1e-6 * dm.buoyed_weight:
            return dm, ""
    here = float(system.hanging_weight())
    return None, (f"{label} was trained on another string or mesh: its design FEM {name!r} "
                  f"({n_nodes} nodes) hangs {weight / 1e3:.3f} kN; no FEM of this case's "
                  f"string with {n_nodes - 1} elements, nor its hybrid24 design FEM, matches "
                  f"it (the string hangs {here / 1e3:.3f} kN)")


def dhp_for_case(dhp, label: str = "dhp"):
    """A benchmark factory ``(system, case) -> controller`` for a trained DHP (e.g. loaded from
    a file): n/a unless it was trained on a directional design FEM of the case's string (the
    model name, node count and hanging hook load of a coarse FEM of the case's system or of its
    ``hybrid24`` design FEM, :func:`_design_of`) at the case's step, and the case's hook takes
    a hook load; otherwise :func:`observed_dhp` on that FEM. The DHP tracks the reference it
    was trained for (it ignores the case's).

    Parameters
    ----------
    dhp : DHPController
        The trained controller.
    label : str
        Its name in the score table.

    Returns
    -------
    callable
        ``(system, case) -> controller``, raising ``NotApplicable`` with the reason.
    """
    from downhole.compare.runner import NotApplicable

    model = dhp.meta.get("model") if isinstance(dhp.meta.get("model"), dict) else {}
    md = model.get("metadata") or {}

    def factory(system, case):
        if md.get("family") != "directional" or "n_nodes" not in md:
            raise NotApplicable(f"{label} was not trained on a directional FEM design model "
                                f"(model {model.get('name', '?')!r}), the only DHP design the "
                                f"benchmark's surface observer runs on")
        if abs(dhp.dt - case.dt) > 1e-12:
            raise NotApplicable(f"{label} runs every {dhp.dt:g} s; the case steps every "
                                f"{case.dt:g} s")
        dm, why = _design_of(system, int(md["n_nodes"]), str(md.get("model", "")),
                             float(model.get("hanging_hook_load") or 0.0), label)
        if dm is None:
            raise NotApplicable(why)
        from downhole.control.dhp.directional import directional_affine_model

        des = directional_affine_model(dm, dhp.dt)
        ctrl = _on_rig(dhp, dm, des, system, case)
        # a loaded DHP has no design model: attach the case string's, so that past its
        # horizon the feed-forward continues as the trained controller's does
        ctrl.inner.inner.dhp.attach_model(des)
        return ctrl

    factory.__name__ = label
    factory.label = label
    factory.description = (f"DHP from a file ({dhp.n_states} states), run from the surface "
                           f"(observer) through the rig's PI and hook")
    return factory


def observed_dhp(dhp, dmodel, design, case, *, weight: float, top_drive, hook_servo=None):
    """``dhp`` (trained on ``design``, the affine model of ``dmodel``) on the case's rig: the
    surface observer (started at the reference, :class:`_FromReference`) and
    :class:`RigActuators`.

    Parameters
    ----------
    dhp : DHPController
        The trained controller.
    dmodel : DirectionalModel
        Its design FEM.
    design : ControlAffineModel
        The affine model ``dhp`` was trained on.
    case : Case
        The benchmark case.
    weight : float
        Buoyed weight of the case's string, N (hook load = weight - slack-off).
    top_drive : TopDrive
        The case's top drive (PI gains, speed range).
    hook_servo : (float, float, float), optional
        (hook load at zero error N, stiffness N/m, damping N s/m) of the case's velocity hook,
        when it takes block velocities; None for a hook that takes hook loads.

    Returns
    -------
    controller
        The observer-fed DHP with rig actuators.
    """
    from downhole.control.observer import dhp_from_surface

    fb = dhp_from_surface(dhp, dmodel, design=design)
    m = dmodel.design_model()
    x0 = _start_estimate(dhp, fb.estimator.kf, m.n_states, m.bit.kernel_params())
    fb.estimator = _FromReference(fb.estimator, x0)
    return RigActuators(fb, weight=weight, kp=top_drive.kp, ki=top_drive.ki, speed=case.speed,
                        dt=case.dt, hook_servo=hook_servo)
