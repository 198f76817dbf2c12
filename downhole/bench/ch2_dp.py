"""Benchmarks of the Ch. 2 dynamic programming (seed Table 2.2 and Fig. 2.15).

Every row of Table 2.2 is a case with the seed's MATLAB minutes as ``seed_seconds``: customized
DP (with the seed's x1/x3 index regions, so the work is the seed's algorithm's) and robust DP,
20 s and 50 s horizons, search grids 5x5 ... 20x10. The step is 0.05 s (the seed's most likely
step: Table 4.2's DP rows are exactly twice Table 2.2's 20 s rows) and the bounds are wide, so
that every grid transition is a candidate, as in the seed. The robust rows run the forward
ensemble search over (x2, x4) nodes with the three models of Eq. 2.25 (epsilon +/-10 %),
perturbed models integrated with 12.5 ms linearly implicit substeps (~1 % of v_m against a fine
integration); the index grid does not enter it (x1/x3 regions leave the optimum unchanged).
A separate case times the customized DP against the standard DP (forward projection +
interpolation) on the same grid in the same run.
"""

from __future__ import annotations

from downhole.bench import BenchOutcome, bench_case, timed
from downhole.experiments.ch2_dp import _WIDE, TABLE_2_2, _grid, table_problem

__all__: list[str] = []


def _warm():
    from downhole.control.dp import solve_customized, solve_robust

    p = table_problem(1.0, 5, 2, step=0.25)
    solve_customized(p, regions=True)
    solve_customized(p, regions=False)
    solve_robust(p)


def _make_case(kind, horizon, search, index, minutes):
    name = f"table2.2 {kind} DP {horizon} s grid {search}x{index}"
    quick = (search == 5 and horizon == 20) or (kind == "customized" and search == 10
                                                 and horizon == 20)

    @bench_case(name, seed_seconds=minutes * 60.0, quick=quick, group="ch2-dp")
    def _case(quick_run, kind=kind, horizon=horizon, search=search, index=index):
        from downhole.control.dp import solve_customized, solve_robust

        _warm()
        p = table_problem(horizon, search, index)
        if kind == "customized":
            seconds, sol = timed(solve_customized, p, regions=True)
            plain, sol_plain = timed(solve_customized, p, regions=False)
            extra = {"cost": sol.cost, "cost_without_regions": sol_plain.cost,
                     "seconds_without_regions": plain, "nodes": sol.info["nodes"],
                     "steps": p.steps, "step_s": p.step}
        else:
            seconds, sol = timed(solve_robust, p)
            extra = {"cost": sol.cost, "ensemble": list(p.robust.epsilon_scales),
                     "steps": p.steps, "step_s": p.step, "transitions": sol.info["transitions"],
                     "note": "forward robust search over (x2, x4); the index grid does not "
                             "enter it (regions leave the optimum unchanged)"}
        return BenchOutcome(seconds, "none (seed minutes in seed_seconds)", None, extra)

    return _case


for _row in TABLE_2_2:
    _make_case(*_row)


def _versus_standard(horizon, search, step):
    from downhole.control.dp import DPProblem, solve_customized, solve_standard

    p = DPProblem(horizon=horizon, step=step, x2=_grid(0.01, search), x4=_grid(10.0, search),
                  bounds={"force": (0.0, 250e3), "torque": (0.0, 45e3)},
                  standard={"force_levels": 21, "torque_levels": 21, "substep": 5e-3})
    tiny = p.with_updates(horizon=step, bounds=_WIDE)
    solve_customized(tiny)
    solve_standard(tiny)
    seconds, cust = timed(solve_customized, p)
    base, std = timed(solve_standard, p)
    return BenchOutcome(seconds, "standard DP (21x21 inputs, 5 ms substeps, bilinear)", base,
                        {"customized_cost": cust.cost, "standard_cost": std.cost,
                         "standard_cost_estimate": std.info["cost_estimate"]})


@bench_case("dp customized vs standard 20 s grid 11x11 step 0.25", quick=True, group="ch2-dp")
def _vs_standard_small(quick):
    return _versus_standard(20.0, 11, 0.25)


@bench_case("dp customized vs standard 20 s grid 21x21 step 0.25", quick=False, group="ch2-dp")
def _vs_standard_big(quick):
    return _versus_standard(20.0, 21, 0.25)
