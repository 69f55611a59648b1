"""
What a discrepancy run leaves in its --out: only its own outputs, summary.json last.

An earlier run's augmented.yaml, validation/ and plots used to stay beside a new summary
whose verdict was none; two runs into one directory mixed their files; a full disk left a
complete-looking summary.json without report.md; Ctrl-C inside a model step was counted as
a model error and the run went on.
"""

import dataclasses
import json
from types import SimpleNamespace

import numpy as np
import pytest

from bb_friction_ros.discrepancy.synthetic import draw_effect, synthesize
from bb_friction_ros.discrepancy.workflow import _only_run_in
from bb_friction_ros.empirical_terms import TermSet
from bb_friction_ros.runner import InputSample, ModelRunner

from .test_discrepancy_inputs import run_cli
from .test_discrepancy_measured import write_csv


@pytest.fixture(scope="module")
def rec(base):
    rng = np.random.default_rng(8)
    fit, _ = synthesize(base, TermSet([draw_effect("seal_drag", rng)]), 0.004, rng)
    return fit


def test_a_new_run_removes_the_earlier_runs_outputs(rec, tmp_path):
    out = tmp_path / "o"
    f = write_csv(tmp_path / "a.csv", rec)
    assert run_cli(["--no-physical", f, "--out", out, "--no-progress", "--validate", f]) == 0
    assert (out / "augmented.yaml").is_file() and (out / "validation").is_dir()
    assert any(out.glob("*.png"))
    (out / "notes.txt").write_text("mine")          # never the user's own files
    short = write_csv(tmp_path / "short.csv", rec.take(np.arange(len(rec)) < 50))
    assert run_cli(["--no-physical",
                    short, "--out", out, "--no-progress"]) == 2      # too short to tell
    s = json.loads((out / "summary.json").read_text())
    assert s["verdict"] == "none" and s["complete"] is True
    assert not (out / "augmented.yaml").exists() and not (out / "validation").exists()
    assert not any(out.glob("*.png"))
    assert (out / "notes.txt").read_text() == "mine"


def test_a_second_run_into_a_directory_in_use_is_refused(rec, tmp_path, capsys):
    out = tmp_path / "o"
    out.mkdir()
    f = write_csv(tmp_path / "a.csv", rec)
    with _only_run_in(out):
        assert run_cli(["--no-physical", f, "--out", out, "--no-progress", "--no-plots"]) == 2
    assert "another bb-friction discrepancy is writing into it" in capsys.readouterr().err
    assert run_cli(["--no-physical", f, "--out", out, "--no-progress", "--no-plots"]) == 0


def test_summary_is_written_last_and_says_complete(rec, tmp_path):
    out = tmp_path / "o"
    assert run_cli(["--no-physical",
                    write_csv(tmp_path / "a.csv", rec), "--out", out, "--no-progress"]) == 0
    files = sorted(out.iterdir(), key=lambda p: p.stat().st_mtime_ns)
    assert files[-1].name == "summary.json"
    assert json.loads(files[-1].read_text())["complete"] is True


def test_failure_while_writing_leaves_a_summary_that_says_incomplete(rec, tmp_path,
                                                                     monkeypatch):
    from bb_friction_ros.discrepancy import report

    def full(*args, **kwargs):
        raise OSError(28, "No space left on device")
    monkeypatch.setattr(report, "write_report", full)
    out = tmp_path / "o"
    with pytest.raises(OSError):
        run_cli(["--no-physical",
                 write_csv(tmp_path / "a.csv", rec), "--out", out, "--no-progress"])
    s = json.loads((out / "summary.json").read_text())
    assert s["complete"] is False and "No space left" in s["error"]


class _Interrupted:
    """A screw whose step is interrupted inside compiled code (as numba reports it)."""

    def reset(self, nut_angle_rad):
        pass

    def step(self, *args, **kwargs):
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt as exc:
            raise SystemError("returned a result with an exception set") from exc


def test_ctrl_c_inside_a_model_step_stops_the_run_and_is_no_model_error():
    runner = ModelRunner(_Interrupted(), 100.0)
    with pytest.raises(KeyboardInterrupt):
        runner.process(InputSample(0.0, 0.0, 1.0, 1000.0))
    assert runner.stats.rejected["model_error"] == 0


def test_ctrl_c_inside_a_model_step_exits_130_without_a_traceback(rec, tmp_path, capsys,
                                                                  monkeypatch):
    from bb_friction_ros.ball_screw import whole_screw
    step = whole_screw.WholeScrew.step
    calls = SimpleNamespace(n=0)

    def interrupted_later(self, *args, **kwargs):
        calls.n += 1
        if calls.n == 200:
            return _Interrupted().step()
        return step(self, *args, **kwargs)
    monkeypatch.setattr(whole_screw.WholeScrew, "step", interrupted_later)
    f = write_csv(tmp_path / "a.csv", dataclasses.replace(rec))
    assert run_cli(["--no-physical",
                    f, "--out", tmp_path / "o", "--no-progress", "--recompute-prediction"]) \
        == 130
    err = capsys.readouterr().err
    assert "interrupted" in err and "Traceback" not in err


def test_physical_with_no_model_of_the_screw_says_it_was_ignored(rec, tmp_path):
    out = tmp_path / "o"
    f = write_csv(tmp_path / "a.csv", rec)
    assert run_cli([f, "--out", out, "--no-progress", "--no-plots", "--physical",
                    "--baseline", "zero"]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["physical"] is None
    assert any("--physical was ignored" in w for w in s["warnings"])


def test_physical_candidates_on_by_default_are_skipped_quietly_without_a_model(rec, tmp_path):
    # on by default, they apply only where a model of the screw is in use: a zero-baseline
    # run skips them without a warning, and says why in its own key
    out = tmp_path / "o"
    f = write_csv(tmp_path / "a.csv", rec)
    assert run_cli([f, "--out", out, "--no-progress", "--no-plots", "--baseline", "zero"]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["physical"] is None
    assert not any("--physical" in w for w in s["warnings"])
    assert "no model of this screw" in s["physical_skipped"]
