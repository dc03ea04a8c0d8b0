"""Redundant sensors: the combination of time-aligned recordings into one synthetic signal."""

__all__: list[str] = []
