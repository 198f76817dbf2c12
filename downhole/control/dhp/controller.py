"""The trained DHP controller: online law, behaviour past the horizon, save/load without pickle.

Online (Eq. 4.34 with the network of Eq. 4.35 and the feed-forward):

    u_k = u_ff,k - R^-1 g^T W_k^T phi(zbar_k) = u_ff,k - kc_k - kd_k (zbar_k - rbar_k)

in non-dimensional units, then u = U ubar, clipped to the input limits. The stored arrays are
``kc`` (n_steps, m) and ``kd`` (n_steps, m, n), i.e. exactly the rows R^-1 g^T W_k^T that the law
uses (the full weights W_k, (n + 1) x n per step, would take 190 MB for 24 states over 40 s at
dt = 1e-3; snapshots are kept in ``weights`` for plots).

Past the trained horizon (k >= n_steps) the behaviour is set by ``past_horizon``:

``"stationary"`` (default, receding-horizon re-use)
    The gain of the stationary stage, kd at ``stationary_step`` (default n_steps // 2: far from
    the final condition, where the backward recursion has converged to its stationary value),
    is re-used with kc = 0 and the reference and feed-forward continued from the reference
    description (the affine term kc vanishes when the feed-forward is consistent with the
    reference, which :func:`~downhole.control.dhp.drilling.feed_forward` makes it). The
    feed-forward past the horizon is computed from the attached model when there is one
    (:meth:`DHPController.attach_model`, automatic after design) and otherwise extrapolated
    linearly from the last two trained steps.
``"error"``
    Raise :class:`~downhole.errors.DownholeInputError` (re-train with a longer horizon).

Files: ``save(path)`` writes ``path.npz`` (arrays) and ``path.json`` (settings, model
description, reference, weights, version); :func:`load_controller` reads them back with
``allow_pickle=False``.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import numpy as np

from downhole.control.dhp.references import BitReference
from downhole.errors import DownholeInputError

__all__ = ["MAX_DHP_ARRAY_BYTES", "MAX_DHP_JSON_BYTES", "MAX_DHP_NPZ_BYTES",
           "PAST_HORIZON_POLICIES", "DHPController", "load_controller"]

PAST_HORIZON_POLICIES = ("stationary", "error")
_FORMAT = "downhole.dhp_controller/1"


class DHPController:
    """A trained DHP tracking controller (time-varying affine state feedback).

    Build with :func:`downhole.control.dhp.design_dhp` or :func:`load_controller`.

    Parameters
    ----------
    kc, kd : ndarray
        (n_steps, m) and (n_steps, m, n): R^-1 g^T c_k and R^-1 g^T D_k^T.
    reference_nd : ndarray (n_steps + 1, n)
        Non-dimensional state reference of the training.
    u_ff : ndarray (n_steps, m)
        Non-dimensional feed-forward of the training.
    state_scale, input_scale : ndarray
        P and U.
    dt : float
        Step, s.
    state_names, state_kinds, input_names : sequence of str
    reference : BitReference
        The bit-velocity reference it was trained for.
    input_limits : ndarray (m, 2) or None
        Physical limits applied online (clip).
    past_horizon : {"stationary", "error"}
    stationary_step : int or None
    meta : dict
        JSON-able information (settings, weights, model description, training diagnostics).
    arrays : dict
        Extra arrays saved with the controller (weights snapshots, iterations, errors, mu).
    """

    def __init__(self, kc, kd, reference_nd, u_ff, state_scale, input_scale, dt, state_names,
                 state_kinds, input_names, reference: BitReference, input_limits=None,
                 past_horizon: str = "stationary", stationary_step: int | None = None,
                 meta: dict | None = None, arrays: dict | None = None):
        self.kc = np.asarray(kc, float)
        self.kd = np.asarray(kd, float)
        ns, m, n = self.kd.shape
        if self.kc.shape != (ns, m):
            raise DownholeInputError(f"kc must be ({ns}, {m}), got {self.kc.shape}")
        self.reference_nd = np.asarray(reference_nd, float)
        self.u_ff = np.asarray(u_ff, float)
        if self.reference_nd.shape != (ns + 1, n) or self.u_ff.shape != (ns, m):
            raise DownholeInputError("reference_nd / u_ff do not match the gains' horizon")
        self.state_scale = np.asarray(state_scale, float)
        self.input_scale = np.asarray(input_scale, float)
        self.dt = float(dt)
        self.state_names = tuple(state_names)
        self.state_kinds = tuple(state_kinds)
        self.input_names = tuple(input_names)
        self.reference = reference
        self.input_limits = None if input_limits is None else np.asarray(input_limits, float)
        if past_horizon not in PAST_HORIZON_POLICIES:
            raise DownholeInputError(f"past_horizon must be one of {PAST_HORIZON_POLICIES}, got "
                                     f"{past_horizon!r}")
        self.past_horizon = past_horizon
        self.stationary_step = ns // 2 if stationary_step is None else int(stationary_step)
        if not 0 <= self.stationary_step < ns:
            raise DownholeInputError(f"stationary_step must be in 0..{ns - 1}, got "
                                     f"{self.stationary_step}")
        self.meta = dict(meta or {})
        self.arrays = dict(arrays or {})
        self._model = None
        self._ext_ref = None
        self._ext_uff = None
        integ = self.meta.get("model", {}).get("metadata", {}).get("integral") \
            if isinstance(self.meta.get("model"), dict) else None
        self._integral = integ or self.meta.get("integral")
        self.reset()

    # ------------------------------------------------------------------ sizes
    @property
    def n_steps(self) -> int:
        return self.kd.shape[0]

    @property
    def horizon(self) -> float:
        """Trained horizon, s."""
        return self.n_steps * self.dt

    @property
    def n_states(self) -> int:
        return self.kd.shape[2]

    def attach_model(self, model) -> DHPController:
        """Attach the design model (used for the feed-forward past the horizon)."""
        if model.n_states != self.n_states or tuple(model.state_names) != self.state_names:
            raise DownholeInputError(f"model {model.name!r} does not match the controller's "
                                     f"states ({self.n_states}: {self.state_names[:3]}...)")
        self._model = model
        return self

    def calibrate_feed_forward(self, plant_model) -> DHPController:
        """Correct the feed-forward with the steady-state inputs of another model of the plant.

        The design model's static map (the inputs that hold the string at the reference
        velocities) differs from a finer plant's (e.g. the 68-state hybrid needs ~4% more
        torque than the 24-state design FEM: the contact forces of the finer mesh). This adds
        u_ff,plant,k - u_ff,design,k (both by :func:`~downhole.control.dhp.drilling.feed_forward`
        along the same bit reference) to the commands, like calibrating a feed-forward on the
        rig. The gains are unchanged. Saved with the controller (``arrays["u_ff_correction"]``).

        Parameters
        ----------
        plant_model : ControlAffineModel
            Control-affine model of the plant (e.g. ``directional_affine_model(hybrid68)``),
            with the same inputs and dt.
        """
        from downhole.control.dhp.drilling import feed_forward, reference_states

        if tuple(plant_model.input_names) != self.input_names or abs(plant_model.dt
                                                                      - self.dt) > 1e-15:
            raise DownholeInputError("plant_model must have the controller's inputs "
                                     f"{self.input_names} and dt = {self.dt}")
        v, w, x, a = self.reference.sample(self.n_steps, self.dt)
        ref = reference_states(plant_model, v, w, x, a)
        u_plant = feed_forward(plant_model, ref) * plant_model.input_scale
        self.arrays["u_ff_correction"] = u_plant / self.input_scale - self.u_ff
        self.meta["feed_forward_calibrated_on"] = plant_model.name
        return self

    def reset(self) -> None:
        """Restart the integrator states (integral action); otherwise the law is stateless."""
        self._xi = None
        self._xi_k = -1
        self._xi_v = None
        self._saturated = False

    def _augment(self, k: int, z: np.ndarray) -> np.ndarray:
        """Append the integrator states xi (sums of the bit velocities, physical) to ``z``.

        The error xi - r_xi is frozen while an input saturated at the last command
        (anti-windup); the integrator restarts at zero error at step 0 or a step backwards."""
        nb = int(self._integral["n_base"])
        iv, iw = (int(i) for i in self._integral["source"])
        r_xi = self.step_terms(k)[0][nb:] * self.state_scale[nb:]
        if self._xi is None or k <= 0 or k < self._xi_k:
            self._xi = r_xi.copy()
        elif k > self._xi_k:
            if self._saturated:
                r_prev = self.step_terms(self._xi_k)[0][nb:] * self.state_scale[nb:]
                self._xi = self._xi + (r_xi - r_prev)
            else:
                self._xi = self._xi + (k - self._xi_k) * self.dt * self._xi_v
        self._xi_k = k
        self._xi_v = np.array([z[iv], z[iw]])
        return np.concatenate([z, self._xi])

    # ------------------------------------------------------------------ reference beyond
    def _extend(self, k: int) -> None:
        """Continue reference and feed-forward up to step k (past-horizon policy)."""
        from downhole.control.dhp.drilling import feed_forward

        have = self.n_steps if self._ext_uff is None else self.n_steps + self._ext_uff.shape[0]
        if k < have:
            return
        total = max(k + 1, 2 * have) + 1
        v, w, x, a = self.reference.sample(total, self.dt)
        kinds = {"axial_position": x, "angular_position": a, "axial_velocity": v,
                 "angular_velocity": w}
        r = np.zeros((total + 1, self.n_states))
        for i, kind in enumerate(self.state_kinds):
            if kind in kinds:
                r[:, i] = kinds[kind]
        r /= self.state_scale
        if self._model is not None and self.meta.get("use_feed_forward", True):
            uff, r = feed_forward(self._model, r, return_reference=True)
        else:
            rate = self.u_ff[-1] - self.u_ff[-2] if self.n_steps > 1 else 0.0 * self.u_ff[-1]
            extra = np.arange(1, total - self.n_steps + 1)[:, None] * rate + self.u_ff[-1]
            uff = np.vstack([self.u_ff, extra])
        shift = self.arrays.get("reference_shift")     # a planned start-up (plan.py)
        self._ext_ref = r[self.n_steps + 1:] + (0.0 if shift is None else np.asarray(shift))
        self._ext_uff = uff[self.n_steps:total]

    def step_terms(self, k: int):
        """(rbar_k, u_ff,k, kc_k, kd_k) for step ``k`` (>= 0), applying the past-horizon policy."""
        if k < 0:
            raise DownholeInputError(f"step index must be >= 0, got {k}")
        corr = self.arrays.get("u_ff_correction")
        if k < self.n_steps:
            uff = self.u_ff[k] if corr is None else self.u_ff[k] + corr[k]
            return self.reference_nd[k], uff, self.kc[k], self.kd[k]
        if self.past_horizon == "error":
            raise DownholeInputError(
                f"step {k} (t = {k * self.dt:.6g} s) is past the trained horizon "
                f"{self.horizon:.6g} s; re-train with a longer horizon or use "
                "past_horizon='stationary'")
        self._extend(k)
        j = k - self.n_steps
        ks = self.stationary_step
        uff = self._ext_uff[j] if corr is None else self._ext_uff[j] + corr[-1]
        return self._ext_ref[j], uff, np.zeros_like(self.kc[ks]), self.kd[ks]

    # ------------------------------------------------------------------ the law
    def control(self, k: int, z) -> np.ndarray:
        """Physical input at step ``k`` for the physical state ``z`` (n,)."""
        z = np.asarray(z, dtype=float)
        if self._integral is not None and z.shape == (int(self._integral["n_base"]),):
            z = self._augment(k, z)
        if z.shape != (self.n_states,):
            raise DownholeInputError(f"state must have shape ({self.n_states},), got {z.shape}")
        r, uff, kc, kd = self.step_terms(k)
        ubar = uff - kc - kd @ (z / self.state_scale - r)
        u = ubar * self.input_scale
        if self.input_limits is not None:
            uc = np.clip(u, self.input_limits[:, 0], self.input_limits[:, 1])
            self._saturated = bool(np.any(uc != u))
            u = uc
        return u

    def unclipped(self, k: int, z) -> np.ndarray:
        r, uff, kc, kd = self.step_terms(k)
        return (uff - kc - kd @ (np.asarray(z, float) / self.state_scale - r)) * self.input_scale

    def reference_at(self, k: int) -> tuple[float, float]:
        """(v_d, omega_d) at step k, m/s and rad/s."""
        v, w = self.reference.velocities(np.array([k * self.dt]))
        return float(v[0]), float(w[0])

    def command(self, t: float, observation: dict, reference=None) -> dict:
        """Controller interface: named command from named observations at time ``t``.

        ``observation`` holds either ``"state"`` (the physical state vector in the model's
        order) or one entry per state name. ``reference`` is ignored (the DHP law is trained for
        its own reference; re-train for another one). Returns ``{input_name: value}``.
        """
        if "state" in observation:
            z = np.asarray(observation["state"], dtype=float)
        else:
            # with integral action the controller keeps its integrator states itself: the
            # plant reports the model's states only
            names = self.state_names if self._integral is None else \
                self.state_names[:int(self._integral["n_base"])]
            try:
                z = np.array([float(observation[n]) for n in names])
            except KeyError as exc:
                raise DownholeInputError(
                    f"observation lacks state {exc.args[0]!r}: the DHP controller needs the full "
                    f"state ({', '.join(names)}) or an entry 'state'") from None
        k = int(round(t / self.dt))
        u = self.control(k, z)
        return {name: float(val) for name, val in zip(self.input_names, u)}

    # ------------------------------------------------------------------ files
    def save(self, path: str | os.PathLike) -> tuple[Path, Path]:
        """Write ``path.npz`` and ``path.json`` (no pickle; the folder is created if missing).
        Returns both paths."""
        path = Path(path)
        if path.parent.exists() and not path.parent.is_dir():
            raise DownholeInputError(f"cannot save the controller under {path.parent}: it is "
                                     f"a file, not a folder")
        path.parent.mkdir(parents=True, exist_ok=True)
        stem = path.with_suffix("") if path.suffix in (".npz", ".json") else path
        npz, js = stem.with_suffix(".npz"), stem.with_suffix(".json")
        arrays = {"kc": self.kc, "kd": self.kd, "reference_nd": self.reference_nd,
                  "u_ff": self.u_ff, "state_scale": self.state_scale,
                  "input_scale": self.input_scale}
        if self.input_limits is not None:
            arrays["input_limits"] = self.input_limits
        for k, v in self.arrays.items():
            arrays[f"extra_{k}"] = np.asarray(v)
        from downhole import __version__

        meta = {"format": _FORMAT, "downhole_version": __version__, "dt": self.dt,
                "state_names": list(self.state_names), "state_kinds": list(self.state_kinds),
                "input_names": list(self.input_names), "reference": self.reference.to_dict(),
                "past_horizon": self.past_horizon, "stationary_step": self.stationary_step,
                "meta": self.meta}
        from downhole._atomic import atomic_path, write_text_atomic

        with atomic_path(npz) as tmp, open(tmp, "wb") as fh:
            np.savez_compressed(fh, **arrays)
        write_text_atomic(js, json.dumps(meta, indent=2, default=_json_default))
        return npz, js

    def __repr__(self) -> str:
        return (f"DHPController(n={self.n_states}, m={len(self.input_names)}, "
                f"horizon={self.horizon:g} s, dt={self.dt:g}, reference={self.reference.kind})")


def _json_default(o):
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, np.bool_):
        return bool(o)
    raise TypeError(f"not JSON-able: {type(o).__name__}")


#: Largest JSON settings file of a saved DHP controller read (bytes; a few kB in practice).
MAX_DHP_JSON_BYTES = 16 << 20
#: Largest ``.npz`` archive of a saved DHP controller read (bytes on disk).
MAX_DHP_NPZ_BYTES = 512 << 20
#: Largest total size of its arrays once decompressed (bytes, as the archive declares them).
MAX_DHP_ARRAY_BYTES = 1 << 30
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
    if meta.get("format") != _FORMAT:
        raise _refuse(js, "format", f"is not a downhole DHP controller (format "
                      f"{str(meta.get('format'))[:60]!r}, expected {_FORMAT!r})")
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


def load_controller(path: str | os.PathLike) -> DHPController:
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
