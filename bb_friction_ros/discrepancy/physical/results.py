"""The named results of the physical search: what was asked, tried, chosen, at what cost."""

import dataclasses
import math

import numpy as np

from bb_friction_ros.discrepancy.physical.trials import PhysicalKind, PhysicalSettings, TrialRun


@dataclasses.dataclass
class PhysicsContext:
    """What the physical candidates need besides the recording: the model and its rate."""

    config_path: object
    runner_args: tuple        # runner_args(replay settings): the trials' schedule
    settings: PhysicalSettings = PhysicalSettings()
    # the replay path's own schedule (NodeParameters.schedule(): a due step at a dense input
    # follows its answer); None: the trials' schedule
    replay_args: tuple = None


@dataclasses.dataclass
class Outcome:
    """The empirical selection on r - d(p) at one trial value (or on r: ``value`` None)."""

    kind: object              # PhysicalKind or None
    value: float
    terms: object             # TermSet
    trace: list
    ctx: object               # selection.SelectionContext
    score: float              # penalised BIC, the physical parameter counted
    run: TrialRun = None
    delta_fit: np.ndarray = None
    profile: object = None    # the _Profile its value was found on, when not _held's

    @property
    def members(self):
        """Return the chosen empirical (Candidate, nonlinear value) pairs."""
        return self.ctx.best[self.ctx.chosen].members


@dataclasses.dataclass
class PhysicalChoice:
    """A chosen physical effect: the parameter's value, its interval and its columns."""

    kind: PhysicalKind
    value: float
    base_value: float
    interval_95: tuple
    run: TrialRun             # the model at ``value`` over the whole recording
    delta_nm: np.ndarray      # T(value) - T(base) at the usable samples

    def effect(self):
        """Return the summary.json entry."""
        lo, hi = self.interval_95
        p = self.kind.param
        return {"name": self.kind.name, "kind": "physical", "params": {p: self.value},
                "units": {p: self.kind.unit},
                "interval_95": {p: [lo, hi]},
                "config_value": {p: self.base_value},
                "config_key": f"ball_screw.{self.kind.section}.{p}"}


@dataclasses.dataclass
class PhysicalSearch:
    """The whole physical search: what was tried, what was chosen, what it cost."""

    chosen: PhysicalChoice = None
    trials: list = dataclasses.field(default_factory=list)    # rows for summary/report
    runs: int = 0
    wall_s: float = 0.0
    workers: int = 1
    identifiability: list = dataclasses.field(default_factory=list)
    base: TrialRun = None     # the model at the config's values (all samples of the input)
    usable: np.ndarray = None    # mask of the usable samples in the input recording
    none_score: float = math.nan
    context: object = None       # the PhysicsContext (validation runs the model again)
    rejected: PhysicalChoice = None     # chosen on the fit part, no better held out
    validation_runs: int = 0
    validation_wall_s: float = 0.0
    replay_runs: int = 0         # runs of the replay path at the chosen value (replay_change)
    notes: list = dataclasses.field(default_factory=list)
    selections: int = 0          # empirical selections run (none, and per candidate refined)
    threads: int = 1
    coarse_step_factor: int = 1
    coarse_runs: int = 0         # of ``runs``: at the coarse step (smooth candidates)
    tie: bool = False            # chosen on a tie with its twin (prefer_model_parameter_on_tie)
    heldout_judged: bool = True  # False: its change is too small there (unseen_on_hold)
    # the base run (the config's values) is the prediction's own run over the recording,
    # kept: the model ran over the recording once before its trials (trials.base_run)
    base_run_kept: bool = False

    def as_dict(self):
        """Return summary.json → ``physical``."""
        return {"model_runs": self.runs, "model_run_wall_s": self.wall_s,
                "base_run_kept": self.base_run_kept,
                "replay_path_runs": self.replay_runs,
                "selections": self.selections,
                "workers": self.workers, "threads": self.threads,
                "coarse_runs": self.coarse_runs,
                "coarse_step_factor": self.coarse_step_factor,
                "chosen": self.chosen.effect() if self.chosen else None,
                "chosen_on_tie": self.tie if self.chosen else False,
                "heldout_judged": self.heldout_judged if self.chosen else None,
                "penalised_bic_none": self.none_score,
                "trials": self.trials, "identifiability": self.identifiability,
                "notes": self.notes}
