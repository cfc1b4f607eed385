"""The core packages stay plain Python: importing them never pulls in Django."""

import subprocess
import sys

import pytest

from tests.conftest import ROOT


@pytest.mark.parametrize("package", ["generation", "rendering", "analysis"])
def test_core_package_does_not_import_django(package):
    """Import every module of a core package in a fresh interpreter; Django stays out."""
    code = (
        "import pkgutil, importlib, sys\n"
        f"import {package}\n"
        f"for info in pkgutil.walk_packages({package}.__path__, '{package}.'):\n"
        "    importlib.import_module(info.name)\n"
        "bad = sorted(m for m in sys.modules if m == 'django' or m.startswith('django.'))\n"
        "print(','.join(bad))\n"
    )
    result = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=False
    )
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "", f"{package} imports Django: {result.stdout}"
