"""Shared fixtures. Simulator tests are marked ``sim``; everything else runs without PyBullet."""

from __future__ import annotations

import os
import shutil
import tempfile

import pytest

from pickdemo.scenario.load import Scenario, load_scenario
from tests.episodes import SHARED_DIR_ENV

_SHARED = pytest.StashKey[str]()


def pytest_configure(config: pytest.Config) -> None:
    """The session's directory of shared episodes (:mod:`tests.episodes`), made once by the process
    that starts the session; pytest-xdist's workers inherit it."""
    if hasattr(config, "workerinput") or SHARED_DIR_ENV in os.environ:
        return
    config.stash[_SHARED] = os.environ[SHARED_DIR_ENV] = tempfile.mkdtemp(prefix="pickdemo-test-episodes-")


def pytest_unconfigure(config: pytest.Config) -> None:
    made = config.stash.get(_SHARED, None)
    if made is not None:
        shutil.rmtree(made, ignore_errors=True)
        os.environ.pop(SHARED_DIR_ENV, None)


@pytest.fixture(scope="session")
def cube_scenario() -> Scenario:
    return load_scenario("pick_cube")


@pytest.fixture(scope="session")
def cylinder_scenario() -> Scenario:
    return load_scenario("pick_cylinder")
