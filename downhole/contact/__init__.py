"""Wellbore contact: soft-string normal force and regularized, implicitly applied friction."""

from downhole.contact import softstring as _softstring
from downhole.contact.softstring import *  # noqa: F403 -- re-exported: the public names of downhole.contact.softstring

__all__ = list(_softstring.__all__)
