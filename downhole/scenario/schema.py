"""The one scenario schema (:mod:`downhole._schema`, documented there): the tables every
command reads (``TABLES``), the renames of the older dialects (``RENAMES``, ``VALUE_RENAMES``)
and the reader every command uses (``read_scenario``: the hardened reader, then
``check_dialect``)."""

from downhole import _schema
from downhole._schema import *  # noqa: F403 -- re-exported: the public names of downhole._schema

__all__ = list(_schema.__all__)
