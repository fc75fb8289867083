"""Live puppeteering (issue §7): a mocap source (a BVH clip replayed on the simulation clock, or live UDP
datagrams of :mod:`live`) → LWL2 (:class:`puppeteer.ArmRetargeter`) → upper-body joint targets for the
whole-body controller, which keeps the legs balancing in physics (:class:`PuppetWalkingController`).

The session runs at ``rate_hz`` (60 Hz): each period it takes the newest pose (UDP: every waiting datagram is
drained and only the newest valid one kept, so a flood never queues up; a malformed one is counted and named
in ``last_error``, never raised), retargets it, and hands the controller a target that it interpolates
linearly over the next period (consecutive LWL2 outputs are joined by collision-free straight lines, so the
interpolated targets stay collision-free too).
"""

from __future__ import annotations

import dataclasses
import socket
import time
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from engine.control.walking_controller import WalkingController
from engine.retarget.humanoid_arm.live import DatagramError, parse_datagram
from engine.retarget.humanoid_arm.puppeteer import ArmRetargeter
from engine.retarget.humanoid_arm.realtime import CallTiming, RealtimeSection
from engine.safe_io import one_line

RATE_HZ = 60.0
MAX_DRAIN = 512  # datagrams read per period at most (a flood is dropped by the kernel beyond the buffer)


class ClipSource:
    """A clip's 15-d poses played on a clock (looping)."""

    def __init__(self, poses15: np.ndarray, fps: float, name: str = "clip"):
        if len(poses15) == 0:
            raise ValueError(f"{name}: no frames")
        self.poses, self.fps, self.name = np.asarray(poses15, dtype=float), float(fps), name
        self.last_error = ""  # a clip has no transport errors (the same interface as UdpSource)

    def pose_at(self, t_s: float) -> np.ndarray:
        return self.poses[int(t_s * self.fps) % len(self.poses)]

    def close(self) -> None:
        pass


class UdpSource:
    """Live datagrams on 127.0.0.1:``port`` (``port`` 0: a free port, see :attr:`port`)."""

    def __init__(self, port: int = 0, host: str = "127.0.0.1"):
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind((host, port))
        self.sock.setblocking(False)
        self.port = self.sock.getsockname()[1]
        self.name = f"udp://{host}:{self.port}"
        self.latest: np.ndarray | None = None
        self.received = self.bad = self.dropped = 0
        self.last_error = ""

    def poll(self) -> np.ndarray | None:
        """The newest valid pose (None before the first one); reads what is waiting, keeps the newest."""
        newest = None
        for _ in range(MAX_DRAIN):
            try:
                data, sender = self.sock.recvfrom(65_536)
            except (BlockingIOError, InterruptedError):
                break
            except OSError as exc:
                self.last_error = f"{self.name}: {exc}"
                break
            self.received += 1
            try:
                _, pose = parse_datagram(data)
            except DatagramError as exc:  # the only error it raises (tests/fuzz/test_fuzz_motion_readers.py)
                self.bad += 1
                self.last_error = one_line(f"datagram from {sender[0]}:{sender[1]}", exc.field_path, exc.detail)
                continue
            if newest is not None:
                self.dropped += 1  # an older frame superseded within the same period
            newest = pose
        if newest is not None:
            self.latest = newest
        return self.latest

    def close(self) -> None:
        self.sock.close()


WINDOW = 8192  # the statistics cover the latest this many calls
SLOW_CALL_S = 0.002  # the live goal's p99: calls slower than this are counted (and how many were preempted)


