"""The Retarget workspace: bring a source motion onto a quadruped (STMR's UVM / SMR), watch and export it.

The panel only views and starts: the engine process imports, retargets, computes every frame's body poses
(forward kinematics) and exports, as jobs (``StartJob`` / ``JobProgress`` / ``CancelJob``, engine/jobs.py). The
panel plays back what the engine sent: the result robot, the source keypoints as a skeleton beside it, an
optional kinematic ghost over the result (UVM's motion beside an SMR result; SMR's — the motion TMR started from,
at the same point of the motion — beside an STMR result, which plays the open-loop replay in physics), a timeline
scrubber (an STMR result's α segments drawn on it), a contact strip (source vs result) and the metrics.
"""

from __future__ import annotations

import itertools
import threading
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import viser
from viser._messages import GuiSliderMark  # viser 1.1.1: the Slider's marks (no public name for them)

from engine import protocol as msg
from engine.jobs import DEMO_SOURCES, export_outputs
from engine.motion_files import OutsideLibrary, confined, list_files, motion_kind, motions_root, shared_root
from studio.job_outputs import cleanup_lost_outputs, lost_job_text

if TYPE_CHECKING:
    from studio.app import Studio

QUADRUPEDS = ("go1", "go2", "a1", "b1", "anymal_c")
METHODS = ("smr", "uvm", "stmr")  # stmr: SMR + TMR (BO over time scaling, iLQR in MuJoCo; minutes)
EXPORT_FORMATS = ("amp-json", "unitree-csv", "npz")
PLAYBACK_OFFSET = (0.0, 1.0, 0.0)  # the result plays beside the simulated robot (away from the camera)
SKELETON_OFFSET = (0.0, 1.0, 0.0)  # the source skeleton stands beside the result (relative to it)
PLAYBACK_HZ = 20.0
STRIP_COLUMNS = 60
LEG_NAMES = ("FL", "FR", "RL", "RR")
# skeleton segments between keypoints 4·leg + k (hip, thigh, knee, foot), plus the body quadrilateral
SEGMENTS = [(4 * leg + k, 4 * leg + k + 1) for leg in range(4) for k in range(3)] + [(0, 4), (4, 12), (12, 8), (8, 0)]
STANCE_RGB = np.array([20, 150, 60])
SWING_RGB = np.array([230, 120, 20])
BODY_RGB = np.array([60, 60, 200])
GHOST_RGB = (200, 60, 190)  # the kinematic ghost: see-through magenta over the result (light grey-blue robots)
# the α bar lines up with the Frame slider's track (measured in viser 1.1.1: label column on the left, the
# slider's number box on the right, inside the Mocap › Retarget › Playback folder)
ALPHA_BAR_INSET_LEFT, ALPHA_BAR_INSET_RIGHT = "7.45rem", "4.45rem"


def alpha_color(alpha: float) -> str:
    """Faster segments (α < 1) blue, slower (α > 1) orange, untouched grey; stronger the further from 1."""
    x = float(np.clip(np.log2(alpha), -2.0, 2.0)) / 2.0
    if abs(x) < 1e-3:
        return "#9e9e9e"
    base = np.array([40, 110, 230]) if x < 0 else np.array([230, 120, 20])
    rgb = (np.array([190, 190, 190]) * (1 - abs(x) ** 0.5) + base * abs(x) ** 0.5).astype(int)
    return "#" + "".join(f"{c:02x}" for c in rgb)


