"""Shared pytest set-up for all tests of bb_friction_ros.

DDS isolation: every test session keeps its ROS 2 traffic on this machine
(``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``) and on its own ``ROS_DOMAIN_ID`` (1..101, from the
pid), so parallel test runs on one machine do not hear each other. The workers of one
``pytest -n N`` run (pytest-xdist, as ``make test`` runs the suite) take consecutive ids from
their controller's pid, so no two of them share a domain. Both are set here, at import time,
before any test can call ``rclpy.init()``; child processes started by tests inherit them.

Fixtures for tests that need ROS 2 (rclpy is imported lazily, so tests of the pure-Python physics
core do not depend on it):

- ``ros_context``: an initialised ``rclpy.Context`` of the test's own, shut down afterwards.
- ``repo_root``: the repository root as a ``pathlib.Path``.
"""

import os
import pathlib

import pytest

from bb_friction_ros.interface import local_domain_id


def session_domain_id(environ=os.environ):
    """Return this test session's ROS domain id (an xdist worker's differs from its peers')."""
    worker = environ.get("PYTEST_XDIST_WORKER")          # "gw0", "gw1", ... under pytest -n
    if not worker:
        return local_domain_id()
    return local_domain_id(os.getppid() + int(worker.lstrip("gw")))


ROS_DOMAIN_ID = session_domain_id()
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ['ROS_DOMAIN_ID'] = str(ROS_DOMAIN_ID)

REPO_ROOT = pathlib.Path(__file__).resolve().parent.parent


@pytest.fixture(scope='session')
def repo_root():
    """Return the repository root."""
    return REPO_ROOT


@pytest.fixture
def ros_context():
    """Yield an initialised rclpy context private to the test; shut it down afterwards."""
    import rclpy

    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        yield context
    finally:
        if context.ok():
            rclpy.shutdown(context=context)
