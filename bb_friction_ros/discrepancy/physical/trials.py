"""
Model runs at trial values of the physical candidates, and the candidates themselves.

A trial value is a model run over the recording: the replay path's ``ModelRunner`` around a
``WholeScrew`` of the base config with the one value changed.  The runs only visit the
samples at which the runner steps the model (its schedule does not depend on the
parameters); the schedule comes from one full run of the base config (``base_run``), which
is also the reference T(p0).  ``TrialRunner`` runs batches in threads or on a Dask
LocalCluster and counts the runs and their time.
"""

from concurrent.futures import ThreadPoolExecutor
import dataclasses
import math
import time

import numpy as np

from bb_friction_ros.ball_screw.whole_screw import WholeScrew
from bb_friction_ros.config import field, from_mapping, LOCALHOST
from bb_friction_ros.model_file import load_ball_screw
from bb_friction_ros.drive import run_samples, SampleColumns
from bb_friction_ros.runner import ModelRunner


# chi-square(1) 95 % quantile: the profile-likelihood interval of one parameter
CHI2_1_95 = 3.841458820694124


@dataclasses.dataclass(frozen=True)
class PhysicalSettings:
    """Settings of the physical candidates (``discrepancy: physical:``)."""

    # On by default whenever a model of the screw is in use: the model's own parameters are
    # the first suspects of a discrepancy, and with the fused compiled step the ~20 trial
    # runs of a 60 s, 1 kHz recording take seconds, not minutes (bench_discrepancy.py
    # --physical prints the wall time).  ``--no-physical`` turns them off.  With no model of
    # the screw (``--baseline zero``, ``physics: none``) there is nothing to try and they are
    # skipped.  ``workflow.analyse`` tries them whenever it is given a PhysicsContext.
    enabled: bool = True
    theta_max_deg: float = field(5.0, "deg", "largest theta amplitude of the bracket (the "
                                 "bracket runs from 0 in theta_bracket_points steps)",
                                 lo=0.0, lo_open=True, hi=10.0)
    theta_bracket_points: int = field(5, "1", "theta amplitudes of the bracket", lo=2, hi=50)
    theta_resolution_deg: float = field(0.01, "deg", "refinement stops when the parabola "
                                        "moves the theta amplitude by less", lo=0.0,
                                        lo_open=True)
    mu_ratio_lo: float = field(0.6, "1", "smallest friction coefficient of the bracket, as a "
                               "fraction of the config's", lo=0.0, lo_open=True, hi=1.0)
    mu_ratio_hi: float = field(1.6, "1", "largest friction coefficient of the bracket, as a "
                               "multiple of the config's", lo=1.0, hi=10.0)
    mu_bracket_points: int = field(4, "1", "friction coefficients of the bracket (besides "
                                   "the config's)", lo=2, hi=50)
    mu_resolution: float = field(0.0002, "1", "refinement stops when the parabola moves mu "
                                 "by less", lo=0.0, lo_open=True)
    # The preload's torque has a threshold (on Table 4's screw it rises steeply between 2 and
    # 3 um of oversize): a 1.5 um grid missed a hidden 2.19 um and named mu instead, a 0.5 um
    # grid names it (docs/discrepancy.md).
    preload_max_um: float = field(4.0, "um", "largest ball oversize of the bracket (from "
                                  "the config's value)", lo=0.0, lo_open=True, hi=100.0)
    preload_bracket_points: int = field(8, "1", "ball oversizes of the bracket (besides the "
                                        "config's)", lo=2, hi=50)
    preload_resolution_um: float = field(0.01, "um", "refinement stops when the parabola "
                                         "moves the oversize by less", lo=0.0, lo_open=True)
    refine_runs: int = field(3, "1", "model runs of the refinement per candidate refined "
                             "(_next_value)", lo=0, hi=50)
    refine_candidates: int = field(2, "1", "candidates refined at most: those whose bracket "
                                   "run's change, at its best scale, beats no physical "
                                   "change, best first", lo=1, hi=3)
    max_nonconverged_fraction: float = field(0.01, "1", "a trial whose model steps fail to "
                                             "converge more often than this is not used",
                                             lo=0.0, hi=1.0)
    workers: int = field(1, "1", "Dask LocalCluster worker processes for the trial runs "
                         "(1: in this process)", lo=1, hi=256)
    # The compiled kernels release the GIL (test/test_nogil.py), so the runs of a batch can
    # share this process's cores without a cluster's start-up and transfers.
    threads: int = field(2, "1", "trial runs of a batch run at once in this many threads of "
                         "this process (with workers = 1)", lo=1, hi=64)
    # A physical parameter and its empirical twin (TWINS) whose readings differ by less than
    # bic_threshold are one ambiguous effect: the data cannot tell them apart, and the
    # choice is the prior's.  On such a tie the model's own parameter is kept (as it already
    # was when it led): the twins' documented meaning is the parameter's ("load_dependent:
    # the model's friction coefficient is off"), the model's parameters are the first
    # suspects of a discrepancy, and only the parameter is what the node can run.  Its cost
    # is a false alarm on a recording whose twin is truly empirical and not separable from
    # the parameter (measured: docs/discrepancy.md, "The tie rule").  False: the better score
    # decides.
    prefer_model_parameter_on_tie: bool = True
    # The change of mu or of the preload is smooth in the nut angle (it scales or shifts
    # every contact's force); a 4x coarser step reproduces it within 0.6 % (mu) and 1.8 %
    # (preload) rms at 4.3x less cost, while theta's B2B change (contacts closing at ball
    # configurations) is off by 22-31 % (docs/discrepancy.md).  The value chosen is run
    # again at the replay path's step.
    coarse_step_factor: int = field(4, "1", "the trial runs of the smooth candidates "
                                    "(friction_coefficient, preload) step this many times "
                                    "coarser (model step and time floor); 1: every run at "
                                    "the replay path's step", lo=1, hi=64)


