"""The core packages stay plain Python, and the layers import downwards only.

``motion`` (the data model, skeletons, datasets, file formats) is the lowest;
``generation`` (methods) builds on it, ``rendering`` (clips) on it alone, and
``motion_metrics`` (objective metrics, the classifier, method comparisons) on both;
``analysis`` (statistics of study responses) uses only ``motion.registry`` and, to read
clip files as a participant's browser receives them, ``rendering``. None imports
Django. No module of the project imports, through any chain of imports (those inside
functions included), a module that imports it back.
"""

import ast
import subprocess
import sys

import pytest

from tests.conftest import ROOT

CORE = ["motion", "generation", "rendering", "analysis", "motion_metrics"]
# Packages a core package must not import, beside Django.
FORBIDDEN = {
    "motion": ["generation", "rendering", "analysis", "motion_metrics", "studyapp", "torch"],
    "generation": ["rendering", "analysis", "motion_metrics", "studyapp"],
    "rendering": ["generation", "analysis", "motion_metrics", "studyapp"],
    "analysis": ["generation", "motion_metrics", "studyapp"],
    "motion_metrics": ["rendering", "analysis", "studyapp"],
}


def imported(package: str) -> set[str]:
    """Return the top-level packages loaded by importing every module of ``package`` afresh."""
    code = (
        "import pkgutil, importlib, sys\n"
        f"import {package}\n"
        f"for info in pkgutil.walk_packages({package}.__path__, '{package}.'):\n"
        "    importlib.import_module(info.name)\n"
        "print(','.join(sorted({m.split('.')[0] for m in sys.modules})))\n"
    )
    result = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=False
    )
    assert result.returncode == 0, result.stderr
    return set(result.stdout.strip().split(","))


@pytest.mark.parametrize("package", CORE)
def test_core_package_imports_no_django_and_no_higher_layer(package):
    """Import every module of a core package in a fresh interpreter; Django and the others stay out."""
    loaded = imported(package)
    assert "django" not in loaded, f"{package} imports Django"
    wrong = sorted(loaded & set(FORBIDDEN[package]))
    assert not wrong, f"{package} imports {', '.join(wrong)}"


# --- no import cycles among the project's modules -----------------------------------

PROJECT = CORE + ["studyapp"]


def project_modules() -> dict:
    """Return ``{dotted name: path}`` of every module of the project (migrations aside)."""
    modules = {}
    for package in PROJECT:
        for path in (ROOT / package).rglob("*.py"):
            parts = list(path.relative_to(ROOT).with_suffix("").parts)
            if "migrations" in parts:
                continue
            if parts[-1] == "__init__":
                parts = parts[:-1]
            modules[".".join(parts)] = path
    return modules


def import_graph() -> dict:
    """Return ``{module: modules it imports}``, counting imports inside functions too."""
    modules = project_modules()

    def known(name):
        while name and name not in modules:
            name = name.rpartition(".")[0]
        return name

    graph = {}
    for name, path in modules.items():
        package = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
        targets = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                targets.update(known(alias.name) for alias in node.names)
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    base = ".".join(package[:len(package) - node.level + 1] + [base]).strip(".")
                for alias in node.names:
                    full = f"{base}.{alias.name}"
                    targets.add(full if full in modules else known(base))
        graph[name] = targets - {name, ""}
    return graph


def cycles(graph: dict) -> list[list[str]]:
    """Return the strongly connected groups of more than one module (Tarjan's algorithm)."""
    index, low, stack, on_stack, found = {}, {}, [], set(), []

    def visit(node):
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for other in graph.get(node, ()):
            if other not in index:
                visit(other)
                low[node] = min(low[node], low[other])
            elif other in on_stack:
                low[node] = min(low[node], index[other])
        if low[node] == index[node]:
            group = []
            while True:
                member = stack.pop()
                on_stack.discard(member)
                group.append(member)
                if member == node:
                    break
            if len(group) > 1:
                found.append(sorted(group))

    for node in sorted(graph):
        if node not in index:
            visit(node)
    return found


def test_the_cycle_finder_sees_imports_inside_functions():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert cycles(graph) == [["a", "b", "c"]]
    assert cycles({"a": {"b"}, "b": set()}) == []


def test_no_import_cycle_among_the_projects_modules():
    """An import inside a function that only hides a cycle is a cycle: move the shared
    piece down, or pass the dependency in (plug-ins are found by name by their registry)."""
    found = cycles(import_graph())
    assert not found, "import cycles: " + "; ".join(" <-> ".join(group) for group in found)
