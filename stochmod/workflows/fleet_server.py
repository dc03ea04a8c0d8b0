"""Imported last by the fleet's process server (:func:`stochmod.workflows.fleet.start_process_server`)
and by nothing else: the server's exit skips the interpreter's teardown.

The server writes nothing and holds nothing to release; it exits when the command stops it
after its cluster closed, and the command waits for it (so that the workers' CPU time is
counted in the command's children). A normal exit would tear down every module the server
imported (numba, llvmlite, scipy, distributed), which the command would
wait for at the end of every fleet run. The workers forked from the server do not run this
handler: a forkserver's child leaves through ``os._exit`` after its process function.
"""

from __future__ import annotations

import atexit
import os

__all__: list[str] = []

atexit.register(os._exit, 0)
