"""Every public function of the package documents its parameters (issue 23, item 9).

A public function is a top-level function of a ``downhole`` module whose name is listed in
that module's ``__all__``; if it takes parameters, its docstring must have a numpydoc
``Parameters`` section (a line ``Parameters`` underlined with dashes). The check reads the
source with :mod:`ast` and imports nothing.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "downhole"

_SECTION = re.compile(r"^\s*Parameters\s*\n\s*-{3,}\s*$", re.MULTILINE)

#: Public functions still without a ``Parameters`` section, as (file relative to the package,
#: function). This list may only shrink: document a function and remove its entry here (the
#: test fails while an entry is documented but still listed); never add one.
PENDING: set[tuple[str, str]] = {
    ("_atomic.py", "atomic_path"),
    ("_atomic.py", "is_incomplete"),
    ("_atomic.py", "new_temp"),
    ("_atomic.py", "replace_atomic"),
    ("_atomic.py", "sync_files"),
    ("_atomic.py", "temp_path"),
    ("_atomic.py", "write_bytes_atomic"),
    ("_atomic.py", "write_json_atomic"),
    ("_atomic.py", "write_text_atomic"),
    ("_reader.py", "read_scenario_text"),
    ("_schema.py", "raise_validation"),
    ("_schema.py", "read_scenario"),
    ("_timing.py", "best_time"),
    ("_timing.py", "timed"),
    ("_workers.py", "broken_pool_error"),
    ("analysis/torque_drag.py", "display_table"),
    ("analysis/torque_drag.py", "plot_broomstick"),
    ("analysis/torque_drag.py", "plot_profiles"),
    ("analysis/torque_drag.py", "plot_survey"),
    ("analysis/torque_drag.py", "summary"),
    ("analysis/torque_drag.py", "survey_table"),
    ("analysis/torque_drag.py", "torque_drag_table"),
    ("analysis/torque_drag.py", "write_csv"),
    ("bench/__init__.py", "bench_case"),
    ("bench/__init__.py", "run_bench"),
    ("bench/ch3_neutral.py", "ndde_method_of_steps"),
    ("bench/ch5_models.py", "lsoda_seconds"),
    ("cli/__init__.py", "fail"),
    ("cli/_units.py", "resolve_units"),
    ("cli/compare.py", "compare_controllers_cmd"),
    ("cli/design_dhp.py", "design_dhp_cmd"),
    ("cli/sil.py", "export_fmu"),
    ("cli/sil.py", "sil"),
    ("cli/sil.py", "sil_controller"),
    ("compare/builtin.py", "declared_stand_in"),
    ("compare/builtin.py", "register"),
    ("compare/core.py", "resolve_controllers"),
    ("compare/core.py", "summarize_scores"),
    ("compare/policies.py", "gym_policy"),
    ("compare/policies.py", "load_controller_spec"),
    ("compare/report.py", "render_html"),
    ("compare/runner.py", "case_plant"),
    ("compare/runner.py", "run_cell"),
    ("compare/runner.py", "score_run"),
    ("compare/suite.py", "get_suite"),
    ("compare/systems.py", "build_system"),
    ("compare/systems.py", "describe_system"),
    ("control/dhp/baseline.py", "riccati_numpy"),
    ("control/dhp/closed_loop.py", "channels_from_states"),
    ("control/dhp/design.py", "build_problem"),
    ("control/dhp/drilling.py", "integral_augmented_model"),
    ("control/dhp/drilling.py", "penalty_matrices"),
    ("control/dhp/drilling.py", "table_4_1_weights"),
    ("control/dhp/plan.py", "design_dhp_planned"),
    ("control/dhp/plan.py", "planned_controller"),
    ("control/dhp/riccati.py", "draw_offsets"),
    ("control/dhp/riccati.py", "train_riccati"),
    ("control/dp/__init__.py", "solve"),
    ("control/dp/kernels.py", "advance"),
    ("control/dp/kernels.py", "backward_plain"),
    ("control/dp/kernels.py", "discrete_replay"),
    ("control/dp/kernels.py", "node_bit_loads"),
    ("control/dp/kernels.py", "path_inputs"),
    ("control/dp/kernels.py", "path_load_table"),
    ("control/dp/kernels.py", "path_replay"),
    ("control/dp/kernels.py", "project_table"),
    ("control/dp/kernels.py", "regions_step"),
    ("control/dp/kernels.py", "standard_backward"),
    ("control/dp/kernels.py", "standard_choose"),
    ("control/dp/kernels.py", "steady_loads"),
    ("control/dp/kernels.py", "transition_lists"),
    ("control/dp/standard.py", "input_levels"),
    ("control/eid/controller.py", "load_eid"),
    ("control/eid/damper.py", "coupled_axial_reference"),
    ("control/eid/damper.py", "damper_arrays"),
    ("control/eid/damper.py", "damper_step"),
    ("control/eid/design.py", "channel_closed_loop_design"),
    ("control/eid/design.py", "lmi_blocks"),
    ("control/eid/neutral_runner.py", "make_neutral_runner"),
    ("control/eid/neutral_runner.py", "run_neutral_eid"),
    ("control/eid/predictor.py", "predictive_closed_loop"),
    ("control/eid/references.py", "envelope_tracking_reference"),
    ("control/eid/references.py", "startup_reference"),
    ("control/eid/references.py", "startup_time"),
    ("control/eid/stability.py", "bit_rock_open_loop_roots"),
    ("control/eid/stability.py", "channel_loop_matrices"),
    ("control/eid/stability.py", "characteristic_roots"),
    ("control/eid/stability.py", "plot_roots"),
    ("control/eid/stability.py", "regenerative_closed_loop"),
    ("control/observer.py", "bit_law_jacobian"),
    ("errors.py", "positive_number"),
    ("experiments/__init__.py", "experiment"),
    ("experiments/__init__.py", "get_experiment"),
    ("experiments/__init__.py", "run_experiment"),
    ("experiments/ch2_dp.py", "robust_pair"),
    ("experiments/ch2_dp.py", "spread_metrics"),
    ("experiments/ch2_dp.py", "table_problem"),
    ("experiments/ch4_fem.py", "fig4_4"),
    ("experiments/ch5_hybrid.py", "fig5_4"),
    ("experiments/ch5_hybrid.py", "fig5_5"),
    ("experiments/ch5_hybrid.py", "fig5_6"),
    ("experiments/ch5_hybrid.py", "fig5_7"),
    ("experiments/ch5_hybrid.py", "fig5_8"),
    ("experiments/ch5_hybrid.py", "fig5_9"),
    ("experiments/ch5_hybrid.py", "table5_2"),
    ("scenario/__init__.py", "build_lumped_model"),
    ("scenario/__init__.py", "is_lumped_type"),
    ("scenario/__init__.py", "load_scenario"),
    ("scenario/__init__.py", "model_type"),
    ("scenario/__init__.py", "parse_scenario"),
    ("scenario/__init__.py", "register_model_type"),
    ("scenario/__init__.py", "validate_data"),
    ("scenario/__init__.py", "validate_lumped"),
    ("scenario/__init__.py", "validate_scenario"),
    ("scenario/dhp.py", "is_dhp_dialect"),
    ("scenario/dhp.py", "load_dhp_scenario"),
    ("scenario/dhp.py", "parse_dhp_scenario"),
    ("scenario/dhp.py", "run_dhp_scenario"),
    ("scenario/dhp.py", "run_scenario_simulation"),
    ("scenario/directional.py", "build_directional"),
    ("scenario/directional.py", "run_directional_scenario"),
    ("scenario/directional.py", "validate_directional_scenario"),
    ("scenario/neutral.py", "build_controller"),
    ("scenario/neutral.py", "build_neutral"),
    ("scenario/neutral.py", "build_reference"),
    ("scenario/neutral.py", "load_neutral_scenario"),
    ("scenario/neutral.py", "run_neutral_scenario"),
    ("scenario/neutral.py", "validate_neutral_scenario"),
    ("scenario/system.py", "build_system"),
    ("scenario/system.py", "check_fidelity"),
    ("scenario/system.py", "is_system_dialect"),
    ("scenario/system.py", "run_system_scenario"),
    ("scenario/system.py", "validate_system_scenario"),
    ("scenario/torque_drag.py", "run_torque_drag"),
    ("scenario/torque_drag.py", "torque_drag_case"),
    ("sil/console.py", "format_seconds"),
    ("sil/controllers.py", "controller_choices"),
    ("sil/controllers.py", "pi_controller_for"),
    ("sil/controllers.py", "plant_stick_slip_frequency"),
    ("sil/controllers.py", "plant_torsional_impedance"),
    ("sil/controllers.py", "run_offline"),
    ("sil/link.py", "is_loopback"),
    ("sil/protocol.py", "load_key"),
    ("sil/protocol.py", "pack"),
    ("sil/protocol.py", "pack_layout"),
    ("sil/protocol.py", "unpack"),
    ("sil/protocol.py", "unpack_layout"),
    ("sil/scenario.py", "check_code_allowed"),
    ("sil/scenario.py", "dashboard_token"),
    ("sil/scheduling.py", "elevate_priority"),
    ("sil/scheduling.py", "sleep_until"),
    ("sil/testing.py", "ch6_dhp"),
    ("sim/kernel.py", "new_run_state"),
    ("sim/kernel.py", "thomas_solve"),
    ("sim/plant.py", "check_start"),
    ("sim/plant.py", "plant_bit_radius"),
    ("sim/reference_numpy.py", "simulate_lumped4_numpy"),
    ("string/fem.py", "fem_from_nodes"),
    ("string/fem.py", "table_5_1_setup"),
    ("string/torque_drag.py", "md_nodes"),
    ("system.py", "steady_bit_state"),
}


def _all_names(tree: ast.Module) -> set[str]:
    """Names listed in the module's ``__all__`` (a literal list or tuple of strings)."""
    names: set[str] = set()
    for node in tree.body:
        if isinstance(node, ast.Assign):
            targets = node.targets
        elif isinstance(node, ast.AnnAssign):
            targets = [node.target]
        else:
            continue
        if any(isinstance(t, ast.Name) and t.id == "__all__" for t in targets) and isinstance(
                node.value, (ast.List, ast.Tuple)):
            names |= {e.value for e in node.value.elts
                      if isinstance(e, ast.Constant) and isinstance(e.value, str)}
    return names


