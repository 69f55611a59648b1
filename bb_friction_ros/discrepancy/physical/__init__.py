"""
Physical candidates of the discrepancy selection: the model's own parameters.

When a real screw disagrees with the model, the paper's own parameters are the first
suspects: the contact-angle deviation theta of the grooves (it drives ball-to-ball contact),
the friction coefficient mu and the preload (ball oversize).  Each is a candidate beside the
empirical library:

- ``contact_angle_deviation``: ``errors.theta_amplitude_deg`` (cycles per revolution and
  phase are kept from the config: a recording of a few revolutions rarely pins them down);
- ``friction_coefficient``: ``material.friction_coefficient``;
- ``preload``: ``geometry.ball_oversize_um``.

A trial value is a model run over the recording: the replay path's ``ModelRunner`` around a
``WholeScrew`` of the base config with the one value changed.  Its column is the change of
the physics torque, d(p) = T(p) - T(p0), with coefficient 1 (not a free amplitude: the
parameter itself is what is fitted).  The physical candidate then competes with the empirical
terms under the same BIC and cross-validation: at a candidate's best value the empirical
best-subset selection runs on r - d(p), and the physical parameter counts as one more
parameter (and one more ``bic_threshold``) in the penalised BIC.  "None" is a valid answer,
and empirical terms may be fitted on top of the physical change.  Between trials only the
model column changes, so a trial is scored by its profile (the RSS of r - d(p) with the
empirical terms held, by projection), and the selection runs once per candidate refined,
not once per trial (``search.PhysicalSelection``).

Cost (each trial is a model run): the runs only visit the samples at which the runner steps
the model (``ModelRunner`` steps on a schedule of input stamps and direction changes that
does not depend on the parameters; every other sample holds the last step's torque), so a
trial costs the model's steps, not the recording's samples.  The schedule comes from one full
run of the base config through the runner (also the reference T(p0)).  The smooth
candidates (mu, preload) search at a ``coarse_step_factor`` times coarser step, their change
interpolated between the coarse steps; the winner is run again at the replay step.  A coarse
bracket per candidate (``PhysicalSettings``) runs first, its runs in ``threads`` threads (the
kernels release the GIL) or on a Dask LocalCluster when ``workers`` > 1; a candidate
whose bracket change, at its best scale, could beat "none" is refined (``_next_value``: the
fitted scale of a run's change says how large the change should be, and the value giving
that size is interpolated between the runs: robust at the B2B contact's onset, where a
parabola through the RSS is not), a model run per step, at most
``refine_runs``; the 95 % interval is read from the profile's parabola, where n' ln(RSS/n)
rises by 3.84 (chi-square, one parameter).

Identifiability, said out loud (``identifiability``): a change of mu scales the whole model
torque, which is nearly the ``load_dependent`` column (k |W| sign w) when the torque is
nearly proportional to the load; an angle ripple can mimic part of a B2B signature.  After
the choice the twin is swapped in and refitted; a BIC difference below ``bic_threshold``
names the pair as one ambiguous effect (the model's own parameter is kept: it is the
physical reading, and the one the node can run).  The twin may also be there beside the
change: the chosen value's reading with the twin held is followed too
(``PhysicalDecision.with_twin``), and two readings within ``bic_threshold`` make the value
itself ambiguous (both reported, the interval covering both).

The modules by purpose: ``trials`` (the candidates and the model runs at trial values),
``profile`` (scoring a trial, the next value, the interval), ``search`` (bracket and refine,
and the workflow's hooks), ``choice`` (the verdict), ``identifiability`` (twins and ties),
``results`` (the named results), ``report`` (the calibrated config, summary.json,
report.md and the B2B share figure).
"""

from bb_friction_ros.discrepancy.physical.identifiability import (  # noqa: F401
    _cv_judges, _heldout_gap, _other_parameters, _tie, _unchosen_twins, identifiability)
from bb_friction_ros.discrepancy.physical.report import (  # noqa: F401
    B2B_FIGURE, b2b_share, calibrated_section, effects, meaning, names, plot_b2b_share,
    report_lines, SHARE_MIN_TORQUE_FRACTION, statement, summary)
from bb_friction_ros.discrepancy.physical.choice import PhysicalDecision  # noqa: F401
from bb_friction_ros.discrepancy.physical.results import (  # noqa: F401
    Outcome, PhysicalChoice, PhysicalSearch, PhysicsContext)
from bb_friction_ros.discrepancy.physical.search import (  # noqa: F401
    PhysicalSelection, reject, select, select_with_physics, shift_nm, unseen_on_hold)
from bb_friction_ros.discrepancy.physical.trials import (  # noqa: F401
    base_run, CHI2_1_95, chosen, coarse_args, load_physical_settings, PHYSICAL, PhysicalKind,
    PhysicalSettings, replay_change, replay_path_total, runner_args, Schedule, step_run,
    TrialRun, TrialRunner, TWINS, use_replay_change, validation_shift)
