"""
The demo: a generated recording, played through the live node in-process, then replayed.

The recording is ``trajectories.make_demo_events`` (``config/demo_recording.yaml``).
"""

import numpy as np


def run_demo(out, events, speed=1.0):
    """
    Write the demo bag, play it through the live node in-process, replay it, compare.

    Prints where the outputs are and how live and replay compare; returns 1 if the live
    node answered nothing.
    """
    import json
    from bb_friction_ros.bags import write_events
    from bb_friction_ros.harness import play_through_node
    from bb_friction_ros.replay import replay
    out.mkdir(parents=True, exist_ok=True)
    bag = out / "demo_bag"
    if bag.exists():
        import shutil
        shutil.rmtree(bag)
    write_events(bag, events, storage="mcap")
    n_inputs = sum(e.kind == "nut_state" for e in events)
    print(f"demo recording: {bag} ({n_inputs} nut_state messages); playing it through "
          f"friction_node at {speed:g}x ...", flush=True)
    # Ctrl-C is the demo's own (exit 130): rclpy's handlers, installed at init, could take a
    # SIGINT that came while they were being put in place, and the demo ran on to exit 0
    preds, groups, diag, _ = play_through_node(events, {"reliable_qos": True}, speed=speed,
                                               ros_signal_handlers=False)
    live = out / "live"
    live.mkdir(exist_ok=True)
    lat = np.array([p["model_latency_s"] for p in preds])
    live_summary = {
        "predictions": len(preds), "inputs": n_inputs, "contact_group_messages": len(groups),
        "latency_p50_s": float(np.percentile(lat, 50)) if lat.size else None,
        "latency_p99_s": float(np.percentile(lat, 99)) if lat.size else None,
        "diagnostics": diag}
    (live / "summary.json").write_text(json.dumps(live_summary, indent=2))
    with open(live / "prediction.csv", "w") as fh:
        fh.write("t_s,torque_pred_nm,torque_b2b_nm,n_groups,model_latency_s\n")
        for p in preds:
            fh.write(f"{p['stamp_s']:.9f},{p['torque_total_nm']!r},{p['torque_b2b_nm']!r},"
                     f"{p['n_groups']},{p['model_latency_s']!r}\n")
    summary = replay(bag, out / "replay", progress=False)
    rep = np.genfromtxt(out / "replay" / "prediction.csv", delimiter=",", names=True)
    live_t = {round(p["stamp_s"], 6): p["torque_total_nm"] for p in preds}
    diffs = [abs(live_t[round(t, 6)] - v) for t, v in zip(rep["t_s"], rep["torque_pred_nm"])
             if round(t, 6) in live_t]
    max_diff = max(diffs) if diffs else float("nan")
    print(f"live node: {len(preds)} predictions for {n_inputs} inputs, latency p50 "
          f"{live_summary['latency_p50_s'] * 1e3:.2f} ms, p99 "
          f"{live_summary['latency_p99_s'] * 1e3:.2f} ms, skipped "
          f"{diag['skipped_inputs']}; outputs in {live}")
    print(f"replay: {summary['samples']} predictions, {summary['speed_vs_realtime']:.1f}x "
          f"real time, RMSE vs measured {summary.get('rmse_nm', float('nan')):.4f} N m; "
          f"report in {out / 'replay'}")
    skipped = diag["skipped_inputs"]
    shed = diag.get("shed_inputs", 0)
    if skipped == 0 and len(diffs) == summary["samples"]:
        verdict = f"identical to {max_diff:.1g} N m"
    elif skipped == 0 and diffs and len(diffs) + shed == summary["samples"]:
        verdict = (f"identical to {max_diff:.1g} N m on every answered input; {shed} answers "
                   "were shed as older than max_answer_age_s (counted in /diagnostics)")
    else:
        verdict = (f"max |difference| {max_diff:.3g} N m: the node answered "
                   f"{len(diffs)} of {summary['samples']} inputs and skipped {skipped} model "
                   "steps where it fell behind the input (counted in /diagnostics); "
                   "replay never skips")
    print(f"live vs replay over {len(diffs)} common stamps: {verdict}")
    return 0 if preds else 1
