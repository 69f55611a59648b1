"""
Former home of the node test harness and its pytest plugin; kept so existing imports work.

``bb_friction_ros.harness`` is the harness (no pytest); ``bb_friction_ros.pytest_plugin`` is
the ``pytest11`` plugin (the ``friction_node`` fixture).  New code imports those.
"""

from bb_friction_ros.harness import (Collector, console_script, DEFAULT_TIMEOUT_S,  # noqa: F401
                                     FrictionNodeHarness, local_domain_id, message_class,
                                     play_through_node, prediction_dict, PROFILE_TOPIC,
                                     PROFILE_TYPE, stamp_msg)
from bb_friction_ros.pytest_plugin import friction_node, pytest_configure  # noqa: F401
