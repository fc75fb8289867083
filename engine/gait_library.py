"""Gait library (paper §9, future work): one closed-loop walk per velocity of a grid, on Ray.

A library is a folder::

    DIR/library.json                 what it is: robot, style, duration, the grid (fixed at creation)
    DIR/cells/<cell>/reference.npz   the planner's reference (``studio plan`` arrays) at that velocity
    DIR/cells/<cell>/simulated.npz   the closed-loop walk (``studio walk --out`` arrays + names)
    DIR/cells/<cell>/summary.json    the walk's figures; written last: its presence marks the cell done
    DIR/index.json                   every finished cell with its figures and file paths
    DIR/summary.png                  the velocity grid coloured by fell / stance slip / tracking error
    DIR/exports/<format>/<cell>_<take>.<ext>   with ``export_formats``: each cell's simulated walk and its
                                     reference in the learning formats (engine/export/), resampled to ``fps``

Each cell's command ramps from standing to its velocity in ``RAMP_S`` and holds it. Cells run as
Ray tasks (a local Ray by default, ``address`` for a cluster: :mod:`engine.ray_cluster`); workers return
the recordings as bytes and only this process writes the folder, so a cluster needs no shared disk. A second run on
the same folder skips finished cells (resume after a cancel or a crash).
"""

from __future__ import annotations

import io
import itertools
import json
import math
import re
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Iterable

import numpy as np

from engine.atomic_io import atomic_write_bytes, atomic_write_text
from engine.ray_cluster import RayClusterError, connect_ray

AXES = ("vx", "vy", "wz")
AXIS_UNITS = {"vx": "m/s", "vy": "m/s", "wz": "rad/s"}
RAMP_S = 1.5  # command ramp from standing to the cell's velocity
MAX_POINTS_PER_AXIS = 101
MIN_SPACING = 0.002  # m/s or rad/s between grid points: cell folders name velocities to 0.001, so they stay unique
SCHEMA = "motion-studio/gait-library"
SLIP_LIMIT_MM = 2.0  # the stack's stance-slip goal: above it a cell is marked as slipping


class GridError(ValueError):
    """A malformed --grid (one line naming the axis and what was expected)."""


class LibraryError(ValueError):
    """A library folder that cannot be used for this run (one line)."""


@dataclass(frozen=True)
class Axis:
    name: str
    low: float
    high: float
    count: int

    @property
    def values(self) -> list[float]:
        if self.count == 1:
            return [self.low]
        return [float(v) for v in np.round(np.linspace(self.low, self.high, self.count), 9)]


@dataclass(frozen=True)
class Grid:
    axes: tuple[Axis, Axis, Axis]  # vx, vy, wz

    @property
    def shape(self) -> tuple[int, int, int]:
        return tuple(a.count for a in self.axes)  # type: ignore[return-value]

    def velocities(self) -> list[tuple[float, float, float]]:
        return [tuple(v) for v in itertools.product(*(a.values for a in self.axes))]  # type: ignore[misc]

    def as_dict(self) -> dict[str, dict[str, float | int]]:
        return {a.name: {"low": a.low, "high": a.high, "count": a.count} for a in self.axes}


