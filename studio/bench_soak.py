"""``studio bench soak --minutes M --clients C``: drive a running studio for M minutes (issue 14).

The studio runs in this process (a real engine process behind it) in Test mode. C headless WebSocket
clients (in a child process of their own: this process's RSS and CPU are the studio's) speak viser's protocol (the subprotocol handshake and a camera message, as a browser tab does)
and count what the server streams to them; T browser tabs (Debian's headless Chromium through playwright,
software WebGL) render the studio and count the frames they draw (requestAnimationFrame); they run as on a user's own machine, unable to raise their
priority over the engine (``--tab-nice N`` also lowers it, as a user can). Meanwhile the joystick is held (forward, then turning), the
pelvis is pushed every 10 s and a sample attribute is edited every 5 s (through the style session, so
each edit is validated, autosaved and sent to the engine).

Reported: RSS of the studio and of the engine at the end of warm-up and at the end (growth in %),
WebSocket messages and bytes per second per client, frames per second each browser tab drew, frames per second the studio received from the
engine and how many of them it drew (its stream rate, :mod:`studio.stream_rate`), sim-clock drift against the wall clock (time simulated ÷ Δwall − 1 over the measured window, playback speed
1; a reset of the sim clock — a fall — is counted apart, see :func:`sim_clock`), falls, engine restarts, and every exception seen (logging records with a traceback, thread exceptions,
error notices).
"""

from __future__ import annotations

import logging
import os
import shutil
import tempfile
import threading
import time
import traceback
from pathlib import Path
from typing import Any


def sim_clock(window: list[tuple[float, float]]) -> dict[str, float | int]:
    """The sim clock against the wall clock over frames ``(wall s, sim s)`` in arrival order.

    A reset (a fall, a mode switch) sets the sim clock back: the time simulated is the sum of the
    forward steps, so a reset counts as a reset, not as lost time. ``drift`` = simulated ÷ wall − 1
    (playback speed 1); ``longest_stall_s``: the longest wall time between two frames whose sim time
    did not move forward (a paused or starved engine)."""
    if len(window) < 2:
        return {"drift": float("nan"), "simulated_s": 0.0, "wall_s": 0.0, "resets": 0, "longest_stall_s": 0.0}
    simulated_s, resets, stall_s, longest_stall_s = 0.0, 0, 0.0, 0.0
    for (w_a, s_a), (w_b, s_b) in zip(window, window[1:]):
        if s_b < s_a - 1e-9:
            resets += 1
            stall_s = 0.0
        elif s_b > s_a + 1e-9:
            simulated_s += s_b - s_a
            stall_s = 0.0
        else:
            stall_s += w_b - w_a
            longest_stall_s = max(longest_stall_s, stall_s)
    wall_s = window[-1][0] - window[0][0]
    return {"drift": simulated_s / wall_s - 1.0 if wall_s > 0 else float("nan"), "simulated_s": simulated_s,
            "wall_s": wall_s, "resets": resets, "longest_stall_s": longest_stall_s}


def _rss_mb(pid: int | None) -> float:
    if pid is None:
        return float("nan")
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return float("nan")


def _decode_window(data: bytes, decompressor=None) -> list[dict]:  # noqa: ANN001 - zstandard.ZstdDecompressor
    """The messages of one viser 1.1.1 WebSocket message (a "window"): 8-byte msgpack length, 8-byte
    compressed length, zstd-compressed msgpack ``{"messages": [...]}``, then raw binary buffers.
    ``decompressor``: a ZstdDecompressor to reuse (a client decodes every window with its own, as a browser
    does; a new zstd context per window churns the C heap of the bench's client threads)."""
    import msgspec
    import zstandard

    inner_len = int.from_bytes(data[0:8], "little")
    compressed_len = int.from_bytes(data[8:16], "little")
    dctx = decompressor if decompressor is not None else zstandard.ZstdDecompressor()
    inner = dctx.decompress(data[16:16 + compressed_len], max_output_size=inner_len)
    return list(msgspec.msgpack.decode(inner).get("messages", ()))


