"""Shared fixtures: compile the canonical robots once per session into a private cache."""

from __future__ import annotations

import os

import matplotlib
import pytest

matplotlib.use("Agg")


@pytest.fixture(scope="session", autouse=True)
def _cache_dir(tmp_path_factory: pytest.TempPathFactory):
    """Every test run uses its own model cache (never the user's)."""
    path = tmp_path_factory.mktemp("model-cache")
    old = os.environ.get("THRUSTWALK_CACHE_DIR")
    os.environ["THRUSTWALK_CACHE_DIR"] = str(path)
    yield path
    if old is None:
        os.environ.pop("THRUSTWALK_CACHE_DIR", None)
    else:
        os.environ["THRUSTWALK_CACHE_DIR"] = old


@pytest.fixture(scope="session")
def three_link(_cache_dir):
    from thrustwalk_cli.model import load_model
    from thrustwalk_cli.robot_io import load_robot

    return load_model(load_robot("three_link"))


@pytest.fixture(scope="session")
def rabbit(_cache_dir):
    from thrustwalk_cli.model import load_model
    from thrustwalk_cli.robot_io import load_robot

    return load_model(load_robot("rabbit"))


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    import matplotlib.pyplot as plt

    plt.close("all")


@pytest.fixture(scope="session")
def walk3(_cache_dir):
    """The bundled 3-link gait on its robot: (model, gait, zero dynamics)."""
    from thrustwalk_cli.model import load_model
    from thrustwalk_cli.robot_io import load_gait_for
    from thrustwalk_cli.zero_dynamics import zero_dynamics

    robot, gait = load_gait_for(None, "three_link_walk")
    model = load_model(robot)
    return model, gait, zero_dynamics(model, gait)