def _number(text: str, where: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise GridError(f"--grid: {where}: expected a number, got {text!r}") from None
    if not math.isfinite(value):
        raise GridError(f"--grid: {where}: expected a finite number, got {text!r}")
    return value


def parse_grid(text: str) -> Grid:
    """``vx=LO:HI:N,vy=...,wz=...``; an axis may be one value (``wz=0``) or left out (0)."""
    axes: dict[str, Axis] = {}
    if not text.strip():
        raise GridError("--grid: expected vx=LO:HI:N,vy=LO:HI:N,wz=LO:HI:N, got an empty grid")
    for part in text.split(","):
        name, eq, spec = part.strip().partition("=")
        name = name.strip()
        if not eq:
            raise GridError(f"--grid: expected AXIS=LO:HI:N or AXIS=VALUE, got {part.strip()!r}")
        if name not in AXES:
            raise GridError(f"--grid: {name}: unknown axis; expected one of {', '.join(AXES)}")
        if name in axes:
            raise GridError(f"--grid: {name}: given twice")
        fields = spec.split(":")
        if len(fields) == 1:
            value = _number(fields[0].strip(), name)
            axes[name] = Axis(name, value, value, 1)
            continue
        if len(fields) != 3:
            raise GridError(f"--grid: {name}: expected LO:HI:N (three fields), got {spec!r}")
        low = _number(fields[0].strip(), f"{name} low")
        high = _number(fields[1].strip(), f"{name} high")
        if not re.fullmatch(r"[+-]?\d+", fields[2].strip()):
            raise GridError(f"--grid: {name}: expected a whole number of points N, got {fields[2].strip()!r}")
        count = int(fields[2])
        if count < 1:
            raise GridError(f"--grid: {name}: expected at least 1 point, got {count}")
        if count > MAX_POINTS_PER_AXIS:
            raise GridError(f"--grid: {name}: expected at most {MAX_POINTS_PER_AXIS} points, got {count}")
        if low > high:
            raise GridError(f"--grid: {name}: expected LO ≤ HI, got {low:g} > {high:g} (reversed bounds)")
        if count == 1 and low != high:
            raise GridError(f"--grid: {name}: one point needs LO = HI, got {low:g}:{high:g}:1")
        if count > 1 and low == high:
            raise GridError(f"--grid: {name}: {count} points need LO < HI, got {low:g}:{high:g}")
        if count > 1 and (high - low) / (count - 1) < MIN_SPACING:
            raise GridError(f"--grid: {name}: expected points at least {MIN_SPACING:g} apart, got {count} points "
                            f"over {low:g}:{high:g}; use fewer points or a wider range")
        axes[name] = Axis(name, low, high, count)
    full = tuple(axes.get(n, Axis(n, 0.0, 0.0, 1)) for n in AXES)
    return Grid(full)  # type: ignore[arg-type]


def cell_id(velocity: Iterable[float]) -> str:
    """A folder name that is the velocity itself: stable across runs with other grids."""
    return "_".join(f"{n}{v:+.3f}" for n, v in zip(AXES, velocity)).replace("+", "p").replace("-", "m")


# ----------------------------------------------------------------------------- one cell


def _npz_bytes(arrays: dict[str, np.ndarray]) -> bytes:
    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays)  # type: ignore[arg-type]  # numpy's stub reads **kwds as allow_pickle
    return buf.getvalue()


def cell_schedule(velocity: tuple[float, float, float]):
    from engine.gait.command_schedule import from_keyframes

    return from_keyframes([[0.0, 0.0, 0.0, 0.0], [RAMP_S, *map(float, velocity)]], "gait library")


def run_cell(robot_name: str, style_doc: dict, velocity: tuple[float, float, float], duration_s: float) -> dict:
    """Plan and walk one velocity; returns the summary and both recordings as npz bytes."""
    from engine.gait.offline_plan import run_plan
    from engine.gait.style import style_from_dict
    from engine.robot.model import load_robot
    from engine.walk_runner import run_walk

    robot = load_robot(robot_name)
    style = style_from_dict(style_doc, expected_robot=robot_name)
    schedule = cell_schedule(velocity)
    t0 = time.perf_counter()
    reference = run_plan(robot, style, schedule, duration_s)
    summary, simulated = run_walk(robot, style, schedule, duration_s, record=True, record_reference=True,
                                  command_text=",".join(f"{v:g}" for v in velocity))  # a walk-run file
    summary = {**summary, "command": [float(v) for v in velocity], "cell_wall_time_s": round(time.perf_counter() - t0, 3)}
    return {"summary": summary, "reference": _npz_bytes(reference), "simulated": _npz_bytes(simulated)}


# ----------------------------------------------------------------------------- the library


