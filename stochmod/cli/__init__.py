"""The ``stochmod`` command line: one module per subcommand, each with ``register(subparsers)``."""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import os
import pkgutil
import sys
from collections.abc import Sequence
from typing import NoReturn

from stochmod.core.errors import StochmodError

#: What a local fleet's process server imports before it forks the workers.
FLEET_WARM_MODULE = "stochmod.cli._fleet_worker"

__all__ = ["main", "script", "build_parser"]


def _subcommand_modules() -> list[str]:
    """Public modules of this package, one per subcommand, in alphabetical order."""
    return sorted(m.name for m in pkgutil.iter_modules(__path__) if not m.name.startswith("_"))


def _parser(modules: Sequence[str]) -> tuple[argparse.ArgumentParser, argparse._SubParsersAction]:
    parser = argparse.ArgumentParser(
        prog="stochmod",
        description="Stochastic error models of inertial sensors.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name in modules:
        importlib.import_module(f"stochmod.cli.{name}").register(sub)
    return parser, sub


def build_parser() -> argparse.ArgumentParser:
    """Build the argument parser with every subcommand registered."""
    return _parser(_subcommand_modules())[0]


def _parser_for(argv: Sequence[str]) -> argparse.ArgumentParser:
    """The parser with only the command that `argv` names, when its module registers it (a
    command imports its own module's dependencies, not every command's), else the full one
    (help, unknown commands)."""
    if argv and argv[0] in _subcommand_modules():
        parser, sub = _parser([argv[0]])
        if argv[0] in sub.choices:
            return parser
    return build_parser()


def _local_fleet(argv: Sequence[str]) -> bool:
    """Whether `argv` (not parsed yet) is ``calibrate ... --workers N`` with dask installed: a
    fleet on a local cluster, whose workers' process server starts before the parser's
    imports (:func:`stochmod.workflows.fleet.start_process_server`)."""
    return (argv[:1] == ["calibrate"] and not {"-h", "--help"} & set(argv)
            and any(a == "--workers" or a.startswith("--workers=") for a in argv)
            and importlib.util.find_spec("distributed") is not None)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI; errors on bad input print one line to stderr and return 2."""
    argv = sys.argv[1:] if argv is None else list(argv)
    if _local_fleet(argv):
        from stochmod.workflows.fleet import start_process_server

        start_process_server(FLEET_WARM_MODULE)  # the workers' imports run beside this one's
    parser = _parser_for(argv)
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except (StochmodError, ImportError, OSError) as exc:
        print(f"stochmod {args.command}: error: {exc}", file=sys.stderr)
        return 2


def script() -> NoReturn:
    """The ``stochmod`` console script: :func:`main` on the command line, then the process
    ends with its exit code once stdout and stderr are flushed, without the interpreter's
    teardown (freeing every object of numba, scipy, dask ..., a sizeable part of a short
    command's time; mypy's ``hard_exit`` does the same). Every file a command writes is closed
    before it returns, its process pools and clusters are shut down, and an exception takes
    the normal way out."""
    code = main()
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
