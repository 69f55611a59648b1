#!/usr/bin/env python3
"""
Import Maxon EPOS Studio data-recorder exports into the discrepancy workflow's CSV.

An EPOS export is a header (``Date:;...``, ``Sampling period:;...``, the channel names) and
then ``ms;rpm;%`` rows: "Velocity actual value averaged" [rpm] and "Torque actual value
averaged" [% of the motor's nominal torque, from the current].  This is the format of the
RViMLab screw-drive recordings (A. Mablekos-Alexiou, L. da Cruz, C. Bergeles, "Friction-
Inclusive Modeling of Sliding Contact Transmission Systems in Robotics", IEEE T-RO 37(4),
1252-1267, 2021; MIT licence) in ``../shared/realdata/rvim_screw_drives/raw/``.

Output (the workflow's CSV, SI): ``t_s, nut_angle_rad, nut_velocity_rad_s, axial_load_n,
torque_meas_nm, torque_pred_nm``.
- There is no model of such a drive, so ``torque_pred_nm`` is 0: the workflow then identifies
  every term from the data (as ``--baseline zero``).
- There is no position channel: the angle is the velocity integrated (trapezoid) from 0 at
  the start of each file.  Where the runs were on the stroke is unknown.
- Each file is one run: its ``t_s`` starts at 0 again, which the workflow reads as a new run
  (its acceleration filter restarts; no filtering across files).
- Sign and scale follow the authors' ``getEposData.m``: velocity = -rpm pi/30 [rad/s],
  torque = -% nominal/100 [N m] (``--raw-sign`` keeps the recorder's sign).
- Rows that are not three numbers (the hand-edited first rows of three driveNo3 files, e.g.
  ``-1200,,was -8.9``) are skipped and reported on stderr.

This is an edge adapter, not part of the package core.

    python tools/import_epos.py FILE.csv [FILE.csv ...] --out drive.csv \
        [--nominal-torque-nm 9.84e-3] [--axial-load-n 0.942] [--raw-sign]
    python tools/import_epos.py --rvim DRIVE_DIR --out-dir DIR    # fit.csv and validate.csv
"""

import argparse
import csv
import math
import os
from pathlib import Path
import sys

import numpy as np

from bb_friction_ros.config import BBFrictionError

# Motor of the RViMLab rigs (README of the data): nominal torque 9.84 mN m.
RVIM_NOMINAL_TORQUE_NM = 9.84e-3
COLUMNS = ("t_s", "nut_angle_rad", "nut_velocity_rad_s", "axial_load_n", "torque_meas_nm",
           "torque_pred_nm")


class EposFormatError(BBFrictionError):
    """The file is not an EPOS data-recorder export."""