@dataclass
class LibraryRun:
    robot: str
    style_name: str
    style_doc: dict
    grid: Grid
    duration_s: float
    out: Path

    @property
    def meta(self) -> dict:
        return {"schema": SCHEMA, "version": 1, "robot": self.robot, "style": self.style_name,
                "duration_s": self.duration_s, "ramp_s": RAMP_S, "grid": self.grid.as_dict()}

    def cell_dir(self, velocity) -> Path:
        return self.out / "cells" / cell_id(velocity)

    def finished(self, velocity) -> bool:
        return (self.cell_dir(velocity) / "summary.json").is_file()

    def check_folder(self) -> None:
        """A folder holding another library (other robot, style or duration) is refused."""
        meta_path = self.out / "library.json"
        if self.out.exists() and not self.out.is_dir():
            raise LibraryError(f"--out: {self.out} exists and is not a folder")
        if not meta_path.is_file():
            return
        try:
            old = json.loads(meta_path.read_text())
        except (OSError, json.JSONDecodeError) as exc:
            raise LibraryError(f"{meta_path}: expected a gait library description: {exc}") from None
        for key in ("robot", "style", "duration_s"):
            if old.get(key) != self.meta[key]:
                raise LibraryError(f"{meta_path}: {key}: this library was made with {old.get(key)!r}, "
                                   f"not {self.meta[key]!r}; use another --out")

    def write_cell(self, result: dict) -> None:
        folder = self.cell_dir(result["summary"]["command"])
        atomic_write_bytes(folder / "reference.npz", result["reference"])
        atomic_write_bytes(folder / "simulated.npz", result["simulated"])
        atomic_write_text(folder / "summary.json", json.dumps(result["summary"], indent=1))  # last: marks done

    def export_path(self, velocity, fmt: str, take: str) -> Path:
        from engine.export import SUFFIXES

        return self.out / "exports" / fmt / f"{cell_id(velocity)}_{take}{SUFFIXES[fmt][0]}"

    def export_cells(self, formats: Iterable[str], fps: float | None = None) -> tuple[int, int]:
        """Every finished cell's takes in ``formats`` (files already written are kept: resumable).
        Returns how many files were written and how many were found already written."""
        from engine.export import export_motion
        from engine.retarget.motion import MotionFormatError
        from engine.walk_recording import TAKES, load_run_motion

        written = kept = 0
        for velocity in self.grid.velocities():
            if not self.finished(velocity):
                continue
            for take in TAKES:
                try:
                    motion = load_run_motion(self.cell_dir(velocity) / "simulated.npz", take)
                except MotionFormatError:
                    continue  # a cell of an older library has no reference take
                for fmt in formats:
                    path = self.export_path(velocity, fmt, take)
                    if not path.is_file():
                        export_motion(motion, fmt, path, fps=fps)
                        written += 1
                    else:
                        kept += 1
        return written, kept

    def index(self) -> dict:
        cells = []
        for velocity in self.grid.velocities():
            path = self.cell_dir(velocity) / "summary.json"
            if not path.is_file():
                continue
            s = json.loads(path.read_text())
            rel = path.parent.relative_to(self.out)
            cells.append({
                "id": cell_id(velocity), "command": list(velocity), "fell": s["fell"], "fall_time_s": s["fall_time_s"],
                "max_stance_slip_mm": s["max_stance_slip_mm"], "cop_inside_fraction": s["cop_inside_fraction"],
                "velocity_rmse": s["velocity_rmse"], "distance_m": s["distance_m"],
                "wall_time_s": s.get("cell_wall_time_s"),
                "reference": str(rel / "reference.npz"), "simulated": str(rel / "simulated.npz"),
                "exports": sorted(str(p.relative_to(self.out)) for p in (self.out / "exports").glob(
                    f"*/{cell_id(velocity)}_*") if p.is_file()),
            })
        return {**self.meta, "cells_total": len(self.grid.velocities()), "cells_done": len(cells), "cells": cells}


def run_library(run: LibraryRun, address: str | None = None, workers: int | None = None,
                progress: Callable[[int, int, int], None] | None = None,
                export_formats: Iterable[str] = (), export_fps: float | None = None) -> dict:
    """Run every unfinished cell on Ray; export the cells in ``export_formats``; write the index and
    the summary figure. Returns the index plus ``skipped``/``ran``/``exported`` counts and the wall time."""
    run.check_folder()
    run.out.mkdir(parents=True, exist_ok=True)
    atomic_write_text(run.out / "library.json", json.dumps(run.meta, indent=1))
    todo = [v for v in run.grid.velocities() if not run.finished(v)]
    total = len(run.grid.velocities())
    skipped = total - len(todo)
    t0 = time.perf_counter()
    done = 0
    if progress:
        progress(skipped, total, skipped)
    if todo:
        import ray

        started_here = not ray.is_initialized()
        try:
            connect_ray(address, num_cpus=workers)
        except RayClusterError as exc:
            raise LibraryError(str(exc)) from None
        remote_cell = ray.remote(num_cpus=1, max_retries=1)(run_cell)
        limit = workers or max(1, int(ray.available_resources().get("CPU", 1)))
        pending: dict = {}
        queue = list(todo)
        try:
            while queue or pending:
                while queue and len(pending) < limit:
                    v = queue.pop(0)
                    pending[remote_cell.remote(run.robot, run.style_doc, v, run.duration_s)] = v
                ready, _ = ray.wait(list(pending), num_returns=1)
                for ref in ready:
                    pending.pop(ref)
                    run.write_cell(ray.get(ref))
                    done += 1
                    if progress:
                        progress(skipped + done, total, skipped)
        except BaseException:
            for ref in pending:
                ray.cancel(ref, force=True)
            raise
        finally:
            if started_here:
                ray.shutdown()
    exported, exports_kept = run.export_cells(export_formats, export_fps) if export_formats else (0, 0)
    wall = time.perf_counter() - t0
    index = run.index()
    index["wall_time_s"] = round(wall, 2)
    index["workers"] = workers
    atomic_write_text(run.out / "index.json", json.dumps(index, indent=1))
    write_summary_png(index, run.out / "summary.png")
    return {**index, "ran": done, "skipped": skipped, "exported": exported, "exports_kept": exports_kept}


