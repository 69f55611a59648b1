"""
Write docs/reference/settings.md: every setting of every file and of the node, from the code.

Each setting is a ``config.field`` with its default, unit, admissible range and meaning; this
script prints them as tables, so the reference is the code's own and cannot drift from it.
``test/test_docs.py`` fails when the file is not what this script writes now.

    .venv/bin/python tools/gen_reference.py           # rewrite the file
    .venv/bin/python tools/gen_reference.py --check   # exit 1 when it is out of date
"""

import argparse
import dataclasses
import math
import pathlib
import sys

ROOT = pathlib.Path(__file__).resolve().parent.parent
OUT = ROOT / "docs" / "reference" / "settings.md"
CLI_OUT = ROOT / "docs" / "reference" / "cli.md"

# YAML keys a user may write in an edge unit instead of the SI field (config.EDGE_UNITS)
EDGE = {"rad": ("deg", 180.0 / math.pi), "m": ("mm", 1e3), "m/s": ("mm/s", 1e3)}


def _number(value):
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if value == 0.0:
            return "0"
        return f"{value:.6g}"
    if value is None:
        return "none"
    if isinstance(value, str):
        return f"`{value}`" if value else "empty"
    return f"`{value!r}`"


def _default(f):
    value = f.default
    if value is dataclasses.MISSING:
        return "required"
    unit = (f.metadata or {}).get("unit")
    text = _number(value)
    if unit in EDGE and isinstance(value, float) and value != 0.0:
        edge, factor = EDGE[unit]
        text += f" ({value * factor:.6g} {edge})"
    return text


def _range(meta):
    lo, hi = meta.get("lo"), meta.get("hi")
    if lo is None and hi is None:
        return ""
    left = "(" if meta.get("lo_open") or lo is None else "["
    right = ")" if meta.get("hi_open") or hi is None else "]"
    lo_s = "-inf" if lo is None else _number(lo)
    hi_s = "inf" if hi is None else _number(hi)
    return f"{left}{lo_s}, {hi_s}{right}"


# Meanings of the choice fields that carry no ``config.field`` metadata
CHOICE_DOCS = {
    "load_distribution": "how the axial load is shared by the balls: a rigid nut and shaft "
                         "(one axial displacement for all balls) or elastic bars between "
                         "the balls (explanation: assumptions_ball_screw.md)",
    "elastic.shaft_load_end": "the end of the loaded track where the axial load enters the "
                              "shaft",
    "elastic.nut_support": "how the nut is held: on its outer surface (it does not stretch "
                           "between balls), or by a flange at one end of the track",
    "contact_force_model": "contact loads from rigid statics with the deviated angles, or "
                           "the paper's diagonal approximation",
    "physical.enabled": "try the model's own parameters (theta amplitude, friction "
                        "coefficient, preload) as candidates beside the empirical terms "
                        "whenever a model of the screw is in use "
                        "(false: the same as --no-physical)",
    "physical.prefer_model_parameter_on_tie": "keep the model's parameter when its reading "
                                              "takes its empirical twin's place one for one "
                                              "within bic_threshold (a tie); false: the "
                                              "better score decides",
    "friction_update": "the plant's friction model answered at every integration sub-step, "
                       "or once per servo sample",
    "ball_state": "the balls as assembled (`fresh`: evenly spaced), or after a run-in "
                  "(`run_in`)",
    "speed_fractions": "calibration speeds as fractions of the test's largest speed, "
                       "separated by spaces, each in (0, 2]",
    "kind": "the reference generated (servo/reference.py)",
    "directions": "the directions of the moves",
    "load_factors": "axial loads the mean is tabulated at, as multiples of the model's "
                    "operating load",
    "segments_rev_s": "the speed segments of the demo motion, in rev/s (signed)",
    "nut_joint": "joint name of the nut in nut_state",
}


def _rows(cls, prefix="", choices=None):
    """Yield table rows (key, default, unit, range, meaning) of a config dataclass."""
    choices = choices or {}
    for f in dataclasses.fields(cls):
        if f.name.startswith("_"):
            continue
        meta = f.metadata or {}
        nested = None
        if f.default_factory is not dataclasses.MISSING:
            value = f.default_factory()
            nested = type(value) if dataclasses.is_dataclass(value) else None
        if nested is not None:
            yield from _rows(nested, f"{prefix}{f.name}.", choices)
            continue
        key = f"{prefix}{f.name}"
        doc = meta.get("doc", "") or CHOICE_DOCS.get(key, "")
        if key in choices:
            doc = (doc + "; " if doc else "") + "one of " + ", ".join(
                f"`{c}`" for c in choices[key])
        unit = meta.get("unit")
        unit = "" if unit in (None, "1") else unit
        yield key, _default(f), unit, _range(meta), doc


