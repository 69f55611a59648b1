"""
The pytest plugin of bb_friction_ros (entry point ``pytest11``): the ``friction_node`` fixture.

Any test suite in an environment where bb_friction_ros is installed may use it::

    @pytest.mark.friction_node(parameters={"model_rate_hz": 200.0})
    def test_my_controller(friction_node):
        friction_node.publish_axial_load(1500.0, stamp_s=0.0)
        ...

The harness itself is ``bb_friction_ros.harness`` (no pytest needed).
"""

import pytest

from bb_friction_ros.harness import FrictionNodeHarness


def pytest_configure(config):
    """Register the ``friction_node`` marker."""
    config.addinivalue_line(
        "markers", "friction_node(parameters=None, params_file=None, **kwargs): arguments "
        "of the friction_node fixture (bb_friction_ros.harness.FrictionNodeHarness)")


@pytest.fixture
def friction_node(request):
    """Yield a started ``FrictionNodeHarness``, its arguments from the ``friction_node`` mark."""
    marker = request.node.get_closest_marker("friction_node")
    kwargs = dict(marker.kwargs) if marker else {}
    with FrictionNodeHarness(**kwargs) as harness:
        yield harness
