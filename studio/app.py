"""The studio: a viser app showing the engine's robot, with the editing panels.

Studio code only views and edits engine state: numerics live in the engine process. The
style being edited lives in a :class:`StyleSession`; every accepted edit is sent to the
engine (with a revision number, so frames tell when an edit shows), autosaved, and undoable.
"""

from __future__ import annotations

import threading
import time
from typing import TYPE_CHECKING, Literal

import numpy as np
import viser

from engine import protocol as msg
from engine.robot.config import load_robot_config
from engine.robot.model import load_robot
from studio.accessible_labels import label_text_fields
from studio.engine_link import EngineLink
from studio.overlays import Overlays
from studio.panels.drive_panel import GHOST_OFFSETS, DrivePanel
from studio.panels.plots_panel import PlotsPanel
from studio.panels.robot_panel import RobotPanel
from studio.robot_view import RobotView
from studio.stream_rate import FRAME_HZ, TELEMETRY_HZ, StreamRate
from studio.style_session import StyleSession
from studio.viser_threads import allow_pushes_from_threads
from studio.thread_priority import yield_to_engine

if TYPE_CHECKING:
    from studio.panels.curve_editor import CurveEditor
    from studio.panels.rehearsal_panel import RehearsalPanel
    from studio.panels.style_speeds import StyleSpeeds
    from studio.panels.sample_editor import SampleEditor
    from studio.panels.style_browser import StyleBrowser

STATUS_PERIOD_S = 0.25
SERVE_REHEARSAL_WALKS = 3  # `studio serve`: a rehearsal walks the sweep three times (README "Falls at a margin")
PLOT_EVERY_TICKS = 2  # plots redraw at 2 Hz: each redraw costs the browser's main thread (typing, 3D)
GRAPH_OFFSET = (-2.4, 0.6, 0.15)  # the curve graph stands well left of the robot: nothing occludes it
LIMIT_RED = np.array([230, 40, 40])
PANEL_WIDTH_PX = 384  # 24 em: six tabs (Robot … Plots, Mocap) fit one row
NOTICE_COLORS: dict[str, Literal["red", "yellow", "blue"]] = {"error": "red", "warning": "yellow", "info": "blue"}


