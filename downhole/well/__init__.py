"""Well trajectories: sections, survey import and minimum-curvature geometry along measured depth."""

from downhole.well.path import (
                                Arc,
                                BuildTurn,
                                Tangent,
                                Vertical,
                                WellPath,
                                minimum_curvature,
                                read_survey_csv,
)

__all__ = [
                                "Arc",
                                "BuildTurn",
                                "Tangent",
                                "Vertical",
                                "WellPath",
                                "minimum_curvature",
                                "read_survey_csv",
]
