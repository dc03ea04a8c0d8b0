"""The plugin contract: pluggy hook specifications of the ``stochmod`` project.

A plugin is any module or object with functions marked ``@stochmod.hookimpl`` whose names
match the specifications below. Installed plugins are found through the entry-point group
``stochmod`` (``[project.entry-points.stochmod]`` in a plugin's ``pyproject.toml``); the
first-party process families register exactly that way.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import pluggy

if TYPE_CHECKING:
    from stochmod.process import Process

__all__ = ["PROJECT_NAME", "hookspec", "hookimpl", "StochmodSpec"]

PROJECT_NAME = "stochmod"

hookspec = pluggy.HookspecMarker(PROJECT_NAME)
hookimpl = pluggy.HookimplMarker(PROJECT_NAME)


class StochmodSpec:
    """Hook specifications; each hook returns a list and the registry concatenates them."""

    @hookspec
    def stochmod_processes(self) -> list[type[Process]]:
        """Return the process families (subclasses of :class:`stochmod.process.Process`) a plugin adds.

        Each class carries a unique ``family`` name (e.g. ``"GM"``) under which the composer,
        the spec parser and :func:`stochmod.get_process` find it.
        """

    @hookspec
    def stochmod_criteria(self) -> list[Any]:
        """Return model-selection criteria (objects with ``name`` and ``__call__(fit) -> float``)."""

    @hookspec
    def stochmod_weightings(self) -> list[Any]:
        """Return GMWM weightings: objects with ``name``, ``description``, ``needs_signal``,
        ``needs_fit`` and ``matrix(data) -> WeightingMatrix`` building the matrix Omega of
        eq. 20 (see :mod:`stochmod.fit.weightings`); ``stochmod.gmwm``, ``stochmod.select``
        and the CLI find them by name. (Fusion weights of redundant sensors are not
        weightings but combiners.)"""

    @hookspec
    def stochmod_readers(self) -> list[Any]:
        """Return log-format readers (objects with ``suffixes`` and ``read(path) -> Recording``)."""
