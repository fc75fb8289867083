"""Gait library: grid parsing (properties), resume, a tiny run on Ray, bad input at the CLI."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from engine.gait_library import (
    AXES,
    MIN_SPACING,
    GridError,
    LibraryError,
    LibraryRun,
    cell_id,
    parse_grid,
    run_library,
)
from tests.conftest import run_studio

finite = st.floats(-2.0, 2.0, allow_nan=False).map(lambda x: round(x, 3))


@st.composite
def axis_specs(draw):
    low = draw(finite)
    high = draw(finite.filter(lambda h: h > low))
    count = draw(st.integers(2, 12).filter(lambda n: (high - low) / (n - 1) >= MIN_SPACING))
    return low, high, count


@given(specs=st.lists(axis_specs(), min_size=3, max_size=3), present=st.lists(st.booleans(), min_size=3, max_size=3))
@settings(max_examples=80, deadline=None)
def test_grid_has_the_product_of_its_axes_evenly_spaced(specs, present):
    text = ",".join(f"{name}={lo}:{hi}:{n}" for name, (lo, hi, n), p in zip(AXES, specs, present) if p)
    if not text:
        text = "vx=0"
    grid = parse_grid(text)
    expected_counts = [n if p else 1 for (_, _, n), p in zip(specs, present)]
    assert list(grid.shape) == expected_counts
    velocities = grid.velocities()
    assert len(velocities) == math.prod(expected_counts) == len(set(velocities))
    for axis, (lo, hi, n), p in zip(grid.axes, specs, present):
        values = np.array(axis.values)
        if p:
            assert values[0] == pytest.approx(lo) and values[-1] == pytest.approx(hi)
            assert np.all(np.diff(values) > 0)
            np.testing.assert_allclose(np.diff(values), (hi - lo) / (n - 1), atol=1e-8)
        else:
            assert list(values) == [0.0]  # a left-out axis is zero
    assert len({cell_id(v) for v in velocities}) == len(velocities)  # folder names are unique


def test_points_closer_than_the_folder_resolution_are_refused():
    # six points over 4 mm/s would name two cells the same folder (velocities are named to 0.001)
    with pytest.raises(GridError, match="at least 0.002 apart"):
        parse_grid("wz=0.121:0.125:6")
    assert parse_grid("wz=0.12:0.13:6").shape[2] == 6


@given(lo=finite, hi=finite, n=st.integers(-3, 0))
@settings(deadline=None)
def test_zero_point_grids_are_refused(lo, hi, n):
    with pytest.raises(GridError, match="at least 1 point"):
        parse_grid(f"vx={min(lo, hi)}:{max(lo, hi)}:{n}")


@given(lo=finite, hi=finite, n=st.integers(2, 9))
@settings(deadline=None)
def test_reversed_bounds_are_refused(lo, hi, n):
    if lo <= hi:
        lo, hi = hi + 0.5, lo
    with pytest.raises(GridError, match="reversed bounds"):
        parse_grid(f"vy={lo}:{hi}:{n}")


@pytest.mark.parametrize("text, message", [
    ("vx=0:1", "three fields"), ("vx=0:1:2.5", "whole number"), ("speed=1", "unknown axis"),
    ("vx=nan", "finite"), ("vx=0:1:2,vx=0", "given twice"), ("vx", "AXIS=LO:HI:N"), ("vx=0:1:1", "LO = HI"),
])
def test_malformed_grids_name_the_axis(text, message):
    with pytest.raises(GridError) as err:
        parse_grid(text)
    assert message in str(err.value) and "\n" not in str(err.value)


def _fake_summary(velocity) -> dict:
    return {"fell": False, "fall_time_s": None, "max_stance_slip_mm": 0.5, "cop_inside_fraction": 1.0,
            "velocity_rmse": [0.01, 0.01, 0.01], "distance_m": 1.0, "command": list(velocity), "cell_wall_time_s": 1.0}


def _finish(run: LibraryRun, velocity) -> None:
    folder = run.cell_dir(velocity)
    folder.mkdir(parents=True)
    (folder / "summary.json").write_text(json.dumps(_fake_summary(velocity)))


def test_resume_skips_finished_cells_without_starting_ray(tmp_path):
    import ray

    run = LibraryRun("dino", "neutral", {}, parse_grid("vx=0:0.2:3,wz=-0.5:0.5:2"), 5.0, tmp_path / "lib")
    for v in run.grid.velocities():
        _finish(run, v)
    index = run_library(run)
    assert index["ran"] == 0 and index["skipped"] == 6 and index["cells_done"] == 6
    assert not ray.is_initialized()
    on_disk = json.loads((tmp_path / "lib" / "index.json").read_text())
    assert [c["command"] for c in on_disk["cells"]] == [list(v) for v in run.grid.velocities()]
    assert (tmp_path / "lib" / "summary.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_library_exports_each_cell_in_the_learning_formats_and_resumes(tmp_path):
    """Finished cells (walk-run files) are exported, simulated and reference takes; a second call keeps them."""
    from engine.robot.model import load_robot
    from engine.walk_recording import run_fields, save_run

    robot = load_robot("g1")
    run = LibraryRun("g1", "neutral", {}, parse_grid("vx=0:0.2:2"), 5.0, tmp_path / "lib")
    for v in run.grid.velocities():
        _finish(run, v)
        qpos = np.tile(robot.mj_standing_qpos(), (25, 1))
        qpos[:, 0] = np.linspace(0.0, v[0], 25)
        arrays = {"qpos": qpos, "contact": np.ones((25, 2), bool), "reference_qpos": qpos + 0.001 * (np.arange(36) >= 7)}
        arrays.update(run_fields(robot, "neutral", arrays, {}, 125.0))
        save_run(run.cell_dir(v) / "simulated.npz", arrays)
    formats = ("unitree-csv", "beyondmimic-npz", "amp-json")
    assert run.export_cells(formats, fps=50.0) == (2 * 2 * 3, 0)
    csv = np.loadtxt(run.export_path((0.2, 0.0, 0.0), "unitree-csv", "reference"), delimiter=",", ndmin=2)
    # 25 frames at 125 fps span 0.192 s: 10 frames at 50 fps, the last at 0.18 s (x lerped: 0.2 · 0.18 / 0.192)
    assert csv.shape == (10, 36) and np.isclose(csv[-1, 0], 0.2 * 0.18 / 0.192)
    with np.load(run.export_path((0.0, 0.0, 0.0), "beyondmimic-npz", "simulated")) as bm:
        assert bm["fps"].tolist() == [50] and bm["joint_pos"].shape == (10, 29)
    stamp = run.export_path((0.0, 0.0, 0.0), "amp-json", "simulated").stat().st_mtime_ns
    assert run.export_cells(formats, fps=50.0) == (0, 2 * 2 * 3)  # a second run keeps what it finds
    assert run.export_path((0.0, 0.0, 0.0), "amp-json", "simulated").stat().st_mtime_ns == stamp
    cells = run.index()["cells"]
    assert len(cells[0]["exports"]) == 6 and all(p.startswith("exports/") for p in cells[0]["exports"])


def test_a_folder_of_another_library_is_refused(tmp_path):
    run = LibraryRun("dino", "neutral", {}, parse_grid("vx=0"), 5.0, tmp_path / "lib")
    (tmp_path / "lib").mkdir()
    (tmp_path / "lib" / "library.json").write_text(json.dumps({**run.meta, "style": "strut"}))
    with pytest.raises(LibraryError, match="style: this library was made with 'strut'"):
        run.check_folder()


@pytest.mark.slow
def test_tiny_library_runs_on_ray_and_resumes(tmp_path):
    """Two cells of 0.6 s on a local Ray with one worker; the first was finished by an earlier run."""
    out = tmp_path / "lib"
    first = run_studio("library", "--robot", "dino", "--style", "neutral", "--grid", "vx=0:0.1:2", "--duration", "0.6",
                       "--out", str(out), "--workers", "1", "--json", timeout=1500)
    assert first.returncode == 0, first.stderr
    index = json.loads(first.stdout)
    assert index["ran"] == 2 and index["cells_done"] == 2
    for cell in index["cells"]:
        assert not cell["fell"]
        with np.load(out / cell["simulated"], allow_pickle=False) as sim, \
                np.load(out / cell["reference"], allow_pickle=False) as ref:
            assert sim["qpos"].shape[1] == 7 + len(sim["joint_names"]) and len(sim["t"]) > 50
            assert ref["qpos"].shape[1] == sim["qpos"].shape[1] and len(ref["t"]) == 75  # 0.6 s at 125 Hz
    kept = (out / index["cells"][0]["simulated"]).stat().st_mtime_ns
    second = run_studio("library", "--robot", "dino", "--style", "neutral", "--grid", "vx=0:0.1:2", "--duration",
                        "0.6", "--out", str(out), "--json", timeout=600)
    assert second.returncode == 0, second.stderr
    again = json.loads(second.stdout)
    assert again["ran"] == 0 and again["skipped"] == 2
    assert (out / index["cells"][0]["simulated"]).stat().st_mtime_ns == kept


@pytest.mark.parametrize("args, message", [
    # each case is a `studio library` process: four in the slow tier (grids in process: the tests above)
    (["--grid", "vx=0:0.5:0"], "--grid: vx: expected at least 1 point"),
    pytest.param(["--grid", "vx=0.5:0:3"], "reversed bounds", marks=pytest.mark.slow),
    (["--grid", "vx=0", "--workers", "0"], "--workers: expected at least 1"),
    pytest.param(["--grid", "vx=0", "--duration", "-1"], "--duration", marks=pytest.mark.slow),
    (["--grid", "vx=0", "--style", "nope"], "unknown style 'nope'"),
    (["--grid", "vx=0", "--export", "bvh"], "--export: bvh: expected formats among"),
    pytest.param(["--grid", "vx=0", "--export", "amp-json", "--fps", "0"], "--fps: expected 0 < fps", marks=pytest.mark.slow),
    pytest.param(["--grid", "vx=0:0.5:0,vy=0"], "--grid: vx: expected at least 1 point", marks=pytest.mark.slow),
])
def test_bad_input_is_one_line_exit_2_nothing_written(tmp_path, args, message):
    out = tmp_path / "lib"
    result = run_studio("library", "--robot", "dino", "--out", str(out), *args, timeout=120)
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0], result.stderr
    assert not out.exists()
