"""
The driver: columns of samples through the runner give exactly the event path's answers.

``run_samples`` over ``samples_of_events`` (or ``samples_of_rows`` for a table) must give the
predictions, the rejections and the step schedule of ``replay.run_events`` over the same
messages, since the discrepancy workflow, the physical trials and ``bb-friction
feedforward`` now take this path where they used to take that one.
"""

import dataclasses
import math

import numpy as np

from bb_friction_ros.bags import Event
from bb_friction_ros.config import bundled_config
from bb_friction_ros.drive import run_samples, samples_of_events, samples_of_rows
from bb_friction_ros.node_parameters import NodeParameters
from bb_friction_ros.replay import run_events
from bb_friction_ros.runner import build_runner, InputAssembler
from recordings import short_recording

SETTINGS = NodeParameters()
MAX_LOAD_N = 5000.0


def _runner(answer_first=True):
    return build_runner(bundled_config("ball_screw.yaml"),
                        *SETTINGS.schedule(answer_first=answer_first))


def _rows(n=300, rate_hz=1000.0):
    """Rows of a reversing 1-2 rev/s motion with loads to refuse (too large, NaN, none)."""
    t = np.arange(n) / rate_hz
    w = 2 * math.pi * np.where(t < t[n // 2], 1.0, -2.0)
    a = np.concatenate([[0.0], np.cumsum(w[1:] / rate_hz)])
    f = 1500.0 + 200.0 * np.sin(7.0 * t)
    f[:3] = np.nan                          # no load yet for the first rows
    f[50] = 2 * MAX_LOAD_N                  # refused: the last one held
    f[51] = np.nan
    return t, a, w, f


def _row_events(t, a, w, f):
    for row in zip(t, a, w, f):
        yield Event("axial_load", float(row[0]), value=float(row[3]))
        yield Event("nut_state", float(row[0]), (SETTINGS.nut_joint,), (float(row[1]),),
                    (float(row[2]),))


def test_rows_are_validated_as_their_events_are():
    rows = _rows()
    a = samples_of_rows(*rows, MAX_LOAD_N)
    b = samples_of_events(_row_events(*rows), SETTINGS.nut_joint, MAX_LOAD_N)
    assert len(a) == len(b) == rows[0].size - 3
    for name in ("stamp_s", "nut_angle_rad", "nut_velocity_rad_s", "axial_load_n"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    assert a.rejected == b.rejected == {"no_load_yet": 3, "absurd_load": 1, "non_finite": 4}
    assert a.rejected_nut_state == b.rejected_nut_state == 3


def test_the_driver_answers_as_the_event_path():
    """Same answers to the bit, same counters, and the steps the runner took."""
    events = short_recording(state_rate_hz=1000.0)
    ref_runner = _runner()
    ref = run_events(events, ref_runner, InputAssembler(SETTINGS.nut_joint, MAX_LOAD_N))
    runner = _runner()
    got = run_samples(runner, samples_of_events(events, SETTINGS.nut_joint, MAX_LOAD_N))
    assert len(got) == len(ref) and got.answered.all()
    for name in ("stamp_s", "torque_total_nm", "torque_b2b_nm", "feedforward_nm"):
        np.testing.assert_array_equal(getattr(got, name), [getattr(p, name) for p in ref])
    np.testing.assert_array_equal(got.converged, [p.converged for p in ref])
    wall = dict(last_step_wall_s=0.0)      # a wall time: the one counter that may differ
    assert dataclasses.replace(runner.stats, **wall) == \
        dataclasses.replace(ref_runner.stats, **wall)
    # each answer comes from the latest step at or before its sample, never a later one
    at, step = got.steps()
    assert len(at) == ref_runner.stats.model_steps - ref_runner.stats.substeps
    assert got.run_start[0] and got.run_start.sum() == 1 + ref_runner.stats.resets
    assert np.all(np.diff(step) >= 0) and step[0] == 0
    assert np.all(at[step] <= np.arange(len(got)))
    # a step that follows its answer (dense inputs): the sample is answered by the one before
    after = [i for i in at if i > 0 and not ref[i].stepped]
    assert after and all(step[i] == step[i - 1] for i in after)


def test_the_driver_can_stop_at_the_first_model_error():
    class Failing:
        """A screw whose third step raises."""

        def __init__(self, screw):
            self.screw, self.steps = screw, 0

        def reset(self, angle):
            self.screw.reset(angle)

        def step(self, *args, **kw):
            self.steps += 1
            if self.steps == 3:
                raise RuntimeError("no convergence at all")
            return self.screw.step(*args, **kw)

    runner = _runner(answer_first=False)     # every step before its answer: none settles
    runner.screw = Failing(runner.screw)
    samples = samples_of_rows(*(c[10:] for c in _rows()), MAX_LOAD_N)
    got = run_samples(runner, samples, stop_at_error=True)
    assert not got.answered[-1] and got.answered[:-1].all() and len(got) < len(samples)
    assert runner.stats.rejected["model_error"] == 1 and "no convergence" in \
        runner.stats.last_error


def test_the_physical_base_run_is_the_first_pass_kept(tmp_path):
    """
    ``--physical`` runs the model over the recording once: the trials' schedule and base run
    come from the replay path's own run (steps after their answers at dense inputs), and
    equal, bit for bit, a base run of the trials' own schedule (every step before its answer).
    """
    from bb_friction_ros.discrepancy.data import load_recording
    from bb_friction_ros.discrepancy.physical import base_run, runner_args
    t, a, w, f = _rows(n=1500)
    f[np.isnan(f) | (f > MAX_LOAD_N)] = 1500.0
    path = tmp_path / "rec.csv"
    np.savetxt(path, np.column_stack([t, a, w, f, 0.3 * np.sign(w)]), delimiter=",",
               header="t_s,nut_angle_rad,nut_velocity_rad_s,axial_load_n,torque_meas_nm",
               comments="")
    config = bundled_config("ball_screw.yaml")
    rec = load_recording(path, config, SETTINGS)
    assert rec.first_pass is not None and rec.first_pass.predictions.stepped.any()
    args = runner_args(SETTINGS)
    kept_sched, kept = base_run(rec, config, args)
    again_sched, again = base_run(rec.take(np.ones(len(rec), dtype=bool)), config, args)
    assert kept.first_pass and not again.first_pass and again.wall_s > 0.0
    for name in ("step_inputs", "run_start", "answer"):
        np.testing.assert_array_equal(getattr(kept_sched, name), getattr(again_sched, name))
    for name in ("total_nm", "b2b_nm", "converged"):
        np.testing.assert_array_equal(getattr(kept, name), getattr(again, name))
    # the replay path answered some samples from the step before (a step after its answer)
    assert np.any(rec.first_pass.predictions.step != kept_sched.answer)
