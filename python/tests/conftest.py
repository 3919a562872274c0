"""Shared fixtures: the repository's config/ and the catkin tree's command lines (rod_fk, experiment),
the independent references the Python face is checked against."""
import os
import shutil

import pytest

REPO = os.path.normpath(os.path.join(os.path.dirname(__file__), "..", ".."))


def tool(name: str) -> str:
    """A command line of the catkin build (scripts/build): $HYDROJET_BIN, else .build's devel space."""
    for folder in (os.environ.get("HYDROJET_BIN", ""), os.path.join(REPO, ".build", "devel", "lib", "hydrojet_control")):
        path = os.path.join(folder, name)
        if folder and os.access(path, os.X_OK):
            return path
    found = shutil.which(name)
    if not found:
        pytest.fail(f"{name} not found: build the catkin tree (scripts/build) or set HYDROJET_BIN")
    return found


def config(name: str) -> str:
    return os.path.join(REPO, "config", name)