class Studio:
    def __init__(self, robot: str, host: str = "127.0.0.1", port: int = 8080, styles_folder=None,
                 token: str | None = None, shadows: bool = False, rehearse_after_edits: bool = False,
                 rehearsal_duration_s: float | None = None, rehearsal_walks: int = 1):
        load_robot_config(robot)  # fail fast, before any server or process starts
        self.robot_name = robot
        self.styles_folder = styles_folder
        # The Rehearsal panel walks the style by itself after each edit (`studio serve` turns it on; tests and
        # benchmarks that build a Studio leave it off unless they test it), through a sweep this long.
        self.rehearse_after_edits = rehearse_after_edits
        self.rehearsal_duration_s = rehearsal_duration_s
        self.rehearsal_walks = rehearsal_walks  # the Rehearsal panel's *Walks* at first (3 in `studio serve`)
        self.server = viser.ViserServer(host=host, port=port, label="Motion Studio", verbose=False)
        allow_pushes_from_threads(self.server)  # frames, telemetry, joystick and callbacks push from threads
        self.token = token
        if token:
            from studio.access import require_token

            require_token(self.server, token)  # before any client can see a style
        self.server.scene.set_up_direction("+z")
        self.server.gui.configure_theme(control_layout="fixed", control_width="large", dark_mode=False, show_logo=False)
        self.server.initial_camera.position = (2.0, -2.2, 1.3)
        self.server.initial_camera.look_at = (0.0, 0.0, 0.6)
        self.shadows = shadows
        self.set_shadows(shadows)
        self.server.scene.add_grid("/ground", width=40.0, height=40.0, plane="xy", cell_size=0.25,
                                   section_size=1.0, shadow_opacity=0.2)
        self.view = RobotView(self.server)
        self.ghost_root = self.server.scene.add_frame("/ghost", show_axes=False, visible=False)
        self.ghost_view = RobotView(self.server, root="/ghost/robot", opacity=0.35)
        self.ghost_visible = True
        self.ghost_offset = GHOST_OFFSETS["on robot"]
        self.overlays = Overlays(self.server)
        self.mode = "stand"
        self.robot_simulated = True
        self.session: StyleSession | None = None
        self.events_seen: dict[str, int] = {}
        self.notices: list[tuple[str, str]] = []
        self._last_notice_time = 0.0
        self.loaded = threading.Event()
        self.last_telemetry: msg.Telemetry | None = None
        self.last_engine_frame: msg.Frame | None = None  # the newest frame received (drawn or not)
        self.frame_rate = StreamRate(*FRAME_HZ)  # how many of the engine's frames are drawn
        self.telemetry_rate = StreamRate(*TELEMETRY_HZ)
        self.style_revision = 0
        self.edit_times: dict[int, float] = {}
        self.edit_latencies_s: list[float] = []
        self._limit_bodies: list[str] = []
        self._shade_cache: dict[str, tuple[str, float]] = {}

        # The panel has one explicit width (24 em, the theme's "large"), so a reload never narrows it, and six
        # top-level tabs fit one row in it: the two mocap workspaces (Retarget, Puppet) share the *Mocap* tab
        # as sub-tabs. Quadrupeds open on it (the Retarget workspace).
        self.server.gui.main_panel.set_width(PANEL_WIDTH_PX)
        label_text_fields(self.server)  # text fields reachable by their label (e.g. the Style tab's *New name*)
        tabs = self.server.gui.add_tab_group()
        quadruped_first = load_robot_config(robot).kind == "quadruped"
        if quadruped_first:
            self.tab_mocap = tabs.add_tab("Mocap")
        self.tab_robot = tabs.add_tab("Robot")
        self.tab_style = tabs.add_tab("Style")
        self.tab_sample = tabs.add_tab("Sample")
        self.tab_curves = tabs.add_tab("Curves")
        self.tab_plots = tabs.add_tab("Plots")
        if not quadruped_first:
            self.tab_mocap = tabs.add_tab("Mocap")
        with self.tab_mocap:
            mocap_tabs = self.server.gui.add_tab_group()
            self.tab_retarget = mocap_tabs.add_tab("Retarget")
            self.tab_puppet = mocap_tabs.add_tab("Puppet")
        with self.tab_robot:
            self.robot_panel = RobotPanel(self.server, self)
            self.drive = DrivePanel(self.server, self)
            from studio.panels.record_panel import RecordPanel

            self.record = RecordPanel(self.server, self)
        with self.tab_plots:
            self.plots = PlotsPanel(self.server)
        from studio.panels.retarget_panel import RetargetPanel

        with self.tab_retarget:
            self.retarget = RetargetPanel(self.server, self)
        from studio.panels.puppet_panel import PuppetPanel

        with self.tab_puppet:
            self.puppet = PuppetPanel(self.server, self)
        self._root_pos: np.ndarray | None = None
        self._style_folders: list = []
        self.style_browser: StyleBrowser | None = None
        self.sample_editor: SampleEditor | None = None
        self.curve_editor: CurveEditor | None = None
        self.rehearsal: RehearsalPanel | None = None
        self.speeds: StyleSpeeds | None = None

        self.link = EngineLink(robot, self._on_event, self._on_status, on_lost=self._on_engine_lost)
        self.server.on_client_connect(self._on_client)
        self._stop = threading.Event()
        self._status_thread = threading.Thread(target=self._status_loop, name="studio-status", daemon=True)

    # ------------------------------------------------------------------ lifecycle
    def start(self) -> "Studio":
        self.link.start()
        self._status_thread.start()
        loop = getattr(getattr(self.server, "_websock_server", None), "_background_event_loop", None)
        if loop is not None:  # viser's event loop (serialising and sending to every browser): after the engine
            loop.call_soon_threadsafe(yield_to_engine)
        return self

    def stop(self) -> None:
        self._stop.set()
        self.drive._stop.set()
        self.retarget.stop()
        if self.rehearsal is not None:
            self.rehearsal.stop()
        self.link.stop()
        self.server.stop()

    @property
    def url(self) -> str:
        return f"http://{self.server.get_host()}:{self.server.get_port()}"

    # ------------------------------------------------------------------ robot-dependent panels
    def _build_style_panels(self, robot: str) -> None:
        if self.rehearsal is not None:
            self.rehearsal.stop()
            self.rehearsal = None
        for folder in self._style_folders:
            folder.remove()
        self._style_folders.clear()
        self.session = None
        self.style_browser = self.sample_editor = self.curve_editor = None
        self.speeds = None
        cfg = load_robot_config(robot)
        if cfg.kind != "biped" or not cfg.default_style:
            for tab in (self.tab_style, self.tab_sample, self.tab_curves):
                with tab:
                    folder = self.server.gui.add_folder("Walking")
                    with folder:
                        self.server.gui.add_markdown(f"{cfg.display_name} is a {cfg.kind}: there is no walking "
                                                     "style to edit.")
                    self._style_folders.append(folder)
            return
        session = StyleSession(robot, folder=(self.styles_folder / robot) if self.styles_folder else None)
        session.warn = lambda text: self._notify("warning", text)
        opened = session.open(cfg.default_style)
        if not opened.ok:
            self._notify("error", opened.message)
        from engine.gait.rehearsal import SWEEP_DURATION_S
        from studio.panels.rehearsal_panel import RehearsalPanel
        from studio.panels.sample_editor import SampleEditor
        from studio.panels.style_browser import StyleBrowser
        from studio.panels.style_speeds import StyleSpeeds

        with self.tab_style:
            folder = self.server.gui.add_folder("Style")
            with folder:
                self.style_browser = StyleBrowser(self.server, session, self._notify)
                undo = self.server.gui.add_button("Undo", icon=viser.Icon.ARROW_BACK_UP)
                redo = self.server.gui.add_button("Redo", icon=viser.Icon.ARROW_FORWARD_UP)
                undo.on_click(lambda _: self._report(session.undo()))
                redo.on_click(lambda _: self._report(session.redo()))
            self._style_folders.append(folder)
            folder = self.server.gui.add_folder("Speeds")
            with folder:
                self.speeds = StyleSpeeds(self.server, session, self._notify)
            self._style_folders.append(folder)
        with self.tab_sample:
            folder = self.server.gui.add_folder("Sample")
            with folder:
                self.sample_editor = SampleEditor(self.server, session, self._notify, on_sample=self._on_sample)
            self._style_folders.append(folder)
            folder = self.server.gui.add_folder("Rehearsal")
            with folder:
                self.rehearsal = RehearsalPanel(self.server, session, self.rehearsal_duration_s or SWEEP_DURATION_S,
                                                auto=self.rehearse_after_edits, walks=self.rehearsal_walks,
                                                on_show_sample=self.select_sample)
            self._style_folders.append(folder)
        with self.tab_curves:
            folder = self.server.gui.add_folder("Function curves")
            with folder:
                self.curve_editor = self._make_curve_editor(session)
            self._style_folders.append(folder)
        self.session = session  # published once its panels exist: other threads see a complete set
        session.subscribe(self._on_style_change, urgent=True)  # the robot walks an edit first
        self._send_style()

    def _make_curve_editor(self, session: StyleSession):
        try:
            from studio.panels.curve_editor import CurveEditor
        except Exception:  # noqa: BLE001 - a broken editor module must not take the studio down
            self.server.gui.add_markdown("The curve editor is not available in this build.")
            return None
        editor = CurveEditor(self.server, session)
        editor.root_frame.position = tuple(np.asarray(self.drive.camera.robot_ground) + GRAPH_OFFSET)
        editor.root_frame.visible = self.mode == "edit"

        def bring_graph_beside_robot(client: viser.ClientHandle) -> None:
            """Frame the graph; "Camera follows robot" stays as it is (camera and graph travel together)."""
            if not self.drive.following:
                self.place_graph(self.drive.camera.robot_ground)  # bring it beside the robot first
            editor.root_frame.visible = True

        editor.before_look_at_graph = bring_graph_beside_robot
        editor.place_camera = self.drive.camera.place
        editor.on_sample_picked = self.select_sample
        editor.set_sample(self.sample_editor.sample_name if self.sample_editor else "in_place")
        return editor

    def select_sample(self, name: str) -> None:
        """One selected sample for the Sample tab, the Curves tab and the walk of Edit mode."""
        if self.sample_editor is not None and self.sample_editor.sample_name != name:
            self.sample_editor.select(name)  # → _on_sample

    @property
    def sample_name(self) -> str:
        return self.sample_editor.sample_name if self.sample_editor else "in_place"

    def _on_sample(self, name: str) -> None:
        if self.curve_editor is not None:
            self.curve_editor.set_sample(name)
        if self.mode == "edit":
            self.link.send(msg.SetMode("edit", {"sample": name}))

    def _on_style_change(self, style, reason: str) -> None:
        self._send_style()

    def _send_style(self) -> None:
        if self.session is None or self.session.style is None:
            return
        self.style_revision += 1
        self.edit_times[self.style_revision] = time.perf_counter()
        self.link.send(msg.SetStyle(self.session.as_document(), revision=self.style_revision))

    def _report(self, result) -> None:
        self._notify("info" if result.ok else "warning", result.message)

    # ------------------------------------------------------------------ engine events
    def _on_event(self, event: msg.Event) -> None:
        self.events_seen[event.kind] = self.events_seen.get(event.kind, 0) + 1
        if isinstance(event, msg.Frame):
            self._on_frame(event)
        elif isinstance(event, msg.Telemetry):
            self._on_telemetry(event)
        elif isinstance(event, msg.RobotLoaded):
            self._on_robot_loaded(event)
        elif isinstance(event, msg.Notice):
            self._notify(event.level, event.message)
            self.puppet.on_notice(event.level, event.message)
        elif isinstance(event, msg.JobProgress):
            from studio.panels.record_panel import JOB_PREFIX

            if event.job == "record" or event.job_id.startswith(JOB_PREFIX):
                self.record.on_job(event)
            else:
                self.retarget.on_job(event)

    def _on_frame(self, event: msg.Frame) -> None:
        """Draw the engine's frame — every one while the engine keeps real time, fewer while it falls behind
        (:mod:`studio.stream_rate`: the CPU goes to the simulation first)."""
        now = time.monotonic()
        self.last_engine_frame = event
        if len(event.body_pos):
            self._root_pos = event.body_pos[0]
        speed = float(self.drive.speed.value) if self.drive.speed.value else 1.0  # the sim clock's rate
        for rate in (self.frame_rate, self.telemetry_rate):
            rate.adapt(now, event.real_time_factor / speed)
        shown = self.view.last_frame
        urgent = shown is None or (event.mode, event.style_revision, event.paused, event.fallen) != (
            shown.mode, shown.style_revision, shown.paused, shown.fallen)
        if self.frame_rate.admit(now, urgent):
            self.view.update(event)
            self._measure_edit_latency(event)

    def _on_robot_loaded(self, event: msg.RobotLoaded) -> None:
        changed = event.robot != (self.session.robot if self.session else None)
        self.robot_name = event.robot
        self.robot_simulated = event.simulated
        self.view.load(event.robot, event.body_names)
        self.ghost_view.load(event.robot, event.body_names)
        self.puppet.on_view_loaded(event.robot)  # the capsules hang under the robot's (rebuilt) body frames
        model = load_robot(event.robot)
        self._limit_bodies = [model.mj_model.body(int(model.mj_model.jnt_bodyid[
            model.mj_model.joint(j).id])).name for j in model.joint_names]
        if model.config.soles:
            sole = model.config.soles["left"]
            self.overlays.set_sole(sole.length_m, sole.width_m)
        self.overlays.clear()
        if self.robot_panel.robot.value != event.robot:
            self.robot_panel.robot.value = event.robot  # type: ignore[misc]  # viser 1.1.1's stub types .value read-only
        if changed or self.session is None:
            self.mode = "stand"
            self._build_style_panels(event.robot)
            self.retarget.on_robot(event.robot, event.robot_kind)
            self.puppet.on_robot()
        else:
            self._send_style()  # an engine restart: give it back the edited style
            if self.mode == "puppet" and self.puppet.options:
                self.link.send(msg.SetMode("puppet", self.puppet.options))
            elif self.mode not in ("stand", "puppet") and self.sample_editor is not None:
                self.link.send(msg.SetMode(self.mode, {"sample": self.sample_editor.sample_name}))
        self.loaded.set()

    def _on_telemetry(self, event: msg.Telemetry) -> None:
        self.last_telemetry = event
        s = event.signals
        if self.telemetry_rate.admit(time.monotonic()):
            self._draw_telemetry(event)
        self.plots.add(event.sim_time_s, s)  # every sample: the plots' data, drawn at 2 Hz
        if "puppet" in s:
            self.puppet.on_telemetry(s, self._root_pos, event.sim_time_s)
        style = self.session.style if self.session is not None else None
        if self.curve_editor is not None and "phase" in s and style is not None and self.sample_editor:
            try:
                iv = style.samples[self.sample_editor.sample_name].intervals
                phi = float(s["phase"][0]) % 1.0
                t_cycle = float(iv.phase_map().time_at(phi))
                self.curve_editor.set_playhead(self.curve_editor.playhead_from_cycle_time(t_cycle)
                                               if self.mode == "edit" else None)
            except Exception:  # noqa: BLE001 - the playhead is cosmetic
                pass

    def _draw_telemetry(self, event: msg.Telemetry) -> None:
        """The overlays, the ghost and the joint-limit tints (at :data:`studio.stream_rate.TELEMETRY_HZ`)."""
        s = event.signals
        with self.server.atomic():  # one wake-up of viser's sender for the overlays, the ghost and the tints
            if "support_polygon" in s:
                self.overlays.update(s)
            if "ghost_body_pos" in s and self.ghost_visible:
                self._place_ghost()
                self.ghost_view.update(msg.Frame(0, event.sim_time_s, s["ghost_body_pos"], s["ghost_body_quat"],
                                                 np.zeros(0), False, False, 0.0))
            self._shade_joint_limits(s.get("joint_limit_proximity"))

    def _shade_joint_limits(self, proximity) -> None:
        """Links whose joint nears a limit turn red (paper §6.1)."""
        if proximity is None or len(proximity) != len(self._limit_bodies):
            return
        per_body: dict[str, float] = {}
        for body, p in zip(self._limit_bodies, proximity):
            per_body[body] = max(per_body.get(body, 0.0), float(p))
        for body, p in per_body.items():
            base = self.view.base_colors.get(body)
            if base is None:
                continue
            shade = (1 - p) * np.array(base) + p * np.array(LIMIT_RED)
            color = None if p <= 0.0 else (int(shade[0]), int(shade[1]), int(shade[2]))
            key = (body, round(p, 1))
            if self._shade_cache.get(body) != key:
                self._shade_cache[body] = key
                self.view.tint(body, color)

    def _measure_edit_latency(self, frame: msg.Frame) -> None:
        rev = frame.style_revision
        done = [r for r in self.edit_times if r <= rev]
        now = time.perf_counter()
        for r in done:
            self.edit_latencies_s.append(now - self.edit_times.pop(r))

    def _on_status(self, level: str, text: str) -> None:
        self._notify(level, text)

    def _on_engine_lost(self, pid: int | None) -> None:
        """The engine died: jobs and a recording that ran in it are gone (the link restarts the engine next)."""
        lost = self.retarget.on_engine_lost(pid) + self.record.on_engine_lost(pid)
        if lost:
            self._notify("warning", f"Lost with the engine (pid {pid}): {', '.join(lost)}. Nothing was half-written; "
                                    "start it again when the engine is back.")

    def _notify(self, level: str, text: str) -> None:
        if not text:
            return
        self.notices.append((level, text))
        self._last_notice_time = time.monotonic()
        color = NOTICE_COLORS.get(level, "blue")
        title = {"error": "Engine" if "engine" in text.lower() else "Error", "warning": "Heads up", "info": "Studio"}[
            level if level in ("error", "warning", "info") else "info"]
        for client in self.server.get_clients().values():
            client.add_notification(title, text, color=color, auto_close_seconds=6.0)

    def _on_client(self, client: viser.ClientHandle) -> None:
        for level, text in self.notices[-1:]:
            if level == "error" and time.monotonic() - self._last_notice_time < 10.0:
                client.add_notification("Engine", text, color="red", auto_close_seconds=6.0)

    # ------------------------------------------------------------------ actions
    def switch_robot(self, robot: str) -> None:
        if robot == self.robot_name:
            return
        self.loaded.clear()
        self.link.send(msg.SwitchRobot(robot))

    def set_mode(self, mode: str) -> None:
        if mode != "stand" and self.session is None:
            self._notify("warning", f"{self.robot_name} has no walking style: it can only stand")
            return
        self.mode = mode
        self.puppet.on_mode(mode)
        sample = self.sample_editor.sample_name if self.sample_editor else "in_place"
        self.link.send(msg.SetMode(mode, {"sample": sample}))
        self.overlays.set_visible(mode != "stand" and self.drive.show_overlays.value)
        self.set_ghost_visible(self.drive.show_ghost.value)
        if self.curve_editor is not None:
            self.curve_editor.root_frame.visible = mode == "edit"  # the graph is for editing a walking sample
        self.drive.camera.recentre()

    def set_shadows(self, on: bool) -> None:
        """Shadow maps from the default lights for every browser. Off by default: under software WebGL (no GPU)
        they cut the frame rate 1.7-5x (`studio bench render`); the environment light stays either way."""
        self.shadows = bool(on)
        self.server.scene.configure_default_lights(enabled=True, cast_shadow=self.shadows)

    def set_ghost_visible(self, visible: bool) -> None:
        self.ghost_visible = visible
        self.ghost_root.visible = visible and self.mode != "stand"

    def set_ghost_offset(self, label: str) -> None:
        """Draw the ghost on the robot or beside it (one of :data:`GHOST_OFFSETS`)."""
        self.ghost_offset = GHOST_OFFSETS.get(label, GHOST_OFFSETS["on robot"])
        self._place_ghost()

    def _place_ghost(self) -> None:
        """The ghost's frame: the chosen offset turned with the robot's heading (beside stays beside)."""
        forward, left = self.ghost_offset
        yaw = self.robot_yaw_rad() if (forward or left) else 0.0
        c, s = np.cos(yaw), np.sin(yaw)
        position = (c * forward - s * left, s * forward + c * left, 0.0)
        if tuple(self.ghost_root.position) != position:
            self.ghost_root.position = position

    def place_graph(self, robot_ground) -> None:
        """Put the curve graph at its place beside the robot (called while the camera follows the robot,
        with the same translation as the camera, so the graph stays put on screen)."""
        editor = self.curve_editor
        if editor is None:
            return
        target = tuple(float(v) for v in np.asarray(robot_ground, dtype=float) + GRAPH_OFFSET)
        if np.linalg.norm(np.subtract(target, editor.root_frame.position)) > 1e-3:
            editor.root_frame.position = target

    @property
    def dragging(self) -> bool:
        """A knot or tangent handle of the curve graph is being dragged."""
        return self.curve_editor is not None and self.curve_editor.dragging

    def velocity_limits(self) -> np.ndarray:
        if self.session is None or self.session.style is None:
            return np.zeros(3)
        v = self.session.style.velocities
        return np.array([v.x_max_mps, v.y_max_mps, v.yaw_max_radps])

    @property
    def robot_mass_kg(self) -> float:
        return load_robot(self.robot_name).mass_kg

    def robot_position(self) -> np.ndarray | None:
        frame = self.view.last_frame
        if frame is None or not len(frame.body_pos):
            return None
        return np.asarray(frame.body_pos[0], dtype=float)

    def robot_yaw_rad(self) -> float:
        frame = self.view.last_frame
        if frame is None or len(frame.body_quat) == 0:
            return 0.0
        w, x, y, z = (float(c) for c in frame.body_quat[0])
        return float(np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z)))

    def _status_loop(self) -> None:
        yield_to_engine()
        tick = 0
        while not self._stop.wait(STATUS_PERIOD_S):
            tick += 1
            frame = self.view.last_frame
            pid = self.link.pid
            if frame is None:
                text = f"Engine: starting (pid {pid})…"
            elif not self.robot_simulated:
                text = f"Engine running · pid {pid} · {self.robot_name} is a source skeleton: shown, not simulated"
            else:
                state = "paused" if frame.paused else ("fallen" if frame.fallen else "running")
                x, y = (float(v) for v in frame.body_pos[0][:2])
                yaw_deg = float(np.degrees(self.robot_yaw_rad()))
                walking = f" ({self.sample_name})" if frame.mode == "edit" else ""
                text = (f"Engine {state} · pid {pid} · {frame.mode} mode{walking} · t = {frame.sim_time_s:.1f} s · "
                        f"real-time factor {frame.real_time_factor:.2f} · pelvis at x {x:+.2f} m, y {y:+.2f} m, "
                        f"yaw {yaw_deg:+.0f}°")
                tel = self.last_telemetry
                text += recovery_text(tel.signals if tel is not None else {})
            self.robot_panel.show_status(text)
            self.record.tick_status()
            if tick % PLOT_EVERY_TICKS:
                continue
            try:
                self.plots.render()
            except Exception:  # noqa: BLE001 - plots are cosmetic
                pass


