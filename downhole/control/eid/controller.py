"""The EID controller object (seed Fig. 3.3, corrected): design with :func:`design_eid`, run with
:func:`downhole.sim.simulate` (compiled, through
:meth:`EIDController.kernel_runner` and :mod:`downhole.control.eid.neutral_runner`) or step it
from Python with :meth:`EIDController.command`; save/load as ``.npz`` + JSON (no pickle).

Structure (per channel, see :mod:`downhole.control.eid._kernel`): observer driven by the delayed
command u_f(t - tau) (the plant's own input delay), disturbance estimator
d_hat = B+ L (y - xhat) + u_f(t-tau) - u(t-tau), filter F(s) = bf/(s + bf), internal model
x_R' = B_R (r - x_p), state feedback u_f = Kp x_p + K_R x_R on the prediction
x_p = z + xhat - z(t - tau) (Smith-type predictor, z = delay-free model driven by u_f).
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from downhole.control.eid._kernel import NSIG, EIDChannelParams, eid_arrays, eid_step
from downhole.control.eid.design import ChannelGains, LMIReport, synthesize_channel
from downhole.control.eid.references import Reference, as_reference, constant_reference
from downhole.errors import DownholeInputError

__all__ = ["EIDController", "design_eid", "load_eid"]

CHANNELS = ("axial", "torsional")


@dataclass
class EIDController:
    """Designed EID controller for the neutral model.

    Attributes
    ----------
    gains : tuple of ChannelGains
        (axial, torsional).
    model_coeffs : tuple of dict
        Scalar design models (a0, a1, g1, b, h, tau, offset) per channel.
    reference : Reference
        Default reference (constant 10 mm/s, 20 rad/s).
    predictor : bool
        Smith-type predictor on (default). False: feedback on xhat (printed structure).
    delayed_input_observer : bool
        Observer/estimator fed u_f(t - tau) (default). False: fed u_f(t) as printed.
    reports : list of LMIReport
    u_limits : ((lo, hi), (lo, hi))
        Command saturation in plant units (U_A m/s, U_T rad/s).
    """

    gains: tuple
    model_coeffs: tuple
    reference: Reference = constant_reference()
    predictor: bool = True
    delayed_input_observer: bool = True
    reports: list | None = None
    u_limits: tuple = ((-1e3, 1e3), (-1e3, 1e3))
    dt: float = 1e-3

    #: the controller contract (downhole.control.base): signals read and commands set
    needs = ("bit_axial_velocity", "bit_angular_velocity")
    commands = ("top_drive_axial_velocity", "top_drive_angular_velocity")

    #: Name of the controller in a result's attributes.
    label = "eid"

    # --- compiled parameters ------------------------------------------------------------------
    def compiled_params(self, dt: float) -> tuple[EIDChannelParams, EIDChannelParams]:
        """Parameters ``(axial, torsional)`` of the compiled step at step ``dt``."""
        cp = []
        for i in range(2):
            g, c = self.gains[i], self.model_coeffs[i]
            if dt > c["tau"]:
                raise DownholeInputError(f"dt = {dt} s exceeds the {CHANNELS[i]} delay "
                                         f"{c['tau']:.6g} s")
            cp.append(EIDChannelParams(
                a0=float(c["a0"]), a1=float(c["a1"]), g1=float(c["g1"]), b=float(c["b"]),
                l=float(g.l), kp=float(g.kp), kr=float(g.kr), br=float(g.br), af=-float(g.bf),
                bf=float(g.bf), h_steps=c["h"] / dt, tau_steps=c["tau"] / dt,
                offset=float(c["offset"]), predictor=bool(self.predictor),
                observer_delay=bool(self.delayed_input_observer),
                u_min=float(self.u_limits[i][0]), u_max=float(self.u_limits[i][1])))
        return cp[0], cp[1]

    def kernel_runner(self, pack):
        """The compiled closed loop on the neutral-type string: the fast-path hook of
        :func:`downhole.sim.simulate` (see :mod:`downhole.control.eid.neutral_runner`);
        ``None`` (the Python loop) for other models.

        Parameters
        ----------
        pack : object
            The kernel configuration ``simulate`` runs (``pack.kind``, ``pack.dt``).

        Returns
        -------
        callable or None
        """
        if getattr(pack, "kind", None) != "neutral":
            return None
        from downhole.control.eid.neutral_runner import make_neutral_runner

        return make_neutral_runner(self.compiled_params(pack.dt))

    # --- Python stepping (SIL / generic plants) -----------------------------------------------
    def reset(self) -> None:
        """Zero the controller state for steps of :attr:`dt` seconds (the sample time; a
        runner sets it to its control step before calling ``reset``)."""
        self._dt = float(self.dt)
        self._cp = self.compiled_params(self._dt)
        self._cs, self._ch, self._cpos = eid_arrays(self._cp)
        self._u = np.zeros(2)
        self._sig = np.zeros((2, NSIG))

    def command(self, t: float, observation: dict, reference=None) -> dict:
        """One controller step: observation needs ``bit_axial_velocity`` and
        ``bit_angular_velocity``; ``reference`` a mapping with ``reference_axial_velocity`` and
        ``reference_angular_velocity`` (or an array [axial, angular]; default
        :attr:`reference`). Returns ``{"top_drive_axial_velocity": U_A - M_S g/alpha_A,
        "top_drive_angular_velocity": U_T}``, the commands of the Plant contract (the axial
        one relative to the hanging equilibrium). Call :meth:`reset` first; call once per
        ``dt``."""
        if not hasattr(self, "_cp"):
            self.reset()
        try:
            y = np.array([observation["bit_axial_velocity"], observation["bit_angular_velocity"]],
                         float)
        except KeyError as exc:
            raise DownholeInputError(f"observation lacks {exc.args[0]!r}") from None
        if reference is None:
            r = self.reference.sample(np.array([t]))[:, 0]
        elif hasattr(reference, "keys"):
            try:
                r = np.array([reference["reference_axial_velocity"],
                              reference["reference_angular_velocity"]], float)
            except KeyError as exc:
                raise DownholeInputError(f"reference lacks {exc.args[0]!r}") from None
        else:
            r = np.asarray(reference, float).reshape(2)
        eid_step(self._cp, self._cs, self._ch, self._cpos, y, r, self._dt, self._u, self._sig)
        return {"top_drive_axial_velocity": float(self._u[0] - self.model_coeffs[0]["offset"]),
                "top_drive_angular_velocity": float(self._u[1])}

    # --- persistence --------------------------------------------------------------------------
    def to_dict(self) -> dict:
        return {"gains": [asdict(g) for g in self.gains], "model_coeffs": list(self.model_coeffs),
                "predictor": self.predictor,
                "delayed_input_observer": self.delayed_input_observer,
                "u_limits": [list(x) for x in self.u_limits],
                "reference": {"axial": _ref_json(self.reference.axial),
                              "angular": _ref_json(self.reference.angular),
                              "name": self.reference.name},
                "lmi_reports": [r.to_dict() for r in (self.reports or [])]}

    def save(self, directory) -> Path:
        """Write ``eid_gains.npz`` (gain matrices Kp, K_R, L, B_R, A_F, B_F, C_F) and
        ``eid_controller.json`` into ``directory``."""
        d = Path(directory)
        d.mkdir(parents=True, exist_ok=True)
        g = self.gains
        from downhole._atomic import atomic_path, write_text_atomic

        with atomic_path(d / "eid_gains.npz") as tmp:
            np.savez(tmp, Kp=np.diag([g[0].kp, g[1].kp]),
                     K_R=np.diag([g[0].kr, g[1].kr]), L=np.diag([g[0].l, g[1].l]),
                     B_R=np.diag([g[0].br, g[1].br]), A_F=np.diag([-g[0].bf, -g[1].bf]),
                     B_F=np.diag([g[0].bf, g[1].bf]), C_F=np.eye(2))
        write_text_atomic(d / "eid_controller.json", json.dumps(self.to_dict(), indent=2))
        return d


def _ref_json(sig):
    if isinstance(sig, (int, float)):
        return float(sig)
    return None  # callables/samples are not persisted; the default constant is used on load


def load_eid(directory) -> EIDController:
    """Load a controller saved by :meth:`EIDController.save`."""
    d = Path(directory)
    f = d / "eid_controller.json"
    if not f.exists():
        raise DownholeInputError(f"{f} not found (expected a directory written by "
                                 "EIDController.save / downhole design eid)")
    meta = json.loads(f.read_text())
    gains = tuple(ChannelGains(**g) for g in meta["gains"])
    ref = meta.get("reference", {})
    a, w = ref.get("axial"), ref.get("angular")
    reference = constant_reference(a if a is not None else 0.01, w if w is not None else 20.0)
    reports = [LMIReport(**r) for r in meta.get("lmi_reports", [])]
    return EIDController(gains=gains, model_coeffs=tuple(meta["model_coeffs"]),
                         reference=reference, predictor=meta["predictor"],
                         delayed_input_observer=meta["delayed_input_observer"], reports=reports,
                         u_limits=tuple(tuple(x) for x in meta["u_limits"]))


def design_eid(model, *, internal_model_gain=(10.0, 1.0), filter_bandwidth=(20.0, 2.0),
               observer_gain=(20.0, 7.0), gain_bound: float = 5.0, reference=None,
               predictor: bool = True, delayed_input_observer: bool = True,
               eps: float = 1e-6) -> EIDController:
    """Design the EID controller for a :class:`~downhole.string.neutral.NeutralModel`.

    Solves, per channel, the corrected Theorem 1 LMI (see :mod:`downhole.control.eid.design`)
    for the feedback gains (Kp, K_R) with the chosen observer gain L and filter F(s), including
    the delayed disturbance compensation of the delayed-input observer.

    Parameters
    ----------
    model : NeutralModel
    internal_model_gain : (float, float)
        B_R per channel (seed Eq. 3.32: 1 and 0.05; default 1 and 1, see docs/neutral-eid.md).
    filter_bandwidth : (float, float)
        bf of F(s) = bf/(s + bf), rad/s (seed: 200 and 100). Default (20, 2): the axial 20 rad/s
        makes the loop damp the regenerative bit/rock mode (~57 rad/s) up to 2x the nominal
        epsilon (10 rad/s leaves it unstable at 2x; 30 rad/s disturbs tracking), see
        :func:`downhole.control.eid.stability.regenerative_closed_loop` and docs/neutral-eid.md.
    observer_gain : (float, float)
        L per channel (seed: 199.3 and 357.6; with the input delay about 1/50 of those).
    gain_bound : float
        Bound on |[Kp K_R]| per channel.
    reference : Reference, optional
        Default reference (constant 10 mm/s, 20 rad/s).
    predictor, delayed_input_observer : bool
        Input-delay handling (both on by default; off reproduces the printed structure).

    Returns
    -------
    EIDController
        With ``reports`` holding each channel's LMI margins.

    Raises
    ------
    LMIInfeasible
        Names the channel and the constraint family.
    """
    nd = model.ndde()
    gains, reports, coeffs = [], [], []
    for i, name in enumerate(CHANNELS):
        ch = nd.channel(i)
        g, rep = synthesize_channel(ch, name, br=float(internal_model_gain[i]),
                                    bf=float(filter_bandwidth[i]),
                                    observer_gain=float(observer_gain[i]), gain_bound=gain_bound,
                                    delayed_input=delayed_input_observer, eps=eps)
        gains.append(g)
        reports.append(rep)
        coeffs.append(ch)
    return EIDController(gains=tuple(gains), model_coeffs=tuple(coeffs),
                         reference=as_reference(reference), predictor=predictor,
                         delayed_input_observer=delayed_input_observer, reports=reports)
