"""Named DHP penalty-weight sets, read from a TOML registry.

The sets the experiments found or use (``design``, ``robust``, ``hybrid``, ``planned``) are data
in ``downhole/experiments/weight_sets.toml``, shipped with the package and read here through
:mod:`importlib.resources` without importing :mod:`downhole.experiments` (the library does not
depend on the experiments). A user registry (same format: one table per set, the fields of
:class:`~downhole.control.dhp.drilling.PenaltyWeights` as lists of two numbers) can be passed as
``path``.
"""

from __future__ import annotations

import math
import tomllib
from importlib.resources import files
from pathlib import Path

from downhole.errors import DownholeInputError

__all__ = ["REGISTRY", "weight_set", "weight_set_names"]

#: The registry shipped with the package.
REGISTRY = files("downhole") / "experiments" / "weight_sets.toml"

_FIELDS = {"top_position", "node_position", "bit_position", "bit_velocity", "string_velocity",
           "r", "integral"}


def _load(path) -> tuple[str, dict]:
    if isinstance(path, str):
        path = Path(path)
    where = str(path)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise DownholeInputError(f"{where}: cannot read the weight-set registry: "
                                 f"{exc.strerror or exc}") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise DownholeInputError(f"{where}: not a valid TOML weight-set registry: {exc}") from None
    return where, data


def weight_set_names(path=None) -> tuple[str, ...]:
    """Names of the sets in the registry (default :data:`REGISTRY`)."""
    return tuple(_load(REGISTRY if path is None else path)[1])


def weight_set(name: str, path=None) -> dict:
    """The weight set ``name`` as keyword arguments of ``PenaltyWeights`` (tuples of floats).

    Parameters
    ----------
    name : str
        A table of the registry, e.g. ``"planned"``.
    path : str or Path, optional
        Registry file; default the one shipped in ``downhole/experiments/weight_sets.toml``.

    Raises
    ------
    DownholeInputError
        Unknown name (the known ones are listed), unknown field, or a value that is not a pair of
        finite numbers >= 0 -- each naming the file and the dotted field.
    """
    where, data = _load(REGISTRY if path is None else path)
    if name not in data or not isinstance(data[name], dict):
        raise DownholeInputError(f"{where}: no weight set {name!r}; known: {sorted(data)}")
    out = {}
    for key, val in data[name].items():
        if key not in _FIELDS:
            raise DownholeInputError(f"{where}: {name}.{key}: unknown field; expected one of "
                                     f"{sorted(_FIELDS)}")
        if (not isinstance(val, list) or len(val) != 2
                or not all(isinstance(x, (int, float)) and not isinstance(x, bool)
                           for x in val)
                or not all(math.isfinite(x) and x >= 0 for x in val)):
            raise DownholeInputError(f"{where}: {name}.{key}: expected two finite numbers >= 0 "
                                     f"(axial, torsional), got {val!r}")
        out[key] = (float(val[0]), float(val[1]))
    return out
