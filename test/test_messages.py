"""The bb_friction_msgs interfaces: contract, rclpy pub/sub round trip, rosbags serialization.

The round trips run in this process only: one node publishes and subscribes, a
SingleThreadedExecutor spins it (no launch, no ros2 CLI). test/conftest.py keeps the DDS
traffic on this machine and on a per-session domain id.
"""

import array
import dataclasses
import functools
import math
import pathlib
import time

import numpy as np
import pytest
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message

from bb_friction_msgs.msg import (ContactGroup, ContactGroupStatus, FeedforwardProfile,
                                  FrictionPrediction)
from builtin_interfaces.msg import Time
from std_msgs.msg import Header

PACKAGE = 'bb_friction_msgs'
MSG_DIR = pathlib.Path(__file__).resolve().parent.parent / 'msg_defs' / PACKAGE / 'msg'

# The contracts: field names and types, in order, as rosidl reports them.
CONTRACTS = {
    FrictionPrediction: {
        'header': 'std_msgs/Header',
        'nut_angle_rad': 'double',
        'nut_velocity_rad_s': 'double',
        'axial_load_n': 'double',
        'torque_total_nm': 'double',
        'torque_b2g_nm': 'double',
        'torque_b2b_nm': 'double',
        'torque_empirical_nm': 'double',
        'converged': 'boolean',
        'model_latency_s': 'double',
        'model_age_s': 'double',
        'n_groups': 'uint32',
        'torque_state_nm': 'double',
        'state_other_direction': 'boolean',
    },
    ContactGroup: {
        'ball_ids': 'sequence<uint32>',
        'b2b_forces_n': 'sequence<double>',
    },
    ContactGroupStatus: {
        'header': 'std_msgs/Header',
        'nut_angle_rad': 'double',
        'n_balls': 'uint32',
        'groups': 'sequence<bb_friction_msgs/ContactGroup>',
    },
    FeedforwardProfile: {
        'header': 'std_msgs/Header',
        'nut_angle_rad': 'sequence<double>',
        'torque_total_nm': 'sequence<double>',
        'nut_velocity_rad_s': 'double',
        'axial_load_n': 'double',
        'converged': 'boolean',
    },
}

# One sample of each message as plain data; values chosen to catch truncation, sign, ordering,
# uint32 range and empty-sequence mistakes.
HEADER = {'stamp': {'sec': 1_700_000_123, 'nanosec': 987_654_321}, 'frame_id': 'nut'}
GROUPS = [
    {'ball_ids': [3, 4, 5], 'b2b_forces_n': [1.5, 2.25]},
    {'ball_ids': [17], 'b2b_forces_n': []},
    {'ball_ids': [28, 29, 0, 4_294_967_295], 'b2b_forces_n': [0.5, -0.75, 1e-300]},
]
SAMPLES = {
    FrictionPrediction: {
        'header': HEADER,
        'nut_angle_rad': math.pi / 3,
        'nut_velocity_rad_s': -12.5,
        'axial_load_n': 50.0,
        'torque_total_nm': 0.0052 + 0.0019 - 0.0007,
        'torque_b2g_nm': 0.0052,
        'torque_b2b_nm': 0.0019,
        'torque_empirical_nm': -0.0007,
        'converged': True,
        'model_latency_s': 1.25e-3,
        'model_age_s': 0.02,
        'n_groups': 3,
        'torque_state_nm': 0.0064,
        'state_other_direction': False,
    },
    ContactGroup: GROUPS[2],
    ContactGroupStatus: {
        'header': HEADER,
        'nut_angle_rad': -2.5,
        'n_balls': 30,
        'groups': GROUPS,
    },
    FeedforwardProfile: {
        'header': HEADER,
        'nut_angle_rad': [1.0, 0.9375, 0.875],       # moving backwards: decreasing angles
        'torque_total_nm': [-0.25, -0.3125, -1e-300],
        'nut_velocity_rad_s': -6.25,
        'axial_load_n': -1500.0,
        'converged': False,
    },
}


def typename(msg_type):
    """Return the full ROS 2 type name, e.g. ``bb_friction_msgs/msg/ContactGroup``."""
    return f'{PACKAGE}/msg/{msg_type.__name__}'


def make_rclpy(msg_type, data):
    """Build an rclpy message of msg_type from plain data."""
    kwargs = dict(data)
    if 'header' in kwargs:
        header = kwargs['header']
        kwargs['header'] = Header(stamp=Time(**header['stamp']), frame_id=header['frame_id'])
    if 'groups' in kwargs:
        kwargs['groups'] = [make_rclpy(ContactGroup, g) for g in kwargs['groups']]
    return msg_type(**kwargs)