POSE_TYPES = {"SetPositionMessage": "position", "SetOrientationMessage": "wxyz"}


class _Client(threading.Thread):
    """A headless viser client: counts WebSocket messages (viser's windows of messages) and robot-pose
    frames (windows that carry a pose of a body under ``/robot/``), and keeps the last pose of each node."""

    def __init__(self, url: str, stop: threading.Event, robot_root: str = "/robot/"):
        super().__init__(daemon=True, name="soak-client")
        self.url, self.stop = url, stop
        self.robot_root = robot_root
        self.messages = 0
        self.bytes = 0
        self.robot_frames = 0
        self.poses: dict[str, dict[str, tuple[float, ...]]] = {}  # node name → {"position"|"wxyz": value}
        self.error = ""
        self.window: tuple[int, int, int, float] | None = None  # (messages, bytes, frames, t) at the start
        self._dctx: Any = None  # this client's zstd decompressor (created in its thread, reused for every window)

    def mark(self) -> None:
        self.window = (self.messages, self.bytes, self.robot_frames, time.monotonic())

    def rates(self) -> tuple[float, float, float]:
        """WebSocket messages/s, KiB/s and robot-pose frames/s since :meth:`mark`."""
        if self.window is None:
            return float("nan"), float("nan"), float("nan")
        m0, b0, f0, t0 = self.window
        dt = time.monotonic() - t0
        return (self.messages - m0) / dt, (self.bytes - b0) / dt / 1024.0, (self.robot_frames - f0) / dt

    def _take(self, data: bytes) -> None:
        import zstandard

        if self._dctx is None:
            self._dctx = zstandard.ZstdDecompressor()
        robot = False
        for m in _decode_window(data, self._dctx):
            key = POSE_TYPES.get(m.get("type", ""))
            if key is None:
                continue
            name = m.get("name", "")
            self.poses.setdefault(name, {})[key] = tuple(m[key])
            robot = robot or name.startswith(self.robot_root)
        self.robot_frames += robot

    def run(self) -> None:
        import msgspec
        import viser
        from websockets.sync.client import connect

        camera = msgspec.msgpack.encode({
            "type": "ViewerCameraMessage", "wxyz": [1.0, 0.0, 0.0, 0.0], "position": [2.0, -2.2, 1.3],
            "image_height": 480, "image_width": 640, "fov": 1.0, "near": 0.01, "far": 1000.0,
            "look_at": [0.0, 0.0, 0.6], "up_direction": [0.0, 0.0, 1.0]})
        try:
            from websockets.typing import Subprotocol

            with connect(self.url, subprotocols=[Subprotocol(f"viser-v{viser.__version__}")], open_timeout=30,
                         max_size=None) as ws:
                ws.send(camera)
                while not self.stop.is_set():
                    try:
                        data = ws.recv(timeout=0.5)
                    except TimeoutError:
                        continue
                    self.messages += 1
                    self.bytes += len(data)
                    if isinstance(data, bytes):
                        self._take(data)
        except Exception as exc:  # noqa: BLE001 - reported
            self.error = f"{type(exc).__name__}: {exc}"