def load_physical_settings(mapping, path="discrepancy.physical"):
    """Return PhysicalSettings from a mapping (validated; the dotted key is named)."""
    return from_mapping(PhysicalSettings, mapping, path)


@dataclasses.dataclass(frozen=True)
class PhysicalKind:
    """One model parameter as a candidate: its YAML place, unit and bracket."""

    name: str                 # effect name in summary.json
    section: str              # ball_screw section in the model file
    param: str                # its key there, in the edge unit reported
    unit: str
    meaning: str
    # its change of the torque is smooth in the nut angle: its search may run at the coarse
    # step (PhysicalSettings.coarse_step_factor)
    smooth: bool

    def base_value(self, cfg):
        """Return the config's value in the reported unit."""
        if self.name == "contact_angle_deviation":
            return math.degrees(cfg.errors.theta_amplitude_rad)
        if self.name == "friction_coefficient":
            return float(cfg.material.friction_coefficient)
        return cfg.geometry.ball_oversize_m * 1e6

    def bracket(self, base, s):
        """Return the coarse trial values (the config's own value left out)."""
        if self.name == "contact_angle_deviation":
            grid = np.linspace(0.0, s.theta_max_deg, s.theta_bracket_points)
            tol = s.theta_resolution_deg
        elif self.name == "friction_coefficient":
            grid = base * np.linspace(s.mu_ratio_lo, s.mu_ratio_hi, s.mu_bracket_points + 1)
            tol = s.mu_resolution
        else:
            grid = base + np.linspace(0.0, s.preload_max_um, s.preload_bracket_points + 1)
            tol = s.preload_resolution_um
        # within the parameter's own range: a config at mu 0.7 with mu_ratio_hi 1.6 asked for
        # a trial at 1.12, which the model refuses (a config error about a value the user
        # did not write)
        grid = np.unique(np.clip(grid, *self.limits()))
        return tuple(float(v) for v in grid if abs(v - base) > tol)

    def resolution(self, s):
        """Return the refinement tolerance in the reported unit."""
        return {"contact_angle_deviation": s.theta_resolution_deg,
                "friction_coefficient": s.mu_resolution}.get(self.name,
                                                             s.preload_resolution_um)

    def limits(self):
        """Return the admissible range of the value (the config's validated range)."""
        return {"contact_angle_deviation": (0.0, 10.0), "friction_coefficient": (1e-6, 1.0),
                "preload": (-10.0, 100.0)}[self.name]

    def override(self, value):
        """Return the nested config override that sets the value."""
        return {self.section: {self.param: float(value)}}


