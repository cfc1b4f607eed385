"""One registry convention for every registry of the project."""

import importlib

import pytest

from motion.registry import Registry

# Every registry of the project: (module, attribute).
REGISTRIES = [
    ("motion.datasets.base", "DATASETS"),
    ("generation.methods.base", "METHODS"),
    ("motion.formats.base", "_FORMATS"),
    ("motion.skeletons", "_REGISTRY"),
    ("rendering.styles.base", "_STYLES"),
    ("analysis.registry", "ANALYSES"),
    ("motion_metrics.evaluate", "PROTOCOLS"),
    ("motion_metrics.protocol", "MMD_PROTOCOLS"),
    ("studyapp.survey.study_types.base", "registry"),
    ("studyapp.crowd.platform", "registry"),
    ("studyapp.survey.tasks", "JOBS"),
    ("studyapp.participation.bots", "POLICIES"),
]


def test_a_name_is_registered_once():
    things = Registry("thing")

    @things.register("a")
    class A:
        pass

    with pytest.raises(ValueError, match="thing 'a' is already registered"):
        things.register("a")(type("B", (), {}))
    with pytest.raises(ValueError, match="already registered"):
        things.add("a", object())
    assert things.get("a") is A and A.name == "a"


def test_get_returns_what_was_registered_and_names_the_known_ones():
    things = Registry("thing")
    marker = object()
    things.add("b", marker)

    def job():
        return 1

    things.register("c")(job)
    assert things.get("b") is marker and things.get("c") is job
    assert things.names() == ["b", "c"] and list(things) == ["b", "c"] and "b" in things
    with pytest.raises(KeyError, match="unknown thing 'x'; choose one of: b, c"):
        things.get("x")


def test_discovery_imports_every_module_of_the_package_once():
    registry = Registry("rendering style", package="rendering.styles")
    registry.discover()  # the real styles registered themselves in their own registry
    from rendering.styles import base

    assert {"stick", "stick2d", "mesh"} <= set(base._STYLES.names())


@pytest.mark.parametrize("module, attribute", REGISTRIES)
def test_every_registry_is_one_registry(module, attribute):
    registry = getattr(importlib.import_module(module), attribute)
    assert isinstance(registry, Registry)
    assert registry.names(), f"{module}.{attribute} holds nothing"
    for name in registry.names():
        assert registry.get(name) is registry.get(name)