class _ClientProcess:
    """The headless clients in a child process of their own (``python -m studio.bench_soak URL N``), so that the
    studio process's RSS and CPU are the studio's: in this process their threads' C heaps (a decoded window every
    60 ms per client) kept growing — 382 → 403 MB in a 3-minute soak with 8 clients, against 367 → 368 MB with
    the same 8 clients in a child process (glibc's in-use bytes flat at 90 MB either way: freed memory kept by the
    client threads' malloc arenas, all of it returned by malloc_trim). Line protocol on its stdin/stdout:
    ``mark`` (start the measured window), ``report`` (one JSON line: per client messages/s, KiB/s, robot
    frames/s, error), ``stop``."""

    def __init__(self, url: str, clients: int):
        import subprocess
        import sys

        repo = str(Path(__file__).resolve().parents[1])
        env = {**os.environ, "PYTHONPATH": os.pathsep.join([repo, *filter(None, [os.environ.get("PYTHONPATH")])])}
        self.proc = subprocess.Popen([sys.executable, "-m", "studio.bench_soak", url, str(clients)], env=env,
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, bufsize=1)
        self.clients = clients

    @property
    def pid(self) -> int:
        return self.proc.pid

    def _ask(self, command: str) -> str:
        assert self.proc.stdin is not None and self.proc.stdout is not None
        self.proc.stdin.write(command + "\n")
        self.proc.stdin.flush()
        return self.proc.stdout.readline()

    def mark(self) -> None:
        self._ask("mark")

    def report(self) -> list[dict]:
        import json

        line = self._ask("report")
        if not line:
            return [{"rates": [float("nan")] * 3, "error": f"the client process ended ({self.proc.poll()})"}]
        return json.loads(line)

    def stop(self) -> None:
        try:
            self._ask("stop")
        except (OSError, ValueError):
            pass
        try:
            self.proc.wait(10)
        except Exception:  # noqa: BLE001 - a wedged child is killed
            self.proc.kill()
            self.proc.wait(10)


def _client_process_main(url: str, n: int) -> None:
    """The child of :class:`_ClientProcess`: ``n`` clients, answering its parent's commands on stdin."""
    import json
    import sys

    stop = threading.Event()
    pool = [_Client(url, stop) for _ in range(n)]
    for c in pool:
        c.start()
    print("ready", flush=True)
    for line in sys.stdin:
        command = line.strip()
        if command == "mark":
            for c in pool:
                c.mark()
            print("ok", flush=True)
        elif command == "report":
            print(json.dumps([{"rates": list(c.rates()), "error": c.error} for c in pool]), flush=True)
        elif command == "stop":
            break
    stop.set()
    for c in pool:
        c.join(5)
    print("stopped", flush=True)


THREAD_GROUPS = (  # thread name prefix → what it does (the studio's threads, then the bench's own)
    ("engine-link", "frame path (robot, ghost, overlays, plots buffer)"),
    ("studio-status", "status text + plots"),
    ("joystick", "joystick + camera follow"),
    ("ThreadPoolExecutor", "viser callbacks"),
    ("soak-client", "bench: headless clients"),  # in process only in tests; the soak runs them in a child
    ("soak-tab", "bench: tab drivers"),
    ("MainThread", "bench: driver"),
)


