"""
Input trajectories: generated nut motion and load, as events in log order.

``make_demo_events`` builds the demo recording from ``config/demo_recording.yaml``: reversing
nut motion at several speeds with a varying load.  Its ``measured_torque`` is synthetic: the
model's own prediction plus viscous and seal drag and noise (named in the config), so that
the replay and discrepancy reports have a measurement to compare against.  The demo, the
``make-demo-bag`` command, the discrepancy workflow's synthetic recordings and the tests use
them.
"""

import dataclasses
import math

import numpy as np

from bb_friction_ros.bags import Event, with_measurement
from bb_friction_ros.config import field, from_mapping, load_section


@dataclasses.dataclass(frozen=True)
class DemoRecording:
    """Parameters of the generated demo recording."""

    state_rate_hz: float = field(500.0, "Hz", "nut_state rate", lo=1.0, hi=10000.0)
    load_rate_hz: float = field(100.0, "Hz", "axial_load rate", lo=0.1, hi=10000.0)
    accel_rad_s2: float = field(60.0, "rad/s^2", "nut acceleration limit", lo=0.0,
                                lo_open=True)
    segments_rev_s: tuple = (1.0, -1.0, 0.5, -0.5, 2.0, -2.0)
    segment_duration_s: float = field(1.5, "s", "duration of each speed segment", lo=0.01)
    load_mean_n: float = field(1500.0, "N", "mean axial load", lo=-1e6, hi=1e6)
    load_amplitude_n: float = field(500.0, "N", "load variation amplitude", lo=0.0)
    load_period_s: float = field(4.0, "s", "load variation period", lo=0.01)
    viscous_drag_nm_s_per_rad: float = field(0.004, "N m s/rad", "synthetic viscous drag",
                                             lo=0.0)
    seal_drag_nm: float = field(0.03, "N m", "synthetic seal drag", lo=0.0)
    noise_nm: float = field(0.005, "N m", "synthetic noise std", lo=0.0)
    seed: int = field(20190517, "1", "random seed", lo=0)
    nut_joint: str = "nut_joint"


def load_demo_recording(path):
    """Read the ``demo_recording`` mapping of a YAML file."""
    data = dict(load_section(path, "demo_recording"))
    if "segments_rev_s" in data:
        data["segments_rev_s"] = tuple(float(v) for v in data["segments_rev_s"])
    return from_mapping(DemoRecording, data, "demo_recording")


def nut_motion(cfg, t):
    """Nut speed [rad/s] and angle [rad] at times ``t``: segments joined at limited accel."""
    dt = t[1] - t[0]
    target = np.array(cfg.segments_rev_s) * 2.0 * math.pi
    idx = np.minimum((t // cfg.segment_duration_s).astype(int), target.size - 1)
    speed = np.empty_like(t)
    w = 0.0
    for k, goal in enumerate(target[idx]):
        w += np.clip(goal - w, -cfg.accel_rad_s2 * dt, cfg.accel_rad_s2 * dt)
        speed[k] = w
    angle = np.concatenate([[0.0], np.cumsum(0.5 * (speed[1:] + speed[:-1]) * dt)])
    return speed, angle


def make_demo_events(cfg, predict):
    """
    Events of the demo recording in log order.

    ``predict(samples)`` returns the model's friction torque for the nut-state samples (the
    replay path); the measured torque adds the configured synthetic effects and noise.
    """
    duration = len(cfg.segments_rev_s) * cfg.segment_duration_s
    t = np.arange(0.0, duration, 1.0 / cfg.state_rate_hz)
    speed, angle = nut_motion(cfg, t)
    t_load = np.arange(0.0, duration, 1.0 / cfg.load_rate_hz)
    load = cfg.load_mean_n + cfg.load_amplitude_n * np.sin(2 * math.pi * t_load
                                                           / cfg.load_period_s)
    events = []
    j = 0
    for k in range(t.size):
        while j < t_load.size and t_load[j] <= t[k]:
            events.append(Event("axial_load", float(t_load[j]), value=float(load[j])))
            j += 1
        events.append(Event("nut_state", float(t[k]), (cfg.nut_joint,), (float(angle[k]),),
                            (float(speed[k]),)))
    model = np.asarray(predict(events), dtype=float)
    rng = np.random.default_rng(cfg.seed)
    measured = (model + cfg.viscous_drag_nm_s_per_rad * speed
                + cfg.seal_drag_nm * np.sign(speed) + rng.normal(0.0, cfg.noise_nm, t.size))
    return with_measurement(events, measured)
