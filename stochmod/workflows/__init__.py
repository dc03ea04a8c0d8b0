"""Workflows over many results: fleets of units on a dask cluster or serially."""

__all__: list[str] = []
