"""Pydantic field types that accept numbers (SI) or unit strings and store SI floats."""

from __future__ import annotations

from typing import Annotated

from pydantic import BeforeValidator

from downhole.units import UnitError, to_si

__all__ = ["Q"]


def _quantity_validator(dimension: str):
    def _parse(value):
        try:
            return to_si(value, dimension)
        except UnitError as exc:
            raise ValueError(str(exc)) from None

    return BeforeValidator(_parse)


class _QFactory:
    """``Q["velocity"]`` is a float field that accepts "30 m/h" and stores m/s."""

    def __getitem__(self, dimension: str):
        return Annotated[float, _quantity_validator(dimension)]


Q = _QFactory()
