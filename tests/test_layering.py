"""The core packages stay plain Python, and the layers import downwards only.

``generation`` (datasets, methods, the classifier) is the lowest; ``motion_metrics``
(objective metrics, evaluation, benchmark) builds on it; ``analysis`` (statistics of study
responses) stands apart. None imports Django.
"""

import subprocess
import sys

import pytest

from tests.conftest import ROOT

CORE = ["generation", "rendering", "analysis", "motion_metrics"]
# Packages a core package must not import, beside Django.
FORBIDDEN = {
    "generation": ["analysis", "motion_metrics", "studyapp"],
    "rendering": ["analysis", "motion_metrics", "studyapp"],
    "analysis": ["motion_metrics", "studyapp"],
    "motion_metrics": ["analysis", "studyapp"],
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
