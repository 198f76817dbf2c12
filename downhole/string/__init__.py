"""Drill-string mechanics core: elements (lumped chains, bar FEM, wave segments) and models."""
