"""``stochmod processes``: the registered process families, their parameters, domains and units."""

from __future__ import annotations

import argparse
from typing import Any

from stochmod.cli._common import print_json
from stochmod.core.params import get_domain
from stochmod.core.process import Process
from stochmod.plugin.registry import processes

__all__ = ["register", "run", "describe"]

_FREQ = 100.0  # sampling frequency of the example instances whose physical units are listed


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``processes`` subcommand (it reads no recording)."""
    p = subparsers.add_parser(
        "processes",
        help="list the registered process families with parameters, domains and units",
        description=(
            "List every process family registered by a plugin: its parameters (canonical, per "
            "sample at the sampling frequency, in terms of the signal unit u), their domains and "
            "units, and the physical quantities it reports (e.g. GM correlation time Tc [s])."
        ),
    )
    p.add_argument("--json", action="store_true", help="print machine-readable JSON")
    p.set_defaults(func=run)


def _parameters(cls: type[Process]) -> list[Any]:
    try:
        specs = cls().parameters()
    except Exception:  # families whose parameters depend on structure without defaults
        specs = cls.parameter_specs
    return list(specs)


def describe(cls: type[Process]) -> dict[str, Any]:
    """A JSON-safe description of a family."""
    params = [{"name": s.name, "domain": s.domain, "domain_description": get_domain(s.domain).description,
               "unit": s.unit, "size": s.size, "description": s.description}
              for s in _parameters(cls)]
    physical = []
    try:
        physical = [{"name": k, "unit": v.unit, "description": v.description}
                    for k, v in cls.example(_FREQ).physical(_FREQ).items()]
    except Exception:  # a family without an example instance still gets listed
        pass
    return {
        "family": cls.family,
        "description": cls.description,
        "stationary": bool(cls.stationary),
        "structural_fields": list(cls.structural_fields),
        "parameters": params,
        "physical": physical,
        "plugin": cls.__module__,
    }


def run(args: argparse.Namespace) -> int:
    """Print the registered families."""
    table = [describe(cls) for cls in processes().values()]
    if args.json:
        print_json({"processes": table})
        return 0
    from stochmod.core.tables import format_table

    blocks = []
    for d in table:
        rows = [[p["name"], p["domain_description"], p["unit"], p["description"]] for p in d["parameters"]]
        structure = f" (structure: {', '.join(d['structural_fields'])})" if d["structural_fields"] else ""
        title = f"{d['family']}: {d['description']}{structure} [{d['plugin']}]"
        text = format_table(["parameter", "domain", "unit", "meaning"], rows, title=title)
        if d["physical"]:
            text += "\n  physical: " + ", ".join(f"{q['name']} [{q['unit']}]" for q in d["physical"])
        blocks.append(text)
    print("\n\n".join(blocks))
    return 0
