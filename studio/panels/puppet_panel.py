"""The Puppeteer workspace: a mocap clip or a live UDP source drives a humanoid's arms and torso (LWL2) while
its legs balance under the whole-body controller in MuJoCo.

The panel only views and starts: the engine runs the source, LWL2 and the controller (``SetMode("puppet",
{"source": "clip", "clip": …})`` or ``{"source": "udp", "port": …}``, engine/core.py) and reports in
telemetry (``puppet``: frames, inference µs median/p99, datagrams received/bad, graph steps, holds;
``puppet_pose15``: the source pose; ``puppet_capsule_distance``: the simulated arms' capsule distances;
``puppet_capsule_min_distance``: each capsule's smallest). The source pose is drawn as a stick figure beside the
robot; colliding capsule pairs are counted in red and named. *Show capsules* draws LWL2's capsules on the robot
(:mod:`studio.capsule_view`: children of the robot's body frames, tinted red when colliding, orange when near).
*Export recording* writes the recorded span as a robot motion (``motions/<robot>/NAME.npz``, ``robot-motion/1``,
:mod:`engine.retarget.humanoid_arm.puppet_export`), the name confined to that folder, the write atomic.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import viser

from engine import protocol as msg
from studio.capsule_view import CapsuleView

if TYPE_CHECKING:
    from engine.retarget.humanoid_arm.capsules import CapsuleOnBody
    from studio.app import Studio

ARM_ROBOTS = ("g1", "talos")
LIVE = "live (UDP on 127.0.0.1)"
DEFAULT_PORT = 9870
SKELETON_OFFSET = np.array([0.0, 0.9, 0.0])  # the source stands beside the robot
# drawing lengths of the stick figure (m): the 15-d pose carries directions only
SPINE_M, UPPER_ARM_M, FOREARM_M, HALF_SHOULDERS_M = 0.45, 0.28, 0.25, 0.17
SKELETON_RGB = (40, 110, 220)
DEFAULT_EXPORT_NAME = "puppet_take"


def _one_line(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return (text[0] if text else type(exc).__name__).replace("`", "'")[:200]


def stick_figure(pose15: np.ndarray, hips: np.ndarray) -> np.ndarray:
    """(5, 2, 3) line segments of a 15-d pose (body frame = world heading 0) drawn from ``hips``."""
    v = np.asarray(pose15, dtype=float).reshape(5, 3)
    neck = hips + SPINE_M * v[0]
    left = np.array([0.0, 1.0, 0.0]) * HALF_SHOULDERS_M
    segs = [(hips, neck)]
    for shoulder, upper, fore in ((neck - left, v[1], v[2]), (neck + left, v[3], v[4])):
        elbow = shoulder + UPPER_ARM_M * upper
        segs += [(shoulder, elbow), (elbow, elbow + FOREARM_M * fore)]
    segs.append((neck - left, neck + left))
    return np.array(segs, dtype=np.float32)


class PuppetPanel:
    def __init__(self, server: viser.ViserServer, studio: "Studio"):
        self.server, self.studio = server, studio
        self.active = False
        self.options: dict | None = None  # the engine's puppet options (re-sent after an engine restart)
        self.status_updates = 0
        gui = server.gui
        with gui.add_folder("Puppeteer"):
            self.intro = gui.add_markdown("Pick a clip or live mocap: the arms and torso follow (LWL2), the legs "
                                          "balance under the whole-body controller.")
            self.source = gui.add_dropdown("Source", self._source_options())
            self.port = gui.add_number("UDP port", DEFAULT_PORT, min=1024, max=65535, step=1)
            self.start = gui.add_button("Start puppet", icon=viser.Icon.PLAYER_PLAY)
            self.stop_button = gui.add_button("Stop puppet", icon=viser.Icon.PLAYER_STOP, disabled=True)
            self.show_skeleton = gui.add_checkbox("Show source skeleton", True)
            self.show_capsules = gui.add_checkbox("Show capsules", False,
                                                  hint="LWL2's self-collision capsules on the robot: red when "
                                                       "colliding, orange when closer than 2 cm")
            self.realtime = gui.add_checkbox("Real-time priority", False,
                                             hint="Run each LWL2 call under SCHED_FIFO, so other processes cannot "
                                                  "preempt it (needs CAP_SYS_NICE); applies at Start puppet")
            self.status = gui.add_markdown("Puppet: idle")
        with gui.add_folder("Gesture → walking style"):
            self.record_s = gui.add_slider("Record seconds", min=0.5, max=10.0, step=0.5, initial_value=2.0)
            self.knots = gui.add_slider("Knots", min=2, max=32, step=1, initial_value=8)
            self.record = gui.add_button("Record gesture", icon=viser.Icon.PLAYER_RECORD, disabled=True)
            self.apply = gui.add_button("Use as arm curves", icon=viser.Icon.CHECK, disabled=True)
            self.undo = gui.add_button("Undo style edit", icon=viser.Icon.ARROW_BACK_UP)
            self.record_status = gui.add_markdown("Start the puppet, record a span of its arms, then make it the "
                                                  "arm curves of the current gait sample (one undoable edit).")
        with gui.add_folder("Export motion"):
            self.export_name = gui.add_text("Export name", DEFAULT_EXPORT_NAME,
                                            hint="motions/<robot>/NAME.npz: letters, digits, '-' or '_'")
            self.export = gui.add_button("Export recording", icon=viser.Icon.DOWNLOAD, disabled=True)
            self.export_status = gui.add_markdown("Record gesture, then export the span as a robot motion "
                                                  "(robot-motion/1, 30 fps: `studio export` and the Retarget tab "
                                                  "read it).")
        self.export.on_click(lambda _: self.export_recording())
        self.export_path: Path | None = None  # the last exported file
        self.record.on_click(lambda _: self.start_recording())
        self.apply.on_click(lambda _: self.apply_recording())
        self.undo.on_click(lambda _: self.undo_edit())
        self._recording: list[tuple[float, np.ndarray, np.ndarray | None]] | None = None
        self._recorded: tuple[np.ndarray, np.ndarray] | None = None
        self._recorded_pose15: np.ndarray | None = None
        self._recorded_meta: dict = {}  # robot and source of the recording
        self.start.on_click(lambda _: self.start_puppet())
        self.stop_button.on_click(lambda _: self.stop_puppet())
        self.show_skeleton.on_update(lambda _: self._skeleton_visible())
        self.skeleton: viser.LineSegmentsHandle | None = None
        self.capsule_view = CapsuleView(server, studio.view.root)
        self._capsules: dict[str, list[CapsuleOnBody]] = {}  # per robot (a deterministic fit: computed once)
        self._capsules_robot: str | None = None  # whose capsules the view holds
        self.colliding_capsules: list[str] = []
        self._starting = False  # Start puppet sent, no puppet telemetry yet (a refusal comes back as a notice)
        self._before: tuple[str, dict | None] = ("stand", None)
        self.show_capsules.on_update(lambda _: self._capsules_shown())

    def _source_options(self) -> tuple[str, ...]:
        from engine.retarget.humanoid_arm.puppet_session import puppet_clips

        return (*puppet_clips(), LIVE)

    def start_puppet(self) -> None:
        robot = self.studio.robot_name
        if robot not in ARM_ROBOTS:
            self.status.content = f"Puppet: {robot} has no trained arms (robots: {', '.join(ARM_ROBOTS)})"
            return
        if self.source.value == LIVE:
            options: dict = {"source": "udp", "port": int(self.port.value)}
            where = f"udp://127.0.0.1:{int(self.port.value)} (send with `studio stream-bvh FILE --to udp://127.0.0.1:{int(self.port.value)}`)"
        else:
            options = {"source": "clip", "clip": self.source.value}
            where = f"`{self.source.value}`"
        options["realtime"] = bool(self.realtime.value)
        self._before = (self.studio.mode, self.options)  # restored if the engine refuses
        self._starting = True  # until the engine's first puppet telemetry
        self.options = options
        self.studio.mode = "puppet"
        self.studio.link.send(msg.SetMode("puppet", options))
        self.active = True
        self.start.disabled, self.stop_button.disabled = False, False
        self.record.disabled = False
        self.status.content = f"Puppet: starting on {robot} from {where}…"

    def on_notice(self, level: str, message: str) -> None:
        """An engine notice: while starting, a refused ``set_mode`` (no weights, a bad clip, a UDP port in use)
        is the answer to Start puppet — said in the status line, the puppet off, the studio's mode as before."""
        if not (self._starting and self.active and level == "error" and message.startswith("set_mode")):
            return
        self._starting = False
        reason = _one_line(ValueError(message.removeprefix("set_mode: ")))
        mode, options = self._before
        self.studio.mode, self.options = mode, options
        if mode == "puppet" and options is not None:  # the engine goes on with the previous source
            self.status.content = f"Puppet: refused: {reason} (still following the previous source)"
            return
        self.active = False
        self.stop_button.disabled = self.record.disabled = True
        self.status.content = f"Puppet: refused: {reason}"

    def stop_puppet(self) -> None:
        self.active, self.options = False, None
        self._recording = None
        self.stop_button.disabled = self.record.disabled = True
        self.studio.set_mode("stand")
        self.status.content = "Puppet: idle"
        self._skeleton_visible()
        self.capsule_view.tint(None)

    def on_mode(self, mode: str) -> None:
        """The studio chose another mode (Stand, Edit or Test): the engine leaves puppet mode."""
        if mode != "puppet" and self.active:
            self.active, self.options = False, None
            self._recording = None
            self.stop_button.disabled = self.record.disabled = True
            self.status.content = f"Puppet: idle (the robot is in {mode} mode)"
            self._skeleton_visible()
            self.capsule_view.tint(None)

    # ------------------------------------------------------------------ gesture → style
    def start_recording(self) -> None:
        if not self.active:
            return
        self._recording, self._recorded, self._recorded_pose15 = [], None, None
        self.apply.disabled = self.export.disabled = True
        self._recorded_meta = {"robot": self.studio.robot_name, **(self.options or {})}
        self.record_status.content = f"Recording {self.record_s.value:g} s…"

    def _record(self, t_s: float, q: np.ndarray, pose15: np.ndarray | None = None) -> None:
        rec = self._recording
        if rec is None:
            return
        if rec and t_s <= rec[-1][0]:
            return
        rec.append((t_s, np.array(q, dtype=float), None if pose15 is None else np.array(pose15, dtype=float)))
        if t_s - rec[0][0] >= float(self.record_s.value):
            self._recorded = (np.array([r[0] for r in rec]), np.stack([r[1] for r in rec]))
            poses = [r[2] for r in rec]
            self._recorded_pose15 = np.stack(poses) if all(p is not None for p in poses) else None  # type: ignore[arg-type]
            self._recording = None
            self.apply.disabled = self.export.disabled = False
            self.record_status.content = (f"Recorded {len(rec)} frames over {t_s - rec[0][0]:.1f} s: "
                                          f"**Use as arm curves** of `{self.studio.sample_name}`")

    def apply_recording(self) -> None:
        """The recording as the current sample's upper-body curves: one undoable style edit."""
        from engine.retarget.humanoid_arm.style_curves import style_with_gesture
        from engine.retarget.humanoid_arm.upper_body import SPECS

        session = self.studio.session
        if self._recorded is None or session is None or session.style is None:
            self.record_status.content = "Nothing recorded (or no walking style open)"
            return
        sample = self.studio.sample_name
        t, q = self._recorded
        try:
            joints = SPECS[self.studio.robot_name]().joints
            new = style_with_gesture(session.style, sample, t, q, joints, int(self.knots.value), session.ctx)
        except (ValueError, KeyError) as exc:
            self.record_status.content = f"Refused: {exc}"
            return
        result = session.apply(new, f"gesture → {sample} arm curves")
        self.record_status.content = (f"`{sample}`: {len(joints)} arm curves with {int(self.knots.value)} knots from "
                                      f"{t[-1] - t[0]:.1f} s of the puppet (Undo style edit reverts it)" if result.ok
                                      else f"Refused: {result.message}")

    # ------------------------------------------------------------------ export
    def export_recording(self) -> None:
        """The recorded span as ``motions/<robot>/<name>.npz`` (robot-motion/1): one line on any refusal."""
        from engine.motion_files import motions_root
        from engine.paths import confined
        from engine.retarget.humanoid_arm.puppet_export import EXPORT_FPS, save_puppet_motion

        if self._recorded is None:
            self.export_status.content = "Nothing recorded: **Record gesture** first"
            return
        robot = str(self._recorded_meta.get("robot", self.studio.robot_name))
        t, q = self._recorded
        source = {k: v for k, v in self._recorded_meta.items() if k in ("source", "clip", "port")}
        try:
            path = confined(motions_root() / robot, str(self.export_name.value).strip(), ".npz", field="Export name")
            if path.exists():
                raise ValueError(f"motions/{robot}/{path.name} exists: pick another name")
            summary = save_puppet_motion(path, robot, t, q, self._recorded_pose15, EXPORT_FPS, source)
        except (ValueError, OSError) as exc:
            self.export_status.content = f"Export refused: {_one_line(exc)}"
            return
        self.export_path = path
        self.export_status.content = (f"Exported `motions/{robot}/{path.name}`: {summary['frames']} frames at "
                                      f"{summary['fps']:g} fps, collision-free "
                                      f"{summary['collision_free_fraction']:.0%} (min capsule distance "
                                      f"{summary['min_capsule_distance_mm']:+.1f} mm)")

    # ------------------------------------------------------------------ capsules
    def _capsule_list(self, robot: str | None) -> list[CapsuleOnBody]:
        if robot not in ARM_ROBOTS:
            return []
        if robot not in self._capsules:
            from engine.retarget.humanoid_arm.capsules import fitted_capsules_on_bodies

            self._capsules[robot] = fitted_capsules_on_bodies(robot)
        return self._capsules[robot]

    def _capsules_shown(self) -> None:
        """The checkbox: draw the capsules (built on first use for this robot) or hide them."""
        show = bool(self.show_capsules.value)
        robot = self.studio.robot_name
        if show and self._capsules_robot != robot:
            self.on_view_loaded(robot)
            if robot not in ARM_ROBOTS:
                self.status.content = f"Puppet: {robot} has no capsule model (robots: {', '.join(ARM_ROBOTS)})"
            return
        self.capsule_view.set_visible(show)

    def on_view_loaded(self, robot: str) -> None:
        """The robot's body frames were (re)built (robot loaded, engine restarted): the capsules hang under them,
        so they are rebuilt too (when shown, or shown before)."""
        if robot in ARM_ROBOTS and (self.show_capsules.value or self._capsules_robot is not None):
            self.capsule_view.build(self._capsule_list(robot), visible=bool(self.show_capsules.value))
            self._capsules_robot = robot
        else:
            self.capsule_view.clear()
            self._capsules_robot = None

    def undo_edit(self) -> None:
        session = self.studio.session
        if session is not None:
            self.record_status.content = session.undo().message

    def on_robot(self) -> None:
        """Another robot loaded: it starts standing, the puppet is off."""
        self.active, self.options = False, None
        self._recording = self._recorded = self._recorded_pose15 = None
        self.record.disabled = self.apply.disabled = self.export.disabled = True
        self.stop_button.disabled = True
        self.status.content = "Puppet: idle"
        self._skeleton_visible()

    def _skeleton_visible(self) -> None:
        if self.skeleton is not None:
            self.skeleton.visible = bool(self.active and self.show_skeleton.value)

    def on_telemetry(self, signals: dict, frame_pelvis: np.ndarray | None = None, sim_time_s: float = 0.0) -> None:
        """Telemetry from the engine (the link's thread)."""
        s = signals.get("puppet")
        if s is None or not self.active:
            return
        self._starting = False
        frames, med, p99, received, bad, graph, hold, *timing = (float(v) for v in s)
        dist = signals.get("puppet_capsule_distance")
        colliding = int(np.sum(dist < 0)) if dist is not None else 0
        per_capsule = signals.get("puppet_capsule_min_distance")
        names = [c.name for c in self._capsule_list(self.studio.robot_name)]
        self.colliding_capsules = ([n for n, d in zip(names, per_capsule) if d < 0]
                                   if per_capsule is not None and len(per_capsule) == len(names) else [])
        col = (f"<span style='color:#d00'>**{colliding} capsule pairs colliding**"
               f"{' (' + ', '.join(self.colliding_capsules) + ')' if self.colliding_capsules else ''}</span>"
               if colliding else "no capsule pair colliding")
        if self.capsule_view.visible:
            self.capsule_view.tint(per_capsule)
        cpu = ""
        if len(timing) >= 3:  # the thread's CPU time, preempted calls (of the latest 8192), real-time section
            cpu_p99, preempted, realtime = timing[:3]
            cpu = f" (CPU {cpu_p99 / 1000:.1f} ms p99; {int(preempted)} preempted{'; real-time' if realtime else ''})"
        text = (f"Puppet: **{int(frames)} frames** · LWL2 {med / 1000:.1f} ms median, {p99 / 1000:.1f} ms p99{cpu} · "
                f"datagrams {int(received)} ({int(bad)} bad) · graph steps {int(graph)}, holds {int(hold)} · {col}")
        if text != self.status.content:
            self.status.content = text
            self.status_updates += 1
        q = signals.get("puppet_q")
        pose = signals.get("puppet_pose15")
        if q is not None and self._recording is not None:
            self._record(float(sim_time_s), q, pose)
        if pose is not None and self.show_skeleton.value:
            hips = (frame_pelvis if frame_pelvis is not None else np.array([0.0, 0.0, 0.75])) + SKELETON_OFFSET
            points = stick_figure(pose, hips)
            if self.skeleton is None:
                self.skeleton = self.server.scene.add_line_segments("/puppet/skeleton", points, SKELETON_RGB,
                                                                    thickness=0.02)
            else:
                self.skeleton.points = points
            self.skeleton.visible = True