PHYSICAL = {k.name: k for k in (
    PhysicalKind("contact_angle_deviation", "errors", "theta_amplitude_deg", "deg",
                 "amplitude of the grooves' contact-angle deviation theta(phi); drives "
                 "ball-to-ball contact (paper Sec. 3.4, Fig. 19)", False),
    PhysicalKind("friction_coefficient", "material", "friction_coefficient", "1",
                 "Coulomb coefficient mu of the groove and ball-to-ball contacts", True),
    PhysicalKind("preload", "geometry", "ball_oversize_um", "um",
                 "preload: ball diameter minus the diameter that just touches all four "
                 "arcs", True),
)}
# The empirical term each physical candidate is nearly collinear with (identifiability).
TWINS = {"friction_coefficient": "load_dependent", "contact_angle_deviation": "angle_ripple",
         "preload": "seal_drag"}


# ------------------------------------------------------------------------------------------
# Model runs at trial values (the replay path's runner, stepping only where it steps)


@dataclasses.dataclass
class Schedule:
    """The samples at which the runner steps the model, and which step answers each sample."""

    step_inputs: np.ndarray   # (k, 4): stamp, nut angle, nut velocity, axial load
    run_start: np.ndarray     # (k,) bool: the runner reset before this step
    answer: np.ndarray        # (n,) index of the step whose state answers sample i; -1: none
    runner_args: tuple        # (model_rate_hz, model_step_deg, max_model_step_deg)

    @property
    def first_answer(self):
        """Return, per step, a sample it answered (the stepping sample itself)."""
        ok = np.flatnonzero(self.answer >= 0)
        first = np.full(len(self.step_inputs), -1, dtype=np.int64)
        # the first sample answered by each step: where the answer index changes
        j = self.answer[ok]
        new = np.ones(j.size, dtype=bool)
        new[1:] = j[1:] != j[:-1]
        first[j[new]] = ok[new]
        return first


@dataclasses.dataclass
class TrialRun:
    """The physics torque of one trial value at every sample of the recording."""

    value: float
    total_nm: np.ndarray
    b2b_nm: np.ndarray
    converged: np.ndarray
    wall_s: float
    delta_nm: np.ndarray = None     # total_nm less the base run's at the same step
    coarse: bool = False            # run at the coarse step (its delta is the coarse base's)
    first_pass: bool = False        # the replay path's run over the recording, not a new one


def runner_args(replay_settings):
    """
    Return the runner's schedule settings of a NodeParameters, as the replay path uses.

    But every due step before its answer (``NodeParameters.schedule``): the trials compare
    runs at the same angles, some at a coarser step, not the node's answers.
    """
    return replay_settings.schedule(answer_first=False)


def coarse_args(args, factor):
    """Return runner args ``factor`` times coarser: the model step and the time floor."""
    rate, step_deg, max_step_deg, after = args
    return (rate / factor, step_deg * factor, max(max_step_deg, step_deg * factor), after)


def _runner(config_path, overrides, args):
    """Build a ModelRunner of the physics alone (no empirical terms) at ``overrides``."""
    cfg = load_ball_screw(config_path, overrides)
    rate, step_deg, max_step_deg, after = args
    runner = ModelRunner(WholeScrew(cfg), rate, None, step_deg, max_step_deg, after)
    # as build_runner: the same warm-up, so the runs equal the replay path's
    runner.warm_up(cfg.operation.axial_load_n, cfg.operation.nut_velocity_rad_s)
    return runner


def _samples(rec):
    """Return the input samples of a Recording as the driver takes them."""
    return SampleColumns.of(rec.t_s, rec.nut_angle_rad, rec.nut_velocity_rad_s,
                            rec.axial_load_n)