def alpha_bar_html(segments: dict, span_s: float) -> str:
    """An STMR result's α segments as blocks over the playback time (the Frame slider's range ``span_s``): each
    block is one of the S equal segments of the source motion, as long as it plays after re-timing, labelled
    with its α; below, the boundaries in seconds and the durations before → after."""
    alpha = [float(a) for a in segments["alpha"]]
    knots = [float(k) for k in segments["knots_s"]]
    span_s = max(float(span_s), 1e-9)
    cells = []
    for i, a in enumerate(alpha):
        t0, t1 = knots[i], min(knots[i + 1], span_s)
        cells.append(
            f'<div class="alpha-segment" data-alpha="{a:.4f}" title="segment {i + 1} of {len(alpha)}: '
            f'{knots[i]:.2f}–{knots[i + 1]:.2f} s, α {a:.3f}" style="flex:0 0 {100 * max(t1 - t0, 0.0) / span_s:.3f}%;'
            f'background:{alpha_color(a)};color:#fff;font-size:11px;text-align:center;overflow:hidden;'
            f'white-space:nowrap;border-left:{"2px solid #222" if i else "0"}">α {a:.2f}</div>')
    boundaries = " | ".join(f"{k:.2f}" for k in knots)
    before = float(segments.get("duration_before_s", knots[-1]))
    return (f'<div style="display:flex;height:18px;border-radius:3px;overflow:hidden;'
            f'margin:2px {ALPHA_BAR_INSET_RIGHT} 0 {ALPHA_BAR_INSET_LEFT}">{"".join(cells)}</div>'
            f'<div class="alpha-caption" style="font-size:11px;color:#666;margin-left:{ALPHA_BAR_INSET_LEFT}">'
            f'α segments {boundaries} s · {before:.2f} → {knots[-1]:.2f} s</div>')


def alpha_marks(segments: dict, fps: float, frames: int) -> tuple[GuiSliderMark, ...]:
    """Slider marks at the α segments' boundaries (frames), labelled with their time in seconds."""
    last = max(frames - 1, 1)
    out = []
    for k in segments["knots_s"]:
        f = float(min(max(float(k) * fps, 0.0), last))
        out.append(GuiSliderMark(f, f"{float(k):.2f} s"))
    return tuple(out)


def segment_at(segments: dict, t_s: float) -> tuple[int, float]:
    """(index, α) of the segment playing at ``t_s``."""
    knots = np.asarray(segments["knots_s"], float)
    i = int(np.clip(np.searchsorted(knots, t_s, side="right") - 1, 0, len(segments["alpha"]) - 1))
    return i, float(segments["alpha"][i])