def _table(rows):
    out = ["| key | default | unit | range | meaning |", "|---|---|---|---|---|"]
    for key, default, unit, rng, doc in rows:
        doc = doc.replace("|", "\\|")
        out.append(f"| `{key}` | {default} | {unit} | {rng} | {doc} |")
    return "\n".join(out)


def _terms():
    from bb_friction_ros.empirical_terms import LIBRARY
    parts = []
    for name, kind in LIBRARY.items():
        rows = list(_rows(kind.params_cls))
        fixed = getattr(kind, "fixed", ()) or ()
        text = [f"### `{name}`", "", kind.meaning[0].upper() + kind.meaning[1:] + "."]
        if fixed:
            names = ", ".join(f"`{k}`" for k in fixed)
            text.append(f"Fixed by the analysis, not fitted: {names}.")
        text += ["", _table(rows), ""]
        parts.append("\n".join(text))
    return "\n".join(parts)


def render():
    """Return the text of docs/reference/settings.md."""
    sys.path.insert(0, str(ROOT))
    from bb_friction_ros.ball_screw.arrangement import ArrangementAverage
    from bb_friction_ros.ball_screw.parameters import BallScrewConfig
    from bb_friction_ros.config import LinearBearingConfig
    from bb_friction_ros.discrepancy.settings import DiscrepancySettings
    from bb_friction_ros.node_parameters import (B2B_FEEDFORWARDS, FIELDS, MODEL_PARAMETERS,
                                                 NodeParameters, RUNTIME)
    from bb_friction_ros.planned import PlannedSettings
    from bb_friction_ros.servo.reference import KINDS, ReferenceSpec
    from bb_friction_ros.servo.settings import (BALL_STATES, CalibrationSettings,
                                                FRICTION_UPDATES, LoopSettings,
                                                ModelSettings, PlantSettings)
    from bb_friction_ros.trajectories import DemoRecording

    screw_choices = {"load_distribution": ("rigid", "elastic"),
                     "elastic.shaft_load_end": ("track_start", "track_end"),
                     "elastic.nut_support": ("outer_surface", "flange_at_track_start",
                                             "flange_at_track_end")}
    b2b = {"b2b_feedforward": B2B_FEEDFORWARDS}
    fixed_params = [n for n in FIELDS if n not in RUNTIME]
    reference = {"kind": KINDS, "directions": ("ccw", "cw", "both")}
    servo = {"friction_update": FRICTION_UPDATES, "ball_state": BALL_STATES}
    sections = [
        ("The model file: `ball_screw:`",
         "The model file (`config/ball_screw.yaml`, `augmented.yaml`, the node's "
         "`config_file`, `--config` of replay, discrepancy, feedforward and servo-test). "
         "Keys are SI; a key ending `_rad` may be written `_deg`, `_m` as `_mm` or `_um`, "
         "`_m_s` as `_mm_s` (the default is also shown in that unit). The file may also hold "
         "`empirical_terms:` (below) and `physics: ball_screw | none` (`none`: the terms "
         "alone, written by `discrepancy --baseline zero`).",
         list(_rows(BallScrewConfig, choices=screw_choices))),
        ("The node: `friction_node: ros__parameters:`",
         "ROS parameters of `friction_node` (`config/friction_node.yaml`, "
         "`bb-friction node --params-file`). Types are ROS's: a double refuses `100`, an "
         "integer refuses `256.0`. Changeable while the node runs: all but "
         + ", ".join(f"`{n}`" for n in fixed_params) + "; a change of "
         + ", ".join(f"`{n}`" for n in sorted(MODEL_PARAMETERS))
         + " rebuilds the model. `replay --params-file` reads the same file.",
         list(_rows(NodeParameters, choices=b2b))),
        ("Discrepancy workflow: `discrepancy:` (`--settings FILE`)",
         "Thresholds and grids of `bb-friction discrepancy`; `physical.*` are the model's "
         "own parameters as candidates (`--physical`).",
         list(_rows(DiscrepancySettings))),
        ("Feedforward along a plan: `feedforward:` (`bb-friction feedforward --settings`)",
         "", list(_rows(PlannedSettings, choices=b2b))),
        ("Servo test, `loop:` (LOOP.yaml)", "The servo test and its figures: "
         "[../servo_test.md](../servo_test.md).",
         list(_rows(LoopSettings))),
        ("Servo test, `plant:`", "", list(_rows(PlantSettings, choices=servo))),
        ("Servo test, `model:`", "", list(_rows(ModelSettings, choices={**b2b, **servo}))),
        ("Servo test, `calibration:`", "", list(_rows(CalibrationSettings))),
        ("Servo test reference spec", "The moves of `servo-test --reference`.",
         list(_rows(ReferenceSpec, choices=reference))),
        ("Arrangement average (the `averaged` B2B feedforward)",
         "How the mean B2B torque over the balls' arrangements is taken "
         "(`ball_screw/arrangement.py`).", list(_rows(ArrangementAverage))),
        ("Linear bearing: `linear_bearing:` (`bb-friction linear --config`)",
         "", list(_rows(LinearBearingConfig,
                        choices={"contact_force_model": ("rigid", "diagonal")}))),
        ("Demo recording (`bb-friction make-demo-bag`)", "", list(_rows(DemoRecording))),
    ]
    out = ["<!-- Written by tools/gen_reference.py from the code; do not edit by hand. -->",
           "", "# Settings reference", "",
           "Every setting of the package: its key, default, unit, admissible range and "
           "meaning, as the code declares them (`config.field`). A value outside its range, "
           "an unknown key or a wrong type is refused with the dotted key named "
           "(exit status 2; a bad node parameter refuses the start). Ranges: `[` closed, "
           "`(` open.", ""]
    for title, intro, rows in sections:
        out += [f"## {title}", ""]
        if intro:
            out += [intro, ""]
        out += [_table(rows), ""]
    out += ["## Empirical terms: `empirical_terms:`", "",
            "A list in the model file, each `{name: NAME, params: {KEY: value}}`, as "
            "`bb-friction discrepancy` writes it (`augmented.yaml`). Keys are SI; edge units "
            "as above (`sin1_um` for `sin1_m`). What each term means physically: "
            "[../discrepancy.md](../discrepancy.md), \"The term library\".", "",
            _terms()]
    return "\n".join(out).rstrip() + "\n"


