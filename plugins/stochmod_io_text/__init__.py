"""Text and numpy readers: the stochmod plugin for CSV/TSV/TXT/DAT, ``.npy`` and ``.npz`` files.

Registered through the ``stochmod`` entry point like any third-party reader. No optional
dependency: numpy reads the binary formats, the standard library the text ones.
"""

from __future__ import annotations

from stochmod.sdk import Reader, hookimpl
from stochmod_io_text.numpy_files import NpyReader, NpzReader
from stochmod_io_text.text import TextReader

__all__ = ["TextReader", "NpyReader", "NpzReader", "stochmod_readers"]


@hookimpl
def stochmod_readers() -> list[Reader]:
    """Register the text, ``.npy`` and ``.npz`` readers."""
    return [TextReader(), NpyReader(), NpzReader()]
