"""Fixtures of the conformance tests: the registered families, and runtime registration of
test-only families (so that the spec round trip of the kit can find them by name)."""

from __future__ import annotations

from collections.abc import Callable, Iterator

import pytest

import stochmod
from stochmod import sdk
from stochmod.core.process import Process


def pytest_generate_tests(metafunc: pytest.Metafunc) -> None:
    """Parametrise ``family_name`` over every registered family (first-party and installed)."""
    if "family_name" in metafunc.fixturenames:
        metafunc.parametrize("family_name", stochmod.process_names())


@pytest.fixture
def register() -> Iterator[Callable[[type[Process]], type[Process]]]:
    """``register(cls)`` adds `cls` to the registry for the duration of the test."""
    plugins = []

    def add(cls: type[Process]) -> type[Process]:
        class Plugin:
            @sdk.hookimpl
            def stochmod_processes(self) -> list[type[Process]]:
                return [cls]

        plugin = Plugin()
        stochmod.register_plugin(plugin, name=f"test-{cls.family}")
        plugins.append(plugin)
        return cls

    yield add
    for plugin in plugins:
        stochmod.unregister_plugin(plugin)
