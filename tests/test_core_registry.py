"""Tests of stochmod.plugin.registry: entry-point discovery of the first-party families, lookup by
name, runtime plugins, and the errors for unknown and duplicate families."""

from __future__ import annotations

import subprocess
import sys
from typing import ClassVar

import attrs
import numpy as np
import pytest

import stochmod
from stochmod import sdk
from stochmod.core.errors import SpecError, StochmodError, UnknownProcessError
from stochmod.core.params import Parameter
from stochmod.core.process import Process
from stochmod.plugin.registry import criteria, get_process, plugin_manager, process_names, processes

FIRST_PARTY = {"WN": "stochmod_wn", "RW": "stochmod_rw", "GM": "stochmod_gm", "AR": "stochmod_ar",
               "QN": "stochmod_qn", "RR": "stochmod_rr", "BI": "stochmod_bi"}


@attrs.frozen
class Toy(Process):
    """A runtime-registered family."""

    a: float | None = None
    family: ClassVar[str] = "TOYREG"
    parameter_specs: ClassVar[tuple[Parameter, ...]] = (
        Parameter("a", "positive", "u^2", role="variance"),)

    def white_variance(self, freq):
        return float(self.a)

    def psd(self, f, freq):  # white: the variance spread evenly over (-freq/2, freq/2]
        return np.full(np.shape(f), float(self.a) / freq)

    def start(self, wv, freq, *, index=0, count=1, rng=None):
        return self.with_values(a=2.0 * float(wv[0]))

    @classmethod
    def example(cls, freq):
        return cls(a=1.0)


@attrs.frozen
class FakeWN(Process):
    """Claims the name of a first-party family."""

    family: ClassVar[str] = "WN"


def _plugin(*classes: type) -> object:
    class Plugin:
        @sdk.hookimpl
        def stochmod_processes(self) -> list[type]:
            return list(classes)

    return Plugin()


def test_first_party_families_are_discovered_through_entry_points() -> None:
    names = process_names()
    assert set(FIRST_PARTY) <= set(names), f"missing: {sorted(set(FIRST_PARTY) - set(names))}"
    assert names == sorted(names)
    for name, module in FIRST_PARTY.items():
        cls = get_process(name)
        assert cls.family == name and issubclass(cls, Process)
        assert cls.__module__.split(".")[0] == module
    # the entry points are what loaded them
    loaded = {mod.__name__ for _, mod in plugin_manager().list_name_plugin()}
    assert set(FIRST_PARTY.values()) <= loaded


@pytest.mark.parametrize("module", sorted(set(FIRST_PARTY.values())))
def test_a_plugin_imported_before_stochmod_is_registered_complete(module: str) -> None:
    # entry points load at first use, not while the plugin module is half imported
    code = (f"import {module}, stochmod; names = stochmod.process_names(); "
            f"assert set({sorted(FIRST_PARTY)!r}) <= set(names), names; "
            "assert stochmod.fit.criteria.criterion_names() == ['wvic']")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr


def test_get_process_and_attribute_access() -> None:
    WN = get_process("WN")
    assert stochmod.WN is WN
    assert processes()["WN"] is WN
    assert "WN" in dir(stochmod)
    with pytest.raises(AttributeError, match="no attribute 'NOPE'"):
        stochmod.NOPE  # noqa: B018
    with pytest.raises(AttributeError, match="no attribute 'lowercase_thing'"):
        stochmod.lowercase_thing  # noqa: B018


def test_unknown_family_lists_the_registered_ones() -> None:
    with pytest.raises(UnknownProcessError) as info:
        get_process("GMX")
    message = str(info.value)
    assert message.startswith("unknown process family 'GMX'; registered families: ")
    for name in process_names():
        assert name in message
    # catchable as a spec error and as a KeyError (mapping-style lookup)
    assert isinstance(info.value, SpecError) and isinstance(info.value, KeyError)
    with pytest.raises(UnknownProcessError):
        get_process("wn")  # names are case-sensitive


def test_register_and_unregister_a_runtime_plugin() -> None:
    plugin = _plugin(Toy)
    assert "TOYREG" not in process_names()
    stochmod.register_plugin(plugin, name="toy")
    try:
        assert get_process("TOYREG") is Toy
        assert stochmod.TOYREG is Toy
        model = stochmod.model_from_spec("TOYREG(a=2.5)+WN", 100.0)
        assert model.processes[0] == Toy(a=2.5)
    finally:
        stochmod.unregister_plugin(plugin)
    assert "TOYREG" not in process_names()
    with pytest.raises(UnknownProcessError):
        stochmod.model_from_spec("TOYREG")


def test_duplicate_family_name_is_refused_and_rolled_back() -> None:
    before = process_names()
    plugin = _plugin(FakeWN)
    with pytest.raises(StochmodError, match=r"two plugins register a process family named 'WN'"):
        stochmod.register_plugin(plugin, name="impostor")
    assert not plugin_manager().is_registered(plugin)
    assert process_names() == before and get_process("WN") is not FakeWN


def test_plugin_returning_a_non_process_is_refused() -> None:
    plugin = _plugin(int)
    with pytest.raises(StochmodError, match="not a Process subclass"):
        stochmod.register_plugin(plugin)
    assert not plugin_manager().is_registered(plugin)


def test_registering_the_same_class_twice_is_harmless() -> None:
    """Two plugins may return the same class (e.g. a re-export); it is one family."""
    a, b = _plugin(Toy), _plugin(Toy)
    stochmod.register_plugin(a)
    stochmod.register_plugin(b)
    try:
        assert process_names().count("TOYREG") == 1
    finally:
        stochmod.unregister_plugin(a)
        stochmod.unregister_plugin(b)


def test_criteria_hook() -> None:
    class Criterion:
        name = "toy-criterion"

        def __call__(self, fit: object) -> float:
            return 0.0

    class Plugin:
        @sdk.hookimpl
        def stochmod_criteria(self) -> list[object]:
            return [Criterion()]

    plugin = Plugin()
    assert "toy-criterion" not in criteria()
    stochmod.register_plugin(plugin)
    try:
        assert isinstance(criteria()["toy-criterion"], Criterion)
    finally:
        stochmod.unregister_plugin(plugin)
    assert "toy-criterion" not in criteria()
