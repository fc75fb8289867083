"""EngineCore: the engine's state machine, independent of processes and clocks.

It owns the robot model, the simulation and the controllers, applies commands and produces
events. The engine process (:mod:`engine.process`) drives it in real time; tests and
benchmarks drive it directly, as fast as it goes.

Modes (bipeds with styles): ``stand`` (joint PD on the standing pose), ``test`` (walk under
the joystick command) and ``edit`` (walk the selected sample's cycle at that sample's
velocity, paper §6.1). Quadrupeds and source skeletons only stand / are shown.
"""

from __future__ import annotations

import math
import time
from typing import TYPE_CHECKING, Callable

import mujoco
import numpy as np

from engine import protocol as msg
from engine.control.controller import Controller
from engine.robot.config import RobotConfigError
from engine.robot.model import RobotModel, load_robot
from engine.sim import CONTROL_PERIOD_S, Simulation, standing_controller

if TYPE_CHECKING:
    from engine.control.walking_controller import WalkingController
    from engine.gait.kinematic_preview import KinematicPreview
    from engine.gait.style import Style, StyleContext
    from engine.retarget.humanoid_arm.puppet_session import PuppetSession
    from engine.walk_recording import WalkRecorder

FALL_RESET_DELAY_S = 1.5  # a fallen robot lies this long (so the user sees it) before the reset
MODES = ("stand", "test", "edit", "puppet")  # puppet: stand under the WBC, arms from LWL2 (humanoid_arm)
JOINT_LIMIT_WARNING_RAD = 0.15  # links shade red within this distance of a joint limit
# The kinematic ghost is solved when telemetry goes out (20 Hz), the only time it is shown; it was solved every
# 16 ticks (31 Hz): ≈ 10 % of the engine's CPU on G1, ≈ 6 % now (issue 12: the status line's real-time factor).
#: The ghost is drawn (and kept as a recording's reference pose), not used to control: its Gauss-Newton stops at
#: a weighted residual of 1e-4 instead of KinematicPreview's 1e-7. Over 10 s of a G1 walk at 0.3 m/s, 20 Hz
#: (KinematicPreview.solve at both tolerances on the same references): soles within 0.09 mm of the reference,
#: joints within 0.4 mrad of the 1e-7 solve, 3.6 passes instead of 4.7, 0.82 ms per solve instead of 1.40 (about
#: 2 % of the engine's CPU); tests/control/test_engine_modes.py bounds it at 0.3 mm and 2 mrad.
GHOST_TOLERANCE = 1e-4
RECORD_EVERY_TICKS = 4  # a recording keeps every 4th tick (125 Hz) with the ghost solved at that instant
#: Stand asked of a walking robot: it first comes to rest under the walking controller (zero command: its
#: rate-limited command ramps down, then it steps in place) and holds its joints only once that command has
#: been zero for STAND_SETTLE_QUIET_S and both soles are flat on the ground; a joint hold mid-stride or at
#: walking speed topples it (G1: 14 of 16 tries fell, from 0–0.5 m/s).
STAND_SETTLE_QUIET_S = 0.4
STAND_SETTLE_MAX_S = 6.0  # after this, the hold starts at the next moment both soles are down, however fast
RUNS_DIR = "runs"  # recordings, in the motion library