def read_epos(path):
    """
    Return (t_s, velocity_rpm, torque_pct, skipped_lines) of one EPOS export, raw units.

    ``skipped_lines`` lists (line number, text) of data rows that are not three numbers.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig", errors="strict")
    except (OSError, UnicodeDecodeError) as exc:
        raise EposFormatError(f"{path}: cannot read ({exc})") from None
    lines = text.splitlines()
    start = next((i for i, line in enumerate(lines)
                  if line.split(";")[0].strip().rstrip(",") == "ms"), None)
    if start is None:
        raise EposFormatError(f"{path}: no 'ms;rpm;%' units row: not an EPOS data-recorder "
                              "export")
    names = lines[start - 1].split(";") if start else []
    if not any("Velocity" in n for n in names) or not any("Torque" in n for n in names):
        raise EposFormatError(f"{path}: channels {names[1:]} are not velocity and torque")
    t, w, q, skipped = [], [], [], []
    for k, line in enumerate(lines[start + 1:], start=start + 2):
        fields = line.rstrip().rstrip(",").split(";")
        try:
            a, b, c = (float(f) for f in fields)
        except ValueError:
            if line.strip(" ,;"):
                skipped.append((k, line.strip()))
            continue
        if not all(math.isfinite(v) for v in (a, b, c)):
            skipped.append((k, line.strip()))
            continue
        t.append(a * 1e-3)
        w.append(b)
        q.append(c)
    if len(t) < 2:
        raise EposFormatError(f"{path}: fewer than 2 data rows")
    return np.array(t), np.array(w), np.array(q), skipped


def positive_finite(text):
    """argparse type: a finite number > 0 (a nominal torque: <= 0 would flip or zero the sign)."""
    value = float(text)
    if not (math.isfinite(value) and value > 0.0):
        raise argparse.ArgumentTypeError(f"must be a finite number > 0, got {text!r}")
    return value


def finite(text):
    """argparse type: a finite number (NaN or inf would poison every row of the CSV)."""
    value = float(text)
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be a finite number, got {text!r}")
    return value


def to_si(t_s, rpm, pct, nominal_torque_nm=RVIM_NOMINAL_TORQUE_NM, raw_sign=False,
          axial_load_n=0.0):
    """
    Return the workflow's columns (dict of arrays) of one run.

    Raises ValueError naming the argument if ``nominal_torque_nm`` is not finite and > 0
    (a negative value would flip the torque's sign silently) or ``axial_load_n`` is not finite.
    """
    if not (math.isfinite(nominal_torque_nm) and nominal_torque_nm > 0.0):
        raise ValueError(f"nominal_torque_nm must be a finite number > 0, got {nominal_torque_nm}")
    if not math.isfinite(axial_load_n):
        raise ValueError(f"axial_load_n must be a finite number, got {axial_load_n}")
    sign = 1.0 if raw_sign else -1.0
    w = sign * rpm * math.pi / 30.0
    torque = sign * pct * nominal_torque_nm / 100.0
    t = t_s - t_s[0]
    angle = np.concatenate(([0.0], np.cumsum(0.5 * (w[1:] + w[:-1]) * np.diff(t))))
    return {"t_s": t, "nut_angle_rad": angle, "nut_velocity_rad_s": w,
            "axial_load_n": np.full(t.size, float(axial_load_n)), "torque_meas_nm": torque,
            "torque_pred_nm": np.zeros(t.size)}


def write_csv(path, runs):
    """Write runs (dicts of arrays, in order) as one CSV; return the number of rows."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    n = 0
    with path.open("w", newline="") as fh:
        out = csv.writer(fh)
        out.writerow(COLUMNS)
        for run in runs:
            for row in zip(*(run[c] for c in COLUMNS)):
                out.writerow(f"{v:.10g}" for v in row)
                n += 1
    return n


def import_files(paths, out, nominal_torque_nm=RVIM_NOMINAL_TORQUE_NM, raw_sign=False,
                 axial_load_n=0.0, log=sys.stderr):
    """Import EPOS files, one run each, into CSV ``out``; return the number of rows."""
    runs = []
    for p in paths:
        t, w, q, skipped = read_epos(p)
        for line, text in skipped:
            print(f"{p}:{line}: skipped (not three numbers): {text}", file=log)
        runs.append(to_si(t, w, q, nominal_torque_nm, raw_sign, axial_load_n))
    return write_csv(out, runs)


# --- the RViMLab recordings: which runs are fitted, which validate ------------------------

# The drives' axial load on the nut from the 0.096 kg payload (README of the data): 0.942 N
# on the lead screws; the worm drive (driveNo3) lifts it on a pulley, not along its axis.
RVIM_AXIAL_LOAD_N = {"driveNo1": 0.942, "driveNo2": 0.942, "driveNo3": 0.0}


def _signed_rpm(path):
    name = Path(path).stem
    return -float(name[1:]) if name.startswith("n") else float(name)


def _spread_order(n):
    """Indices 0..n-1 in van der Corput order: every tail of the list spans the range."""
    def radical_inverse(i):
        x, f = 0.0, 0.5
        while i:
            x += f * (i & 1)
            i >>= 1
            f *= 0.5
        return x
    return sorted(range(n), key=lambda i: radical_inverse(i))


def rvim_split(drive_dir):
    """
    Return (fit files, validation files) of one RViMLab drive directory.

    Steady-state runs sorted by signed speed alternate between the two sets, so both span
    1-200 rpm in both directions; of the two start-stop runs, the slower one is fitted and
    the faster one validates.  The fit list starts with its start-stop run (the held-out
    last 30 % of the fit recording is then steady-state) and orders the steady runs so that
    every tail spans the speeds (the held-out part sees the regimes the fit saw).
    """
    drive_dir = Path(drive_dir)
    steady = sorted((drive_dir / "steady_state").glob("*/*.csv"), key=_signed_rpm)
    starts = sorted((drive_dir / "start_stop").glob("*.csv"), key=_signed_rpm)
    if not steady or len(starts) < 2:
        raise FileNotFoundError(f"{drive_dir}: expected steady_state/*/*.csv and two "
                                "start_stop/*.csv")
    fit_steady, val_steady = steady[0::2], steady[1::2]
    fit = [starts[0]] + [fit_steady[i] for i in _spread_order(len(fit_steady))]
    val = [starts[-1]] + val_steady
    return fit, val


def import_rvim(drive_dir, out_dir, log=sys.stderr):
    """Write ``fit.csv`` and ``validate.csv`` of one RViMLab drive; return their paths."""
    drive_dir = Path(drive_dir)
    fit, val = rvim_split(drive_dir)
    load = RVIM_AXIAL_LOAD_N.get(drive_dir.name, 0.0)
    out_dir = Path(out_dir)
    paths = out_dir / "fit.csv", out_dir / "validate.csv"
    import_files(fit, paths[0], axial_load_n=load, log=log)
    import_files(val, paths[1], axial_load_n=load, log=log)
    return paths


REALDATA_ENV = "BB_FRICTION_REALDATA"
REPO_ROOT = Path(__file__).resolve().parent.parent


def find_realdata(repo_root=REPO_ROOT):
    """
    Return the directory of the measured recordings, or (None, reason).

    Looked up in order: ``$BB_FRICTION_REALDATA``; ``../shared/realdata`` next to the
    repository; for a git worktree, ``../shared/realdata`` next to its main checkout.
    Return (path, "") when found.
    """
    tried = []
    env = os.environ.get(REALDATA_ENV)
    candidates = [Path(env)] if env else []
    candidates.append(repo_root.parent / "shared" / "realdata")
    git = repo_root / ".git"
    if git.is_file():      # a worktree: ".git" says "gitdir: <main>/.git/worktrees/<name>"
        text = git.read_text().strip()
        if text.startswith("gitdir:"):
            main = Path(text.split(":", 1)[1].strip()).parent.parent.parent
            candidates.append(main.parent / "shared" / "realdata")
    for c in candidates:
        if (c / "rvim_screw_drives").is_dir():
            return c, ""
        tried.append(str(c))
    return None, (f"measured recordings not found (set ${REALDATA_ENV}; tried "
                  f"{', '.join(tried)})")


def main(argv=None):
    """Command line: see the module docstring."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument("files", nargs="*", help="EPOS data-recorder exports (.csv)")
    ap.add_argument("--out", help="output CSV (with FILES)")
    ap.add_argument("--rvim", metavar="DRIVE_DIR", help="an RViMLab drive directory "
                    "(raw/experiments/driveNoN): writes fit.csv and validate.csv to --out-dir")
    ap.add_argument("--out-dir", help="output directory (with --rvim)")
    ap.add_argument("--nominal-torque-nm", type=positive_finite, default=RVIM_NOMINAL_TORQUE_NM,
                    help="motor nominal torque [N m] (100 %% of the torque channel)")
    ap.add_argument("--axial-load-n", type=finite, default=0.0,
                    help="constant axial load written to axial_load_n [N]")
    ap.add_argument("--raw-sign", action="store_true",
                    help="keep the recorder's sign (default: the authors' convention, negated)")
    args = ap.parse_args(argv)
    try:
        if args.rvim:
            if not args.out_dir:
                ap.error("--rvim needs --out-dir")
            for p in import_rvim(args.rvim, args.out_dir):
                print(p)
            return 0
        if not args.files or not args.out:
            ap.error("give EPOS FILES and --out, or --rvim DRIVE_DIR --out-dir DIR")
        n = import_files(args.files, args.out, args.nominal_torque_nm, args.raw_sign,
                         args.axial_load_n)
    except (EposFormatError, FileNotFoundError) as exc:
        print(f"import_epos: {exc}", file=sys.stderr)
        return 2
    print(f"{n} rows -> {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
