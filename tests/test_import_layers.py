"""The import graph of ``stochmod`` follows DESIGN.md "Layers", has no cycles, and no module
takes a private name from another public module.

Every module under ``stochmod/`` is parsed (AST) and every import is collected, those inside
functions (lazy imports) and under ``if TYPE_CHECKING:`` included. ``from stochmod.core import
units`` counts as an import of the submodule ``stochmod.core.units``; ``from stochmod import
gmwm`` as one of the top-level package. A module's layer is its folder; it may import its own
layer or a lower one, and no chain of imports may come back to where it started.
"""

from __future__ import annotations

import ast
from collections.abc import Iterator
from pathlib import Path

import attrs
import networkx as nx
import pytest

REPO = Path(__file__).resolve().parents[1]
PACKAGE = REPO / "stochmod"

#: DESIGN.md "Layers", bottom first: a module's layer is its folder under ``stochmod/``
#: (``stochmod.fit.gmwm`` is in ``fit``); ``nav`` and ``redundant`` share a rank (neither
#: imports the other), as do ``workflows`` and ``testing`` (the conformance kits fit models).
#: The top-level package ``stochmod`` sits above everything it re-exports.
LAYERS: tuple[tuple[str, ...], ...] = (
    ("core",),
    ("plugin",),
    ("io",),
    ("data",),
    ("empirical",),
    ("fit",),
    ("nav", "redundant"),
    ("output",),
    ("workflows", "testing"),
    ("cli",),
)
TOP = len(LAYERS)

#: Lazy imports the issue allows: an operator returning an object of a module that imports
#: this one (``Process.__add__`` / ``__mul__`` return a Model). They must stay inside functions.
OPERATOR_IMPORTS = {("stochmod.core.process", "stochmod.core.model")}


@attrs.frozen
class Edge:
    source: str
    target: str
    line: int
    lazy: bool  # inside a function or class body
    type_only: bool  # under ``if TYPE_CHECKING:``
    names: tuple[str, ...] = ()  # names taken by ``from target import ...``