def _has_parameters(fn: ast.FunctionDef | ast.AsyncFunctionDef) -> bool:
    a = fn.args
    names = [x.arg for x in a.posonlyargs + a.args + a.kwonlyargs]
    names = [n for n in names if n not in ("self", "cls")]
    return bool(names or a.vararg or a.kwarg)


def undocumented() -> set[tuple[str, str]]:
    """(file, function) of every public function with parameters but no Parameters section."""
    missing = set()
    for path in sorted(PACKAGE.rglob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
        public = _all_names(tree)
        if not public:
            continue
        rel = path.relative_to(PACKAGE).as_posix()
        for node in tree.body:
            if (isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef))
                    and node.name in public and _has_parameters(node)
                    and not _SECTION.search(ast.get_docstring(node) or "")):
                missing.add((rel, node.name))
    return missing


def test_public_functions_document_their_parameters():
    new = sorted(undocumented() - PENDING)
    assert not new, ("public functions without a numpydoc Parameters section (document them; "
                     f"do not add them to PENDING): {new}")


def test_pending_list_is_honest():
    done = sorted(PENDING - undocumented())
    assert not done, f"documented now: remove these entries from PENDING: {done}"


if __name__ == "__main__":  # print the current list, to shrink PENDING after documenting
    print("PENDING: set[tuple[str, str]] = {")
    for path, name in sorted(undocumented()):
        print(f'    ("{path}", "{name}"),')
    print("}")
