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


def test_threads_that_look_up_at_once_all_wait_for_the_discovery(monkeypatch):
    """simulate_participants' threads (and a threaded server's) ask a registry at once:
    none may see it empty while another thread is still importing its modules."""
    import threading
    import time

    things = Registry("thing", package="json")  # any package: the imports are faked
    started = threading.Event()

    def slow_import(name):
        started.set()
        time.sleep(0.2)
        things._items.setdefault("late", object())
        return importlib.__import__("json")

    import pkgutil

    monkeypatch.setattr(pkgutil, "iter_modules", lambda path: [])
    monkeypatch.setattr(importlib, "import_module", slow_import)
    seen = []
    first = threading.Thread(target=lambda: seen.append(things.names()))
    first.start()
    started.wait()
    others = [threading.Thread(target=lambda: seen.append(things.names())) for _ in range(4)]
    for thread in others:
        thread.start()
    for thread in [first, *others]:
        thread.join()
    assert seen == [["late"]] * 5
