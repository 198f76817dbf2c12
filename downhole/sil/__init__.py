"""Real-time software-in-the-loop testbed (seed Ch. 6): runtime, UDP link, HIL, dashboard, FMU.

- :mod:`~downhole.sil.runtime`: :class:`RealTimeRunner` paced to ``time.monotonic()`` at a fixed
  step, deadline-miss / overrun counting, safety action on controller timeout;
- :mod:`~downhole.sil.protocol` and :mod:`~downhole.sil.link`: the versioned binary UDP protocol,
  :class:`PlantLink` (plant end) and :class:`ControllerClient` (client library);
- :mod:`~downhole.sil.plants`: :func:`build_plant`, any plant as a fixed named-signal layout;
- :mod:`~downhole.sil.hil`: hardware-in-the-loop string and a software rig;
- :mod:`~downhole.sil.scenario`: SIL scenario files, read with the one scenario schema
  (:mod:`downhole._schema`) and the SIL's defaults;
- :mod:`~downhole.sil.dashboard`: the FastAPI + WebSocket live dashboard;
- :mod:`~downhole.sil.fmu`: FMI 2.0 co-simulation export (pythonfmu).

See ``docs/sil.md``.
"""

from downhole.sil.controllers import SurfacePI, load_controller_file, pi_controller_for, run_offline
from downhole.sil.link import ControllerClient, PlantLink
from downhole.sil.plants import SilPlant, build_plant
from downhole.sil.protocol import VERSION as PROTOCOL_VERSION
from downhole.sil.recorder import RingRecorder, load_chunks
from downhole.sil.runtime import RealTimeRunner, SafetyPolicy

__all__ = [
    "PROTOCOL_VERSION",
    "ControllerClient",
    "PlantLink",
    "RealTimeRunner",
    "RingRecorder",
    "SafetyPolicy",
    "SilPlant",
    "SurfacePI",
    "build_plant",
    "load_chunks",
    "load_controller_file",
    "pi_controller_for",
    "run_offline",
]
