"""Shared fixtures. The suite runs against the built package (ctest sets
PYTHONPATH to build/python, EARSHOT_CLI to the built `earshot` and
EARSHOT_SOURCE_DIR to the checkout); it reads only the project's own files."""
import os
import subprocess

import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
SOURCE_DIR = os.environ.get("EARSHOT_SOURCE_DIR", os.path.normpath(os.path.join(HERE, "..", "..")))
CLI = os.environ.get("EARSHOT_CLI", os.path.join(SOURCE_DIR, "build", "tools", "earshot"))
SHOEBOX = os.path.join(SOURCE_DIR, "samples", "shoebox", "shoebox.gltf")
SHOEBOX_MAP = os.path.join(SOURCE_DIR, "samples", "shoebox", "materials_map.json")


@pytest.fixture(scope="session")
def shoebox():
    import earshot
    return earshot.Scene(SHOEBOX, material_map=SHOEBOX_MAP)


def run_cli(*args):
    """Runs the earshot command; returns the completed process (asserts exit 0)."""
    p = subprocess.run([CLI, *map(str, args)], capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    return p
