"""Model types of scenario files beyond the lumped ones, registered with
:func:`downhole.scenario.register_model_type`. Each runner takes ``(data, source, text)`` and
returns a :class:`~downhole.sim.Result`; modules are imported only when a scenario uses them."""

from __future__ import annotations

from downhole.scenario import register_model_type


def _neutral(data, source, text):
    from downhole.scenario.neutral import run_neutral_scenario

    return run_neutral_scenario(data, source, text)


def _directional(data, source, text):
    from downhole.scenario.directional import run_directional_scenario

    return run_directional_scenario(data, source, text)


register_model_type("neutral", _neutral)
register_model_type("fem", _directional)
register_model_type("hybrid", _directional)


def _dhp(data, source, text):
    from downhole.scenario.dhp import run_dhp_scenario

    return run_dhp_scenario(data, source, text)


register_model_type("dhp", _dhp)


def _system(data, source, text):
    from downhole.scenario.system import run_system_scenario

    return run_system_scenario(data, source, text)


register_model_type("system", _system)