def _thread_cpu_s() -> dict[str, float]:
    """CPU seconds (user + system) of this process's threads, summed per :data:`THREAD_GROUPS` entry;
    every other thread (viser's event loop: message windows, serialisation, WebSocket sends) is "viser"."""
    names = {t.native_id: t.name for t in threading.enumerate()}
    tick = os.sysconf("SC_CLK_TCK")
    out: dict[str, float] = {}
    for task in Path("/proc/self/task").iterdir():
        try:
            fields = (task / "stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        cpu = (int(fields[11]) + int(fields[12])) / tick
        name = names.get(int(task.name), "")
        group = next((g for prefix, g in THREAD_GROUPS if name.startswith(prefix)), "viser event loop + other")
        out[group] = out.get(group, 0.0) + cpu
    return out


def _process_cpu_s(pid: int | None) -> float:
    if pid is None:
        return float("nan")
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return float("nan")
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _children() -> dict[int, list[int]]:
    out: dict[int, list[int]] = {}
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                ppid = int((d / "stat").read_text().rsplit(")", 1)[1].split()[1])
            except (OSError, IndexError, ValueError):
                continue
            out.setdefault(ppid, []).append(int(d.name))
    return out


def _tab_processes(engine_pid: int | None) -> list[int]:
    """This process's descendants but the engine's: the tabs (playwright's driver and Chromium's processes)."""
    children, found, todo = _children(), [], [os.getpid()]
    while todo:
        for kid in children.get(todo.pop(), []):
            if kid != engine_pid:
                found.append(kid)
                todo.append(kid)
    return found


def _tabs_cpu_s(pids: list[int]) -> dict[int, float]:
    return {pid: cpu for pid in pids if (cpu := _process_cpu_s(pid)) == cpu}  # NaN: gone


def _lowest_nice(pids: list[int]) -> str:
    """The lowest niceness of any Chromium thread of ``pids`` (Chromium sets it per thread) and the niceness of
    their autogroups (the share of the CPU the browser gets against the studio's session)."""
    values, groups = [], set()
    for pid in pids:
        try:
            if Path(f"/proc/{pid}/comm").read_text().strip() != "chromium":
                continue
            groups.add(Path(f"/proc/{pid}/autogroup").read_text().split()[-1])
            for task in Path(f"/proc/{pid}/task").iterdir():
                values.append(int((task / "stat").read_text().rsplit(")", 1)[1].split()[16]))
        except (OSError, IndexError, ValueError):
            continue
    return f"{min(values) if values else '?'}, autogroup nice {'/'.join(sorted(groups)) or '?'}"


def _machine_busy_s() -> float:
    """CPU seconds all cores spent busy since boot (/proc/stat: everything but idle and iowait)."""
    fields = [int(v) for v in Path("/proc/stat").read_text().split("\n", 1)[0].split()[1:]]
    return (sum(fields[:8]) - fields[3] - fields[4]) / os.sysconf("SC_CLK_TCK")


class _Browser(threading.Thread):
    """One headless Chromium with ``tabs`` tabs on the studio (as a user opens several tabs in one browser),
    counting the frames each tab renders (requestAnimationFrame)."""

    COUNTER_JS = ("() => { if (!window.__soakFrames) { window.__soakFrames = 0; const tick = () => "
                  "{ window.__soakFrames++; requestAnimationFrame(tick); }; requestAnimationFrame(tick); } "
                  "return window.__soakFrames; }")

    def __init__(self, url: str, tabs: int, stop: threading.Event, mark: threading.Event, executable: str | None = None):
        super().__init__(daemon=True, name="soak-tab")
        self.url, self.tabs, self.stop, self.mark_event = url, tabs, stop, mark
        self.executable = executable or shutil.which("chromium") or "/usr/bin/chromium"
        self.error = ""
        self.loaded = threading.Event()
        self.window: list[tuple[int, float] | None] = [None] * tabs
        self.last: list[tuple[int, float] | None] = [None] * tabs
        self.finish = threading.Event()  # take a last sample and stop
        self.finished = threading.Event()

    def fps(self, tab: int) -> float:
        first, last = self.window[tab], self.last[tab]
        if first is None or last is None or last[1] <= first[1]:
            return float("nan")
        return (last[0] - first[0]) / (last[1] - first[1])

    def run(self) -> None:
        try:
            from playwright.sync_api import sync_playwright

            with sync_playwright() as p:
                browser = p.chromium.launch(executable_path=self.executable,
                                            args=["--no-sandbox", "--enable-unsafe-swiftshader"])
                # one window per tab (a context each), all shown: a background tab would not render
                pages = [browser.new_context(viewport={"width": 800, "height": 600}).new_page() for _ in range(self.tabs)]
                for page in pages:
                    page.goto(self.url, timeout=120_000)
                for page in pages:
                    page.wait_for_selector("canvas", timeout=120_000)
                    page.evaluate(self.COUNTER_JS)
                self.loaded.set()
                while not self.stop.is_set():
                    final = self.finish.is_set()
                    for i, page in enumerate(pages):
                        count = int(page.evaluate(self.COUNTER_JS))
                        now = time.monotonic()
                        if self.mark_event.is_set() and self.window[i] is None:
                            self.window[i] = (count, now)
                        elif self.window[i] is not None:
                            self.last[i] = (count, now)
                    if final:
                        break
                    self.finish.wait(1.0)
                self.finished.set()
                browser.close()
        except Exception as exc:  # noqa: BLE001 - reported
            self.error = f"tab: {type(exc).__name__}: {exc}"[:200]
            self.loaded.set()
            self.finished.set()


class _Errors(logging.Handler):
    def __init__(self) -> None:
        super().__init__(logging.ERROR)
        self.records: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        text = f"{record.name}: {record.getMessage()}"[:200]
        if record.exc_info and record.exc_info[1] is not None:  # the exception and where it was raised
            exc = record.exc_info[1]
            where = " < ".join(f"{Path(f.filename).name}:{f.lineno} {f.name}"
                               for f in reversed(traceback.extract_tb(exc.__traceback__)[-4:]))
            text += f" | {type(exc).__name__}: {exc} at {where}"[:400]
        self.records.append(text)


CAP_SYS_NICE = 23  # capability bit: may raise a process's priority (root has it)


def _may_raise_priority() -> bool:
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("CapEff:"):
                return bool(int(line.split()[1], 16) >> CAP_SYS_NICE & 1)
    except (OSError, ValueError):
        pass
    return os.geteuid() == 0


def _user_chromium(folder: Path, niceness: int) -> tuple[str, str]:
    """Debian's Chromium as an ordinary user's browser runs, and a description of its priority.

    Playwright starts the browser in a session of its own, so with the kernel's autogroups (on here and on
    most desktops) the browser and the studio (with its engine) get equal shares of the CPU whatever the
    threads' niceness; inside the browser's share, Chromium raises its browser and GPU threads to nice -8 when
    it may (as root it may; on a user's machine it may not). The browser starts without that capability
    (``setpriv --bounding-set -sys_nice``) and, with ``niceness`` > 0, with its session's autogroup and its
    processes at that niceness — what a user can do to their own browser without privileges (``nice``, and
    ``/proc/<pid>/autogroup``), so the engine gets the CPU first."""
    chromium = shutil.which("chromium") or "/usr/bin/chromium"
    setpriv = shutil.which("setpriv")
    lines = ["#!/bin/sh"]
    prefix = []
    if niceness:
        lines.append(f"echo {int(niceness)} > /proc/self/autogroup 2>/dev/null")  # this session: the browser's
        prefix.append(f"nice -n {int(niceness)}")
    if _may_raise_priority() and setpriv:
        prefix.insert(0, f"{setpriv} --bounding-set -sys_nice")
    if not prefix:
        return chromium, "nice 0"
    wrapper = folder / "chromium-as-user"
    lines.append(f'exec {" ".join(prefix)} {chromium} "$@"')
    wrapper.write_text("\n".join(lines) + "\n")
    wrapper.chmod(0o755)
    cannot = "cannot raise itself" if setpriv or not _may_raise_priority() else "MAY raise itself to -8"
    return str(wrapper), f"nice {int(niceness)}, {cannot}"


def _second_half_growth(timeline: list[tuple[float, float, float]], same_engine: bool) -> dict:
    """RSS growth (%) of the studio and the engine over the second half of the measured window."""
    if len(timeline) < 3:
        return {}
    t_mid = (timeline[0][0] + timeline[-1][0]) / 2
    mid = min(timeline, key=lambda r: abs(r[0] - t_mid))
    end = timeline[-1]
    return {"studio_rss_growth_2nd_half_pct": round(100 * (end[1] / mid[1] - 1), 1),
            "engine_rss_growth_2nd_half_pct": round(100 * (end[2] / mid[2] - 1), 1) if same_engine else "restarted"}


def _free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def bench_soak(minutes: float = 1.0, clients: int = 4, tabs: int = 2, robot: str = "g1", tab_nice: int = 0) -> list[dict]:
    from dataclasses import replace

    from engine import protocol as msg
    from engine.gait.style import styles_dir
    from studio.app import Studio

    errors = _Errors()
    logging.getLogger().addHandler(errors)
    thread_errors: list[str] = []
    previous_hook = threading.excepthook
    threading.excepthook = lambda a: thread_errors.append(f"{a.thread.name if a.thread else '?'}: {a.exc_type.__name__}: "
                                                          f"{a.exc_value}"[:200])
    scratch = Path(tempfile.mkdtemp(prefix="motion-studio-soak-"))
    shutil.copytree(styles_dir(robot), scratch / robot, ignore=shutil.ignore_patterns(".autosave"))
    studio = Studio(robot, port=_free_port(), styles_folder=scratch).start()
    stop = threading.Event()
    frames: list[tuple[float, float]] = []  # every frame the studio received from the engine (drawn or not)
    original_on_event = studio.link.on_event

    def record(event) -> None:
        original_on_event(event)
        if isinstance(event, msg.Frame):
            frames.append((time.monotonic(), event.sim_time_s))

    studio.link.on_event = record
    pool: _ClientProcess | None = None
    browsers: list[_Browser] = []
    marked_event = threading.Event()
    try:
        if not studio.loaded.wait(180):
            raise RuntimeError("the studio did not load its robot within 180 s")
        studio.drive.set_mode("test")
        url = f"ws://127.0.0.1:{studio.server.get_port()}/"
        if clients:
            pool = _ClientProcess(url, clients)
            assert pool.proc.stdout is not None
            pool.proc.stdout.readline()  # "ready": its clients are connecting
        chromium, tab_priority = _user_chromium(scratch, tab_nice)
        browsers = [_Browser(f"http://127.0.0.1:{studio.server.get_port()}/", tabs, stop, marked_event, chromium)
                    ] if tabs else []
        for b in browsers:
            b.start()
        for b in browsers:  # the soak starts once every tab shows the studio
            b.loaded.wait(180)
        duration_s = 60.0 * minutes
        warmup_s = min(30.0, 0.25 * duration_s)
        t0 = time.monotonic()
        marked, frame_mark = False, 0
        drawn0, rates_hz = 0, []  # frames the studio drew, its stream rate: from the mark on
        tab_pids: list[int] = []
        tabs_cpu0: dict[int, float] = {}
        tab_nice_seen = "?"
        rss0 = (float("nan"), float("nan"))
        rss_timeline: list[tuple[float, float, float]] = []  # (time, studio MB, engine MB) every 15 s after warm-up
        next_rss = 0.0
        restarts0 = studio.link.restarts
        pool_cpu0 = 0.0
        next_push, next_edit, edits, pushes = t0 + 10.0, t0 + 5.0, 0, 0
        engine_pid0 = studio.link.pid
        while time.monotonic() - t0 < duration_s:
            now = time.monotonic()
            phase = int((now - t0) // 8) % 3  # forward, turning, standing still
            if phase == 0:
                studio.drive.hold(0, 1.0)
            elif phase == 1:
                studio.drive.hold(2, 1.0)
            if now >= next_push:
                studio.link.send(msg.ApplyPush((0.0, 25.0, 0.0), 0.2))
                pushes += 1
                next_push += 10.0
            session = studio.session
            style = session.style if session is not None else None
            if now >= next_edit and session is not None and style is not None:
                sample = style.samples["in_place"]
                width = 0.22 + 0.02 * (edits % 3)
                edited = replace(sample, attributes=replace(sample.attributes, stance_width_m=width))
                session.apply(style.with_sample("in_place", edited), "soak edit")
                edits += 1
                next_edit += 5.0
            if not marked and now - t0 >= warmup_s:
                marked = True
                rss0 = (_rss_mb(os.getpid()), _rss_mb(studio.link.pid))
                cpu0, engine_cpu0, cpu_t0 = _thread_cpu_s(), _process_cpu_s(studio.link.pid), time.monotonic()
                tab_pids = _tab_processes(studio.link.pid) if browsers else []
                tabs_cpu0, machine0 = _tabs_cpu_s(tab_pids), _machine_busy_s()
                tab_nice_seen = _lowest_nice(tab_pids)
                if pool is not None:
                    pool.mark()
                    pool_cpu0 = _process_cpu_s(pool.pid)
                marked_event.set()
                frame_mark = len(frames)
                drawn0 = studio.frame_rate.admitted
            if marked:
                rates_hz.append(studio.frame_rate.rate_hz)
            if marked and now >= next_rss:  # the RSS timeline: a step after warm-up or a steady climb?
                rss_timeline.append((now, _rss_mb(os.getpid()), _rss_mb(studio.link.pid)))
                next_rss = now + 15.0
            time.sleep(0.1)
        frame_end = len(frames)  # the measured window ends here (not after the tabs have closed)
        for b in browsers:  # each tab's last frame count
            b.finish.set()
        for b in browsers:
            b.finished.wait(60)
        rss1 = (_rss_mb(os.getpid()), _rss_mb(studio.link.pid))
        cpu1, engine_cpu1, cpu_t1 = _thread_cpu_s(), _process_cpu_s(studio.link.pid), time.monotonic()
        machine1 = _machine_busy_s()
        tabs_cpu1 = _tabs_cpu_s(tab_pids) if marked else {}
        window = frames[frame_mark:frame_end] if marked else frames[:frame_end]
        (w0, s0), (w1, s1) = window[0], window[-1]
        clock = sim_clock(window)
        drift, simulated_s = float(clock["drift"]), float(clock["simulated_s"])
        fall_notices = sum(1 for level, t in studio.notices if " fell at t = " in t)
        reports = pool.report() if pool is not None else []
        rates = [tuple(r["rates"]) for r in reports]
        pool_cpu = _process_cpu_s(pool.pid) - pool_cpu0 if pool is not None and marked else 0.0
        error_notices = [t for level, t in studio.notices  # the link logs its own (with the traceback)
                         if level == "error" and not t.startswith("studio failed to show ")]
        exceptions = (errors.records + thread_errors + [r["error"] for r in reports if r["error"]]
                      + [b.error for b in browsers if b.error] + error_notices)
        rows = [{
            "section": "soak", "what": "studio", "minutes": round(minutes, 2), "clients": clients,
            "studio_rss_mb": f"{rss0[0]:.0f}→{rss1[0]:.0f}", "studio_rss_growth_pct": round(100 * (rss1[0] / rss0[0] - 1), 1),
            "engine_rss_mb": f"{rss0[1]:.0f}→{rss1[1]:.0f}",
            "engine_rss_growth_pct": round(100 * (rss1[1] / rss0[1] - 1), 1) if studio.link.pid == engine_pid0 else "restarted",
            # the second half of the measured window alone: a leak keeps climbing there, a one-time step does not
            **_second_half_growth(rss_timeline + [(time.monotonic(), *rss1)], studio.link.pid == engine_pid0),
            "engine_frames_per_s": round((len(window) - 1) / (w1 - w0), 1), "sim_clock_drift_pct": round(100 * drift, 2),
            "sim_clock_resets": clock["resets"], "longest_sim_stall_s": round(float(clock["longest_stall_s"]), 2),
            "falls": fall_notices,
            "studio_drawn_frames_per_s": round((studio.frame_rate.admitted - drawn0) / (w1 - w0), 1) if marked else "-",
            "studio_stream_rate_hz": (f"{min(rates_hz):.0f}–{max(rates_hz):.0f}" if marked and rates_hz else "-"),
            "pushes": pushes, "edits": edits, "engine_restarts": studio.link.restarts - restarts0,
            "tabs": tabs, "tab_priority": tab_priority if tabs else "-", "tab_fps": ", ".join(f"{b.fps(i):.1f}" for b in browsers for i in range(b.tabs)) or "-",
            "exceptions": len(exceptions), "load_avg_1min": round(os.getloadavg()[0], 1), "cpus": os.cpu_count(),
        }]
        if rates:
            rows[0]["min_client_robot_frames_per_s"] = round(min(r[2] for r in rates), 1)
        for i, (m, kb, f) in enumerate(rates):
            rows.append({"section": "soak clients", "what": f"client {i}", "robot_frames_per_s": round(f, 1),
                         "ws_messages_per_s": round(m, 1), "ws_kib_per_s": round(kb, 1)})
        if marked:  # where the CPU went, per frame the studio received from the engine
            n_frames = max(len(window) - 1, 1)
            span_s = cpu_t1 - cpu_t0
            groups = sorted(set(cpu0) | set(cpu1), key=lambda g: -(cpu1.get(g, 0.0) - cpu0.get(g, 0.0)))
            for group in groups:
                used = cpu1.get(group, 0.0) - cpu0.get(group, 0.0)
                rows.append({"section": "soak cpu", "what": group, "cpu_ms_per_frame": round(1e3 * used / n_frames, 2),
                             "cpu_pct_of_core": round(100 * used / span_s, 1)})
            studio_used = sum(cpu1.get(g, 0.0) - cpu0.get(g, 0.0) for g in groups if not g.startswith("bench"))
            rows.append({"section": "soak cpu", "what": "studio total (not bench)",
                         "cpu_ms_per_frame": round(1e3 * studio_used / n_frames, 2),
                         "cpu_pct_of_core": round(100 * studio_used / span_s, 1)})
            if studio.link.pid == engine_pid0:
                used = engine_cpu1 - engine_cpu0
                rows.append({"section": "soak cpu", "what": "engine process", "cpu_ms_per_frame": round(1e3 * used / n_frames, 2),
                             "cpu_pct_of_core": round(100 * used / span_s, 1),  # and what real time needs:
                             "core_s_per_sim_s": round(used / simulated_s, 2) if simulated_s > 0 else "-"})
            tabs_used = sum(tabs_cpu1.get(p, c0) - c0 for p, c0 in tabs_cpu0.items())
            if browsers:
                rows.append({"section": "soak cpu", "what": f"browser tabs (thread nice ≥ {tab_nice_seen})",
                             "cpu_ms_per_frame": round(1e3 * tabs_used / n_frames, 2),
                             "cpu_pct_of_core": round(100 * tabs_used / span_s, 1)})
            if pool is not None:
                rows.append({"section": "soak cpu", "what": "bench: headless clients (own process)",
                             "cpu_ms_per_frame": round(1e3 * pool_cpu / n_frames, 2),
                             "cpu_pct_of_core": round(100 * pool_cpu / span_s, 1)})
            bench_used = sum(cpu1.get(g, 0.0) - cpu0.get(g, 0.0) for g in groups if g.startswith("bench")) + pool_cpu
            ours = studio_used + bench_used + tabs_used + (engine_cpu1 - engine_cpu0)
            rows.append({"section": "soak cpu", "what": "other processes on the machine", "cpu_ms_per_frame": "-",
                         "cpu_pct_of_core": round(100 * (machine1 - machine0 - ours) / span_s, 1)})
        for i, (t, studio_mb, engine_mb) in enumerate(rss_timeline):
            if i % 4 == 0 or i == len(rss_timeline) - 1:  # a sample a minute
                rows.append({"section": "soak rss", "what": f"+{t - rss_timeline[0][0]:.0f} s",
                             "studio_mb": round(studio_mb), "engine_mb": round(engine_mb)})
        for text in exceptions[:20]:
            rows.append({"section": "soak exceptions", "what": "exception", "text": text})
        return rows
    finally:
        stop.set()
        if pool is not None:
            pool.stop()
        for b in browsers:
            b.join(30)
        studio.stop()
        threading.excepthook = previous_hook
        logging.getLogger().removeHandler(errors)
        shutil.rmtree(scratch, ignore_errors=True)


if __name__ == "__main__":  # the headless clients' process (:class:`_ClientProcess`)
    import sys

    _client_process_main(sys.argv[1], int(sys.argv[2]))
