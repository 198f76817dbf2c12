"""The one step-by-step contract every drill-string plant honours, as Gymnasium's ``Env`` is.

A :class:`Plant` is a model being simulated: it owns the simulation state and advances it by one
fixed step ``dt`` per :meth:`Plant.step`. Commands and observations are dictionaries of *named*
scalar signals declared in :mod:`downhole.signals` (their SI units and, for commands, their
admissible ranges come from there). The runners — ``simulate``, the real-time SIL loop, the FMU
slave and the Gymnasium environment — use only this contract:

``reset(*, start="rest", set_point=None) -> observation``
    Start a run. ``start`` is one of :data:`START_MODES`:

    ``"rest"``
        Everything at rest, the bit on a flat hole bottom (the seed's start).
    ``"off_bottom"``
        The string moving steadily at the set-point (rotating, lowering at the axial set-point)
        with the bit ``clearance`` above a flat hole bottom: no bit force.
    ``"steady"``
        The steady drilling state at the set-points: the string wound up and compressed by the
        steady bit forces, the bit cutting at equilibrium on a helical hole bottom (depth of cut
        2 pi v / omega).

    ``set_point`` maps the plant's set-point signals to values (default: the plant's default
    command). A plant that cannot start in a mode raises
    :class:`~downhole.errors.DownholeInputError` naming the mode and why.
``step(command) -> observation``
    Hold ``command`` over one step and advance ``dt``. Every declared command must be present;
    non-finite or out-of-range values raise :class:`~downhole.errors.DownholeInputError` and are
    never applied (:meth:`Plant.command_vector`).

Subclasses set ``command_names``, ``observation_names`` and ``dt`` and implement ``_reset`` and
``_step``; the base class validates.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from downhole.errors import DownholeInputError
from downhole.signals import SIGNALS, check_command_value
from downhole.units import as_si

__all__ = ["START_MODES", "Plant", "check_start", "plant_bit_radius", "under_rig"]

#: The ways a run can start (see the module docstring).
START_MODES = ("rest", "off_bottom", "steady")


def check_start(start: str) -> str:
    """``start`` if it is one of :data:`START_MODES`, else a precise error."""
    if start not in START_MODES:
        raise DownholeInputError(f"start must be one of {START_MODES}, got {start!r}")
    return start


def _si_value(name: str, value) -> float:
    """``value`` of signal ``name`` in SI: numbers as they are, unit strings (``"60 rpm"``) and
    pint quantities converted to the signal's declared dimension (:mod:`downhole.signals`)."""
    if isinstance(value, str) or hasattr(value, "magnitude"):
        sig = SIGNALS.get(name)
        if sig is None:
            raise DownholeInputError(f"{name}: a quantity needs a declared signal; give a number")
        return float(as_si(value, sig.dimension, name))
    try:
        return float(value)
    except (TypeError, ValueError):
        raise DownholeInputError(f"{name}: expected a number, got {value!r}") from None


class Plant:
    """Base class of the plant contract (see the module docstring).

    Attributes
    ----------
    command_names : tuple of str
        Declared command signals, in the order :meth:`command_vector` returns them.
    observation_names : tuple of str
        Declared observation signals (keys of every observation).
    dt : float
        Step, s.
    """

    command_names: tuple = ()
    observation_names: tuple = ()
    dt: float = 0.0

    # ------------------------------------------------------------------ contract
    def reset(self, *, start: str = "rest", set_point: Mapping[str, float] | None = None,
              **options) -> dict:
        """Start a run from ``start`` (see :data:`START_MODES`); returns the first observation.

        Parameters
        ----------
        start : {"rest", "off_bottom", "steady"}
        set_point : mapping of str to float, optional
            Values of the command signals the start is computed for (default:
            :meth:`default_command`).
        **options
            Plant-specific start options (e.g. ``clearance`` for ``"off_bottom"``).
        """
        check_start(start)
        sp = self.default_command()
        if set_point is not None:
            unknown = set(set_point) - set(self.command_names)
            if unknown:
                raise DownholeInputError(f"set_point names {sorted(unknown)} are not commands of "
                                         f"this plant; commands: {self.command_names}")
            sp.update({k: _si_value(k, v) for k, v in set_point.items()})
        self.command_vector(sp)  # validates the set-point like any command
        return self._reset(start, sp, **options)

    def step(self, command: Mapping[str, float]) -> dict:
        """Hold ``command`` over one step and advance ``dt``; returns the observation."""
        return self._step(self.command_vector(command))

    def default_command(self) -> dict:
        """The command a run holds when nothing else is given (zeros unless overridden)."""
        return {n: 0.0 for n in self.command_names}

    # ------------------------------------------------------------------ helpers
    def command_vector(self, command: Mapping[str, float]) -> np.ndarray:
        """The declared commands of ``command`` as a float vector, validated.

        Raises
        ------
        DownholeInputError
            A command is missing, not a number, non-finite or outside its declared range.
        """
        try:
            values = [command[n] for n in self.command_names]
        except KeyError as exc:
            raise DownholeInputError(f"command lacks {exc.args[0]!r}; expected "
                                     f"{self.command_names}") from None
        except TypeError:
            raise DownholeInputError(f"command must be a mapping of {self.command_names} to "
                                     f"numbers, got {type(command).__name__}") from None
        out = np.empty(len(values))
        for i, (name, v) in enumerate(zip(self.command_names, values)):
            why = check_command_value(name, v)
            if why is not None:
                if not isinstance(v, str) and not hasattr(v, "magnitude"):
                    raise DownholeInputError(f"command refused: {why}")
                # a unit string or pint quantity ("60 rpm"): converted off the hot path
                v = _si_value(name, v)
                why = check_command_value(name, v)
                if why is not None:
                    raise DownholeInputError(f"command refused: {why}")
            out[i] = float(v)
        return out

    @property
    def command_units(self) -> dict:
        """SI unit of every command (from :mod:`downhole.signals`)."""
        return {n: SIGNALS[n].unit if n in SIGNALS else "" for n in self.command_names}

    # ------------------------------------------------------------------ to implement
    def _reset(self, start: str, set_point: dict, **options) -> dict:  # pragma: no cover
        raise NotImplementedError

    def _step(self, command: np.ndarray) -> dict:  # pragma: no cover
        raise NotImplementedError


