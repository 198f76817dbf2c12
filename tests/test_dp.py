"""Dynamic programming (seed Eqs. 2.12-2.25): customized vs brute force, replays, baselines."""

import itertools

import numpy as np
import pytest

from downhole.bit.law import approx_depth_of_cut, bit_forces
from downhole.control.dp import (
    DPProblem,
    best_constant_velocities,
    ensemble_costs,
    load_solution,
    replay_discrete,
    replay_path,
    solve_customized,
    solve_robust,
    solve_standard,
    trajectory_cost,
)
from downhole.errors import DownholeInputError


def _tiny(**kw):
    base = dict(horizon=4.0, step=1.0, x2={"min": 0.0, "max": 0.02, "points": 3},
                x4={"min": 0.0, "max": 20.0, "points": 3},
                bounds={"force": (-50e3, 250e3), "torque": (-20e3, 60e3)})
    base.update(kw)
    return DPProblem(**base)


def _brute_force(problem):
    """Enumerate every (x2, x4) grid path from rest; independent loads and cost in Python."""
    g2, g4 = problem.grid2(), problem.grid4()
    a = problem.arrays()
    dt = problem.step
    w, t = problem.weights, problem.targets
    nodes = [(v, om) for v in g2 for om in g4]

    def loads(v, om):
        d = approx_depth_of_cut(v, om, a.bit)
        return bit_forces(d, v, om, a.bit)

    def ok(n0, n1):
        (v0, w0), (v1, w1) = n0, n1
        acc, alpha = (v1 - v0) / dt, (w1 - w0) / dt
        (W0, T0), (W1, T1) = loads(v0, w0), loads(v1, w1)
        f = (W0 + a.ca * v0 + a.mass * acc, W1 + a.ca * v1 + a.mass * acc)
        tq = (T0 + a.ct * w0 + a.inertia * alpha, T1 + a.ct * w1 + a.inertia * alpha)
        fb, tb = problem.bounds.force, problem.bounds.torque
        return all(fb[0] <= x <= fb[1] for x in f) and all(tb[0] <= x <= tb[1] for x in tq)

    best = np.inf
    for rest in itertools.product(nodes, repeat=problem.steps):
        path = [(0.0, 0.0), *rest]
        if not all(ok(path[k], path[k + 1]) for k in range(problem.steps)):
            continue
        c = sum((w.lambda1 * (v - t.v_m) ** 2 + w.lambda2 * (om - t.w_m) ** 2) * dt
                for v, om in path[:-1])
        v, om = path[-1]
        c += w.lambda3 * (v - t.v_d) ** 2 + w.lambda4 * (om - t.w_d) ** 2
        best = min(best, c)
    return best


@pytest.mark.parametrize("bounds", [{"force": (-50e3, 250e3), "torque": (-20e3, 60e3)},
                                    {"force": (0.0, 200e3), "torque": (0.0, 45e3)}])
def test_customized_equals_brute_force_on_tiny_problem(bounds):
    p = _tiny(bounds=bounds)
    bf = _brute_force(p)
    sol = solve_customized(p)
    # same discretization: the DP is exact (grid-resolution bound = 0)
    assert sol.cost == pytest.approx(bf, rel=1e-12)
    p_reg = p.with_updates(x1_regions=3, x3_regions=2)
    assert solve_customized(p_reg, regions=True).cost == pytest.approx(bf, rel=1e-12)


