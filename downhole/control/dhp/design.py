"""``design_dhp``: train a DHP tracking controller for a model and a bit-velocity reference.

Puts the drilling specifics together: the reference transform (Eqs. 4.21-4.23), the steady-state
feed-forward, the penalty layout (Eq. 4.45) and the trainer (Algorithm 1 or its fast paths).
"""

from __future__ import annotations

import math

import numpy as np

from downhole.control.affine import ControlAffineModel
from downhole.control.dhp.controller import DHPController
from downhole.control.dhp.drilling import (
    PenaltyWeights,
    feed_forward,
    penalty_matrices,
    reference_states,
)
from downhole.control.dhp.references import BitReference
from downhole.control.dhp.trainer import DHPProblem, DHPSettings, train_dhp
from downhole.errors import DownholeInputError

__all__ = ["build_problem", "design_dhp"]


def build_problem(model: ControlAffineModel, reference: BitReference, horizon: float,
                  weights: PenaltyWeights, use_feed_forward: bool = True) -> DHPProblem:
    """The non-dimensional tracking problem of ``model`` for ``reference`` over ``horizon`` s."""
    if not isinstance(model, ControlAffineModel):
        raise DownholeInputError(f"model must be a ControlAffineModel, got {type(model).__name__}")
    if not (isinstance(horizon, (int, float)) and math.isfinite(horizon)):
        raise DownholeInputError(f"horizon must be a number of seconds, got {horizon!r}")
    n_steps = int(round(horizon / model.dt))
    if n_steps < 1:
        raise DownholeInputError(f"horizon = {horizon!r} s is shorter than one step "
                                 f"(dt = {model.dt:g} s)")
    v, w, x, a = reference.sample(n_steps, model.dt)
    ref = reference_states(model, v, w, x, a)
    uff = None
    if use_feed_forward:
        # the steady deflected trajectory (static twist/stretch under the bit and contact
        # forces) on which u_ff is an exact equilibrium; bit positions stay at int v_d, int w_d
        uff, ref = feed_forward(model, ref, return_reference=True)
    Q, R, S = penalty_matrices(model, weights)
    return DHPProblem(model, Q, R, S, ref, uff)


def design_dhp(model: ControlAffineModel, reference: BitReference | None = None, *,
               horizon: float = 40.0, weights: PenaltyWeights | None = None,
               settings: DHPSettings | None = None, input_limits=None,
               use_feed_forward: bool = True, past_horizon: str = "stationary",
               progress: bool = False) -> DHPController:
    """Train a DHP controller (seed Algorithm 1 or a fast path) and return it.

    Parameters
    ----------
    model : ControlAffineModel
        Non-dimensional design model (approximated depth of cut with the floor of Eq. 4.16).
    reference : BitReference, optional
        Default: the step 10 mm/s, 20 rad/s of Fig. 4.7.
    horizon : float
        Training horizon t_f, s (40 s in Table 4.2).
    weights : PenaltyWeights, optional
        Q, R, S layout (Eq. 4.45); default ``PenaltyWeights()``.
    settings : DHPSettings, optional
        Trainer settings (method, N_S, N_I, threshold, sample radius, ...).
    input_limits : array_like (m, 2), optional
        Physical input limits applied online; default the model's.
    use_feed_forward : bool
        Penalize u - u_ff (True) or u itself (the seed's formulation).
    past_horizon : {"stationary", "error"}
        Behaviour past the horizon (see :mod:`downhole.control.dhp.controller`).
    progress : bool
        Progress bar.

    Returns
    -------
    DHPController
        With ``.training`` (the :class:`~downhole.control.dhp.trainer.DHPTraining`).
    """
    reference = reference or BitReference.step()
    weights = weights or PenaltyWeights()
    settings = settings or DHPSettings()
    if any(float(x) != 0.0 for x in weights.integral) and "integral" not in model.metadata:
        from downhole.control.dhp.drilling import integral_augmented_model

        model = integral_augmented_model(model)
    problem = build_problem(model, reference, horizon, weights, use_feed_forward)
    tr = train_dhp(problem, settings, progress=progress)
    limits = model.input_limits if input_limits is None else np.asarray(input_limits, float)
    if limits is not None and np.asarray(limits).shape != (model.n_inputs, 2):
        raise DownholeInputError(f"input_limits must be ({model.n_inputs}, 2), got "
                                 f"{np.asarray(limits).shape}")
    settings_d = {k: (list(v) if isinstance(v, tuple) else v)
                  for k, v in settings.__dict__.items()}
    if not isinstance(settings.basis, str):       # a user basis object: record its name
        settings_d["basis"] = str(getattr(settings.basis, "name",
                                          type(settings.basis).__name__))
    meta = {"model": model.describe(), "settings": settings_d, "weights": weights.to_dict(),
            "horizon": problem.n_steps * model.dt, "use_feed_forward": use_feed_forward,
            "training_seconds": tr.seconds, "method": tr.method,
            "max_iterations": int(tr.iterations.max()) if tr.iterations.size else 0,
            "mean_iterations": float(tr.iterations.mean()) if tr.iterations.size else 0.0,
            "max_mu": float(np.nanmax(tr.mu))}
    arrays = {"weight_steps": tr.weight_steps, "weights": tr.weights,
              "iterations": tr.iterations, "errors": tr.errors, "mu": tr.mu}
    ctrl = DHPController(tr.kc, tr.kd, problem.reference, problem.u_ff, model.state_scale,
                         model.input_scale, model.dt, model.state_names, model.state_kinds,
                         model.input_names, reference, input_limits=limits,
                         past_horizon=past_horizon, meta=meta, arrays=arrays)
    ctrl.attach_model(model)
    ctrl.training = tr
    ctrl.problem = problem
    return ctrl