def plant_bit_radius(plant) -> float | None:
    """Radius, m, of the bit of the model ``plant`` simulates, or None when it cannot be found.

    Results record it as the ``bit_radius`` attribute, which the mechanical specific energy
    (``Result.summary()["mse"]``) needs. Looked up, on the plant and on the plants it wraps
    (``plant``, ``inner``, ``hp`` attributes), as ``bit_radius``, ``model.bit.radius``,
    ``dmodel.bit.radius``, ``bit.radius`` or ``rig_bit.radius``.
    """
    obj, seen = plant, set()
    while obj is not None and id(obj) not in seen:
        seen.add(id(obj))
        r = obj.__dict__.get("bit_radius") if hasattr(obj, "__dict__") else None
        candidates = [r] + [getattr(getattr(getattr(obj, a, None), "bit", None), "radius", None)
                            for a in ("model", "dmodel")]
        candidates += [getattr(getattr(obj, a, None), "radius", None) for a in ("bit", "rig_bit")]
        for c in candidates:
            if isinstance(c, (int, float)) and math.isfinite(c) and c > 0:
                return float(c)
        obj = next((getattr(obj, a) for a in ("plant", "inner", "hp")
                    if getattr(obj, a, None) is not None), None)
    return None


def steady_depth_of_cut(v: float, omega: float) -> float:
    """Total depth of cut per revolution when the bit moves steadily at ``v`` m/s and ``omega``
    rad/s: d = 2 pi v / omega (Eq. 2.11 without the floor), m. Needs omega > 0."""
    if not (math.isfinite(v) and math.isfinite(omega) and omega > 0):
        raise DownholeInputError(f"a steady drilling start needs a positive angular set-point, "
                                 f"got omega = {omega!r} rad/s")
    return 2.0 * math.pi * v / omega


def under_rig(model, integrator: str | None = None):
    """``model.with_rig()``: a lumped chain or a neutral model of a described system under the
    rig's top node (the model the top drive and the hook act on, as on a FEM's top node).

    Parameters
    ----------
    model : ChainModel or NeutralModel
        A model with a ``with_rig`` builder (None for a seed preset) and a ``rigless_top``
        sentence saying what its top is instead.
    integrator : str, optional
        Must be None or ``"newmark"`` (the rig's node steps with Newmark).

    Returns
    -------
    DirectionalModel

    Raises
    ------
    DownholeInputError
        A preset's model (its own top takes no rig) or another integrator.
    """
    if model.with_rig is None:
        raise DownholeInputError(f"{model.rigless_top}; it takes no top_drive / hook: describe "
                                 "the system (DrillingSystem, [well] and [string]) to run it "
                                 "under a rig")
    if integrator not in (None, "newmark"):
        raise DownholeInputError(f"integrator={integrator!r}: the rig's node (top-drive "
                                 "inertia, PI, hook servo) steps with 'newmark'; explicit Euler "
                                 "is the seed's scheme for the Table 2.1 presets' ideal top "
                                 "drive")
    return model.with_rig()
