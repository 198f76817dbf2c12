"""Registry of runnable experiments, one per figure/table of the dissertation.

Each module of this package registers its experiments with :func:`experiment`. An experiment
function receives ``(out_dir: pathlib.Path, quick: bool)``, writes its figure(s) and data into
``out_dir`` and returns ``{"measured": {...}, "passed": bool}``; :func:`run_experiment` writes
``claim.json`` = {"id", "claim", "measured", "passed"} next to them.
"""

from __future__ import annotations

import importlib
import pkgutil
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from downhole._atomic import write_json_atomic

__all__ = ["Experiment", "all_experiments", "experiment", "get_experiment", "run_experiment"]


@dataclass(frozen=True)
class Experiment:
    """A registered experiment.

    Attributes
    ----------
    id : str
        The dissertation's figure/table number (``fig2.3``, ``table2.2``) or a descriptive id.
    title : str
        One line saying what it shows.
    claim : str
        The claim checked, in words, with its numeric threshold.
    chapter : int
        Dissertation chapter (for the report).
    caption : str
        The dissertation's caption of the figure/table, if any.
    func : callable
        ``func(out_dir, quick) -> {"measured": dict, "passed": bool}``.
    """

    id: str
    title: str
    claim: str
    chapter: int
    func: Callable = field(repr=False)
    caption: str = ""


_REGISTRY: dict[str, Experiment] = {}
_LOADED = False


def experiment(id: str, *, title: str, claim: str, chapter: int, caption: str = ""):
    """Decorator registering an experiment function under ``id``."""

    def deco(func):
        if id in _REGISTRY:
            raise ValueError(f"experiment id {id!r} registered twice")
        _REGISTRY[id] = Experiment(id=id, title=title, claim=claim, chapter=chapter, func=func,
                                   caption=caption)
        return func

    return deco


def _load_all() -> None:
    global _LOADED
    if _LOADED:
        return
    for mod in pkgutil.iter_modules(__path__):
        if not mod.name.startswith("_"):
            importlib.import_module(f"{__name__}.{mod.name}")
    _LOADED = True


def _sort_key(eid: str):
    import re

    m = re.match(r"(fig|table)(\d+)\.(\d+)", eid)
    if m:
        return (int(m.group(2)), 0 if m.group(1) == "fig" else 1, int(m.group(3)), eid)
    return (99, 2, 0, eid)


def all_experiments() -> list[Experiment]:
    """All registered experiments, ordered by chapter and number."""
    _load_all()
    return [_REGISTRY[k] for k in sorted(_REGISTRY, key=_sort_key)]


def get_experiment(eid: str) -> Experiment:
    """The experiment ``eid``; raises ``KeyError`` listing the known ids."""
    _load_all()
    if eid not in _REGISTRY:
        raise KeyError(f"unknown experiment {eid!r}; known: {', '.join(sorted(_REGISTRY, key=_sort_key))}")
    return _REGISTRY[eid]


def run_experiment(eid: str, out_dir: Path, quick: bool = False) -> dict:
    """Run ``eid`` into ``out_dir/eid/`` and write its ``claim.json``; returns that dict."""
    exp = get_experiment(eid)
    target = Path(out_dir) / eid
    target.mkdir(parents=True, exist_ok=True)
    outcome = exp.func(target, quick)
    claim = {"id": eid, "claim": exp.claim, "measured": _jsonable(outcome["measured"]),
             "passed": bool(outcome["passed"])}
    write_json_atomic(target / "claim.json", claim)
    return claim


def _jsonable(obj):
    import numpy as np

    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, (np.floating, np.integer)):
        return obj.item()
    if isinstance(obj, np.bool_):
        return bool(obj)
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    return obj