def make_rosbags(store, msg_type, data):
    """Build a rosbags message of msg_type from plain data."""
    kwargs = dict(data)
    if 'header' in kwargs:
        header = kwargs['header']
        stamp = store.types['builtin_interfaces/msg/Time'](**header['stamp'])
        kwargs['header'] = store.types['std_msgs/msg/Header'](
            stamp=stamp, frame_id=header['frame_id'])
    if 'groups' in kwargs:
        kwargs['groups'] = [make_rosbags(store, ContactGroup, g) for g in kwargs['groups']]
    for name in ('nut_angle_rad', 'torque_total_nm'):
        if isinstance(kwargs.get(name), list):
            kwargs[name] = np.array(kwargs[name], dtype=np.float64)
    if 'ball_ids' in kwargs:
        kwargs['ball_ids'] = np.array(kwargs['ball_ids'], dtype=np.uint32)
        kwargs['b2b_forces_n'] = np.array(kwargs['b2b_forces_n'], dtype=np.float64)
    return store.types[typename(msg_type)](**kwargs)


def to_plain(value):
    """Turn an rclpy or rosbags message into plain dicts, lists and Python scalars."""
    if hasattr(value, 'get_fields_and_field_types'):  # rclpy message
        return {name: to_plain(getattr(value, name))
                for name in value.get_fields_and_field_types()}
    if dataclasses.is_dataclass(value):  # rosbags message
        return {f.name: to_plain(getattr(value, f.name))
                for f in dataclasses.fields(value) if not f.name.startswith('__')}
    if isinstance(value, (list, tuple, array.array, np.ndarray)):
        return [to_plain(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    return value


@functools.lru_cache(maxsize=None)
def rosbags_typestore():
    """Return a Jazzy typestore with the .msg files of msg_defs/bb_friction_msgs registered."""
    from rosbags.typesys import Stores, get_typestore, get_types_from_msg

    store = get_typestore(Stores.ROS2_JAZZY)
    types = {}
    for path in sorted(MSG_DIR.glob('*.msg')):
        types.update(get_types_from_msg(path.read_text(), f'{PACKAGE}/msg/{path.stem}'))
    store.register(types)
    return store


def round_trip(context, msg_type, msg, timeout_s=10.0):
    """Publish msg and receive it in the same process; return (received, publisher type hash)."""
    node = rclpy.create_node(f'roundtrip_{msg_type.__name__.lower()}', context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    topic = f'/bb_friction_test/{msg_type.__name__}'
    qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
    received = []
    try:
        publisher = node.create_publisher(msg_type, topic, qos)
        node.create_subscription(msg_type, topic, received.append, qos)
        deadline = time.monotonic() + timeout_s
        # Publish until the subscription has matched and got one: discovery takes a moment.
        while not received and time.monotonic() < deadline:
            publisher.publish(msg)
            executor.spin_once(timeout_sec=0.1)
        infos = node.get_publishers_info_by_topic(topic)
    finally:
        executor.shutdown()
        node.destroy_node()
    assert received, f'no {msg_type.__name__} received on {topic} within {timeout_s} s'
    assert len(infos) == 1
    return received[0], str(infos[0].topic_type_hash)


@pytest.mark.parametrize('msg_type', list(CONTRACTS), ids=lambda t: t.__name__)
def test_contract(msg_type):
    assert msg_type.get_fields_and_field_types() == CONTRACTS[msg_type]
    assert list(SAMPLES[msg_type]) == list(CONTRACTS[msg_type])


@pytest.mark.parametrize('msg_type', list(CONTRACTS), ids=lambda t: t.__name__)
def test_rclpy_round_trip(ros_context, msg_type):
    sent = make_rclpy(msg_type, SAMPLES[msg_type])
    received, type_hash = round_trip(ros_context, msg_type, sent)
    assert to_plain(received) == SAMPLES[msg_type]
    assert received == sent
    # A bag written by rosbags records the same type hash as the live system uses.
    assert type_hash == rosbags_typestore().hash_rihs01(typename(msg_type))


@pytest.mark.parametrize('msg_type', list(CONTRACTS), ids=lambda t: t.__name__)
def test_rosbags_serialization(msg_type):
    store = rosbags_typestore()
    raw = store.serialize_cdr(make_rosbags(store, msg_type, SAMPLES[msg_type]),
                              typename(msg_type))
    # rosbags reads its own bytes back ...
    assert to_plain(store.deserialize_cdr(raw, typename(msg_type))) == SAMPLES[msg_type]
    # ... and rclpy reads rosbags' bytes (as a node does when it replays a bag written with
    # rosbags). The other way round, rclpy's bytes may carry up to 8 junk bytes at the end, which
    # rosbags' deserialize_cdr rejects: write bags with rosbags' serialize_cdr.
    from_ros = deserialize_message(bytes(raw), msg_type)
    assert to_plain(from_ros) == SAMPLES[msg_type]
    assert from_ros == make_rclpy(msg_type, SAMPLES[msg_type])
