"""The one controller contract, and the loop that runs any controller on any plant.

A controller reads named observations and named references and returns named commands, the
signals of :mod:`downhole.signals`::

    controller.reset()
    command = controller.command(t, observation, reference)

It declares what it needs (``needs``: observation signals) and what it sets (``commands``);
:func:`check_pair` says whether it can drive a given plant, and why not. Commands a controller
does not set keep the plant's default (e.g. a rotary controller on a plant that also takes a
hook load). :func:`run_closed_loop` runs the pair offline; the real-time SIL loop, the UDP
link and the FMU runner call the same two methods.

References are a mapping of reference signal names (``reference_axial_velocity``,
``reference_angular_velocity``, ...) to values; a controller that needs none ignores it.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

import numpy as np

from downhole.errors import DownholeInputError
from downhole.sim.loop import run_loop

__all__ = ["Controller", "check_pair", "run_closed_loop"]


class Controller:
    """Base class of the controller contract.

    Attributes
    ----------
    needs : tuple of str
        Observation signals read by :meth:`command`.
    commands : tuple of str
        Command signals returned by :meth:`command` (a subset of the plant's).
    """

    needs: tuple = ()
    commands: tuple = ()
    #: Sample time, s, for a discrete-time controller (None: continuous or self-timed). A
    #: runner sets it to its control step before :meth:`reset`; ``reset`` takes no arguments.
    dt: float | None = None

    def reset(self) -> None:
        """Forget the history (integrators, filters) before a new run."""

    def command(self, t: float, observation: Mapping[str, float],
                reference: Mapping[str, float] | None = None) -> dict:  # pragma: no cover
        """Commands at time ``t`` (s) from the observation and the reference.

        Parameters
        ----------
        t : float
            Time, s.
        observation : mapping
            Observed signal name -> value (SI; at least the names in :attr:`needs`).
        reference : mapping, optional
            Reference signal name -> value (SI), e.g. ``reference_axial_velocity`` (m/s) and
            ``reference_angular_velocity`` (rad/s).

        Returns
        -------
        dict
            Command name -> value (SI), the names of :attr:`commands`.
        """
        raise NotImplementedError


def _declared(obj, name):
    value = getattr(obj, name, None)
    return tuple(value) if value is not None else None


def check_pair(controller, plant) -> str | None:
    """Why ``controller`` cannot drive ``plant`` (None when it can).

    A controller can drive a plant when the plant observes every signal it ``needs`` and takes
    every command it sets. Controllers that declare nothing are not checked here (duck typing);
    their first command is checked by the plant.

    Parameters
    ----------
    controller : Controller or object
        Its optional ``needs`` and ``commands`` are compared.
    plant : Plant or object
        Its optional ``observation_names`` and ``command_names`` are compared.

    Returns
    -------
    str or None
        A one-line reason, or None.
    """
    needs = _declared(controller, "needs")
    commands = _declared(controller, "commands")
    observed = set(getattr(plant, "observation_names", ()) or ())
    taken = set(getattr(plant, "command_names", ()) or ())
    if needs and observed:
        missing = [n for n in needs if n not in observed]
        if missing:
            return (f"{type(controller).__name__} needs {missing}, which "
                    f"{type(plant).__name__} does not observe")
    if commands and taken:
        extra = [n for n in commands if n not in taken]
        if extra:
            return (f"{type(controller).__name__} sets {extra}; {type(plant).__name__} takes "
                    f"{sorted(taken)}")
    return None


def run_closed_loop(plant, controller, duration: float, *, reference=None,
                    start: str = "rest", set_point: Mapping[str, float] | None = None,
                    record: Callable | None = None, **start_options):
    """Run ``controller`` on ``plant`` for ``duration`` s; returns the recorded arrays.

    Parameters
    ----------
    plant : downhole.sim.plant.Plant
        The plant (``reset``, ``step``, ``dt``, ``default_command``, ``command_names``).
    controller : Controller
        Or any object with ``reset()`` and ``command(t, obs, ref)``.
    duration : float
        Simulated time, s (a whole number of plant steps).
    reference : mapping or callable, optional
        Reference signals, constant (mapping) or ``reference(t) -> mapping``.
    start, set_point, **start_options
        Passed to ``plant.reset``.
    record : callable, optional
        ``record(t, observation, command)`` called every step (default: keep everything).

    Returns
    -------
    dict
        ``{"time": array, signal: array, ..., "command:" + name: array}``.

    Raises
    ------
    DownholeInputError
        The pair does not fit (:func:`check_pair`), or a bad duration.
    """
    why = check_pair(controller, plant)
    if why:
        raise DownholeInputError(why)
    if not (isinstance(duration, (int, float)) and np.isfinite(duration) and duration > 0):
        raise DownholeInputError(f"duration must be a positive number of seconds, got "
                                 f"{duration!r}")
    n = int(round(duration / plant.dt))
    obs = plant.reset(start=start, set_point=set_point, **start_options)
    if getattr(controller, "dt", None) is not None:
        controller.dt = plant.dt  # the control step of this loop: every plant step
    controller.reset()
    held = plant.default_command() if set_point is None else dict(plant.default_command(),
                                                                  **set_point)
    names = list(obs)
    rows = np.empty((n + 1, len(names)))
    cmd_names = list(plant.command_names)
    cmds = np.empty((n + 1, len(cmd_names)))

    def on_sample(k, o, h):
        rows[k] = [o[c] for c in names]
        cmds[k] = [h[c] for c in cmd_names]
        if record is not None:
            record(k * plant.dt, o, dict(h))

    ref = (reference if callable(reference)
           else (lambda t, r=dict(reference or {}): r))
    run_loop(plant.step, controller, obs, n, plant.dt, held=held,
             write=lambda out, seen, h: h.update(out), reference=lambda k, t: ref(t),
             on_sample=on_sample)
    result = {"time": np.arange(n + 1) * plant.dt}
    result.update({c: rows[:, i] for i, c in enumerate(names) if c != "time"})
    result.update({f"command:{c}": cmds[:, i] for i, c in enumerate(cmd_names)})
    return result
