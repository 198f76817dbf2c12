"""The one closed loop: a controller on a plant, step by step.

Every Python loop that runs a controller on a plant is this function: ``simulate`` with a
controller (over a model's kernel pack), :func:`downhole.control.run_closed_loop` (over any
:class:`~downhole.sim.plant.Plant`, the loop of ``compare-controllers`` and the FMU checks) and
the DHP's runs on a plant and on its design model (:mod:`downhole.control.dhp.closed_loop`).
What differs between them is passed in: how a step is taken, what the controller sees (noise,
a state vector), how its output becomes the held command (named columns of an array, a dict
update, an adapter) and what is recorded. The paced real-time runtime
(:mod:`downhole.sil.runtime`) keeps its own loop because a wall clock and a link decide when a
command arrives; the compiled fast paths (``controller.kernel_runner``) are this loop compiled
for one controller.

The order is the contract of :mod:`downhole.control.base`: at step k the controller sees the
observation of t_k and its command is held over the next ``every`` steps; the sample of t_k is
recorded with the command held from t_k on; the last sample (k = n) is recorded but no step
follows it.
"""

from __future__ import annotations

from collections.abc import Callable

__all__ = ["run_loop"]


def run_loop(step: Callable, controller, observation, n: int, dt: float, *,
             held, write: Callable, reference: Callable | None = None, every: int = 1,
             measure: Callable | None = None, on_sample: Callable | None = None):
    """Run ``controller`` for ``n`` steps of ``dt`` from ``observation``; returns ``held``.

    Parameters
    ----------
    step : callable
        ``step(held) -> raw``: hold the command over one step and return the new raw
        observation (whatever ``measure`` and ``on_sample`` read).
    controller : object
        ``command(t, observation, reference) -> mapping`` (``reset`` is the caller's).
    observation : object
        The raw observation of t = 0.
    n : int
        Steps to take (n + 1 samples).
    dt : float
        The step, s.
    held : object
        The command held over the steps (a dict, an array), updated in place by ``write``.
    write : callable
        ``write(out, observation, held)``: the controller's output into ``held``.
    reference : callable, optional
        ``reference(k, t) -> mapping`` given to the controller (default: empty).
    every : int
        The controller acts every ``every`` steps (its sample time is ``every * dt``).
    measure : callable, optional
        ``measure(k, raw) -> mapping``: what the controller sees (default: the raw observation).
    on_sample : callable, optional
        ``on_sample(k, raw, held)``, called every step after the controller acted.

    Returns
    -------
    object
        ``held`` after the last sample.
    """
    raw = observation
    no_ref: dict = {}
    for k in range(n + 1):
        if k % every == 0:
            t = k * dt
            seen = raw if measure is None else measure(k, raw)
            out = controller.command(t, seen, no_ref if reference is None else reference(k, t))
            write(out, seen, held)
        if on_sample is not None:
            on_sample(k, raw, held)
        if k == n:
            break
        raw = step(held)
    return held