class EngineCore:
    def __init__(self, robot: str, emit: Callable[[msg.Event], None]):
        self.emit = emit
        self.paused = False
        self.seq = 0
        self.robot: RobotModel
        self.sim: Simulation | None = None
        self._fallen_at_s: float | None = None
        self._kin_data: mujoco.MjData | None = None
        self.real_time_factor = 0.0
        self.playback_speed = 1.0
        self.mode = "stand"
        self._stand_by_s: float | None = None  # Stand asked while walking: settling until this sim time at most
        self._stand_quiet_since_s: float | None = None  # ... and its walking command has been zero since
        self.edit_sample = "in_place"
        self.velocity_command = np.zeros(3)
        self.style: Style | None = None
        self.ctx: StyleContext | None = None
        self.walker: WalkingController | None = None
        self.ghost: KinematicPreview | None = None
        self.ghost_q: np.ndarray | None = None
        self.puppet: PuppetSession | None = None  # in puppet mode
        self._ghost_data: mujoco.MjData | None = None
        self._ticks = 0
        self._ghost_tick = -1  # the tick the ghost was solved at
        self.style_revision = 0
        self._pending_revision: int | None = None
        self.recorder: WalkRecorder | None = None  # while the Record button is on
        self._record_request = ""
        self._record_name = ""
        from engine.jobs import JobRunner

        self.jobs = JobRunner()  # long jobs (retargeting, ...) on worker threads; the loop drains their events
        self.load(robot)

    # ------------------------------------------------------------------ robot
    def load(self, name: str) -> None:
        self._close_puppet()
        if self.recorder is not None:
            self._stop_recording()  # what was recorded of the previous robot is kept
        self.robot = load_robot(name)
        self.style = self.ctx = self.walker = self.ghost = None
        self._stand_by_s = None
        self.ghost_q = None
        self._ghost_data = None
        self.mode = "stand"
        if self.robot.config.simulated:
            self.sim = Simulation(self.robot)
            self._kin_data = None
        else:
            self.sim = None
            self._kin_data = mujoco.MjData(self.robot.mj_model)
            self._kin_data.qpos[:] = self.robot.mj_standing_qpos()
            mujoco.mj_kinematics(self.robot.mj_model, self._kin_data)
        if self.robot.kind == "biped" and self.robot.config.default_style:
            self._load_default_style()
        self._fallen_at_s = None
        self.emit(msg.RobotLoaded(
            robot=self.robot.name, robot_kind=self.robot.kind, body_names=tuple(self.robot.body_names),
            joint_names=tuple(self.robot.joint_names), simulated=self.sim is not None,
        ))

    def _load_default_style(self) -> None:
        from engine.gait.style import StyleContext, StyleError, load_style, styles_dir

        try:
            self.ctx = StyleContext.for_robot(self.robot.name)
            self.style = load_style(styles_dir(self.robot.name) / f"{self.robot.config.default_style}.json", self.ctx)
        except StyleError as exc:
            self.emit(msg.Notice("error", f"default style: {exc}"))
            self.style = None

    @property
    def running(self) -> bool:
        return self.sim is not None and not self.paused

    # ------------------------------------------------------------------ commands
    def handle(self, command: msg.Command) -> None:
        try:
            self._handle(command)
        except RobotConfigError as exc:
            self.emit(msg.Notice("error", _one_line(str(exc))))
        except (ValueError, KeyError, TypeError) as exc:
            self.emit(msg.Notice("error", _one_line(f"{command.kind}: {exc}")))
        except Exception as exc:  # noqa: BLE001 - a malformed command must not kill the engine (a restart replays it)
            self.emit(msg.Notice("error", _one_line(f"{command.kind}: refused ({type(exc).__name__}: {exc})")))

    def _handle(self, command: msg.Command) -> None:
        if isinstance(command, msg.Reset):
            self.reset()
        elif isinstance(command, msg.SetPaused):
            self.paused = bool(command.paused)
        elif isinstance(command, msg.ApplyPush):
            if self.sim is None:
                raise ValueError(f"{self.robot.name} is not simulated")
            force = np.asarray(command.force_n, dtype=float)
            if force.shape != (3,) or not np.all(np.isfinite(force)) or not np.isfinite(command.duration_s):
                raise ValueError("push needs a finite 3-vector force and duration")
            self.sim.push(force, max(0.0, float(command.duration_s)), command.body)
        elif isinstance(command, msg.SwitchRobot):
            if command.robot != self.robot.name:
                self.load(command.robot)
        elif isinstance(command, msg.SetVelocityCommand):
            v = np.array([command.vx_mps, command.vy_mps, command.wz_radps], dtype=float)
            if not np.all(np.isfinite(v)):
                raise ValueError("velocity command must be finite")
            self.velocity_command = v
        elif isinstance(command, msg.SetStyle):
            if self._set_style(command.style):
                if self.walker is None:
                    self.style_revision = int(command.revision)
                else:  # frames report it once a planner tick has run with the new style
                    self._pending_revision = int(command.revision)
        elif isinstance(command, msg.SetMode):
            self._set_mode(command.mode, command.options)
        elif isinstance(command, msg.SetPlaybackSpeed):
            speed = float(command.speed)
            if not (math.isfinite(speed) and 0.05 <= speed <= 4.0):
                raise ValueError(f"playback speed must be within 0.05..4, got {speed}")
            self.playback_speed = speed
        elif isinstance(command, msg.StartJob):
            self.jobs.start(command.job, command.params, command.job_id)
        elif isinstance(command, msg.CancelJob):
            self.jobs.cancel(command.job_id)
        elif isinstance(command, msg.SetRecording):
            self._record_request = str(command.request_id)
            if command.recording:
                self._start_recording(str(command.name))
            elif self.recorder is not None:
                self._stop_recording()
        else:
            raise ValueError(f"not supported by this engine yet: {command.kind}")

    def _set_style(self, document: dict) -> bool:
        from engine.gait.style import StyleContext, StyleError, style_from_dict

        if self.robot.kind != "biped":
            raise ValueError(f"{self.robot.name} does not walk styles")
        ctx = self.ctx or StyleContext.for_robot(self.robot.name)
        try:
            style = style_from_dict(document, ctx, expected_robot=self.robot.name)
        except StyleError as exc:
            self.emit(msg.Notice("error", f"style refused: {exc}"))
            return False
        self.ctx, self.style = ctx, style
        if self.walker is not None:
            self.walker.set_style(style)
        return True

    def _set_mode(self, mode: str, options: dict) -> None:
        if mode not in MODES:
            raise ValueError(f"mode: expected one of {', '.join(MODES)}, got {mode!r}")
        if mode != "stand" and (self.sim is None or self.style is None):
            raise ValueError(f"{self.robot.name} has no walking style: it can only stand")
        if mode == "puppet":
            self._start_puppet(options)
            return
        self._close_puppet()
        sample = options.get("sample", self.edit_sample)
        from engine.gait.velocity_sampler import SAMPLE_NAMES

        if sample not in SAMPLE_NAMES:
            raise ValueError(f"sample: expected one of {', '.join(SAMPLE_NAMES)}, got {sample!r}")
        self.edit_sample = sample
        if mode == self.mode:
            return
        self.mode = mode
        self._stand_by_s = self._stand_quiet_since_s = None
        if mode == "stand":
            assert self.sim is not None
            if self.walker is not None:  # come to rest first (see STAND_SETTLE_SPEED_MPS), then hold
                self._stand_by_s = self.sim.time_s + STAND_SETTLE_MAX_S
            else:
                self.sim.set_controller(standing_controller(self.robot))
        else:
            self._start_walking()

    def _settle_to_stand(self) -> None:
        """Stand mode reached while walking: the walking controller steps with a zero command until both soles
        are flat on the ground and the pelvis is slow, then the joints are held where they are (with the
        static-balance torques of that posture)."""
        from engine.control.controller import StandingPdController
        from engine.control.static_balance import static_contact_torques

        walker, sim = self.walker, self.sim
        assert walker is not None and sim is not None and self._stand_by_s is not None
        if np.all(np.abs(walker.command_filtered) < (0.01, 0.01, 0.02)):
            if self._stand_quiet_since_s is None:
                self._stand_quiet_since_s = sim.time_s
        else:
            self._stand_quiet_since_s = None
        quiet = self._stand_quiet_since_s is not None and sim.time_s - self._stand_quiet_since_s >= STAND_SETTLE_QUIET_S
        if not bool(np.all(walker.wbc_contact)) or not (quiet or sim.time_s >= self._stand_by_s):
            return
        state = sim.state()
        sim.set_controller(StandingPdController(state.q[7:], self.robot.kp, self.robot.kd,
                                                static_contact_torques(self.robot, state.q)))
        self.walker = None
        self._stand_by_s = None

    def _start_puppet(self, options: dict) -> None:
        from engine.retarget.humanoid_arm.puppet_session import PuppetSession, open_source
        from engine.retarget.humanoid_arm.puppeteer import ArmRetargeter

        # the targets keep robots/<name>.toml's [upper_body] puppet_clearance_m between the capsules (the simulated arms
        # lag them); ValueError: no weights
        arms = ArmRetargeter.load(self.robot.name, clearance_m=self.robot.config.puppet_clearance_m)
        source = open_source(options)
        self._close_puppet()
        assert self.ctx is not None  # a walking robot has its style context
        self.puppet = PuppetSession(arms, source, tuple(self.ctx.upper_joints),
                                    realtime=options.get("realtime") is True)  # LWL2 calls under SCHED_FIFO
        self._puppet_bad_seen, self._puppet_notice_t = 0, -1e9
        self.mode = "puppet"
        self._start_walking()
        self.emit(msg.Notice("info", f"Puppeteer: {self.robot.name}'s arms follow {source.name}"))

    def _close_puppet(self) -> None:
        if self.puppet is not None:
            self.puppet.close()
            self.puppet = None

    def _puppet_tick(self) -> None:
        from engine.retarget.humanoid_arm.puppet_session import PuppetWalkingController

        walker, session = self.walker, self.puppet
        assert self.sim is not None and session is not None and isinstance(walker, PuppetWalkingController)
        t = self.sim.time_s
        walker.set_clock(t)
        if session.due(t):
            x = session.step(t)
            if x is not None:
                walker.set_arm_target(session.index, x, t, 1.0 / session.rate_hz)
            if session.realtime and session.section.available is False:
                session.realtime = False  # asked for, not permitted here: said once, then run normally
                self.emit(msg.Notice("warning", f"Puppeteer: {session.realtime_error}"))
            bad = getattr(session.source, "bad", 0)
            if bad > self._puppet_bad_seen and t - self._puppet_notice_t >= 2.0:  # at most one notice per 2 s
                self._puppet_bad_seen, self._puppet_notice_t = bad, t
                self.emit(msg.Notice("warning", _one_line(f"Puppeteer: {getattr(session.source, 'last_error', '')} "
                                                          f"({bad} bad datagrams ignored)")))

    def _start_walking(self) -> None:
        from engine.control.walking_controller import WalkingController
        from engine.gait.kinematic_preview import KinematicPreview

        assert self.sim is not None and self.style is not None and self.ctx is not None
        if self.mode == "puppet" and self.puppet is not None:
            from engine.retarget.humanoid_arm.puppet_session import puppet_walking_controller

            self.walker = puppet_walking_controller(self.robot, self.style, ctx=self.ctx)
            self.puppet.arms.reset()
            self.puppet.next_t_s = None
        else:
            self.walker = WalkingController(self.robot, self.style, ctx=self.ctx)
        self.sim.set_controller(self.walker)
        self.ghost = KinematicPreview(self.robot, self.ctx.upper_joints, tolerance=GHOST_TOLERANCE)

    def command_now(self) -> np.ndarray:
        if self.mode in ("puppet", "stand"):  # stand: a walker still running is coming to rest
            return np.zeros(3)
        if self.mode == "edit" and self.style is not None:
            return np.array(self.style.velocities.velocity_of(self.edit_sample))
        return self.velocity_command

    def reset(self) -> None:
        if self.sim is not None:
            if self.mode != "stand" and self.style is not None:
                self._start_walking()
            elif self.mode == "stand":  # the standing pose again (a hold of where it came to rest ends here)
                self.walker, self._stand_by_s = None, None
                self.sim.set_controller(standing_controller(self.robot))
            self.sim.reset()
        self._fallen_at_s = None

    # ------------------------------------------------------------------ stepping
    def tick(self) -> None:
        """One 500 Hz control tick (no-op when paused or not simulated)."""
        if not self.running:
            return
        assert self.sim is not None
        if self.walker is not None:
            self.walker.set_command(self.command_now())
            if self.puppet is not None:
                self._puppet_tick()
            if self._stand_by_s is not None:
                self._settle_to_stand()
        self.sim.step()
        self._ticks += 1
        if self._pending_revision is not None and self.walker is not None and self.walker.tick % 4 == 1:
            self.style_revision, self._pending_revision = self._pending_revision, None
        recording = self.recorder is not None and self.walker is not None and self._ticks % RECORD_EVERY_TICKS == 0
        if recording:
            self._update_ghost()
            self._record_frame()
        if self.sim.fallen:
            if self._fallen_at_s is None:
                self._fallen_at_s = self.sim.time_s
                self.emit(msg.Notice("warning", f"{self.robot.name} fell at t = {self.sim.time_s:.2f} s; resetting"))
            elif self.sim.time_s - self._fallen_at_s > FALL_RESET_DELAY_S:
                self.reset()

    def _update_ghost(self) -> None:
        walker, ghost = self.walker, self.ghost
        if walker is None or ghost is None or walker.ref is None or walker.plan is None:
            return
        self._ghost_tick = self._ticks
        com = walker.plan.com_at(walker.ref.t_s)[0]
        self.ghost_q = ghost.solve(walker.ref, com)
        if self._ghost_data is None:
            self._ghost_data = mujoco.MjData(self.robot.mj_model)
        self._ghost_data.qpos[:] = self.robot.mj_qpos_from_pin(self.ghost_q)
        mujoco.mj_kinematics(self.robot.mj_model, self._ghost_data)

    # ------------------------------------------------------------------ recording (the Record button)
    def _start_recording(self, name: str) -> None:
        from engine.motion_files import check_name
        from engine.walk_recording import WalkRecorder

        if self.sim is None or self.style is None:
            raise ValueError(f"{self.robot.name} does not walk: nothing to record")
        if name:
            check_name(name)
        self._record_name = name or time.strftime("run-%Y%m%d-%H%M%S")
        fps = 1.0 / (RECORD_EVERY_TICKS * CONTROL_PERIOD_S)
        self.recorder = WalkRecorder(self.robot, self.style.name, fps, command_text=f"studio {self.mode} mode")
        self.emit(msg.Notice("info", f"recording {self._record_name} (Test or Edit mode walks are recorded)"))

    def _record_frame(self) -> None:
        rec, walker, sim = self.recorder, self.walker, self.sim
        if rec is None or walker is None or sim is None or self._ghost_data is None or walker.ref is None:
            return
        data = sim.data
        rec.add(sim.time_s, data.qpos, data.qvel, walker.ref.contact, self._ghost_data.qpos, walker.ref.command)
        if rec.full:
            self.emit(msg.Notice("warning", f"recording reached its {rec.max_frames / rec.fps:.0f} s limit: saved"))
            self._stop_recording()

    def _stop_recording(self) -> None:
        from engine.motion_files import confined, motions_root
        from engine.walk_recording import save_run

        rec, self.recorder = self.recorder, None
        rel = f"{RUNS_DIR}/{self._record_name}.npz"
        try:
            if rec is None or rec.frames == 0:
                raise ValueError("nothing was recorded (the robot must walk: Test or Edit mode)")
            root = motions_root()
            save_run(confined(root, rel), rec.arrays())
            result = {"ok": True, "path": rel, "frames": rec.frames, "fps": rec.fps,
                      "duration_s": round(rec.duration_s, 2)}
        except (OSError, ValueError) as exc:
            result = {"ok": False, "error": _one_line(f"{rel}: {exc}")}
        self.emit(msg.JobProgress("record", 1.0, "saved" if result["ok"] else "failed", result=result,
                                  job_id=self._record_request))

    def frame(self) -> msg.Frame:
        self.seq += 1
        if self.sim is not None:
            pos, quat = self.sim.body_poses()
            joint_q = self.sim.joint_positions()
            t, fallen = self.sim.time_s, self.sim.fallen
        else:
            assert self._kin_data is not None
            pos, quat = self._kin_data.xpos[1:].copy(), self._kin_data.xquat[1:].copy()
            joint_q = self._kin_data.qpos[self.robot.mj_qpos_index].copy()
            t, fallen = 0.0, False
        return msg.Frame(
            seq=self.seq, sim_time_s=t, body_pos=pos.astype(np.float32), body_quat=quat.astype(np.float32),
            joint_q=joint_q.astype(np.float32), paused=self.paused, fallen=fallen,
            real_time_factor=self.real_time_factor, mode=self.mode, style_revision=self.style_revision,
        )

    def telemetry(self) -> msg.Telemetry | None:
        """Overlay and plot signals (walking modes), ghost poses, joint-limit proximity."""
        if self.sim is None:
            return None
        signals: dict[str, np.ndarray] = {}
        q = self.sim.joint_positions()
        margin = np.minimum(q - self.robot.joint_lower, self.robot.joint_upper - q)
        signals["joint_limit_proximity"] = np.clip(1.0 - margin / JOINT_LIMIT_WARNING_RAD, 0.0, 1.0).astype(np.float32)
        walker = self.walker
        if walker is not None and walker.ref is not None:
            tel = walker.telemetry
            ref = walker.ref
            signals.update({
                "com_xy": tel.com_xy, "com_ref_xy": tel.com_ref_xy, "cop_ref_xy": tel.cop_ref_xy,
                "com_path_xy": tel.com_path_xy, "cop_path_xy": tel.cop_path_xy,
                "support_polygon": tel.support_polygon, "footholds_planned": tel.footholds,
                "footholds_latched": np.array([walker.planner.latched[s].as_array() for s in ("left", "right")]),
                "sample_weights": tel.sample_weights, "command": tel.command,
                "phase": np.array([ref.phase]), "contact": ref.contact.astype(np.float32),
                "pelvis_z": np.array([ref.pelvis_z, float(self.sim.data.qpos[2])]),
                "pelvis_yaw": np.array([math.atan2(ref.pelvis_rot[1, 0], ref.pelvis_rot[0, 0]), self._base_yaw()]),
            })
            if tel.feedback is not None:
                fb = tel.feedback
                signals["feedback"] = np.array([fb.velocity_adjust_mps[0], fb.velocity_adjust_mps[1],
                                                fb.step_adjust_m[0], fb.step_adjust_m[1], fb.kappa])
            # balance recovery: the neutral gait's share in the blend (0: the style as authored), and 1 while that
            # share is the walk's start from neutral (engine/control/recovery_blend.py) rather than a recovery
            signals["recovery_share"] = np.array([tel.recovery_share, 1.0 if tel.recovery_starting else 0.0])
            if len(ref.upper_q) and self.ctx is not None:
                j = self.ctx.upper_joints.index(_tracked_arm_joint(self.ctx.upper_joints))
                idx = self.robot.joint_names.index(self.ctx.upper_joints[j])
                signals["arm_joint"] = np.array([ref.upper_q[j], q[idx]])
            if self.puppet is not None:
                self._puppet_signals(signals, q)
            if self._ghost_tick != self._ticks:
                self._update_ghost()
            if self.ghost_q is not None and self._ghost_data is not None:
                signals["ghost_body_pos"] = self._ghost_data.xpos[1:].copy()
                signals["ghost_body_quat"] = self._ghost_data.xquat[1:].copy()
        return msg.Telemetry(self.sim.time_s, {k: np.asarray(v, dtype=np.float32) for k, v in signals.items()})

    def _puppet_signals(self, signals: dict, q: np.ndarray) -> None:
        """The Puppeteer's status, its source pose and the simulated arms' capsule distances."""
        session = self.puppet
        if session is None:
            return
        st = session.stats.summary()
        src = session.source
        signals["puppet"] = np.array([st["frames"], st["inference_us_median"], st["inference_us_p99"],
                                      getattr(src, "received", st["frames"]), getattr(src, "bad", 0),
                                      st["graph"], st["hold"], st["inference_cpu_us_p99"], st["preempted"],
                                      float(session.realtime and session.section.available is True)])
        if session.pose15 is not None:
            signals["puppet_pose15"] = session.pose15
        if session.x is not None:
            signals["puppet_q"] = session.x  # LWL2's output, in session.arms.joint_names order
        cm = session.arms.capsules
        measured = q[[self.robot.joint_names.index(j) for j in session.arms.joint_names]]
        pairs = cm.signed_distances(measured)
        signals["puppet_capsule_distance"] = pairs
        signals["puppet_capsule_min_distance"] = cm.capsule_min_distances(pairs)  # per capsule (the studio tints them)

    def _base_yaw(self) -> float:
        assert self.sim is not None
        q = self.sim.data.qpos
        return math.atan2(2 * (q[3] * q[6] + q[4] * q[5]), 1 - 2 * (q[5] ** 2 + q[6] ** 2))


def _tracked_arm_joint(upper: tuple[str, ...]) -> str:
    """The arm joint shown in the tracking plot (an elbow where there is one; Fig. 14)."""
    for name in upper:
        if "elbow" in name or name.endswith("_4_joint"):
            return name
    return upper[0]


CONTROL_RATE_HZ = 1.0 / CONTROL_PERIOD_S


def _one_line(text: str, limit: int = 300) -> str:
    """A notice is one line (library errors, e.g. MuJoCo's overload lists, span several)."""
    text = " ".join(text.split())
    return text if len(text) <= limit else text[: limit - 1] + "…"
