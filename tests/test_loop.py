"""The one closed loop (downhole.sim.loop.run_loop) against closed forms of a scalar plant."""

import numpy as np
import pytest

from downhole.sim.loop import run_loop


class _Gain:
    def __init__(self, k):
        self.k = k

    def command(self, t, obs, ref):
        return {"u": -self.k * (obs["x"] - ref.get("r", 0.0))}


def _plant(a, b):
    state = {"x": 1.0}

    def step(held):
        state["x"] = a * state["x"] + b * held["u"]
        return {"x": state["x"]}

    return step, {"x": state["x"]}


@pytest.mark.parametrize("every", [1, 2, 5])
def test_scalar_loop_matches_the_closed_form_with_a_held_command(every):
    a, b, k, n = 0.95, 0.1, 2.0, 40
    step, obs0 = _plant(a, b)
    xs = np.empty(n + 1)
    us = np.empty(n + 1)

    def on_sample(i, obs, held):
        xs[i], us[i] = obs["x"], held["u"]

    run_loop(step, _Gain(k), obs0, n, 0.01, held={"u": 0.0},
             write=lambda out, seen, held: held.update(out), every=every, on_sample=on_sample)
    # over one control period of m steps with u held at -k x_j:
    # x_{j+m} = a^m x_j - k b (1 + a + ... + a^{m-1}) x_j
    m = every
    period = a ** m - k * b * sum(a ** i for i in range(m))
    for j in range(0, n + 1, m):
        assert xs[j] == pytest.approx(period ** (j // m), rel=1e-12)
        assert us[j] == pytest.approx(-k * xs[j], rel=1e-12)
    # the command is held between control instants
    for j in range(n + 1):
        assert us[j] == us[j - j % m]


def test_reference_measure_and_last_sample_without_a_step():
    a, b, k, n = 1.0, 1.0, 1.0, 3
    step, obs0 = _plant(a, b)
    calls = []

    def counted(held):
        calls.append(dict(held))
        return step(held)

    seen = []
    run_loop(counted, _Gain(k), obs0, n, 0.5, held={"u": 0.0},
             write=lambda out, s, held: held.update(out),
             reference=lambda i, t: {"r": 2.0 * t},
             measure=lambda i, raw: seen.append(i) or {"x": raw["x"] + 0.0})
    assert len(calls) == n  # n steps, n + 1 samples
    assert seen == [0, 1, 2, 3]
    # deadbeat with k = b = a = 1: x_{j+1} = r(t_j) = 2 t_j
    assert calls[0]["u"] == pytest.approx(-(1.0 - 0.0))
    assert calls[1]["u"] == pytest.approx(-(0.0 - 1.0))
