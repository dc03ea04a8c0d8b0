"""The plugin contract: pluggy hook specifications of the ``stochmod`` project.

A plugin is any module or object with functions marked ``@stochmod.sdk.hookimpl`` whose names
match the specifications below. Installed plugins are found through the entry-point group
``stochmod`` (``[project.entry-points.stochmod]`` in a plugin's ``pyproject.toml``); the
first-party process families register exactly that way.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import pluggy

if TYPE_CHECKING:
    from stochmod.core.process import Process

__all__ = ["PROJECT_NAME", "hookspec", "hookimpl", "StochmodSpec"]

PROJECT_NAME = "stochmod"

hookspec = pluggy.HookspecMarker(PROJECT_NAME)
hookimpl = pluggy.HookimplMarker(PROJECT_NAME)


class StochmodSpec:
    """Hook specifications; each hook returns a list and the registry concatenates them."""

    @hookspec
    def stochmod_processes(self) -> list[type[Process]]:
        """Return the process families (subclasses of :class:`stochmod.core.process.Process`) a plugin adds.

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
        eq. 20 (see :mod:`stochmod.fit.weighting_plugins`); ``stochmod.gmwm``, ``stochmod.select``
        and the CLI find them by name. (Fusion weights of redundant sensors are not
        weightings but combiners.)"""

    @hookspec
    def stochmod_combiners(self) -> list[Any]:
        """Return redundant-sensor combiners (objects; see :class:`stochmod.redundant.combination.Combiner`).

        A combiner fuses ``n`` time-aligned recordings of the same quantity into one synthetic
        signal. It carries

        - ``name`` (str): unique registry key, e.g. ``"mean"`` or ``"garch"``;
        - ``description`` (str): one line for listings (``stochmod combiners``);
        - ``assumes`` (str): what the method assumes of the sensors' errors (independence,
          equal or constant variances, ...), reported with every result;
        - ``combine(x, **options) -> CombinationResult``: `x` is a finite float64 array of shape
          ``(n, T)`` (one axis from ``n`` sensors, ``T`` samples each, in the signal unit u) or
          ``(n, T, 3)`` (triads); it returns a :class:`stochmod.redundant.combination.CombinationResult`
          with the synthetic ``signal`` (shape ``x.shape[1:]``, u), the per-sample ``weights``
          (shape of `x`, summing to 1 over the sensors at every sample) and the estimated
          per-sample ``variance`` of the synthetic signal's error (shape ``x.shape[1:]``, u^2).
          Bad input (NaN/inf, fewer sensors than the method needs, unknown options) raises a
          :class:`stochmod.core.errors.StochmodError` subclass naming the problem.

        :func:`stochmod.combine` finds a combiner by name; :func:`stochmod.testing.check_combiner`
        checks one (weights sum to 1, equal inputs give the input back, permutation invariance,
        scale equivariance, NaN refused).
        """

    @hookspec
    def stochmod_readers(self) -> list[Any]:
        """Return log-format readers, called by :func:`stochmod.io.recording.read_recording`.

        A reader is an object (usually an instance of :class:`stochmod.io.recording.Reader`) declaring:

        ``name`` : str
            Unique format name (``"csv"``, ``"ulog"``, ``"rosbag"``), chosen with
            ``read_recording(path, reader=name)``.
        ``suffixes`` : tuple of str
            Lower-case file suffixes with the dot (``(".ulg",)``; ``""`` for none) that select it.
        ``sniff(path) -> bool``
            Whether a file or folder is in this format whatever its suffix (a ROS 2 bag is a
            folder holding ``metadata.yaml``); return False when unsure.
        ``options`` : tuple of str
            Names of the keyword options ``read`` takes (``("topic", "instance")``); the core
            refuses any other option with an error naming those accepted.
        ``description`` : str, optional
            One line for listings.
        ``read(path, **options) -> Recording``
            The samples (n x k, float64), column names, and where the format has them the time
            stamps in s (``time``), the unit of each column (``units``, e.g. ``"rad/s"``) and a
            recorded sampling frequency (``freq``). The core checks the data, estimates the rate
            from the stamps and refuses gaps; a reader only reads. A missing optional
            dependency raises ImportError naming the extra (:func:`stochmod.io.recording.import_optional`).
        """
