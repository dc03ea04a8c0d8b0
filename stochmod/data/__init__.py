"""Bundled example recordings (simulated, with known truth)."""

__all__: list[str] = []
