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
    "MAX_DHP_ARRAY_BYTES",
    "MAX_DHP_JSON_BYTES",
    "MAX_DHP_NPZ_BYTES",
    "ManualFill",
    "SurfacePI",
    "controller_choices",
    "load_controller_file",
    "load_dhp_file",
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

    - ``*.json`` / ``*.npz``: a saved DHP controller (:func:`load_dhp_file`: data only, no code
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
        either name, or a saved DHP controller that :func:`load_dhp_file` refuses.
    """
    path = Path(path)
    if path.suffix in (".json", ".npz"):
        return load_dhp_file(path)
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


#: Largest JSON settings file of a saved DHP controller read (bytes; a few kB in practice).
MAX_DHP_JSON_BYTES = 16 << 20
#: Largest ``.npz`` archive of a saved DHP controller read (bytes on disk).
MAX_DHP_NPZ_BYTES = 512 << 20
#: Largest total size of its arrays once decompressed (bytes, as the archive declares them).
MAX_DHP_ARRAY_BYTES = 1 << 30
_DHP_FORMAT = "downhole.dhp_controller/1"
_JSON_DEPTH = 32
_NAME_CHARS = 128
_MAX_SIGNALS = 10_000
_DHP_ARRAYS = ("kc", "kd", "reference_nd", "u_ff", "state_scale", "input_scale")


def _refuse(source, field: str, message: str):
    from downhole.errors import ScenarioError

    return ScenarioError(str(source), field, message)


def _json_constant(name: str):
    raise ValueError(f"{name} is not a number a controller file may hold")


def _check_json_tree(data, source) -> None:
    """Nesting at most :data:`_JSON_DEPTH` deep, every number finite (iterative walk)."""
    stack = [("", data, 0)]
    while stack:
        field, value, depth = stack.pop()
        if depth > _JSON_DEPTH:
            raise _refuse(source, field or "<top>", f"nested deeper than {_JSON_DEPTH} levels")
        if isinstance(value, float) and not math.isfinite(value):
            raise _refuse(source, field, f"expected a finite number, got {value!r}")
        if isinstance(value, dict):
            stack.extend((f"{field}.{k}" if field else str(k), v, depth + 1)
                         for k, v in value.items())
        elif isinstance(value, list):
            stack.extend((f"{field}.{i}" if field else str(i), v, depth + 1)
                         for i, v in enumerate(value))


def _read_dhp_json(js: Path) -> dict:
    import json

    from downhole._reader import read_regular_file

    raw = read_regular_file(js, MAX_DHP_JSON_BYTES, "a saved DHP controller's JSON")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise _refuse(js, "", f"not UTF-8 text (byte 0x{raw[exc.start]:02x} at offset "
                      f"{exc.start})") from None
    if not text.strip():
        raise _refuse(js, "", "empty file; expected the JSON of a saved DHP controller")
    try:
        meta = json.loads(text, parse_constant=_json_constant)
    except RecursionError:
        raise _refuse(js, "", "not valid JSON: nested too deep") from None
    except json.JSONDecodeError as exc:
        raise _refuse(js, "", f"not valid JSON (truncated?): {exc.msg} (line {exc.lineno}, "
                      f"column {exc.colno})") from None
    except ValueError as exc:  # NaN, Infinity, a 5000-digit integer
        raise _refuse(js, "", f"not valid JSON: {str(exc).split(';')[0]}") from None
    if not isinstance(meta, dict):
        raise _refuse(js, "<top>", f"expected a JSON object, got {type(meta).__name__}")
    _check_json_tree(meta, js)
    if meta.get("format") != _DHP_FORMAT:
        raise _refuse(js, "format", f"is not a downhole DHP controller (format "
                      f"{str(meta.get('format'))[:60]!r}, expected {_DHP_FORMAT!r})")
    return meta


def _read_dhp_npz(npz: Path) -> dict:
    import io
    import zipfile
    import zlib

    from downhole._reader import read_regular_file

    raw = read_regular_file(npz, MAX_DHP_NPZ_BYTES, "a saved DHP controller's npz archive")
    try:
        with zipfile.ZipFile(io.BytesIO(raw)) as zf:
            infos = zf.infolist()
    except (zipfile.BadZipFile, zipfile.LargeZipFile, EOFError, ValueError) as exc:
        raise _refuse(npz, "", f"not an npz archive ({exc})") from None
    declared = sum(i.file_size for i in infos)
    if len(infos) > 256 or declared > MAX_DHP_ARRAY_BYTES:
        raise _refuse(npz, "", f"{len(infos)} arrays of {declared} bytes decompressed; at most "
                      f"256 arrays and {MAX_DHP_ARRAY_BYTES} bytes are read")
    arrays = {}
    try:
        data = np.load(io.BytesIO(raw), allow_pickle=False)
    except (ValueError, OSError, EOFError, zipfile.BadZipFile) as exc:
        raise _refuse(npz, "", f"not an npz archive ({exc})") from None
    with data:
        for k in data.files:
            try:
                arrays[k] = data[k]
            except ValueError as exc:  # an object array: pickled data, refused
                raise _refuse(npz, k, f"{str(exc).split('.')[0]}; a controller holds numbers "
                              "only") from None
            except (OSError, EOFError, KeyError, zipfile.BadZipFile, zlib.error) as exc:
                raise _refuse(npz, k, f"cannot read the array ({exc})") from None
    return arrays


def _names(meta: dict, js: Path, field: str) -> tuple:
    v = meta.get(field)
    if not isinstance(v, list) or not 1 <= len(v) <= _MAX_SIGNALS:
        raise _refuse(js, field, f"expected a list of 1 to {_MAX_SIGNALS} names")
    for i, name in enumerate(v):
        if not isinstance(name, str) or not 0 < len(name) <= _NAME_CHARS:
            raise _refuse(js, f"{field}.{i}", f"expected a name of 1 to {_NAME_CHARS} "
                          "characters")
    return tuple(v)


def _int_field(value, js: Path, field: str, lo: int, hi: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
        raise _refuse(js, field, f"expected an integer in {lo}..{hi}, got {str(value)[:40]}")
    return value


def _array(arrays: dict, npz: Path, key: str, shape: tuple, *, positive: bool = False):
    a = arrays.get(key)
    if a is None:
        raise _refuse(npz, key, "missing")
    if a.dtype.kind != "f" or a.dtype.itemsize != 8:
        raise _refuse(npz, key, f"dtype {a.dtype}; expected float64")
    if a.shape != shape:
        raise _refuse(npz, key, f"shape {a.shape}; expected {shape}")
    if not np.isfinite(a).all():
        raise _refuse(npz, key, "non-finite values (NaN or inf)")
    if positive and not (a > 0).all():
        raise _refuse(npz, key, "expected positive scales")
    return np.ascontiguousarray(a, dtype=np.float64)


def _check_integral(meta: dict, js: Path, n: int) -> None:
    """The integral-action description a DHP controller reads from its ``meta``."""
    model = meta.get("model")
    integ = None
    if isinstance(model, dict):
        md = model.get("metadata", {})
        if not isinstance(md, dict):
            raise _refuse(js, "meta.model.metadata", "expected an object")
        integ = md.get("integral")
        where = "meta.model.metadata.integral"
    if integ is None:
        integ, where = meta.get("integral"), "meta.integral"
    if integ is None:
        return
    if not isinstance(integ, dict):
        raise _refuse(js, where, "expected an object")
    nb = _int_field(integ.get("n_base"), js, f"{where}.n_base", 1, n)
    src = integ.get("source")
    if not isinstance(src, list) or len(src) != 2:
        raise _refuse(js, f"{where}.source", "expected two state indices")
    for i, v in enumerate(src):
        _int_field(v, js, f"{where}.source.{i}", 0, nb - 1)


def load_dhp_file(path):
    """Load a saved DHP controller (``path.json`` + ``path.npz`` of
    :meth:`~downhole.control.dhp.DHPController.save`; ``path`` with or without the suffix),
    checking every field before anything is built.

    Both files must be regular files (a FIFO or a device such as ``/dev/zero`` is refused
    before it is opened) of bounded size (:data:`MAX_DHP_JSON_BYTES`,
    :data:`MAX_DHP_NPZ_BYTES`; the arrays at most :data:`MAX_DHP_ARRAY_BYTES` decompressed);
    the JSON must parse (no NaN or Infinity, at most 32 levels deep) with ``dt`` a step in
    [1e-6, 1] s, the signal names lists of names, ``past_horizon`` and ``stationary_step``
    valid; the arrays float64, finite, of the shapes the gains imply (``kd`` (steps, inputs,
    states), ``kc`` and ``u_ff`` (steps, inputs), ``reference_nd`` (steps + 1, states), scales
    positive, ``input_limits`` (inputs, 2) ordered) and without pickled objects (read with
    ``allow_pickle=False``); extra arrays real numbers.

    Parameters
    ----------
    path : str or os.PathLike
        The controller's path, with or without ``.json``/``.npz``.

    Returns
    -------
    DHPController
        The loaded controller.

    Raises
    ------
    DownholeInputError
        One line naming the file and the field (a :class:`~downhole.errors.ScenarioError`).
    """
    from downhole.control.dhp import DHPController
    from downhole.control.dhp.references import BitReference

    path = Path(path)
    stem = path.with_suffix("") if path.suffix in (".npz", ".json") else path
    npz, js = stem.with_suffix(".npz"), stem.with_suffix(".json")
    meta = _read_dhp_json(js)
    dt = meta.get("dt")
    if isinstance(dt, bool) or not isinstance(dt, (int, float)) or not 1e-6 <= dt <= 1.0:
        raise _refuse(js, "dt", f"{str(dt)[:40]} is not a controller step in [1e-6, 1] s")
    states = _names(meta, js, "state_names")
    kinds = _names(meta, js, "state_kinds")
    inputs = _names(meta, js, "input_names")
    if len(kinds) != len(states):
        raise _refuse(js, "state_kinds", f"{len(kinds)} kinds for {len(states)} states")
    if meta.get("past_horizon") not in ("stationary", "error"):
        raise _refuse(js, "past_horizon", "expected 'stationary' or 'error'")
    inner = meta.get("meta", {})
    if not isinstance(inner, dict):
        raise _refuse(js, "meta", "expected an object")
    ref = meta.get("reference")
    if not isinstance(ref, dict):
        raise _refuse(js, "reference", "expected an object")
    try:
        reference = BitReference.from_dict(ref)
    except (DownholeInputError, TypeError, ValueError) as exc:
        raise _refuse(js, "reference", str(exc).splitlines()[0][:200]) from None
    n, m = len(states), len(inputs)
    _check_integral(inner, js, n)
    arrays = _read_dhp_npz(npz)
    kd = arrays.get("kd")
    if kd is None or kd.ndim != 3 or kd.shape[0] < 1:
        raise _refuse(npz, "kd", "missing or not a (steps, inputs, states) array"
                      if kd is None or kd.ndim != 3 else "no step")
    ns = kd.shape[0]
    a = {"kd": _array(arrays, npz, "kd", (ns, m, n)),
         "kc": _array(arrays, npz, "kc", (ns, m)),
         "u_ff": _array(arrays, npz, "u_ff", (ns, m)),
         "reference_nd": _array(arrays, npz, "reference_nd", (ns + 1, n)),
         "state_scale": _array(arrays, npz, "state_scale", (n,), positive=True),
         "input_scale": _array(arrays, npz, "input_scale", (m,), positive=True)}
    limits = None
    if "input_limits" in arrays:
        limits = _array(arrays, npz, "input_limits", (m, 2))
        if not (limits[:, 0] <= limits[:, 1]).all():
            raise _refuse(npz, "input_limits", "a lower limit above its upper limit")
    step = meta.get("stationary_step")
    if step is not None:
        _int_field(step, js, "stationary_step", 0, ns - 1)
    extras = {}
    for k, v in arrays.items():
        if not k.startswith("extra_"):
            continue
        if v.dtype.kind not in "biuf":
            raise _refuse(npz, k, f"dtype {v.dtype}; expected real numbers")
        if v.dtype.kind == "f" and not np.isfinite(v).all():
            raise _refuse(npz, k, "non-finite values (NaN or inf)")
        extras[k[len("extra_"):]] = v
    try:
        return DHPController(a["kc"], a["kd"], a["reference_nd"], a["u_ff"], a["state_scale"],
                             a["input_scale"], float(dt), states, kinds, inputs, reference,
                             input_limits=limits, past_horizon=meta["past_horizon"],
                             stationary_step=step, meta=inner, arrays=extras)
    except DownholeInputError as exc:
        raise _refuse(js, "", str(exc)) from None


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