def recovery_text(signals: dict) -> str:
    """The status line's note while the controller recovers balance by walking part neutral
    (engine/control/recovery_blend.py): the animator then sees less of the style than authored."""
    share = signals.get("recovery_share")
    if share is None or len(share) == 0 or not float(share[0]) > 0.0:
        return ""
    if len(share) > 1 and float(share[1]) > 0.0:  # the walk's start: neutral first, then the style eases in
        return f" · starting from the neutral gait: walking {100 * float(share[0]):.0f} % neutral"
    return f" · balance recovery: walking {100 * float(share[0]):.0f} % neutral"


def serve(robot: str, host: str, port: int, token: str | None = None, shadows: bool = False,
          rehearse_after_edits: bool = True) -> None:
    from studio.access import browser_url

    studio = Studio(robot, host, port, token=token, shadows=shadows, rehearse_after_edits=rehearse_after_edits,
                    rehearsal_walks=SERVE_REHEARSAL_WALKS).start()
    url = browser_url(host, studio.server.get_port(), token) if token or host != "127.0.0.1" else studio.url
    print(f"Motion Studio: {url}  (robot {robot}; Ctrl+C to stop)", flush=True)

    def terminate(signum, frame):  # SIGTERM: stop like Ctrl+C (engine shut down; autosaves are atomic)
        raise KeyboardInterrupt

    import signal

    signal.signal(signal.SIGTERM, terminate)
    try:
        while True:
            time.sleep(1.0)
    except KeyboardInterrupt:
        pass
    finally:
        studio.stop()
