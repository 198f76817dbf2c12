"""A controller benchmark: any controller scored on a fixed, versioned suite of cases.

>>> from downhole.compare import compare_controllers            # doctest: +SKIP
>>> scores = compare_controllers(["stiff-pi", "z-torque"], suite="smoke", out="out/cmp")

The cases (:mod:`downhole.compare.suite`) run the true plant (the directional FEM of each
system with the delayed depth of cut) through the Plant contract, the controllers through the
Controller contract (:func:`~downhole.control.base.run_closed_loop`); the scores reuse
:mod:`downhole.analysis.metrics`. A controller is a built-in name (:data:`BUILTIN`, a registry
of ``factory(system, case)``), an object with ``reset()`` and ``command(t, obs, ref)``, a
factory, a Gymnasium policy (:func:`gym_policy`) or a file (:func:`load_controller_spec`). A
cell whose plant cannot provide what its controller needs is ``n/a`` with the reason.
"""

from downhole.compare.builtin import BUILTIN, Entry, NotApplicable, register
from downhole.compare.core import FORMAT, SCORES, compare_controllers, summarize_scores
from downhole.compare.policies import GymPolicy, gym_policy, load_controller_spec
from downhole.compare.report import write_report
from downhole.compare.suite import NOISE, SUITE_VERSIONS, SUITES, Case, get_suite

__all__ = [
    "BUILTIN",
    "FORMAT",
    "NOISE",
    "SCORES",
    "SUITES",
    "SUITE_VERSIONS",
    "Case",
    "Entry",
    "GymPolicy",
    "NotApplicable",
    "compare_controllers",
    "get_suite",
    "gym_policy",
    "load_controller_spec",
    "register",
    "summarize_scores",
    "write_report",
]
