"""The default selection lattice, read from the families' declarations in the registry.

A family joins the default lattice of :func:`stochmod.select` by declaring
:attr:`stochmod.core.process.Process.lattice_copies` > 0 (how many of its processes a candidate may
hold) and :attr:`~stochmod.core.process.Process.lattice_rank` (where they sit in model names). The
core names no family: without a plugin its family is simply not in the lattice.
"""

from __future__ import annotations

from collections.abc import Sequence

from stochmod.core.errors import InputError
from stochmod.plugin.registry import processes

__all__ = ["default_families", "default_max_counts"]


def default_families() -> tuple[str, ...]:
    """Names of the registered families with ``lattice_copies > 0``, by ``lattice_rank`` then name.

    Raises
    ------
    InputError
        No registered family declares lattice membership (the lattice would be empty).
    """
    members = [(cls.lattice_rank, name) for name, cls in processes().items() if cls.lattice_copies > 0]
    if not members:
        raise InputError("no registered process family declares lattice_copies > 0: the default "
                         f"selection lattice is empty (registered: {sorted(processes()) or 'none'}); "
                         "pass families= or candidates=")
    return tuple(name for _, name in sorted(members))


def default_max_counts(families: Sequence[str]) -> dict[str, int]:
    """Largest counts of `families` in a lattice: each registered family's ``lattice_copies``
    where it is above 1 (others: 1, :func:`stochmod.fit.selection.candidate_lattice`'s default)."""
    table = processes()
    return {f: table[f].lattice_copies for f in families
            if f in table and table[f].lattice_copies > 1}
