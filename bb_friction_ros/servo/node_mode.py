"""
The ``node`` mode: the real ``friction_node`` over DDS, in real time at the servo rate.

The node runs in this process on a ROS context and domain of its own
(``harness.FrictionNodeHarness``: launch-free, DDS kept on this machine).  At each servo
cycle, paced by the wall clock at the loop's rate, the controller side publishes the
measured state (encoder angle, velocity estimate, the sample's stamp) on ``nut_state``,
takes the newest ``friction/feedforward_profile`` the node has published, and reads the
torque at its measured angle with ``FeedforwardInterpolator``, as a ros2_control controller
would.  The node's answers arrive when they arrive: a cycle whose profile does not cover
its angle gets what the interpolator's rules give (0 N m when empty, stale, reversed or at
standstill; the last point beyond the profile).

The axial load is the recording's first (published once, before the run): a run whose
load varies is not fed its changes.

Coverage: the share of cycles whose measured angle lies inside a valid profile (status
``inside``); the other statuses are counted by name.  Late cycles (the simulation of one
period took longer than the period) are counted too: the run is then slower than real
time and the coverage is optimistic.

The node is given a copy of the model file without its ``inertia`` terms (in a temporary
directory), like the ``model`` mode: J alpha is the loop's acceleration
feedforward, not friction.
"""

from collections import Counter
import time

from bb_friction_ros.feedforward import FeedforwardInterpolator, INSIDE
from bb_friction_ros.model_file import physics_of, read_model_file, write_model_file
from bb_friction_ros.servo.modes import Mode
from bb_friction_ros.servo.plant import friction_terms

# Stamps of the node's inputs: the run's time plus this (a plausible ROS time, > 0).
STAMP_BASE_S = 1000.0


class NodeRuns(list):
    """The AxisRuns of the node mode, with its coverage figures."""

    coverage = None


class NodeMode(Mode):
    """The controller side of the node mode (module docstring)."""

    def __init__(self, harness, period_s):
        """Talk to the node of ``harness``; pace cycles at ``period_s`` of wall time."""
        super().__init__("node")
        self.h = harness
        self.period = period_s
        self.interp = FeedforwardInterpolator()
        self.statuses = Counter()
        self.late = 0
        self.cycles = 0
        self._seen = 0
        self._wall0 = None

    def raw(self, t_s, angle_rad, velocity_rad_s, load_n):
        """Publish the measured state at its cycle's wall time; interpolate the newest profile."""
        now = time.perf_counter()
        if self._wall0 is None:
            self._wall0 = now - t_s
        due = self._wall0 + t_s
        if now < due:
            time.sleep(due - now)
        elif now - due > self.period:
            self.late += 1
        self.cycles += 1
        self.h.publish_nut_state(angle_rad, velocity_rad_s, STAMP_BASE_S + t_s, wait=False)
        profiles = self.h.profiles
        if len(profiles) > self._seen:
            msgs = profiles.messages
            try:
                self.interp.set_profile_msg(msgs[-1])
            except ValueError:
                self.statuses["malformed_profile"] += 1
            self._seen = len(msgs)
        ff = self.interp.torque_at(angle_rad, velocity_rad_s)
        self.statuses[self.interp.status] += 1
        return ff

    def coverage(self):
        """Return the coverage figures (module docstring)."""
        n = max(self.cycles, 1)
        return {"cycles": self.cycles, "coverage": self.statuses[INSIDE] / n,
                "statuses": dict(self.statuses), "late_cycles": self.late,
                "profiles": self._seen}


def friction_only_model(src, dst):
    """Write the model file ``src`` without its inertia terms to ``dst``; return ``dst``."""
    section, terms = read_model_file(src)
    physics = physics_of(src)
    return write_model_file(dst, section, friction_terms(terms),
                            physics=None if physics == "ball_screw" else physics)


def run_node_mode(setup, reference):
    """Run every axis with the node in the loop; return NodeRuns with ``coverage``."""
    from pathlib import Path
    import tempfile
    with tempfile.TemporaryDirectory(prefix="servo_node_") as tmp:
        return _run(setup, reference, Path(tmp))


def _run(setup, reference, workdir):
    import os
    from bb_friction_ros.harness import FrictionNodeHarness
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    runs = NodeRuns()
    cover = []
    for i, axis in enumerate(reference.axes):
        path = setup.model_path if i == 0 or not setup.model_path_y else setup.model_path_y
        model = friction_only_model(path, workdir / f"node_model_{axis.name}.yaml")
        ms = setup.settings.model
        params = {"config_file": str(model), "model_rate_hz": ms.model_rate_hz,
                  "model_step_deg": ms.model_step_deg}
        load = setup.loads(reference, axis)
        with FrictionNodeHarness(parameters=params) as h:
            h.publish_axial_load(float(load[0]), STAMP_BASE_S)
            mode = NodeMode(h, setup.settings.loop.period_s)
            h.profiles     # subscribe before the first input
            runs.append(setup.simulate_axis(reference, axis, mode, axis_index=i))
            c = mode.coverage()
            c["diagnostics"] = {k: v for k, v in h.diagnostics_values().items()
                                if isinstance(v, (int, float, str))}
        c["axis"] = axis.name
        cover.append(c)
    runs.coverage = cover if len(cover) > 1 else cover[0]
    return runs