def test_printed_eq_2_21_without_cost_to_go_is_worse():
    """Eq. 2.21 as printed (stage cost only, greedy per step) does worse than the true DP."""
    p = _tiny()
    bf = _brute_force(p)
    # greedy: at each step pick the admissible successor with the lowest stage cost
    from downhole.control.dp.customized import stage_vector, transitions

    sp, succ, _, _ = transitions(p)
    stage, term = stage_vector(p)
    n = 0
    x2, x4 = [0.0], [0.0]
    g2, g4 = p.grid2(), p.grid4()
    for _ in range(p.steps):
        cand = succ[sp[n]:sp[n + 1]]
        n = int(cand[np.argmin(stage[cand])])
        x2.append(g2[n // g4.size])
        x4.append(g4[n % g4.size])
    assert trajectory_cost(p, x2, x4) >= bf


def test_reported_cost_equals_replayed_cost_and_path():
    p = DPProblem(horizon=5.0, step=0.25)
    sol = solve_customized(p)
    x = replay_discrete(sol)  # Eq. 2.12 driven by the DP's u1(k), u2(k)
    np.testing.assert_allclose(x[:, 1], sol.x2, atol=1e-12)
    np.testing.assert_allclose(x[:, 3], sol.x4, atol=1e-9)
    assert trajectory_cost(p, x[:, 1], x[:, 3]) == pytest.approx(sol.cost, rel=1e-9)
    # continuous model driven by the path inversion follows the path closely
    r = replay_path(sol, dt=1e-3)
    assert np.max(np.abs(r["x2"] - sol.x2)) < 5e-3 * p.targets.v_m
    assert np.max(np.abs(r["x4"] - sol.x4)) < 5e-3 * p.targets.w_m
    assert trajectory_cost(p, r["x2"], r["x4"]) == pytest.approx(sol.cost, rel=0.02)


def test_regions_leave_cost_and_path_unchanged():
    p = DPProblem(horizon=5.0, step=0.25, x2={"min": 0, "max": 0.02, "points": 11},
                  x4={"min": 0, "max": 20, "points": 21})
    plain = solve_customized(p)
    for r1, r3 in ((1, 1), (5, 5), (10, 3)):
        sol = solve_customized(p.with_updates(x1_regions=r1, x3_regions=r3), regions=True)
        assert sol.cost == pytest.approx(plain.cost, rel=1e-12)
        assert sol.info["nodes"] >= plain.info["nodes"] / 21  # it did build region nodes


def test_both_dp_variants_beat_best_constant_speeds():
    p = DPProblem(horizon=10.0, step=0.25, x2={"min": 0, "max": 0.02, "points": 11},
                  x4={"min": 0, "max": 20, "points": 11},
                  bounds={"force": (-50e3, 250e3), "torque": (-20e3, 60e3)},
                  standard={"force_levels": 11, "torque_levels": 11, "substep": 0.0125})
    const_cost, v0, w0 = best_constant_velocities(p, scan=7)
    cust = solve_customized(p)
    cont = replay_path(cust, dt=2.5e-3)  # its inputs on the continuous model
    assert trajectory_cost(p, cont["x2"], cont["x4"]) < const_cost
    std = solve_standard(p)
    assert std.cost < const_cost
    # the standard DP's interpolated estimate is not the cost it achieves; the customized DP's is
    assert np.all(std.path_i2 == -1)


def test_robust_with_nominal_only_equals_customized_and_costs_are_consistent():
    p = DPProblem(horizon=5.0, step=0.25, x2={"min": 0, "max": 0.02, "points": 11},
                  x4={"min": 0, "max": 20, "points": 21})
    cust = solve_customized(p)
    rob1 = solve_robust(p, epsilon_scales=(1.0,))
    assert rob1.cost == pytest.approx(cust.cost, rel=1e-12)
    rob = solve_robust(p, epsilon_scales=(0.5, 1.0, 2.0))
    # reported ensemble cost = mean of each model's replayed cost (Eq. 2.25)
    assert rob.cost == pytest.approx(np.mean(rob.info["ensemble_costs"]), rel=1e-9)
    # it minimizes Eq. 2.25 at least as well as the nominal solution does
    assert rob.cost <= np.mean(ensemble_costs(cust, (0.5, 1.0, 2.0))) * (1 + 1e-9)


def test_standard_dp_rollout_cost_is_recomputed():
    p = DPProblem(horizon=3.0, step=0.25, x2={"min": 0, "max": 0.02, "points": 5},
                  x4={"min": 0, "max": 20, "points": 11},
                  standard={"force_levels": 9, "torque_levels": 9, "substep": 0.0125})
    sol = solve_standard(p)
    assert sol.cost == pytest.approx(trajectory_cost(p, sol.x2, sol.x4), rel=1e-12)
    f_lo, f_hi = p.bounds.force
    assert np.all((sol.force >= f_lo) & (sol.force <= f_hi))


def test_save_load_roundtrip_without_pickle(tmp_path):
    p = DPProblem(horizon=2.0, step=0.25)
    sol = solve_customized(p)
    sol.save(tmp_path / "s")
    with np.load(tmp_path / "s" / "solution.npz", allow_pickle=False) as z:
        assert z["x2"].dtype == np.float64
    back = load_solution(tmp_path / "s")
    assert back.cost == sol.cost and back.method == "customized"
    np.testing.assert_array_equal(back.u1, sol.u1)
    assert back.problem == p
    (tmp_path / "s" / "solution.npz").unlink()
    with pytest.raises(DownholeInputError, match="solution.npz"):
        load_solution(tmp_path / "s")


def test_input_signals_path_inversion_matches_discrete_inputs_at_step_starts():
    p = DPProblem(horizon=2.0, step=0.25)
    sol = solve_customized(p)
    t, u1, u2 = sol.input_signals(0.25)
    # at each step start the continuous inversion equals x1_path + F(k)/Ka, with x1 trapezoidal
    a = p.arrays()
    x1 = np.concatenate([[0], np.cumsum(0.5 * (sol.x2[1:] + sol.x2[:-1]) * p.step)])
    np.testing.assert_allclose(u1[:-1], x1[:-1] + sol.force / a.ka, rtol=1e-12, atol=1e-12)


def test_replay_on_simulation_models_and_over_epsilon():
    """The 4th-order simulation model follows the path; epsilon sweeps order the bit speed."""
    from downhole.control.dp import replay_epsilon, replay_lumped

    p = DPProblem(horizon=4.0, step=0.25)
    sol = solve_customized(p)
    res4 = replay_lumped(sol, 4, depth_of_cut="approximate", record_dt=0.25)
    np.testing.assert_allclose(res4["bit_axial_velocity"], sol.x2, atol=1e-3 * p.targets.v_m)
    res12 = replay_lumped(sol, 12, depth_of_cut="approximate", record_dt=0.25)
    assert np.all(np.isfinite(res12["bit_axial_velocity"]))
    sweep = replay_epsilon(sol, (0.5, 1.0, 2.0), use_sim=True, depth_of_cut="approximate",
                           record_dt=0.25)
    own = replay_epsilon(sol, (0.5, 1.0, 2.0), dt=1e-3)
    # same inputs, two integrators: agree; softer rock drills faster
    np.testing.assert_allclose(sweep["x2"], own["x2"], atol=0.03 * p.targets.v_m)
    late = sweep["x2"][:, -4:].mean(1)
    assert late[0] > late[1] > late[2]