@dataclass
class PuppetStats:
    """Per LWL2 call (latest :data:`WINDOW`): wall time, the thread's CPU time, whether the scheduler preempted
    it, whether it ran in a real-time section (:mod:`realtime`)."""
    frames: int = 0
    inference_s: deque = field(default_factory=lambda: deque(maxlen=WINDOW))
    cpu_s: deque = field(default_factory=lambda: deque(maxlen=WINDOW))
    preempted: deque = field(default_factory=lambda: deque(maxlen=WINDOW))
    realtime: deque = field(default_factory=lambda: deque(maxlen=WINDOW))
    gc: deque = field(default_factory=lambda: deque(maxlen=WINDOW))
    transitions: dict = field(default_factory=lambda: {"direct": 0, "graph": 0, "hold": 0})

    def add(self, timing: CallTiming) -> None:
        self.inference_s.append(timing.wall_s)
        self.cpu_s.append(timing.cpu_s)
        self.preempted.append(timing.preempted)
        self.realtime.append(timing.realtime)
        self.gc.append(timing.gc)

    def summary(self) -> dict:
        t = np.array(self.inference_s) if self.inference_s else np.zeros(1)
        cpu = np.array(self.cpu_s) if self.cpu_s else np.zeros(1)
        rt = np.array(self.realtime, dtype=bool) if self.realtime else np.zeros(1, dtype=bool)
        us = lambda v, q: round(float(np.percentile(v, q)) * 1e6, 1) if len(v) else 0.0  # noqa: E731
        return {"frames": self.frames, "inference_us_median": us(t, 50), "inference_us_p99": us(t, 99),
                "inference_cpu_us_median": us(cpu, 50), "inference_cpu_us_p99": us(cpu, 99),
                "preempted": int(np.sum(np.array(self.preempted, dtype=bool))) if self.preempted else 0,
                "gc_during_calls": int(np.sum(np.array(self.gc, dtype=bool))) if self.gc else 0,
                "slow_calls": int(np.sum(t > SLOW_CALL_S)) if self.inference_s else 0,
                "slow_calls_preempted": int(np.sum((t > SLOW_CALL_S) & np.array(self.preempted, dtype=bool)))
                if self.inference_s else 0,
                "realtime_calls": int(np.sum(rt)),
                "inference_us_p99_realtime": us(t[rt], 99), "inference_us_p99_ordinary": us(t[~rt], 99),
                **self.transitions}


class PuppetSession:
    """Source → LWL2 at ``rate_hz``; :meth:`step` is called on the simulation clock."""

    def __init__(self, arms: ArmRetargeter, source: ClipSource | UdpSource, upper_joints: tuple[str, ...],
                 rate_hz: float = RATE_HZ, realtime: bool = False):
        """``realtime``: run each LWL2 call in a real-time section (:mod:`realtime`; ignored where the
        process may not raise its priority — :attr:`realtime_error` says why)."""
        self.arms, self.source, self.rate_hz = arms, source, float(rate_hz)
        self.realtime = bool(realtime)
        self.section = RealtimeSection()
        self.upper_joints = tuple(upper_joints)
        missing = [j for j in arms.joint_names if j not in self.upper_joints]
        if missing:
            raise ValueError(f"upper_body.joints: the controller does not drive {', '.join(missing)}")
        self.index = np.array([self.upper_joints.index(j) for j in arms.joint_names])
        self.stats = PuppetStats()
        self.next_t_s: float | None = None
        self.x: np.ndarray | None = None  # the latest LWL2 output
        self.pose15: np.ndarray | None = None
        arms.reset()

    def due(self, t_s: float) -> bool:
        return self.next_t_s is None or t_s >= self.next_t_s - 1e-9

    def step(self, t_s: float) -> np.ndarray | None:
        """One period at time ``t_s``: the new driven-joint targets (None while no pose arrived yet)."""
        self.next_t_s = (t_s if self.next_t_s is None else self.next_t_s) + 1.0 / self.rate_hz
        pose = self.source.pose_at(t_s) if isinstance(self.source, ClipSource) else self.source.poll()
        if pose is None:
            return None
        with self.section.run(self.realtime):
            result = self.arms.retarget(pose)
        self.pose15, self.x = pose, result.x
        self.stats.frames += 1
        assert self.section.last is not None
        self.stats.add(self.section.last)
        self.stats.transitions[result.transition] += 1
        return result.x

    @property
    def realtime_error(self) -> str:
        return self.section.error

    def close(self) -> None:
        self.source.close()