def _module_name(path: Path, root: Path) -> str:
    parts = path.relative_to(root.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _is_module(name: str) -> bool:
    path = PACKAGE.parent.joinpath(*name.split("."))
    return path.with_suffix(".py").is_file() or (path / "__init__.py").is_file()


def _is_type_checking(node: ast.AST) -> bool:
    test = getattr(node, "test", None)
    return isinstance(node, ast.If) and (
        (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING")
        or (isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"))


def _walk(node: ast.AST, lazy: bool = False, type_only: bool = False
          ) -> Iterator[tuple[ast.AST, bool, bool]]:
    for child in ast.iter_child_nodes(node):
        yield child, lazy, type_only
        yield from _walk(child,
                         lazy or isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef,
                                                    ast.Lambda, ast.ClassDef)),
                         type_only or _is_type_checking(child))


def _edges(path: Path, root: Path, prefix: str) -> list[Edge]:
    """Imports of modules whose name starts with `prefix` in the file `path`."""
    source = _module_name(path, root)
    package = source if path.name == "__init__.py" else source.rpartition(".")[0]
    out = []
    for node, lazy, type_only in _walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            out.extend(Edge(source, a.name, node.lineno, lazy, type_only)
                       for a in node.names if a.name.split(".")[0].startswith(prefix))
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:  # relative import
                anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(anchor + ([base] if base else []))
            if not base.split(".")[0].startswith(prefix):
                continue
            names = tuple(a.name for a in node.names)
            subs = [f"{base}.{n}" for n in names if _is_module(f"{base}.{n}")]
            out.extend(Edge(source, s, node.lineno, lazy, type_only) for s in subs)
            if len(subs) < len(names):
                out.append(Edge(source, base, node.lineno, lazy, type_only,
                                tuple(n for n in names if f"{base}.{n}" not in subs)))
    return out


def _core_edges() -> list[Edge]:
    return [e for path in sorted(PACKAGE.rglob("*.py"))
            for e in _edges(path, PACKAGE, "stochmod") if e.target.startswith("stochmod")
            and e.target.split(".")[0] == "stochmod"]


def _layer(module: str) -> int:
    parts = module.split(".")
    if parts == ["stochmod"] or (len(parts) == 2 and (PACKAGE / f"{parts[1]}.py").is_file()):
        return TOP  # the package and its root modules (the SDK) re-export the layers
    for rank, folders in enumerate(LAYERS):
        if parts[1] in folders:
            return rank
    raise AssertionError(f"module {module} is in no layer: stochmod/{parts[1]} is not a folder of "
                         f"DESIGN.md 'Layers' (LAYERS in {__file__})")


def _layer_name(rank: int) -> str:
    return "stochmod" if rank == TOP else "/".join(LAYERS[rank])


def _where(e: Edge) -> str:
    kind = "type-only " if e.type_only else "lazy " if e.lazy else ""
    return f"{e.source} -> {e.target} ({kind}import, line {e.line})"


def test_the_walk_sees_lazy_and_type_only_imports() -> None:
    edges = {(e.source, e.target): e for e in _core_edges()}
    assert len({e.source for e in edges.values()}) > 40  # every module was parsed
    operator = edges[("stochmod.core.process", "stochmod.core.model")]
    assert operator.lazy and not operator.type_only
    spec = edges[("stochmod.plugin.hookspecs", "stochmod.core.process")]
    assert spec.type_only
    top = edges[("stochmod", "stochmod.plugin.registry")]
    assert not top.lazy and not top.type_only
    # the top-level package imports its re-exports on first access (stochmod.__getattr__);
    # its TYPE_CHECKING block names them for type checkers
    assert edges[("stochmod", "stochmod.fit.gmwm")].type_only


def test_every_module_has_a_layer() -> None:
    for path in PACKAGE.rglob("*.py"):
        _layer(_module_name(path, PACKAGE))


def test_imports_point_down_the_layers() -> None:
    bad = []
    for e in _core_edges():
        if _layer(e.target) > _layer(e.source):
            bad.append(f"{_where(e)}: {_layer_name(_layer(e.source))} imports "
                       f"{_layer_name(_layer(e.target))}")
    assert not bad, "imports against DESIGN.md 'Layers':\n" + "\n".join(bad)


def test_no_import_cycles_lazy_and_type_only_imports_included() -> None:
    graph = nx.DiGraph()
    for e in _core_edges():
        if e.source == e.target:
            continue
        if (e.source, e.target) in OPERATOR_IMPORTS:
            assert e.lazy, f"{_where(e)} is allowed only inside the operator that needs it"
            continue
        graph.add_edge(e.source, e.target, edge=e)
    cycles = list(nx.simple_cycles(graph))
    lines = [" ; ".join(_where(graph.edges[a, b]["edge"]) for a, b in zip(c, c[1:] + c[:1]))
             for c in cycles]
    assert not cycles, "import cycles:\n" + "\n".join(lines)


def _private_imports(root: Path, prefix: str) -> list[Edge]:
    out = []
    for path in sorted(root.rglob("*.py")):
        for e in _edges(path, root, prefix):
            if any(part.startswith("_") for part in e.target.split(".")):
                continue  # a private helper module serves its package
            if any(n.startswith("_") and not n.startswith("__") for n in e.names):
                out.append(e)
    return out


def test_no_module_takes_a_private_name_from_a_public_module() -> None:
    found = _private_imports(PACKAGE, "stochmod")
    for plugin in sorted((REPO / "plugins").iterdir()):
        if (plugin / "__init__.py").is_file():
            found.extend(_private_imports(plugin, "stochmod"))
    bad = [f"{_where(e)} takes {', '.join(n for n in e.names if n.startswith('_'))}" for e in found]
    assert not bad, "private names taken from public modules:\n" + "\n".join(bad)


def test_the_core_never_imports_a_plugin_package() -> None:
    plugins = {p.name for p in (REPO / "plugins").iterdir() if (p / "__init__.py").is_file()}
    assert "stochmod_gm" in plugins
    bad = [_where(e) for path in sorted(PACKAGE.rglob("*.py"))
           for e in _edges(path, PACKAGE, "stochmod_") if e.target.split(".")[0] in plugins]
    assert not bad, "the core imports plugins (reach them through the registry):\n" + "\n".join(bad)


@pytest.mark.parametrize("code, target, lazy, type_only", [
    ("import stochmod.fit.gmwm\n", "stochmod.fit.gmwm", False, False),
    ("def f():\n    from stochmod.core import units\n", "stochmod.core.units", True, False),
    ("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from stochmod.core.model import Model\n",
     "stochmod.core.model", False, True),
    ("class A:\n    def f(self):\n        from stochmod import model_from_spec\n", "stochmod", True, False),
    ("from .weighting import chi2_variance\n", "stochmod.fit.weighting", False, False),
    ("from stochmod import sdk\n", "stochmod.sdk", False, False),
])
def test_edges_are_resolved(tmp_path: Path, code: str, target: str, lazy: bool, type_only: bool) -> None:
    root = tmp_path / "stochmod"
    (root / "fit").mkdir(parents=True)
    path = root / "fit" / "probe.py"
    path.write_text(code)
    (edge,) = _edges(path, root, "stochmod")
    assert (edge.source, edge.target, edge.lazy, edge.type_only) == ("stochmod.fit.probe", target,
                                                                      lazy, type_only)


@pytest.mark.parametrize("root", [REPO / "plugins", REPO / "docs" / "examples" / "third_party_plugin"],
                         ids=["plugins", "third_party_example"])
def test_plugins_import_only_the_sdk_from_stochmod(root: Path) -> None:
    """A plugin module imports from stochmod only ``stochmod.sdk`` (and its own package)."""
    paths = sorted(root.rglob("*.py"))
    assert paths
    bad = [f"{e.source}:{e.line} imports {e.target}"
           for path in paths for e in _edges(path, root, "stochmod")
           if e.target != "stochmod.sdk" and e.target.split(".")[0] not in e.source.split(".")]
    assert not bad, "\n".join(bad)
