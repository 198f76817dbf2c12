"""The one scenario schema (:mod:`downhole._schema`, documented there): the tables every
command reads (``TABLES``), the renames of the older dialects (``RENAMES``, ``VALUE_RENAMES``)
and the reader every command uses (``read_scenario``: the hardened reader, then
``check_dialect``)."""

from downhole._schema import (
                              RENAMES,
                              TABLES,
                              VALUE_RENAMES,
                              check_dialect,
                              raise_validation,
                              read_scenario,
)

__all__ = [
                              "RENAMES",
                              "TABLES",
                              "VALUE_RENAMES",
                              "check_dialect",
                              "raise_validation",
                              "read_scenario",
]
