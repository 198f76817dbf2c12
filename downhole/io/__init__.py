"""Result export to the formats drilling tools read: LAS 2.0 (time-indexed) and CSV.

:meth:`Result.to_las` (a method of every Result) calls :func:`write_las`.
"""

from downhole.io.las import read_las, write_las

__all__ = ["read_las", "write_las"]
