"""What ``import stochmod`` and the ``stochmod`` command load at start-up.

Every ``stochmod`` command, and every fleet worker process (spawned, it imports the console
script's ``stochmod.cli`` first), pays its imports before any work. scipy.signal, scipy.stats,
networkx and numba cost 1-2 s together and only some paths use them, so they are imported
where they are used (``stochmod.__getattr__``: the top-level names on first access). These
tests run a fresh interpreter and read its ``sys.modules``, so the gain cannot silently come
back through a new module-level import.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

HEAVY = ("scipy.signal", "scipy.stats", "networkx", "numba")


def _loaded(code: str) -> dict[str, bool]:
    """Which of :data:`HEAVY` a fresh interpreter has imported after running `code`."""
    probe = f"{code}\nimport json, sys\nprint(json.dumps({{m: m in sys.modules for m in {HEAVY!r}}}))"
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True)
    return json.loads(done.stdout.splitlines()[-1])


@pytest.mark.parametrize("code", ["import stochmod.cli", "import stochmod",
                                  "from stochmod import InputError, get_process"])
def test_package_import_loads_no_heavy_module(code: str) -> None:
    assert _loaded(code) == dict.fromkeys(HEAVY, False)


def test_calibrate_and_its_report_load_neither_scipy_signal_nor_stats() -> None:
    # calibrate's figures are drawn by worker processes that import the report module:
    # scipy.signal and scipy.stats (a second of import in each) are for PSDs and readings
    loaded = _loaded("import stochmod.cli.calibrate, stochmod.output.html_report")
    assert not loaded["scipy.signal"] and not loaded["scipy.stats"]


def test_lazy_names_resolve_to_their_modules() -> None:
    # the probe must see the heavy modules once a name that needs them is used, else the
    # test above could pass on a broken probe
    loaded = _loaded("import numpy, stochmod\nstochmod.fit_garch\nstochmod.select\n"
                     "stochmod.psd(numpy.random.default_rng(0).normal(size=256), 1.0)")
    assert loaded["scipy.signal"] and loaded["networkx"] and loaded["scipy.stats"]
    import stochmod
    from stochmod.fit.garch import fit_garch
    from stochmod.fit.selection import select

    assert stochmod.select is select and stochmod.fit_garch is fit_garch
    missing = [n for n in stochmod.__all__ if not hasattr(stochmod, n)]
    assert missing == []
    assert len(stochmod.__all__) <= 26  # a small API: the rest through its subpackage
    # no module is reached through the package by its name alone
    for name in ("not_a_name", "units", "datasheet", "fit_arma", "lowercase_thing"):
        with pytest.raises(AttributeError, match=f"no attribute '{name}'"):
            getattr(stochmod, name)


def test_the_sdk_loads_no_heavy_module_until_a_lazy_name_is_used() -> None:
    # numba is the compiler of the families' kernels, which a plugin imports with the SDK
    loaded = _loaded("import stochmod.sdk")
    assert not (loaded["scipy.signal"] or loaded["scipy.stats"] or loaded["networkx"])
    import stochmod.sdk as sdk
    from stochmod.fit.garch import fit_garch

    assert sdk.fit_garch is fit_garch
    assert [n for n in sdk.__all__ if not hasattr(sdk, n)] == []


def test_a_command_imports_its_own_module_only() -> None:
    code = ("import sys\nfrom stochmod.cli import _parser_for\n_parser_for(['processes'])\n"
            "assert 'stochmod.cli.processes' in sys.modules\n"
            "assert 'stochmod.cli.navigate' not in sys.modules and 'stochmod.nav.filter' not in sys.modules")
    assert _loaded(code)["networkx"] is False  # calibrate's and select's selection is not loaded
    from stochmod.cli import _parser_for, _subcommand_modules

    # help and unknown commands get the full parser, which lists every command
    for argv in ([], ["--help"], ["not-a-command"]):
        sub = _parser_for(argv)._subparsers._group_actions[0]  # type: ignore[union-attr]
        assert sorted(sub.choices) == _subcommand_modules()


def test_calibrate_and_every_plugin_load_without_scipy_signal_or_stats() -> None:
    # a fleet worker's start (stochmod.cli._fleet_worker) before its warm-up: the calibrate command
    # and every registered plugin; scipy.signal is for simulations and the classical readings,
    # scipy.stats (0.4 s) for the classical readings' tests (calibrate's p-values and
    # intervals take scipy.special's chdtrc and ndtri, which scipy.stats' chi2 and norm call)
    code = ("from stochmod.cli import _parser_for\n_parser_for(['calibrate'])\n"
            "from stochmod.plugin.registry import combiners, processes, readers\n"
            "assert len(processes()) >= 7 and readers() and len(combiners()) >= 3")
    loaded = _loaded(code)
    assert loaded["scipy.signal"] is False and loaded["scipy.stats"] is False


def test_type_checking_block_names_the_lazy_names() -> None:
    # the package lists each lazy name twice: in _LAZY (run time) and under TYPE_CHECKING
    # (type checkers, editors); they must agree, module for module
    import ast
    import inspect

    import importlib

    import stochmod
    import stochmod.sdk

    packages = [importlib.import_module(f"stochmod.{p.parent.name}")
                for p in sorted(Path(stochmod.__file__).parent.glob("*/__init__.py"))]
    lazy = [m for m in (stochmod, stochmod.sdk, *packages) if hasattr(m, "_LAZY")]
    assert len(lazy) >= 10  # the package, the SDK and every subpackage but cli, nav, testing
    for module in lazy:
        assert [n for n in module.__all__ if not hasattr(module, n)] == [], module.__name__
        tree = ast.parse(inspect.getsource(module))
        block = next(n for n in tree.body if isinstance(n, ast.If)
                     and getattr(n.test, "id", None) == "TYPE_CHECKING")
        typed: dict[str, set[str]] = {}
        for node in block.body:
            assert isinstance(node, ast.ImportFrom)
            typed.setdefault(node.module or "", set()).update(a.name for a in node.names)
        assert typed == {m: set(names) for m, names in module._LAZY.items()}