def base_run(rec, config_path, args):
    """
    Run every sample of ``rec`` through the runner at the base config: the schedule and T(p0).

    Return (Schedule, TrialRun).  This is the replay path exactly (the runner answers each
    sample from its latest step); the trial runs feed only the stepping samples.  A
    recording the replay path predicted at the same config and schedule
    (``rec.first_pass``) has both already: its steps are the schedule and its steps' states
    answer the samples (``_base_of_first_pass``), and the model does not run over the
    recording a second time (TrialRun ``wall_s`` 0).
    """
    first = getattr(rec, "first_pass", None)
    if first is not None and first.config_path == str(config_path) \
            and tuple(first.schedule_args[:3]) == tuple(args[:3]) \
            and len(first.predictions) == len(rec) \
            and first.predictions.stepped.sum() == first.predictions.states["converged"].size:
        # (every step taken has its state: none failed after its answer)
        return _base_of_first_pass(first.predictions, args)
    t0 = time.perf_counter()
    runner = _runner(config_path, None, args)
    preds = run_samples(runner, _samples(rec), settle=False)
    at, answer = preds.steps()
    sched = Schedule(np.column_stack([preds.stamp_s[at], preds.nut_angle_rad[at],
                                      preds.nut_velocity_rad_s[at], preds.axial_load_n[at]]),
                     preds.run_start[at], answer, tuple(args))
    return sched, TrialRun(math.nan, preds.torque_total_nm, preds.torque_b2b_nm,
                           preds.converged, time.perf_counter() - t0)


def _base_of_first_pass(preds, args):
    """
    Return base_run's (Schedule, TrialRun) from the replay path's run over the recording.

    The steps are the same at any ``step_after_answer_fraction`` (it decides only whether a
    due step follows its sample's answer); with every step before its answer, as the trials
    take them, a sample is answered by the last step at or before it, under the runner's
    answer rules without terms (``ModelRunner._answer``): a sample moving against that
    step's direction gets 0 N m, not converged; a converged friction against the motion is
    cut to 0 N m.
    """
    at = np.flatnonzero(preds.stepped)
    answer = np.cumsum(preds.stepped) - 1
    st = preds.states
    total = st["torque_total_nm"][answer]
    b2b = st["torque_b2b_nm"][answer]
    conv = st["converged"][answer]
    d = np.sign(preds.nut_velocity_rad_s)
    other = (d != 0.0) & (d != st["direction"][answer])
    cut = ~other & conv & (total * d < 0.0)
    total = np.where(other | cut, 0.0, total)
    b2b = np.where(other, 0.0, b2b)
    conv = conv & ~other
    sched = Schedule(np.column_stack([preds.stamp_s[at], preds.nut_angle_rad[at],
                                      preds.nut_velocity_rad_s[at], preds.axial_load_n[at]]),
                     preds.run_start[at], answer, tuple(args))
    return sched, TrialRun(math.nan, total, b2b, conv, 0.0, first_pass=True)


def step_run(config_path, overrides, step_inputs, run_start, args):
    """
    Run the runner over the stepping samples only; return (total, b2b, converged) per step.

    Every fed sample steps (it did at the base config: the schedule depends on stamps and
    directions only); a run start resets the runner as the base run's reset did.  Top-level
    so that Dask workers can run it.
    """
    runner = _runner(config_path, overrides, args)
    preds = run_samples(runner, SampleColumns.of(*np.asarray(step_inputs, float).reshape(-1, 4).T),
                        settle=False, reset_before=run_start)
    return preds.torque_total_nm, preds.torque_b2b_nm, preds.converged


def _expand(sched, per_step):
    out = np.full(sched.answer.size, np.nan)
    ok = sched.answer >= 0
    out[ok] = per_step[sched.answer[ok]]
    return out


