"""
The health of the live schedule, as diagnostic_updater's ``FrequencyStatus`` would judge it.

ERROR when no nut_state arrived for ``input_timeout_s``; WARN when the model stepped less
often than its configured floor allows (``model_rate_tolerance``), took coarser steps, shed,
skipped, rejected or dropped inputs; OK otherwise.  ``LiveHealth`` is the diagnostics side
of ``live.LiveSchedule``: it reads the schedule's counters, the runner's statistics and the
status window under the schedule's lock.
"""

import math

# Levels of diagnostic_msgs/DiagnosticStatus (bytes there; plain ints here, no ROS).
OK, WARN, ERROR = 0, 1, 2


class LiveHealth:
    """Diagnostics of a ``live.LiveSchedule``: counters, status and the warnings it logs."""

    def _window_start(self, now):
        stats = self._runner.stats
        return {"t": now, "steps": stats.model_steps, "shed": getattr(self, "_shed", 0),
                "stalls": stats.stamp_stalls, "coarse": stats.coarse_steps,
                "skipped": stats.skipped_steps, "resets": stats.resets, "first_stamp": None,
                "last_stamp": None, "accepted": 0}

    def values(self, advance=True):
        """Return the counters as diagnostics key/values; ``advance`` starts a new window."""
        with self._lock:
            return self._values(advance)

    def _values(self, advance):
        stats = self._runner.stats
        now = self._monotonic()
        w = self._window
        elapsed = max(now - w["t"], 1e-9)
        latest = self._latest
        values = {
            "ready": self.ready,
            "model_rate_hz": (stats.model_steps - w["steps"]) / elapsed,
            "model_steps": stats.model_steps,
            "last_step_s": stats.last_step_wall_s,
            "nonconverged_steps": stats.nonconverged_steps,
            "feedforward_held": self._ff_held,
            "feedforward_zeroed": stats.feedforward_zeroed,
            "model_step_deg": math.degrees(self._runner.model_step_rad),
            "coarse_steps": stats.coarse_steps,
            "stamp_stalls": stats.stamp_stalls,
            "term_restarts": stats.term_restarts,
            "queue_length": len(self._queue),
            "skipped_inputs": self._dropped + stats.skipped_steps,
            "skipped_steps": stats.skipped_steps,
            "dropped_inputs": self._dropped,
            "shed_inputs": self._shed,
            "shed_since_last_report": self._shed - w["shed"],
            "max_answer_age_s": 1e-9 * self._max_age_ns,
            "published": self._published,
            "answered_inline": self._inline,
            "profiles": self._profiles,
            "profiles_abandoned": self._profiles_abandoned,
            "profiles_not_started": self._profiles_not_started,
            "profile_errors": self._profile_errors,
            "resets": stats.resets,
            "late_samples": stats.late_samples,
            "lag_s": 0.0 if latest is None else latest.model_age_s,
            "received_nut_state": self._received["nut_state"],
            "received_axial_load": self._received["axial_load"],
            "input_age_s": (now - (self._t_start if self._last_input is None
                                   else self._last_input)),
            "rejected_total": sum(stats.rejected.values()),
            "rejected_nut_state": stats.rejected_nut_state,
        }
        for reason, n in sorted(stats.rejected.items()):
            values[f"rejected_{reason}"] = n
        if advance:
            self._window = self._window_start(now)
        return values, w, latest is None or latest.converged

    @property
    def params(self):
        """Return the node's parameters now (NodeParameters)."""
        return self._params

    @property
    def held_load_n(self):
        """Return the axial load held for the next nut state [N], or None before any."""
        return self._assembler.load_n

    def status(self, extra_warnings=()):
        """
        Return (level, message, values) of the schedule's health and start a new window.

        ``extra_warnings``: the node's own notes (another publisher, unknown parameters).
        """
        with self._lock:
            values, w, converged = self._values(advance=True)
            notes, self._notes = self._notes, []
            p = self._params
            stats = self._runner.stats
        errors = []
        if values["input_age_s"] > p.input_timeout_s:
            errors.append(f"no nut_state for {values['input_age_s']:.3g} s (input_timeout_s "
                          f"= {p.input_timeout_s:g} s)" if self._last_input is not None
                          else f"no nut_state received yet ({values['input_age_s']:.3g} s "
                          "since start)")
        warnings = []
        floor, span_s = self._expected_steps(w, p)
        steps = values["model_steps"] - w["steps"]
        if steps < (1.0 - p.model_rate_tolerance) * floor:
            warnings.append(f"model rate low: {steps} steps in {span_s:.3g} s of input, "
                            f"expected at least {floor:.0f} (model_rate_hz = "
                            f"{p.model_rate_hz:g}, model_rate_tolerance = "
                            f"{p.model_rate_tolerance:g})")
        if not converged:
            warnings.append("solver did not converge: feedforward holds the last converged "
                            "value (0 after a reversal or at standstill)")
        if values["shed_since_last_report"]:
            warnings.append(f"shedding load: {values['shed_since_last_report']} answers "
                            f"older than max_answer_age_s = {values['max_answer_age_s']:.6g} "
                            "s not published")
        if stats.stamp_stalls > w["stalls"]:
            warnings.append(f"input stamps do not advance ({values['stamp_stalls']} samples "
                            "with the previous sample's stamp): the model steps on nut "
                            "angle, direction and load only, and model_age_s is 0 for those")
        if stats.coarse_steps > w["coarse"]:
            warnings.append(f"model could not keep up: {values['coarse_steps']} coarser "
                            f"steps, now {values['model_step_deg']:.3g} deg per step "
                            f"(model_step_deg = {p.model_step_deg:g})")
        if values["skipped_steps"]:
            warnings.append(f"model fell behind: {values['skipped_steps']} steps skipped "
                            "(answers differ from replay from then on)")
        if values["rejected_total"] or values["dropped_inputs"]:
            warnings.append(f"{values['rejected_total']} inputs rejected, "
                            f"{values['dropped_inputs']} dropped")
        if values["profile_errors"]:
            warnings.append(f"{values['profile_errors']} look-ahead profiles failed")
        if stats.resets > w["resets"]:
            warnings.append(f"input stamps went backwards: model state reset "
                            f"{stats.resets - w['resets']} times ({stats.resets} in all)")
        warnings += list(extra_warnings) + notes
        level = ERROR if errors else WARN if warnings else OK
        message = "; ".join(errors + warnings) or ("ok" if self.ready else "starting")
        return level, message, values

    def _expected_steps(self, w, p):
        """
        Return (the fewest model steps the window's accepted inputs must cause, their span).

        The schedule's time floor steps the model once per 1/model_rate_hz of input time
        (stamps, not wall time: a recording played slowly is no low rate), and at most once
        per input.  0 when the window tells nothing (under two inputs, stamps stalled or
        gone backwards).
        """
        if w["accepted"] < 2:
            return 0.0, 0.0
        span_s = w["last_stamp"] - w["first_stamp"]
        if not span_s > 0.0:
            return 0.0, 0.0
        # minus one: the window may begin just after a step
        return max(0.0, min(math.floor(span_s * p.model_rate_hz),
                            w["accepted"] - 1) - 1.0), span_s

    def _reset_warning(self, resets, stamp_s):
        """
        Log a stamps-backwards reset, at most once per diagnostics period (counted always).

        A looping source resets at every loop, and a flaky one may reset at every sample:
        one line per reset flooded the log (1191 lines in 5 s).
        """
        now = self._monotonic()
        logged, t_logged = self._resets_logged
        if now - t_logged < 1.0 / self._params.diagnostics_rate_hz:
            return
        self._resets_logged = (resets, now)
        more = resets - logged - 1
        self.outputs.log("warning", f"input stamps went backwards at {stamp_s:.6f} s: "
                         "model state reset" + (f" ({more} more resets since the last "
                                                "warning)" if more > 0 else ""))

    def _log_model_error(self, runner):
        self.outputs.log("error", f"model step failed: {runner.stats.last_error}; state reset")