class PuppetWalkingController(WalkingController):
    """A :class:`~engine.control.walking_controller.WalkingController` whose upper-body reference comes from
    the puppet (linear interpolation of the latest two targets over one period); wrists and joints LWL2 does
    not drive keep the gait's reference, except wrists held at zero like LWL2's capsule model assumes."""
    puppet_index: np.ndarray | None = None
    _from: np.ndarray | None = None
    _to: np.ndarray | None = None
    _t0 = 0.0
    _period = 1.0 / RATE_HZ
    _clock = 0.0

    def set_arm_target(self, index: np.ndarray, x: np.ndarray, now_s: float, period_s: float) -> None:
        cur = self._current(now_s)
        self.puppet_index = index
        self._from = x.copy() if cur is None else cur
        self._to, self._t0, self._period = x.copy(), now_s, period_s

    def set_clock(self, now_s: float) -> None:
        self._clock = now_s

    def _current(self, now_s: float) -> np.ndarray | None:
        if self._to is None or self._from is None:
            return None
        s = min(max((now_s - self._t0) / self._period, 0.0), 1.0)
        return self._from + s * (self._to - self._from)

    def _wbc_reference(self, dt_since: float):  # noqa: ANN202 - WbcReference
        ref = super()._wbc_reference(dt_since)
        target = self._current(self._clock)
        if target is None or self.puppet_index is None:
            return ref
        q = np.array(ref.upper_body_q_rad, dtype=float)
        qd = np.zeros_like(q)
        for k, name in enumerate(self.ctx.upper_joints):
            if "wrist" in name:
                q[k] = 0.0
        q[self.puppet_index] = target
        if self._to is not None and self._from is not None and self._clock - self._t0 < self._period:
            qd[self.puppet_index] = (self._to - self._from) / self._period
        return dataclasses.replace(ref, upper_body_q_rad=q, upper_body_qd_radps=qd)


def puppet_walking_controller(robot, style, ctx=None) -> PuppetWalkingController:  # noqa: ANN001 - RobotModel, Style, StyleContext
    """The walking controller of puppet mode (see :class:`PuppetWalkingController`)."""
    return PuppetWalkingController(robot, style, ctx=ctx)


SETTLE_S = 0.5  # the robot starts in its standing pose, whose arms the (conservative) capsules already overlap


