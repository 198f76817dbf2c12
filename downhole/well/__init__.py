"""Well trajectories: sections, survey import and minimum-curvature geometry along measured depth."""

from downhole.well import path as _path
from downhole.well.path import *  # noqa: F403 -- re-exported: the public names of downhole.well.path

__all__ = list(_path.__all__)