def _interpolate(sched, per_step, t_s):
    """
    Return a per-step quantity at every sample, linear in time between the steps.

    For the change of a coarse run: held, it lags the load and speed by up to a coarse step
    (a mu 0.13 change, held 80 ms while the load moves 70 N, is ~1 % off rms: more than the
    noise on a large change, and the change was not refined); between two steps of the
    same run and direction it is interpolated instead, an offline analysis seeing the next
    step.
    """
    out = _expand(sched, per_step)
    ok = sched.answer >= 0
    j = sched.answer[ok]
    k = len(sched.step_inputs)
    nxt = np.minimum(j + 1, k - 1)
    stamps = sched.step_inputs[:, 0]
    span = stamps[nxt] - stamps[j]
    w = np.sign(sched.step_inputs[:, 2])
    # not across a reset, nor across a reversal (the runner steps at the first sample of the
    # new direction: the friction changes sign between the two steps)
    inner = (nxt > j) & ~sched.run_start[nxt] & (span > 0.0) & (w[nxt] == w[j])
    f = np.where(inner, (t_s[ok] - stamps[j]) / np.where(inner, span, 1.0), 0.0)
    f = np.clip(f, 0.0, 1.0)
    a, b = per_step[j], per_step[nxt]
    out[ok] = np.where(inner & np.isfinite(b), a + f * (b - a), a)
    return out


class TrialRunner:
    """
    Runs the model at trial values over one recording; counts the runs and their time.

    ``workers`` > 1: the runs of a batch go to a Dask LocalCluster of that many single-threaded
    worker processes (started on first use, closed by ``close``); otherwise ``threads`` > 1
    runs them at once in threads of this process (the kernels release the GIL).
    ``coarse_factor`` > 1: the runs of smooth candidates (``PhysicalKind.smooth``) step that
    many times coarser, against a base run at the same coarse step (made on first use).
    """

    def __init__(self, rec, config_path, args, workers=1, threads=1, coarse_factor=1):
        """Make the base run (the schedule and T(p0)) over ``rec``."""
        self.config_path = str(config_path)
        self.workers = int(workers)
        self.threads = int(threads)
        self.coarse_factor = int(coarse_factor)
        self.rec = rec
        self.schedule, self.base = base_run(rec, config_path, args)
        self._coarse = None
        # the base run is a model run unless the replay path's own run was reused
        self.runs = 0 if self.base.first_pass else 1
        self.coarse_runs = 0
        self.wall_s = self.base.wall_s
        self._client = None
        self._cluster = None

    def _coarse_base(self):
        if self._coarse is None:
            args = coarse_args(self.schedule.runner_args, self.coarse_factor)
            self._coarse = base_run(self.rec, self.config_path, args)
            self.runs += 1
            self.coarse_runs += 1
            self.wall_s += self._coarse[1].wall_s
        return self._coarse

    def _dask(self):
        if self._client is None:
            # dask only when asked for (workers > 1): its import costs about a second
            from dask.distributed import Client, LocalCluster
            self._cluster = LocalCluster(n_workers=self.workers, threads_per_worker=1,
                                         processes=True, host=LOCALHOST,
                                         dashboard_address=None)
            self._client = Client(self._cluster)
        return self._client

    def is_coarse(self, kind, fine=False):
        """Tell whether a run of ``kind`` steps coarse (``fine``: at the replay step)."""
        return not fine and self.coarse_factor > 1 and kind.smooth

    def run(self, trials, fine=False):
        """
        Return a TrialRun per (PhysicalKind, value) of ``trials``: one model run each.

        A batch of more than one run goes to the Dask cluster when ``workers`` > 1, else to
        ``threads`` threads.  ``fine``: every run at the replay path's step.
        """
        trials = [(k, float(v)) for k, v in trials]
        if not trials:
            return []
        coarse = [self.is_coarse(k, fine) for k, _ in trials]
        scheds = [(self._coarse_base() if c else (self.schedule, self.base)) for c in coarse]
        t0 = time.perf_counter()
        if self.workers > 1 and len(trials) > 1:
            client = self._dask()
            sent = {}
            for sched, _ in scheds:
                if id(sched) not in sent:
                    sent[id(sched)] = (client.scatter(sched.step_inputs, broadcast=True),
                                       client.scatter(sched.run_start, broadcast=True))
            futures = [client.submit(step_run, self.config_path, k.override(v),
                                     *sent[id(sched)], sched.runner_args, pure=False)
                       for (k, v), (sched, _) in zip(trials, scheds)]
            results = client.gather(futures)
        else:
            def one(i):
                (k, v), (sched, _) = trials[i], scheds[i]
                return step_run(self.config_path, k.override(v), sched.step_inputs,
                                sched.run_start, sched.runner_args)
            if self.threads > 1 and len(trials) > 1:
                with ThreadPoolExecutor(min(self.threads, len(trials))) as pool:
                    results = list(pool.map(one, range(len(trials))))
            else:
                results = [one(i) for i in range(len(trials))]
        wall = time.perf_counter() - t0
        self.runs += len(trials)
        self.coarse_runs += sum(coarse)
        self.wall_s += wall
        out = []
        for (_, v), (sched, base), c, res in zip(trials, scheds, coarse, results):
            tot, b2b, conv = res
            total = _expand(sched, tot)
            if c:
                # the base run's per-step torque: it answered each sample from its steps
                base_step = base.total_nm[sched.first_answer]
                delta = _interpolate(sched, tot - base_step, self.rec.t_s)
            else:
                delta = total - base.total_nm
            out.append(TrialRun(v, total, _expand(sched, b2b),
                                _expand(sched, conv.astype(float)) > 0.5, wall / len(trials),
                                delta, c))
        return out

    def close(self):
        """Close the Dask cluster, if one was started."""
        if self._client is not None:
            self._client.close()
            self._cluster.close()
            self._client = self._cluster = None


