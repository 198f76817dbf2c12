"""Result export to the formats drilling tools read: LAS 2.0 (time-indexed) and CSV.

``import downhole.io`` also adds :meth:`Result.to_las`.
"""

from downhole.io.las import read_las, write_las

__all__ = ["write_las", "read_las"]
