"""`studio bench puppet`: the live puppeteer's 60 Hz / 60 s check (issue §7 "Live").

A held-out clip (CMU 141_16) is replayed as live datagrams (the `studio stream-bvh` format) into a UDP
socket on 127.0.0.1 — one per 1/60 s of simulated time — while G1 (and TALOS) stand under the whole-body
controller in MuJoCo and LWL2 drives their arms from whatever datagram is newest. Printed per robot: whether
it fell, the simulated arms' capsule check at every period after the first 0.5 s (the standing pose's own
capsule distance beside it), LWL2's per-period time (median, p99) against the 16.7 ms period and the 2 ms
goal, the share of periods over budget, and the whole loop's real-time factor (simulated s / wall s, on
this shared machine).

Why the wall-clock p99 is what it is, measured side by side in the same run: every other LWL2 call runs in a
real-time section (SCHED_FIFO for the call, :mod:`engine.retarget.humanoid_arm.realtime`), the others as an
ordinary process (``p99_us_ordinary`` / ``p99_us_realtime``); ``cpu_*`` is the thread's CPU time per call
and ``preempted`` the share of calls with an involuntary context switch (the scheduler gave the core to
another process mid-call); ``calls_over_2ms`` / ``of_them_preempted`` / ``gc_during_calls`` say what made the
slow calls slow.
"""

from __future__ import annotations

import socket

import numpy as np


def bench_puppet(duration_s: float = 60.0, robot: str = "g1") -> list[dict]:
    """``studio bench puppet [--robot g1|talos] [--duration S]``."""
    from engine.retarget.humanoid_arm import sources
    from engine.retarget.humanoid_arm.live import datagrams_from_points
    from engine.retarget.humanoid_arm.metadata import weights_path
    from engine.retarget.humanoid_arm.pose15 import bvh_points
    from engine.retarget.humanoid_arm.puppet_session import RATE_HZ, UdpSource, run_puppet_in_physics
    from engine.retarget.importers.bvh import load_bvh

    clips = [p for p in sources.evaluation_clips() if "cmu" in str(p)]
    if not clips:
        return [{"section": "puppet", "note": "shared mocap clips absent (set MOTION_STUDIO_SHARED)"}]
    points = bvh_points(load_bvh(clips[0]))
    stride = max(1, int(round(points.fps / RATE_HZ)))
    payloads = [p for _, p in datagrams_from_points(points, stride=stride)]
    rows = []
    for robot in (robot,):
        if not weights_path(robot).with_suffix(".json").is_file():
            rows.append({"section": "puppet", "robot": robot, "note": "no trained weights"})
            continue
        source = UdpSource(0)
        sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)

        def feed(t_s: float, source=source, sender=sender) -> None:
            sender.sendto(payloads[int(round(t_s * RATE_HZ)) % len(payloads)], ("127.0.0.1", source.port))

        try:
            r = run_puppet_in_physics(robot, source, duration_s, feed=feed, realtime="alternate")
        finally:
            sender.close()
        budget_us = 1e6 / RATE_HZ
        row = {"section": "puppet", "robot": robot, "source": f"{clips[0].name} as UDP datagrams at {RATE_HZ:g} Hz",
               "sim_s": r["sim_s"], "fell": r["fell"], "periods": r["frames"],
               "colliding_periods": r["measured_colliding"], "checked_periods": r["measured_collision_checks"],
               "min_distance_mm": r["min_measured_distance_mm"], "standing_pose_distance_mm": r["standing_pose_distance_mm"],
               "median_us": r["inference_us_median"], "p99_us": r["inference_us_p99"],
               "p99_us_ordinary": r["inference_us_p99_ordinary"], "p99_us_realtime": r["inference_us_p99_realtime"],
               "cpu_median_us": r["inference_cpu_us_median"], "cpu_p99_us": r["inference_cpu_us_p99"],
               "preempted": round(r["preempted"] / max(r["frames"], 1), 4),
               "calls_over_2ms": r["slow_calls"], "of_them_preempted": r["slow_calls_preempted"],
               "gc_during_calls": r["gc_during_calls"],
               "realtime": "every other period" if not r["realtime_error"] else r["realtime_error"],
               "over_budget": round(float(np.mean(np.array(r["inference_s_all"]) > budget_us * 1e-6)), 4),
               "budget_us": round(budget_us, 1), "goal_p99_us": 2000,
               "graph_steps": r["graph"], "holds": r["hold"], "bad_datagrams": source.bad,
               "real_time_factor": round(r["sim_s"] / max(r["wall_s"], 1e-9), 3)}
        rows.append(row)
    return rows


__all__ = ["bench_puppet"]