def chosen(search):
    """Return the chosen PhysicalChoice of a PhysicalSearch, or None."""
    return None if search is None else search.chosen


def replay_path_total(rec, config_path, overrides, args):
    """Return the physics' torque at every sample of ``rec`` as the replay path answers it."""
    runner = _runner(config_path, overrides, args)
    return run_samples(runner, _samples(rec), settle=False).torque_total_nm


def replay_change(search, rec, ok):
    """
    Return the chosen physical change at the usable samples of ``rec`` as replay gives it.

    The trials step before they answer, so that runs at different steps compare at the same
    angles; replay and the node answer a dense input first.  The figures reported for a
    choice must be what replay and the node will do with ``augmented.yaml``: two runs of the
    replay path's schedule (the config's value and the chosen one, physics alone) give the
    change (before, the base run differed from replay on 836 of 4500 demo samples and the
    validation RMSE was reported 1.37x replay's).  Counted in ``search.replay_runs``.
    """
    choice = chosen(search)
    if choice is None:
        return np.zeros(int(np.sum(ok)))
    ctx = search.context
    args = ctx.replay_args or ctx.runner_args
    base = replay_path_total(rec, ctx.config_path, None, args)
    new = replay_path_total(rec, ctx.config_path, choice.kind.override(choice.value), args)
    search.replay_runs += 2
    return np.nan_to_num(new[ok] - base[ok])


def use_replay_change(search, rec, ok):
    """Make the chosen change (``shift_nm``) the replay path's (``replay_change``)."""
    if chosen(search) is not None:
        t0 = time.perf_counter()
        search.chosen.delta_nm = replay_change(search, rec, ok)
        search.wall_s += time.perf_counter() - t0


def validation_shift(search, rec, ok):
    """
    Return the chosen physical change of the model torque on a second recording (or 0).

    Two runs of the replay path over ``rec`` (every sample drives the model, the usable ones
    are taken): the config's values and the chosen one (``replay_change``).
    """
    if chosen(search) is None:
        return np.zeros(int(np.sum(ok)))
    runs, t0 = search.replay_runs, time.perf_counter()
    shift = replay_change(search, rec, ok)
    search.validation_runs = search.replay_runs - runs
    search.replay_runs = runs
    search.validation_wall_s = time.perf_counter() - t0
    return shift