def contact_strip(source: np.ndarray | None, result: np.ndarray, frame: int, columns: int = STRIP_COLUMNS) -> str:
    """Markdown: per leg, the source's and the result's contacts (█ stance, · swing) and the playhead (▲)."""
    T = len(result)
    cols = min(columns, T)
    idx = np.minimum((np.arange(cols) * T) // cols, T - 1)

    def row(contact: np.ndarray, leg: int) -> str:
        return "".join("█" if contact[i, leg] else "·" for i in idx)

    lines = []
    for leg, name in enumerate(LEG_NAMES):
        if source is not None and len(source) == T:
            lines.append(f"{name} src {row(source, leg)}")
        lines.append(f"{name} res {row(result, leg)}")
    head = int(np.searchsorted(idx, frame, side="right")) - 1
    lines.append("       " + " " * max(head, 0) + "▲")
    return "Contacts (█ stance, · swing)\n```\n" + "\n".join(lines) + "\n```"


def metrics_markdown(metrics: dict[str, Any]) -> str:
    rows = [("foot slide", "foot_slide_mm", "mm"), ("contact IoU", "contact_iou", ""),
            ("penetration", "penetration_mm", "mm"), ("keypoint error", "keypoint_error_mm", "mm"),
            ("DTW keypoint L1 vs UVM target (kinematic)", "dtw_keypoint_l1_percent", "%"),
            ("SMR's DTW keypoint L1 vs UVM target (kinematic)", "smr_kinematic_dtw_pct", "%"),
            ("DTW keypoint L1 (open-loop replay)", "dtw_keypoint_l1_pct", "%"), ("travel", "travel_m", "m"),
            ("frames", "frames", ""), ("fps", "fps", ""), ("wall time", "wall_time_s", "s"),
            ("α (TMR)", "alpha", ""), ("duration (TMR)", "duration_s", "s"), ("BO evaluations", "bo_evaluations", ""),
            ("replay fell", "replay_fell", ""), ("tracking error", "tracking_error_mm", "mm")]
    out = ["| metric | value |", "|---|---|"]
    for label, key, unit in rows:
        if key in metrics:
            value = metrics[key]
            if value is None:
                text = "n/a"
            elif isinstance(value, bool):
                text = "yes" if value else "no"
            elif isinstance(value, (int, float)):
                text = f"{value:g}"
            elif isinstance(value, dict) and {"before", "after"} <= value.keys():
                text = f"{value['before']:g} → {value['after']:g}"
            elif isinstance(value, (list, tuple)):
                text = ", ".join(f"{v:g}" if isinstance(v, (int, float)) else str(v) for v in value)
            else:
                text = str(value)
            out.append(f"| {label} | {text} {unit} |")
    return "\n".join(out)


class RetargetPanel:
    def __init__(self, server: viser.ViserServer, studio: "Studio", root: Path | None = None):
        self.server = server
        self.studio = studio
        self.root = Path(root) if root is not None else motions_root()
        self._ids = itertools.count(1)
        self.job_id: str | None = None  # the running retarget job
        self.playback: dict[str, Any] | None = None
        self.result_path: str | None = None
        self.results_seen = 0
        self._robots_seen = 0
        self._last_robot = ""
        self.frame = 0
        self._time_s = 0.0
        self._setting_slider = False
        self._strip_key: tuple | None = None
        self._lock = threading.Lock()
        self._stop = threading.Event()
        gui = server.gui

        # ---- source
        with gui.add_folder("Source"):
            self.source = gui.add_dropdown("Source", self._source_options())
            self.refresh = gui.add_button("Refresh list", icon=viser.Icon.REFRESH)
            self.import_root = gui.add_dropdown("Import from", ("shared motions-src", "motions"))
            self.import_path = gui.add_text("Import path", "")
            self.import_check = gui.add_markdown("")
            self.import_button = gui.add_button("Import", icon=viser.Icon.FILE_IMPORT)
        # ---- target and method
        with gui.add_folder("Target"):
            self.robot = gui.add_dropdown("Robot", QUADRUPEDS)
            self.method = gui.add_dropdown("Method", METHODS)
            self.baseless = gui.add_checkbox("Baseless", False)
            self.terrain = gui.add_text("Terrain boxes", "", hint="box:x,y,w,d,h; box:…  (metres)")
            self.with_ghost = gui.add_checkbox("Compute UVM ghost", True,
                                               hint="smr: also retarget with UVM, shown as a ghost to compare "
                                                    "(an stmr result's ghost is always its SMR motion)")
            self.budget = gui.add_slider("TMR budget", min=1, max=30, step=1, initial_value=6,
                                         hint="stmr: Bayesian-optimisation evaluations at most")
            self.segments = gui.add_slider("TMR segments", min=1, max=6, step=1, initial_value=1,
                                           hint="stmr: S equal segments of the motion, each re-timed by its own α")
            self.run = gui.add_button("Run", icon=viser.Icon.PLAYER_PLAY)
            self.cancel = gui.add_button("Cancel", icon=viser.Icon.PLAYER_STOP, disabled=True)
            self.progress = gui.add_progress_bar(0.0, animated=False)
            self.status = gui.add_markdown("Job: idle")
        # ---- playback
        with gui.add_folder("Playback"):
            self.results = gui.add_dropdown("Result", self._result_options())
            self.view_button = gui.add_button("View result", icon=viser.Icon.EYE)
            self.alpha_bar = gui.add_html("")  # an STMR result's α segments, aligned with the Frame slider
            self.timeline = gui.add_slider("Frame", min=0, max=1, step=1, initial_value=0, disabled=True)
            self.clock = gui.add_markdown("No motion loaded")
            self.play = gui.add_button("Play / pause", icon=viser.Icon.PLAYER_PAUSE, disabled=True)
            self.speed = gui.add_slider("Speed", min=0.1, max=2.0, step=0.05, initial_value=1.0)
            self.show_ghost = gui.add_checkbox("Show ghost", True, hint="the kinematic motion over the result: "
                                               "UVM's beside SMR, SMR's (re-timed by α) beside STMR's physics")
            self.show_skeleton = gui.add_checkbox("Show source skeleton", True)
            self.playing = False
            self.strip = gui.add_markdown("")
            self.metrics = gui.add_markdown("")
        with gui.add_folder("Export"):
            self.export_format = gui.add_dropdown("Format", EXPORT_FORMATS)
            self.amp_full = gui.add_checkbox("AMP full (61 values)", False)
            self.export_button = gui.add_button("Export", icon=viser.Icon.DOWNLOAD, disabled=True)
            self.export_status = gui.add_markdown("")

        self.refresh.on_click(lambda _: self.refresh_lists())
        self.import_button.on_click(lambda _: self.start_import())
        self.import_path.on_update(self._on_import_path_edited)
        self.import_root.on_update(self._on_import_path_edited)
        self.run.on_click(lambda _: self.start_retarget())
        self.cancel.on_click(lambda _: self.cancel_job())
        self.view_button.on_click(lambda _: self.view_result(self.results.value))
        self.timeline.on_update(lambda _: self._on_scrub())
        self.play.on_click(lambda _: self.toggle_play())
        self.export_button.on_click(lambda _: self.start_export())
        self.show_ghost.on_update(lambda _: self._update_visibility())
        self.show_skeleton.on_update(lambda _: self._update_visibility())

        # ---- scene: the result robot, its UVM ghost and the source skeleton
        from studio.robot_view import RobotView

        self.scene_root = server.scene.add_frame("/retarget", position=PLAYBACK_OFFSET, show_axes=False, visible=False)
        self.robot_view = RobotView(server, root="/retarget/robot")
        self.ghost_view = RobotView(server, root="/retarget/ghost", opacity=0.3)
        self.skeleton_root = server.scene.add_frame("/retarget/skeleton", position=SKELETON_OFFSET, show_axes=False)
        self.skeleton: viser.LineSegmentsHandle | None = None
        self._pending: dict[str, str] = {}  # job id → kind of the jobs this panel waits for
        self._outputs: dict[str, tuple[float, list[str]]] = {}  # job id → (start time, files it will write)
        self._thread = threading.Thread(target=self._playback_loop, name="retarget-playback", daemon=True)
        self._thread.start()

    def on_robot(self, robot: str, kind: str) -> None:
        """The studio's robot changed: a quadruped becomes the retarget target and this workspace is its home."""
        if kind != "quadruped" or robot not in QUADRUPEDS:
            return
        self.robot.value = robot  # type: ignore[misc]  # viser 1.1.1's stub types .value read-only
        if self._robots_seen and robot != self._last_robot:  # not again when a restarted engine loads it anew
            self.studio._notify("info", f"{robot} is a quadruped: retarget motions onto it in the Retarget tab.")
        self._robots_seen += 1
        self._last_robot = robot

    # ------------------------------------------------------------------ lists
    def _source_options(self) -> tuple[str, ...]:
        files = [f for f in list_files(self.root, "source") if motion_kind(self.root / f) == "keypoint-motion/1"]
        return (*DEMO_SOURCES, *files)

    def _result_options(self) -> tuple[str, ...]:
        out = [f for f in list_files(self.root) if not f.startswith(("source/", "exports/"))
               and not f.endswith((".uvm.npz", ".smr.npz")) and motion_kind(self.root / f) == "robot-motion/1"]
        return tuple(out) or ("(none yet)",)

    def refresh_lists(self, select_source: str | None = None, select_result: str | None = None) -> None:
        self.source.options = self._source_options()
        if select_source in self.source.options:
            self.source.value = select_source  # type: ignore[misc]  # viser 1.1.1's stub types .value read-only
        self.results.options = self._result_options()
        if select_result in self.results.options:
            self.results.value = select_result  # type: ignore[misc]  # viser 1.1.1's stub types .value read-only

    # ------------------------------------------------------------------ jobs
    def _start(self, job: str, params: dict, outputs: tuple[str, ...] = ()) -> str:
        job_id = f"{job}-{next(self._ids)}"
        self._pending[job_id] = job
        self._outputs[job_id] = (time.time(), list(outputs))
        self.studio.link.send(msg.StartJob(job, params, job_id=job_id))
        return job_id

    def on_engine_lost(self, pid: int | None) -> list[str]:
        """The engine process died (the link's thread, before it restarts the engine): every job this panel
        waited for is lost. Say so where each job reports, re-enable Run, remove the temporaries a write cut
        short may have left next to the outputs (the outputs themselves are written atomically: whole or not at
        all). Returns what was lost, for the studio's notice."""
        lost = []
        for job_id, kind in list(self._pending.items()):
            self._pending.pop(job_id, None)
            started, outputs = self._outputs.pop(job_id, (0.0, []))
            written = cleanup_lost_outputs(self.root, outputs, started)
            again = {"retarget": "press Run", "poses": "press View result", "import": "press Import",
                     "export": "press Export"}.get(kind, "start it")
            text = lost_job_text(pid, written, again)
            if kind == "retarget":
                self.job_id = None
                self.run.disabled = False
                self.cancel.disabled = True
                self.progress.animated = False
                self.progress.value = 0.0  # type: ignore[misc]  # viser 1.1.1's stub types .value read-only
                self._set_status(f"Retarget lost: {text}")
                if written:
                    self.refresh_lists(select_result=written[0])
            elif kind == "export":
                self.export_status.content = f"Export lost: {text}"
            else:
                self._set_status(f"{kind.capitalize()} lost: {text}")
            lost.append(f"the {kind} job")
        return lost

    def _import_root(self) -> Path | None:
        if self.import_root.value.startswith("shared"):
            shared = shared_root()
            return shared / "motions-src" if shared is not None else None
        return self.root

    def _on_import_path_edited(self, _event: object) -> None:
        self._check_import_path()  # shows its verdict under the field

    def _check_import_path(self) -> bool:
        """Say at once whether the typed path can be imported (inside the chosen folder, a file)."""
        path = self.import_path.value.strip()
        root = self._import_root()
        if root is None:
            self.import_check.content = "✗ no shared data folder on this machine"
            return False
        try:
            found = confined(root, path).is_file()  # the engine checks again when it imports
        except OutsideLibrary as exc:
            self.import_check.content = f"✗ `{exc}`"
            return False
        self.import_check.content = f"✓ `{path}`" if found else f"✗ `{path}`: no such file in {root.name}/"
        return found

    def start_import(self) -> None:
        path = self.import_path.value.strip()
        root = "shared" if self.import_root.value.startswith("shared") else "motions"
        if not self._check_import_path():
            self._set_status(f"Import refused: {self.import_check.content.lstrip('✗ ')}")
            return
        self._set_status(f"Importing `{path}`…")
        self._start("import", {"root": root, "path": path}, (f"source/{Path(path).stem.replace(' ', '_')}.npz",))

    def start_retarget(self) -> None:
        if self.job_id is not None:
            return
        source = self.source.value
        method = self.method.value
        terrain = [s.strip() for s in self.terrain.value.split(";") if s.strip()]
        name = f"{Path(source.split(':')[-1]).stem}_{method}" + ("_baseless" if self.baseless.value else "")
        robot = self.robot.value
        outputs = (f"{robot}/{name}.npz", f"{robot}/{name}.uvm.npz", f"{robot}/{name}.smr.npz")
        self.job_id = self._start("retarget", {
            "source": source, "robot": robot, "method": method, "baseless": self.baseless.value,
            "terrain": terrain, "name": name, "uvm_ghost": self.with_ghost.value,
            "budget": int(self.budget.value), "segments": int(self.segments.value),
        }, outputs)
        self._source_of_job = source
        self.run.disabled = True
        self.cancel.disabled = False
        self.progress.value = 0.0  # type: ignore[misc]  # viser 1.1.1's stub types .value read-only
        self.progress.animated = True
        self._set_status(f"Retarget running: {method.upper()} `{source}` → {self.robot.value} (0 %)")

    def cancel_job(self) -> None:
        if self.job_id is not None:
            self.studio.link.send(msg.CancelJob(self.job_id))
            self._set_status("Retarget: cancelling…")

    def view_result(self, path: str) -> None:
        if not path or path.startswith("("):
            return
        params: dict[str, Any] = {"motion": path}
        for suffix in (".smr.npz", ".uvm.npz"):  # an STMR result's SMR motion, else an SMR result's UVM comparison
            ghost = path[:-4] + suffix
            if (self.root / ghost).is_file():
                params["ghost"] = ghost
                break
        source = self._source_for(path)
        if source:
            params["source"] = source
        self._set_status(f"Loading `{path}`…")
        self._start("poses", params)

    def _source_for(self, path: str) -> str | None:
        """The studio source a result was made from, if it is still in the library (or a demo)."""
        from engine.safe_io import ReadError, parse_json, read_npz

        try:  # only the source entry, through safe_io (a bomb elsewhere in the file is never inflated)
            source = read_npz(self.root / path, only=("source",)).get("source")
            meta = parse_json(str(source), path) if source is not None and source.ndim == 0 else {}
        except ReadError:  # then the result plays without its source
            return None
        spec = meta.get("studio_source") if isinstance(meta, dict) else None
        if spec in DEMO_SOURCES or (spec and (self.root / spec).is_file()):
            return spec
        return None

    def start_export(self) -> None:
        if not self.result_path:
            return
        self.export_status.content = "Exporting…"
        params = {"motion": self.result_path, "format": self.export_format.value, "amp_full": self.amp_full.value}
        self._start("export", params, export_outputs(self.root, params))

    def on_job(self, event: msg.JobProgress) -> None:
        """JobProgress from the engine (the link's thread)."""
        kind = self._pending.get(event.job_id)
        if kind is None:
            return
        if event.result is None:
            if event.job_id == self.job_id:
                self.progress.value = float(np.clip(100.0 * event.fraction, 0.0, 100.0))  # type: ignore[misc]  # viser 1.1.1's stub types .value read-only
                self._set_status(f"Retarget running: {event.message} ({100 * event.fraction:.0f} %)")
            return
        self._pending.pop(event.job_id, None)
        self._outputs.pop(event.job_id, None)
        result = event.result
        if kind == "retarget":
            self.job_id = None
            self.run.disabled = False
            self.cancel.disabled = True
            self.progress.animated = False
            if result.get("ok"):
                self.progress.value = 100.0  # type: ignore[misc]  # viser 1.1.1's stub types .value read-only
                self._set_status(f"Result: `{result['path']}` written")
                self.refresh_lists(select_result=result["path"])
                self._show(result["path"], result["playback"], result.get("metrics", {}))
            elif result.get("cancelled"):
                self.progress.value = 0.0  # type: ignore[misc]  # viser 1.1.1's stub types .value read-only
                self._set_status("Retarget cancelled: nothing written")
            else:
                self.progress.value = 0.0  # type: ignore[misc]  # viser 1.1.1's stub types .value read-only
                self._set_status(f"Retarget failed: `{result.get('error')}`")
        elif kind == "poses":
            if result.get("ok"):
                self._set_status(f"Viewing `{result['path']}`")
                self._show(result["path"], result["playback"], result.get("metrics", {}))
            else:
                self._set_status(f"Cannot view: `{result.get('error')}`")
        elif kind == "import":
            if result.get("ok"):
                self._set_status(f"Imported `{result['path']}` ({result['frames']} frames at {result['fps']:g} fps)")
                self.refresh_lists(select_source=result["path"])
            else:
                self._set_status(f"Import failed: {result.get('error')}")
        elif kind == "export":
            self.export_status.content = (f"Exported: `motions/{result['path']}`" if result.get("ok")
                                          else f"Export failed: `{result.get('error')}`")

    def _set_status(self, text: str) -> None:
        self.status.content = text

    # ------------------------------------------------------------------ playback
    def _show(self, path: str, playback: dict, metrics: dict) -> None:
        with self._lock:
            self.playback = playback
            self.result_path = path
            self.frame = 0
            self._time_s = 0.0
            self._strip_key = None
        robot = playback["robot"]
        names = tuple(playback["body_names"])
        self.robot_view.load(robot, names)
        if "ghost_pos" in playback:
            self.ghost_view.load(robot, names)
            for body in list(self.ghost_view.meshes):
                self.ghost_view.tint(body, GHOST_RGB)
        else:
            self.ghost_view.load(robot, ())
        T = int(playback["frames"])
        self.timeline.max = max(T - 1, 1)
        segments = playback.get("segments")
        if segments:
            self.alpha_bar.content = alpha_bar_html(segments, (T - 1) / float(playback["fps"]))
            self.timeline._marks = alpha_marks(segments, float(playback["fps"]), T)
        else:
            self.alpha_bar.content = ""
            self.timeline._marks = None
        ghost_method = playback.get("ghost_method")
        self.show_ghost.label = f"Show {ghost_method.upper()} ghost" if ghost_method else "Show ghost"
        self.timeline.disabled = False
        self.play.disabled = False
        self.export_button.disabled = False
        self.metrics.content = f"`{path}` ({playback['method'].upper()} on {robot})\n\n" + metrics_markdown(metrics)
        self.scene_root.visible = True
        self._update_visibility()
        self.playing = True
        self.results_seen += 1
        self._render(0)
        for client in self.server.get_clients().values():
            start = playback["body_pos"][0, 0] + np.array(PLAYBACK_OFFSET)
            client.camera.look_at = tuple(start + np.array([0.3, 0.4, -0.1]))
            client.camera.position = tuple(start + np.array([1.6, -2.0, 1.0]))

    def _update_visibility(self) -> None:
        pb = self.playback
        ghost = bool(pb is not None and "ghost_pos" in pb and self.show_ghost.value)
        for handle in [*self.ghost_view.frames]:
            handle.visible = ghost
        self.skeleton_root.visible = bool(self.show_skeleton.value and pb is not None and "source_keypoints" in pb)

    def toggle_play(self) -> None:
        self.playing = not self.playing
        self._render(self.frame)

    def _on_scrub(self) -> None:
        if self._setting_slider or self.playback is None:
            return
        self.playing = False
        frame = int(self.timeline.value)
        with self._lock:
            self._time_s = frame / float(self.playback["fps"])
        self._render(frame)

    def _playback_loop(self) -> None:
        period = 1.0 / PLAYBACK_HZ
        last = time.monotonic()
        while not self._stop.wait(period):
            now = time.monotonic()
            dt, last = now - last, now
            pb = self.playback
            if pb is None or not self.playing:
                continue
            with self._lock:
                self._time_s += dt * float(self.speed.value)
                T = int(pb["frames"])
                frame = int(self._time_s * float(pb["fps"])) % T
            try:
                self._render(frame, move_slider=True)
            except Exception:  # noqa: BLE001 - a dropped frame must not stop playback
                pass

    def _render(self, frame: int, move_slider: bool = False) -> None:
        pb = self.playback
        if pb is None:
            return
        frame = int(np.clip(frame, 0, int(pb["frames"]) - 1))
        self.frame = frame
        self.robot_view.update(msg.Frame(frame, frame / pb["fps"], pb["body_pos"][frame], pb["body_quat"][frame],
                                         np.zeros(0), False, False, 0.0))
        if "ghost_pos" in pb and self.show_ghost.value:
            self.ghost_view.update(msg.Frame(frame, 0.0, pb["ghost_pos"][frame], pb["ghost_quat"][frame],
                                             np.zeros(0), False, False, 0.0))
        if "source_keypoints" in pb and self.show_skeleton.value:
            self._draw_skeleton(pb, frame)
        clock = f"Frame {frame} of {int(pb['frames'])} · {frame / pb['fps']:.2f} s · {'playing' if self.playing else 'paused'}"
        if pb.get("segments"):
            i, a = segment_at(pb["segments"], frame / pb["fps"])
            clock += f" · segment {i + 1} of {len(pb['segments']['alpha'])}, α {a:.2f}"
        if clock != self.clock.content:
            self.clock.content = clock
        source_contact = pb.get("source_contact")
        key = (id(pb), int(frame * STRIP_COLUMNS / max(int(pb["frames"]), 1)))
        if key != self._strip_key:
            self._strip_key = key
            self.strip.content = contact_strip(source_contact, pb["contact"], frame)
        if move_slider:
            self._setting_slider = True
            try:
                self.timeline.value = frame  # type: ignore[misc]  # viser 1.1.1's stub types .value read-only
            finally:
                self._setting_slider = False

    def _draw_skeleton(self, pb: dict, frame: int) -> None:
        kp = pb["source_keypoints"]
        # the result may be re-timed (TMR): the engine says which source frame each frame shows (s_α(t))
        f = int(pb["source_frame"][frame]) if "source_frame" in pb else min(frame, len(kp) - 1)
        points = np.array([[kp[f, a], kp[f, b]] for a, b in SEGMENTS], dtype=np.float32)
        contact = pb["source_contact"][min(f, len(kp) - 1)]
        colors = np.array([[STANCE_RGB if contact[i // 3] else SWING_RGB] * 2 for i in range(12)]
                          + [[BODY_RGB] * 2] * 4, dtype=np.uint8)
        if self.skeleton is None:
            self.skeleton = self.server.scene.add_line_segments("/retarget/skeleton/lines", points, colors,
                                                                thickness=0.012)
        else:
            self.skeleton.points = points
            self.skeleton.colors = colors

    def stop(self) -> None:
        self._stop.set()