def _cli_rows(parser):
    import argparse
    out = ["| argument | default | meaning |", "|---|---|---|"]
    for a in parser._actions:
        if isinstance(a, argparse._HelpAction):
            continue
        name = ", ".join(a.option_strings) or (a.metavar or a.dest)
        if a.option_strings and a.nargs != 0:
            name += " " + (a.metavar or a.dest.upper())
        if a.nargs in ("+", "*"):
            name += " ..."
        shown = a.option_strings and a.default is not None and a.default is not False
        default = _number(a.default) if shown else ""
        text = (a.help or "").replace("%%", "%").replace("%(default)g", _number(a.default))
        if a.choices:
            text = (text + "; " if text else "") + "one of " + ", ".join(
                f"`{c}`" for c in a.choices)
        if not a.option_strings:
            text = "(required) " + text
        elif a.required:
            text = "(required) " + text
        out.append(f"| `{name}` | {default} | {text.replace('|', '/')} |")
    return "\n".join(out)


def render_cli():
    """Return the text of docs/reference/cli.md: every command, argument and default."""
    import argparse
    sys.path.insert(0, str(ROOT))
    from bb_friction_ros.cli import build_parser
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    helps = {c.dest: c.help for c in sub._choices_actions}
    out = ["<!-- Written by tools/gen_reference.py from the code; do not edit by hand. -->",
           "", "# Command-line reference: `bb-friction`", "",
           "Every sub-command with its arguments and defaults, as `bb-friction COMMAND "
           "--help` prints them. `friction_node` (the console script) is `bb-friction "
           "node`.", "",
           "Exit status, every command: 0 done; 2 bad input (a file, flag, recording or "
           "value, named in the message; nothing is lost: [../bad_input.md]"
           "(../bad_input.md)); 130 interrupted (Ctrl-C); 1 with a traceback is a bug. "
           "Besides:", "",
           "| command | status | meaning |", "|---|---|---|",
           "| `linear` | 3 | the solve did not converge (`converged: false`) |",
           "| `screw-pair`, `screw-sim` | 1 | a solve did not converge |",
           "| `feedforward` | 1 | a row's model step did not converge (`nonconverged_rows`) |",
           "| `screw-verdict` | 1 | the nominal build fails the verdict |",
           "| `demo` | 1 | the live node published no prediction |",
           "| `sweep`, `screw-verdict` | 3 | incomplete (`--max-samples` reached or a task "
           "failed; rerun to resume) |",
           "| `discrepancy` | 2 | also: the recording is too short or too flat to tell "
           "(`verdict: none` with `reason` and `missing`) |",
           ""]
    for name, p in sub.choices.items():
        out += [f"## `bb-friction {name}`", ""]
        if helps.get(name):
            out += [helps[name][0].upper() + helps[name][1:] + ".", ""]
        out += [_cli_rows(p), ""]
    return "\n".join(out).rstrip() + "\n"


def main(argv=None):
    """Write the reference, or with ``--check`` say whether it is current."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    p.add_argument("--check", action="store_true", help="exit 1 if the file is out of date")
    args = p.parse_args(argv)
    status = 0
    for path, text in ((OUT, render()), (CLI_OUT, render_cli())):
        if args.check:
            current = path.read_text() if path.exists() else ""
            if current != text:
                print(f"{path.relative_to(ROOT)} is out of date: run tools/gen_reference.py")
                status = 1
            continue
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
        print(f"wrote {path.relative_to(ROOT)}")
    return status


if __name__ == "__main__":
    sys.exit(main())
