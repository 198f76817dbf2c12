"""FMU export: the scenario's plant as an FMI 2.0 co-simulation FMU (pythonfmu), for FMPy,
OpenModelica, Simulink and other FMI tools.

:func:`export_fmu` copies :mod:`downhole.sil.fmu_slave` and the scenario into an FMU. Inputs:
``command_<name>`` for every surface command of the plant; outputs: every named signal.
:func:`simulate_fmu` runs an FMU with FMPy and returns a :class:`~downhole.sim.result.Result`.
"""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

import numpy as np

from downhole.errors import DownholeInputError
from downhole.sim.result import Result

__all__ = ["export_fmu", "simulate_fmu"]


def export_fmu(scenario, out="plant.fmu") -> Path:
    """Build ``out`` (an ``.fmu``) from a SIL scenario file (validated first).

    Raises
    ------
    ScenarioError
        Invalid scenario.
    DownholeInputError
        ``out`` does not end in ``.fmu``.
    """
    from pythonfmu.builder import FmuBuilder

    from downhole.sil.scenario import build_from_scenario, load_sil_scenario

    scenario = Path(scenario)
    out = Path(out)
    if out.suffix != ".fmu":
        raise DownholeInputError(f"--out must end in .fmu, got {out}")
    sc = load_sil_scenario(scenario)
    build_from_scenario(sc, with_controller=False)  # fail here, not inside the FMU
    out.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="downhole_fmu_") as tmp:
        tmp = Path(tmp)
        script = tmp / "DownholePlant.py"
        shutil.copy2(Path(__file__).with_name("fmu_slave.py"), script)
        res = tmp / "scenario.toml"
        shutil.copy2(scenario, res)
        built = FmuBuilder.build_FMU(script, dest=tmp / "out", project_files=[res])
        from downhole._atomic import atomic_path

        with atomic_path(out) as part:  # the build is in /tmp: copy, fsync, rename
            shutil.copyfile(built, part)
    return out


def simulate_fmu(fmu, stop_time: float, step_size: float, start_values: dict | None = None
                 ) -> Result:
    """Run ``fmu`` with FMPy (co-simulation) and return the outputs as a Result."""
    import fmpy

    rec = fmpy.simulate_fmu(str(fmu), stop_time=stop_time, output_interval=step_size,
                            start_values=start_values or {}, fmi_type="CoSimulation")
    names = [n for n in rec.dtype.names if n != "time"]
    return Result(np.asarray(rec["time"]), {n: np.asarray(rec[n], float) for n in names},
                  attrs={"runner": "fmpy", "fmu": str(fmu)})
