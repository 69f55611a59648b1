"""
Diagnose the mu / load_dependent ties of ``bench_discrepancy.py --physical``.

Reruns the bench's cases of one seed (the same draws, in the same order) and prints, per
case, what was named, ``physical.notes`` (a tie's fit-part and held-out gaps) and, where mu
is named, the evidence of its change beside the load_dependent column (E = |M d|^2 /
sigma^2 tau, fit and held-out part), both readings' held-out RMS and the change's shape: its
least-squares fit by (a + b |W|) sign w and what is left, per direction.

Run: .venv/bin/python bench/diag_physical_ties.py SEED PHYSICAL_CASES EMPIRICAL_CASES
     [EFFECT|-] [INDICES]   (INDICES: comma-separated, from 0, in the bench's order)
e.g. ... 101 0 12 load_dependent 1,8,9
"""
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import bench_discrepancy as bd  # noqa: E402
from bb_friction_ros.discrepancy import physical as ph  # noqa: E402
from bb_friction_ros.discrepancy.data import inputs_of  # noqa: E402
from bb_friction_ros.discrepancy.selection import candidates  # noqa: E402
from bb_friction_ros.discrepancy.settings import DiscrepancySettings  # noqa: E402
from bb_friction_ros.discrepancy.workflow import analyse  # noqa: E402
from bb_friction_ros.node_parameters import NodeParameters  # noqa: E402


def proj_out(cols, v):
    if not cols:
        return v
    a = np.column_stack(cols)
    coef, *_ = np.linalg.lstsq(a, v, rcond=None)
    return v - a @ coef


def main(seed, physical_cases, empirical_cases, effect=None, only=None):
    cache = os.path.join(bd.cache_dir(), "physical")
    settings = DiscrepancySettings()
    runner = ph.runner_args(NodeParameters(model_rate_hz=50.0))
    rng = np.random.default_rng(seed)
    kinds = [k for k in ph.PHYSICAL for _ in range(physical_cases)] + [None] * empirical_cases
    for i, kind in enumerate(kinds):
        rec, cfg, noise, hidden, terms = bd.physical_case_of(
            kind, rng, cache, False, (effect,) if effect else bd.PHYSICAL_EXTRA_EFFECTS)
        if only is not None and i not in only:
            continue
        t0 = time.perf_counter()
        a = analyse(rec, settings, ph.PhysicsContext(cfg, runner, ph.PhysicalSettings(
            enabled=True)))
        c = ph.chosen(a.physical)
        line = (f"[{i}] hidden {kind} {hidden} + {terms.names} "
                f"{[t.params for t in terms.terms]}; noise {np.std(noise)*1e3:.2f}; named "
                f"{c.kind.name if c else '-'} {c.value if c else ''} + {a.terms.names}; "
                f"tie {a.physical.tie}; tau {a.noise.tau:.2f} sigma {a.noise.std_nm*1e3:.2f}"
                f" ({time.perf_counter() - t0:.1f} s)")
        print(line, flush=True)
        print("    notes:", a.physical.notes, flush=True)
        if c is None or c.kind.name != "friction_coefficient":
            continue
        r = a.residual_nm
        fm = a.fit_mask
        x = inputs_of(a.recording)
        cands = {cc.name: cc for cc in candidates(inputs_of(a.recording, fm), settings)}
        ld = cands["load_dependent"].columns(x, None)[:, 0]
        d = c.delta_nm
        s2 = a.noise.std_nm ** 2 * max(a.noise.tau, 1.0)
        ef = float(np.sum(proj_out([ld[fm]], d[fm]) ** 2)) / s2
        eh = float(np.sum(proj_out([ld[~fm]], d[~fm]) ** 2)) / s2
        # the twin reading fitted on the fit part
        k, *_ = np.linalg.lstsq(ld[fm, None], r[fm], rcond=None)
        e_ld = r - ld * k[0]
        e_mu = r - d
        rms = lambda v: float(np.sqrt(np.mean(v ** 2)))  # noqa: E731
        print(f"    E_sep fit {ef:.1f} hold {eh:.1f}; fit RSS/s2 ld {np.sum(e_ld[fm]**2)/s2:.1f} "
              f"mu {np.sum(e_mu[fm]**2)/s2:.1f}; hold rms ld {rms(e_ld[~fm])*1e3:.4f} "
              f"mu {rms(e_mu[~fm])*1e3:.4f} before {rms(r[~fm])*1e3:.4f}; k {k[0]:.3g}; "
              f"notes {a.physical.notes}", flush=True)
        # the shape of d: affine fit on the load per direction
        w = a.recording.nut_velocity_rad_s
        W = a.recording.axial_load_n
        sg = np.sign(w)
        cols = [sg, np.abs(W) * sg]
        A = np.column_stack(cols)
        coef, *_ = np.linalg.lstsq(A, d, rcond=None)
        res = d - A @ coef
        print(f"    d rms {rms(d)*1e3:.3f} mN m; affine in load: offset {coef[0]*1e3:.3f} mN m"
              f", slope {coef[1]:.3g}; left {rms(res)*1e3:.4f} mN m; per direction: "
              + ", ".join(f"{s:+d}: {rms(res[sg == s])*1e3:.4f}" for s in (1, -1)),
              flush=True)


if __name__ == "__main__":
    seed = int(sys.argv[1])
    pc, ec = int(sys.argv[2]), int(sys.argv[3])
    eff = sys.argv[4] if len(sys.argv) > 4 and sys.argv[4] != "-" else None
    only = set(int(v) for v in sys.argv[5].split(",")) if len(sys.argv) > 5 else None
    main(seed, pc, ec, eff, only)