def run_puppet_in_physics(robot: str, source: ClipSource | UdpSource, duration_s: float,
                          feed=None, progress=None, settle_s: float = SETTLE_S, realtime: bool | str = False) -> dict:
    """Stand ``robot`` under the whole-body controller in MuJoCo while LWL2 drives its arms from ``source``
    for ``duration_s`` simulated seconds. ``feed(t_s)`` is called before each puppet period (e.g. to send the
    datagram of that instant). ``realtime``: LWL2 calls in a real-time section (:mod:`realtime`); "alternate":
    every other period, so both are measured side by side under the same load. Returns fell, the measured
    (simulated) arms' capsule check at every period after ``settle_s`` and the timing stats."""
    from engine.gait.style import StyleContext, load_style, styles_dir
    from engine.robot.model import load_robot
    from engine.sim import CONTROL_PERIOD_S, Simulation

    model = load_robot(robot)
    ctx = StyleContext.for_robot(robot)
    style = load_style(styles_dir(robot) / f"{model.config.default_style}.json", ctx)
    arms = ArmRetargeter.load(robot, clearance_m=model.config.puppet_clearance_m)  # robots/<name>.toml [upper_body]
    walker = puppet_walking_controller(model, style, ctx)
    walker.set_command(np.zeros(3))
    sim = Simulation(model, walker)
    session = PuppetSession(arms, source, tuple(ctx.upper_joints), realtime=bool(realtime))
    ub, cm = arms.ub, arms.capsules
    mj_index = np.array([model.joint_names.index(j) for j in ub.joint_names])  # into sim.joint_positions()
    worst = np.inf
    collided = 0
    checks = 0
    t_wall = time.perf_counter()
    steps = int(round(duration_s / CONTROL_PERIOD_S))
    for k in range(steps):
        t = k * CONTROL_PERIOD_S
        walker.set_clock(t)
        if session.due(t):
            if feed is not None:
                feed(t)
            if realtime == "alternate":
                session.realtime = session.stats.frames % 2 == 1
            x = session.step(t)
            if x is not None:
                walker.set_arm_target(session.index, x, t, 1.0 / session.rate_hz)
            if t >= settle_s:
                d = cm.min_signed_distance(sim.joint_positions()[mj_index])
                worst = min(worst, d)
                collided += d < 0.0
                checks += 1
        sim.step()
        if sim.fallen:
            break
        if progress is not None and k % 500 == 0:
            progress(k / steps)
    wall = time.perf_counter() - t_wall
    session.close()
    standing = cm.min_signed_distance(ub.neutral())
    return {"robot": robot, "source": source.name, "sim_s": round(sim.time_s, 2), "fell": bool(sim.fallen),
            "standing_pose_distance_mm": round(standing * 1000, 1),
            "measured_collision_checks": checks, "measured_colliding": int(collided),
            "min_measured_distance_mm": round(float(worst) * 1000, 1), "wall_s": round(wall, 1),
            "inference_s_all": list(session.stats.inference_s), "realtime_error": session.realtime_error,
            **session.stats.summary()}


__all__ = ["ClipSource", "UdpSource", "PuppetSession", "PuppetStats", "puppet_walking_controller",
           "run_puppet_in_physics", "RATE_HZ"]


def open_source(options: dict):
    """The puppet's source from the studio's options: ``{"source": "udp", "port": P}`` (bound to 127.0.0.1)
    or ``{"source": "clip", "clip": "mocap-src/…/X.bvh"}`` (a BVH inside the shared data folder).
    ValueError naming the option otherwise."""
    from engine.retarget.humanoid_arm import sources
    from engine.retarget.humanoid_arm.pose15 import bvh_points, degenerate_frame
    from engine.retarget.importers.bvh import BvhError, load_bvh

    kind = options.get("source", "clip")
    if kind == "udp":
        port = options.get("port", 0)
        if not isinstance(port, int) or not 0 <= port < 65536:
            raise ValueError(f"port: expected 0..65535, got {port!r}")
        try:
            return UdpSource(port)
        except OSError as exc:
            raise ValueError(f"port {port}: {exc.strerror or exc}") from None
    if kind != "clip":
        raise ValueError(f"source: expected 'clip' or 'udp', got {kind!r}")
    root = sources.shared_dir()
    clip = str(options.get("clip", ""))
    if root is None:
        raise ValueError("clip: no shared data folder on this machine")
    path = (root / clip).resolve()
    if not path.is_relative_to(root.resolve()) or path.suffix.lower() != ".bvh" or not path.is_file():
        raise ValueError(f"clip: expected a .bvh file inside the shared data folder, got {clip!r}")
    try:
        with np.errstate(all="ignore"):  # overflowing coordinates become NaN, refused below
            points = bvh_points(load_bvh(path))
            poses = points.pose15()
    except BvhError as exc:
        raise ValueError(str(exc)) from None
    bad = degenerate_frame(poses)
    if bad is not None:
        raise ValueError(f"{path.name}: MOTION: frame {bad}: expected a skeleton, got coincident arm joints (degenerate)")
    return ClipSource(poses, points.fps, path.name)


def puppet_clips() -> list[str]:
    """BVH clips the Puppeteer offers (relative to the shared data folder): held-out first."""
    from engine.retarget.humanoid_arm import sources

    root = sources.shared_dir()
    if root is None:
        return []
    return [str(p.relative_to(root)) for p in sources.evaluation_clips() + sources.train_clips()]
