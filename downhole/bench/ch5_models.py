"""Benchmarks of the directional FEM and hybrid models (seed Table 5.2, 68-state real-time factor).

Each Table 5.2 row times 10 s simulated with the compiled Newmark kernel and, in the same run,
``scipy.integrate.solve_ivp(method="LSODA")`` on the same equations (approximated depth of cut,
which an ODE solver can integrate; the row's own run uses it too). LSODA is timed over a shorter
horizon (``baseline_horizon``) and scaled linearly to 10 s; the scaling is reported. For hybrid
rows LSODA integrates the FEM with the same nodes and a one-element BC (same state count): an
ODE solver cannot integrate the delay line directly.
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp
from scipy.linalg import solve_banded

from downhole._timing import best_time
from downhole.bench import BenchOutcome, bench_case, timed
from downhole.params.rig import DEFAULT_TOP_DRIVE_INERTIA

__all__ = ["best_time", "lsoda_seconds"]


def _ode_rhs(model, top_speed=10.0, wob=120e3, kp=1e4, ki=2e3, j_td=DEFAULT_TOP_DRIVE_INERTIA):
    from downhole.bit.law import approx_depth_of_cut, bit_forces
    from downhole.contact.softstring import nodal_friction_forces

    m = model.design_model()
    n = m.n_nodes
    bitp = m.bit.kernel_params()
    Ma, Mt = m.Ma.copy(), m.Mt.copy()
    Mt[0, 0] += j_td

    def band(T):
        ab = np.zeros((3, n))
        ab[0, 1:] = T[1, :-1]
        ab[1] = T[0]
        ab[2, :-1] = T[1, :-1]
        return ab

    abM_a, abM_t = band(Ma), band(Mt)

    def mv(T, x):
        y = T[0] * x
        y[:-1] += T[1, :-1] * x[1:]
        y[1:] += T[1, :-1] * x[:-1]
        return y

    H = m.buoyed_weight - wob
    elem, rad, mu, veps = m.elem, m.radius, m.mu, m.v_eps

    def rhs(t, y):
        ua, va, ut, vt = y[:n], y[n:2 * n], y[2 * n:3 * n], y[3 * n:]
        fa = m.gravity.copy()
        fa[0] -= H
        ft = np.zeros(n)
        ft[0] = kp * (top_speed - vt[0]) + ki * (top_speed * t - ut[0])
        if mu > 0:
            T = -m.Ka[1, :-1] * (ua[1:] - ua[:-1])
            f_fr, t_fr = nodal_friction_forces(T, elem, rad, mu, va, vt, veps)
            fa += f_fr
            ft += t_fr
        d = approx_depth_of_cut(va[-1], vt[-1], bitp)
        w, tq = bit_forces(d, va[-1], vt[-1], bitp)
        fa[-1] -= w
        ft[-1] -= tq
        aa = solve_banded((1, 1), abM_a, fa - mv(m.Ca, va) - mv(m.Ka, ua))
        at = solve_banded((1, 1), abM_t, ft - mv(m.Ct, vt) - mv(m.Kt, ut))
        return np.concatenate([va, aa, vt, at])

    from downhole.string.fem import _static_axial

    y0 = np.zeros(4 * n)
    y0[:n] = _static_axial(m, wob)
    return rhs, y0


def lsoda_seconds(model, horizon: float) -> float:
    """Wall seconds of LSODA on the model's ODE (approximated depth of cut) over ``horizon`` s."""
    rhs, y0 = _ode_rhs(model)
    sec, _ = timed(solve_ivp, rhs, (0.0, horizon), y0, method="LSODA", rtol=1e-6, atol=1e-9)
    return sec


def _row(make, dt, quick, horizon):
    from downhole.sim import simulate

    m = make()
    # warm-up: compile (or load the cache) and touch every code path of both depth-of-cut laws
    simulate(m, duration=0.01, dt=dt, depth_of_cut="approximate")
    simulate(m, duration=0.01, dt=dt)
    sec, cpu = best_time(simulate, m, duration=10.0, dt=dt, depth_of_cut="approximate",
                         record_dt=0.01)
    sec_delayed, cpu_delayed = best_time(simulate, m, duration=10.0, dt=dt, record_dt=0.01)
    base = lsoda_seconds(m, horizon) * (10.0 / horizon)
    return BenchOutcome(sec, f"scipy solve_ivp LSODA, same ODE ({horizon:g} s scaled to 10 s)",
                        base, extra={"states": m.n_states, "dt": dt, "cpu_seconds": cpu,
                                     "seconds_delayed_depth_of_cut": sec_delayed,
                                     "cpu_seconds_delayed_depth_of_cut": cpu_delayed,
                                     "timing": "best of 5-50 calls after warm-up"})


def _register():
    from downhole.experiments.ch5_hybrid import table_rows

    for label, make, dt, seed in table_rows():
        big = "FEM" in label or "108" in label

        def case(quick, _make=make, _dt=dt, _big=big):
            return _row(_make, _dt, quick, 0.2 if _big else 1.0)

        bench_case(f"table5.2 {label} (10 s)", seed_seconds=seed, quick=not big,
                   group="ch5")(case)


_register()


@bench_case("hybrid 68 states real-time factor (dt=1e-3, 10 s)", seed_seconds=None, quick=True,
            group="ch5")
def _realtime(quick):
    from downhole.sim import simulate
    from downhole.string.fem import DirectionalPlant
    from downhole.string.hybrid import hybrid_model

    m = hybrid_model("hybrid68")
    simulate(m, duration=0.01, dt=1e-3)
    sec, cpu = best_time(simulate, m, duration=10.0, dt=1e-3, record_dt=0.01)
    plant = DirectionalPlant(m, 1e-3)
    hold = plant.default_command()
    plant.step(hold)

    def stepped():
        plant.reset()
        for _ in range(1000):
            plant.step(hold)

    psec, _ = best_time(stepped, repeat=3)
    base = lsoda_seconds(m, 1.0) * 10.0
    return BenchOutcome(sec, "scipy solve_ivp LSODA, same-size FEM (1 s scaled to 10 s)", base,
                        extra={"real_time_factor": 10.0 / sec, "cpu_seconds": cpu,
                               "real_time_factor_cpu": 10.0 / cpu, "target_real_time_factor": 500,
                               "plant_step_seconds": psec / 1000,
                               "plant_real_time_factor": 1e-3 / (psec / 1000),
                               "timing": "best of 5-50 calls after warm-up"})
