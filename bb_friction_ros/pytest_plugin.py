"""
pytest plugin of bb_friction_ros (entry point ``pytest11``): the ``friction_node`` fixture.

Installed with the package, so any test suite in the same environment can use it::

    @pytest.mark.friction_node(parameters={"model_rate_hz": 200.0})
    def test_my_controller(friction_node):
        friction_node.publish_axial_load(1500.0, stamp_s=0.0)
        ...

The marker's keyword arguments are those of ``bb_friction_ros.testing.FrictionNodeHarness``.
Nothing ROS is imported until a test asks for the fixture.
"""

import pytest


def pytest_configure(config):
    """Register the ``friction_node`` marker."""
    config.addinivalue_line(
        "markers", "friction_node(parameters=None, params_file=None, **kwargs): arguments "
        "of the friction_node fixture (bb_friction_ros.testing.FrictionNodeHarness)")


@pytest.fixture
def friction_node(request):
    """Yield a started ``FrictionNodeHarness``; stopped after the test."""
    from bb_friction_ros.testing import FrictionNodeHarness
    marker = request.node.get_closest_marker("friction_node")
    kwargs = dict(marker.kwargs) if marker else {}
    with FrictionNodeHarness(**kwargs) as harness:
        yield harness