# ----------------------------------------------------------------------------- the figure


def write_summary_png(index: dict, path: Path) -> None:
    """One column per yaw rate, rows fell / stance slip / velocity tracking error, vx × vy cells."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import ListedColormap

    grid = index["grid"]
    values = {a: Axis(a, grid[a]["low"], grid[a]["high"], grid[a]["count"]).values for a in AXES}
    nx, ny, nw = (len(values[a]) for a in AXES)
    fell = np.full((nw, ny, nx), np.nan)
    slip = np.full((nw, ny, nx), np.nan)
    track = np.full((nw, ny, nx), np.nan)
    for cell in index["cells"]:
        vx, vy, wz = cell["command"]
        i, j, k = (int(np.argmin(np.abs(np.array(values[a]) - v))) for a, v in zip(AXES, (vx, vy, wz)))
        fell[k, j, i] = 1.0 if cell["fell"] else 0.0
        slip[k, j, i] = cell["max_stance_slip_mm"]
        track[k, j, i] = float(np.linalg.norm(cell["velocity_rmse"][:2]))
    fig, axes = plt.subplots(3, nw, figsize=(3.2 * nw + 1.2, 7.8), squeeze=False, constrained_layout=True)
    rows = [("fell", fell, ListedColormap(["#4caf50", "#e53935"]), (0, 1), "{:.0f}"),
            ("stance slip (mm)", slip, "magma_r", (0, max(2 * SLIP_LIMIT_MM, float(np.nanmax(slip, initial=0)))), "{:.1f}"),
            ("velocity RMSE (m/s)", track, "viridis", (0, max(0.1, float(np.nanmax(track, initial=0)))), "{:.3f}")]
    extent = _extent(values["vx"]) + _extent(values["vy"])
    for r, (title, data, cmap, (lo, hi), fmt) in enumerate(rows):
        for k in range(nw):
            ax = axes[r][k]
            img = ax.imshow(np.ma.masked_invalid(data[k]), origin="lower", cmap=cmap, vmin=lo, vmax=hi,
                            extent=extent, aspect="auto")
            for j, vy in enumerate(values["vy"]):
                for i, vx in enumerate(values["vx"]):
                    value = data[k, j, i]
                    text = "–" if np.isnan(value) else ("FELL" if r == 0 and value else fmt.format(value))
                    if r == 0 and value == 0:
                        text = "ok"
                    if r == 1 and not np.isnan(value) and value > SLIP_LIMIT_MM:
                        text += "!"
                    ax.text(vx, vy, text, ha="center", va="center", fontsize=7, color="white" if r != 1 else "black")
            ax.set_title(f"{title}, wz {values['wz'][k]:+.2f} rad/s", fontsize=9)
            ax.set_xlabel("vx (m/s)")
            if k == 0:
                ax.set_ylabel("vy (m/s)")
            if k == nw - 1 and r > 0:
                fig.colorbar(img, ax=ax, shrink=0.8)
    done, total = index["cells_done"], index["cells_total"]
    fig.suptitle(f"gait library: {index['robot']} / {index['style']}, {index['duration_s']:g} s per cell, "
                 f"{done}/{total} cells, {sum(c['fell'] for c in index['cells'])} fell", fontsize=10)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    plt.close(fig)
    atomic_write_bytes(path, buf.getvalue())


def _extent(values: list[float]) -> list[float]:
    if len(values) == 1:
        return [values[0] - 0.05, values[0] + 0.05]
    step = (values[-1] - values[0]) / (len(values) - 1)
    return [values[0] - step / 2, values[-1] + step / 2]


def text_progress(stream=sys.stderr) -> Callable[[int, int, int], None]:
    """A one-line progress bar: cells done / total, the skipped ones, elapsed and ETA."""
    start = time.perf_counter()

    def show(done: int, total: int, skipped: int) -> None:
        width = 30
        filled = int(width * done / max(total, 1))
        elapsed = time.perf_counter() - start
        ran = done - skipped
        eta = elapsed / ran * (total - done) if ran > 0 else float("nan")
        eta_text = f"ETA {eta:.0f} s" if math.isfinite(eta) else "ETA –"
        stream.write(f"\r[{'#' * filled}{'.' * (width - filled)}] {done}/{total} cells ({skipped} already done) "
                     f"{elapsed:.0f} s, {eta_text}  ")
        if done == total:
            stream.write("\n")
        stream.flush()

    return show
