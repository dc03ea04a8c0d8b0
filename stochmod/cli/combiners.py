"""``stochmod combiners``: the registered redundant-sensor combiners and what they assume."""

from __future__ import annotations

import argparse
import inspect
from typing import Any

from stochmod.cli._common import print_json
from stochmod.plugin.registry import combiners
from stochmod.core.tables import format_table

__all__ = ["register", "run", "describe"]


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``combiners`` subcommand (it reads no recording)."""
    p = subparsers.add_parser(
        "combiners",
        help="list the registered redundant-sensor combiners, their options and assumptions",
        description=("List every combiner registered by a plugin (entry-point group 'stochmod', "
                     "hook stochmod_combiners): its name for `stochmod combine --method`, what "
                     "it does, the options of its combine(), and what it assumes."),
    )
    p.add_argument("--json", action="store_true", help="print machine-readable JSON")
    p.set_defaults(func=run)


def describe(comb: Any) -> dict[str, Any]:
    """A JSON-safe description of a combiner: name, description, assumptions, options, plugin."""
    options = {}
    for name, par in inspect.signature(comb.combine).parameters.items():
        if par.kind is inspect.Parameter.KEYWORD_ONLY:
            options[name] = None if par.default is inspect.Parameter.empty else repr(par.default)
    return {"name": comb.name, "description": getattr(comb, "description", ""),
            "assumes": comb.assumes, "options": options, "plugin": type(comb).__module__}


def run(args: argparse.Namespace) -> int:
    """Print the registered combiners."""
    table = [describe(c) for c in combiners().values()]
    if args.json:
        print_json({"combiners": table})
        return 0
    rows = [[d["name"], d["description"], ", ".join(f"{k}={v}" for k, v in d["options"].items()) or "-",
             d["plugin"]] for d in table]
    print(format_table(["name", "description", "options", "plugin"], rows,
                       title=f"{len(table)} combiner(s) registered"))
    for d in table:
        print(f"\n{d['name']} assumes: {d['assumes']}")
    return 0
