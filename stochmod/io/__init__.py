"""Recordings: columns with their sensor kind and unit, read through the readers plugin point, and their time stamps."""

__all__: list[str] = []
