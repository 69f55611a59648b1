"""Shared fixtures: one contact model per session (friction maps load once)."""

import pytest

from bb_friction_ros.model_file import load_ball_screw
from bb_friction_ros.ball_screw.screw_model import ScrewModel


@pytest.fixture(scope="session")
def config():
    """Default (Table 4) configuration."""
    return load_ball_screw()


@pytest.fixture(scope="session")
def model(config):
    """ScrewModel of the default configuration."""
    return ScrewModel(config)
