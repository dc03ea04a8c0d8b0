"""The spec language of composite models, resolved against the registered families.

A spec is a string such as ``"2*GM+WN+RW"``, ``"AR(2)+WN"`` or ``"GM(beta=0.1)+WN"`` (values
free unless given), or a dict ``{"processes": [{"family": "GM", "params": {"beta": 0.02,
"sigma2": 1e-6}}, ...]}`` as :meth:`stochmod.core.model.Model.to_spec` writes it.
"""

from __future__ import annotations

import ast
import re
from collections.abc import Mapping
from typing import Any

from stochmod.core.errors import SpecError
from stochmod.core.model import Model
from stochmod.core.process import Process
from stochmod.plugin.registry import get_process

__all__ = ["model_from_spec"]

_TERM = re.compile(r"^\s*(?:(\d+)\s*\*\s*)?([A-Za-z_][A-Za-z0-9_]*)\s*(?:\((.*)\))?\s*$")


def _split_top_level(text: str, sep: str) -> list[str]:
    parts, depth, cur = [], 0, []
    for ch in text:
        depth += ch in "(["
        depth -= ch in ")]"
        if ch == sep and depth == 0:
            parts.append("".join(cur))
            cur = []
        else:
            cur.append(ch)
    parts.append("".join(cur))
    return parts


def _literal(text: str, where: str) -> Any:
    try:
        return ast.literal_eval(text.strip())
    except (ValueError, SyntaxError):
        raise SpecError(f"cannot read {text.strip()!r} in {where!r} as a number or list") from None


def _process_from_term(term: str) -> list[Process]:
    match = _TERM.match(term)
    if not match:
        raise SpecError(f"cannot parse model term {term.strip()!r}; expected e.g. '2*GM', 'AR(2)', 'WN'")
    count = int(match.group(1) or 1)
    if count < 1:
        raise SpecError(f"count must be at least 1 in {term.strip()!r}")
    cls = get_process(match.group(2))
    positional, keywords = [], {}
    if match.group(3) is not None and match.group(3).strip():
        for arg in _split_top_level(match.group(3), ","):
            key, eq, val = arg.partition("=")
            if eq:
                keywords[key.strip()] = _literal(val, term)
            else:
                positional.append(_literal(arg, term))
    if len(positional) > len(cls.structural_fields):
        raise SpecError(
            f"{cls.family} takes {len(cls.structural_fields)} positional argument(s) "
            f"{list(cls.structural_fields)}, got {len(positional)} in {term.strip()!r}"
        )
    keywords.update(zip(cls.structural_fields, positional))
    return [_construct(cls, keywords, term) for _ in range(count)]


def _construct(cls: type[Process], kwargs: Mapping[str, Any], where: str) -> Process:
    try:
        return cls(**kwargs)
    except TypeError as exc:
        raise SpecError(f"bad arguments for {cls.family} in {where!r}: {exc}") from None


def model_from_spec(spec: str | Mapping[str, Any] | Model, freq: float | None = None) -> Model:
    """Build a :class:`Model` from a string or dict spec (see the module docstring).

    Parameters
    ----------
    spec : str or dict or Model
        ``"2*GM+WN"``, ``"AR(2)+WN"``, ``"GM(beta=0.1, sigma2=1e-4)+WN"``, or
        ``{"processes": [{"family": "GM", "params": {...}}, ...], "freq": 100.0}``.
    freq : float, optional
        Sampling frequency in Hz; overrides a ``freq`` in the dict.

    Raises
    ------
    SpecError
        Malformed spec; UnknownProcessError for an unregistered family; DomainError for
        values outside their domains.
    """
    if isinstance(spec, Model):
        model = spec
    elif isinstance(spec, str):
        if not spec.strip():
            raise SpecError("empty model spec")
        procs = [p for term in _split_top_level(spec, "+") for p in _process_from_term(term)]
        model = Model(tuple(procs))
    elif isinstance(spec, Mapping):
        unknown = set(spec) - {"processes", "freq"}
        if unknown:
            raise SpecError(f"unknown key(s) {sorted(unknown)} in model spec; expected 'processes', 'freq'")
        entries = spec.get("processes")
        if not isinstance(entries, (list, tuple)) or not entries:
            raise SpecError("model spec needs a non-empty list under 'processes'")
        procs = []
        for i, entry in enumerate(entries):
            if not isinstance(entry, Mapping) or "family" not in entry:
                raise SpecError(f"processes[{i}] must be a dict with a 'family' key, got {entry!r}")
            cls = get_process(entry["family"])
            params = entry.get("params", {}) or {}
            if not isinstance(params, Mapping):
                raise SpecError(f"processes[{i}].params must be a dict, got {params!r}")
            extra = set(entry) - {"family", "params"} - set(cls.structural_fields)
            if extra:
                raise SpecError(f"processes[{i}] ({cls.family}) has unknown key(s) {sorted(extra)}")
            kwargs = {k: entry[k] for k in cls.structural_fields if k in entry} | dict(params)
            procs.append(_construct(cls, kwargs, f"processes[{i}]"))
        model = Model(tuple(procs), spec.get("freq"))
    else:
        raise SpecError(f"a model spec is a string or a dict, got {type(spec).__name__}")
    return model if freq is None else model.bind(freq)
