"""
friction_node: neither the feedforward nor the prediction opposes the motion when its model
falls behind.

In-process under rclpy (test_node_servo.Probe).  A deliberately slow model makes the node's
queue span model periods, so reversal steps are skipped (``allow_step=False``); every answer
it publishes is checked against its own sample's direction.
"""

import time
from types import SimpleNamespace

from test_node_servo import Probe

from bb_friction_ros.runner import ModelRunner


class SlowScrew:
    """Converged friction of the commanded direction, 0.3 N m, after a 20 ms solve."""

    STEP_S = 0.02

    def __copy__(self):
        return SlowScrew()

    def reset(self, nut_angle_rad):
        pass

    def step(self, nut_angle_rad, nut_velocity_rad_s, axial_load_n, dt_s, substep=False):
        time.sleep(self.STEP_S)
        w = nut_velocity_rad_s
        torque = 0.3 if w > 0 else (-0.3 if w < 0 else 0.0)
        return SimpleNamespace(torque_total_nm=torque, torque_b2g_nm=torque, torque_b2b_nm=0.0,
                               converged=True, groups=[], azimuth_rad=[0.0])


def test_velocity_noise_on_a_lagging_node_never_feeds_forward_against_the_motion(ros_context):
    """+-0.02 rad/s noise flipping sign every 1 ms stamp, sent as a burst of 600 inputs."""
    runner = ModelRunner(SlowScrew(), 100.0)
    probe = Probe(ros_context, {"queue_size": 100000}, runner=runner)
    answers, predicted = [], []
    node = probe.node
    publish = node.live.outputs.answer

    def record(pred, *args):
        answers.append((pred.nut_velocity_rad_s, pred.feedforward_nm))
        predicted.append((pred.nut_velocity_rad_s, pred.torque_total_nm, pred.converged,
                          pred.state_other_direction))
        return publish(pred, *args)

    node.live.outputs.answer = record
    try:
        probe.load(1500.0)
        n = 600
        for k in range(n):
            w = 0.0 if k % 60 == 59 else (0.02 if k % 2 == 0 else -0.02)
            msg = probe.JointState(name=["nut_joint"], position=[1e-5 * (k % 2)], velocity=[w])
            t = 100.0 + 1e-3 * k
            msg.header.stamp.sec = int(t)
            msg.header.stamp.nanosec = int(round((t - int(t)) * 1e9))
            probe.pub_state.publish(msg)
        probe._until(lambda: len(answers) >= n, timeout_s=60.0)
        values = node.diagnostics_values(advance=False)[0]
        assert values["skipped_steps"] > 50, "the node kept up: test is void"
        wrong = [(w, ff) for w, ff in answers if ff * w < 0.0 or (w == 0.0 and ff != 0.0)]
        assert not wrong, f"{len(wrong)} of {len(answers)} answers oppose the motion"
        assert values["feedforward_zeroed"] > 50
        assert any(ff != 0.0 for _, ff in answers)
        # friction/prediction, the richer message a controller may read, neither: a state of
        # the other direction answers 0 N m, not converged, flagged
        assert not [p for p in predicted if p[1] * p[0] < 0.0]
        flagged = [p for p in predicted if p[3]]
        assert flagged and all(p[1] == 0.0 and not p[2] for p in flagged)
    finally:
        probe.close()
