"""Shared set-up of the Python module's tests (run by ctest as Python.pytest).

ctest passes the module's folder in PYTHONPATH and the checkout's places in SDOSLAM_SOURCE_DIR,
SDOSLAM_SHARED_DIR and SDOSLAM_EXECUTABLE; run by hand from the repository root,
    PYTHONPATH=build/python python3 -m pytest -q src/sdoslam/python
finds them beside the checkout as the defaults below.
"""

import os
from pathlib import Path

import pytest

import sdoslam  # noqa: F401  (a missing module fails the run here, once)

SOURCE_DIR = Path(os.environ.get("SDOSLAM_SOURCE_DIR",
                                 Path(__file__).resolve().parents[3]))
SHARED_DIR = Path(os.environ.get("SDOSLAM_SHARED_DIR", SOURCE_DIR.parent / "shared"))


@pytest.fixture(scope="session")
def executable():
    """The `sdoslam` command built beside the module."""
    path = Path(os.environ.get("SDOSLAM_EXECUTABLE", SOURCE_DIR / "build" / "sdoslam"))
    assert path.is_file(), f"{path} is not built"
    return path


@pytest.fixture(scope="session")
def fr2_config():
    return SOURCE_DIR / "configs" / "tum_fr2.yaml"


@pytest.fixture(scope="session")
def fr2_desk():
    """The 50 real TUM fr2_desk frames of ../shared/data, or a skip where they are absent."""
    folder = SHARED_DIR / "data" / "tum_fr2_desk_50"
    if not (folder / "rgb.txt").is_file():
        pytest.skip(f"{folder} is absent (SDOSLAM_SHARED_DIR)")
    return folder


@pytest.fixture(scope="session")
def static_room(tmp_path_factory):
    """A short synthetic sequence with ground truth, rendered once for the session."""
    out = tmp_path_factory.mktemp("synth") / "static_room"
    summary = sdoslam.synth(out=out, scenario="static_room", frames=30)
    return out, summary
