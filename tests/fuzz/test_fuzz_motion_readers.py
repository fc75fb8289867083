"""Fuzzed motion readers (issue 14): motion npz files (keypoint sources, robot motions), BVH clips, live mocap
datagrams and motion_imitation frame files answer malformed input with ONE line naming the file, the field
and what was expected — exit 2 from the CLI (``studio retarget``, ``studio tmr``, ``studio puppet``,
``studio stream-bvh``, ``studio import``), a failed job / a refused source / a counted bad datagram in the
studio — never a traceback, a hang, a huge allocation or a partly written output.

Two layers, as tests/fuzz/test_fuzz_readers.py: the committed corpus (tests/fuzz_corpus/<reader>/, regenerated
by make_corpus.py; the zip bomb, the 100 000-deep files and the files over a size limit are built at test
time) and hypothesis mutations of valid files (``FUZZ_EXAMPLES`` sets how many, 30 by default).
The CLI runs in this process with its minutes-long stages (SMR, TMR) stubbed: the readers and checks in
front of them run for real.
"""

from __future__ import annotations

import json
import os
import socket
import time
import warnings
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from engine.retarget.humanoid_arm.live import DatagramError, parse_datagram
from engine.retarget.importers.bvh import BvhError, load_bvh
from engine.retarget.motion import KeypointMotion, MotionFormatError, RobotMotion, load_motion
from engine.safe_io import ReadError, read_npz
from studio import cli
from tests.conftest import REPO
from tests.fuzz_corpus import make_corpus as mc

pytestmark = pytest.mark.timeout(900)  # a hang is a failure too

CORPUS = REPO / "tests" / "fuzz_corpus"
FUZZ = settings(max_examples=int(os.environ.get("FUZZ_EXAMPLES", "30")), deadline=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture,
                                       HealthCheck.data_too_large])
KEYPOINT_BASE = mc.valid_keypoint_npz()
ROBOT_BASE = mc.valid_robot_npz()


def corpus(reader: str) -> list[Path]:
    return sorted((CORPUS / reader).iterdir())


def one_line(message: str, source: str) -> None:
    assert "\n" not in message and message.startswith(source), message
    assert ": :" not in message and not message.rstrip().endswith((" at", ":")), message
    assert "Traceback" not in message and len(message) < 650, message


def write_huge(path: Path, head: bytes, size: int) -> Path:
    """A file of ``size`` bytes that starts with ``head`` (sparse: nothing of that size in memory or on disk)."""
    path.write_bytes(head)
    os.truncate(path, size)
    return path


def leftovers(folder: Path) -> list[str]:
    """Temporaries of the atomic writer (hidden dot-files) or anything else half-written in ``folder``."""
    return [p.name for p in folder.iterdir() if p.name.startswith(".")]


# ----------------------------------------------------------------------------- the CLI, heavy stages stubbed

@pytest.fixture(scope="module")
def robot_base_file(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("base") / "standing.npz"
    path.write_bytes(mc.npz_bytes(ROBOT_BASE))
    return path


@pytest.fixture
def stubbed(monkeypatch, robot_base_file):
    """``studio retarget`` / ``studio tmr`` with SMR and TMR replaced by a valid robot motion (the reading and
    checking in front of them runs for real); the list records each stub reached."""
    import engine.retarget.quadruped.pipeline as pipeline
    import studio.cli_tmr as cli_tmr

    calls: list[str] = []
    figures = {"frames": 11, "foot_slide_mm": 0.0, "contact_iou": 1.0, "penetration_mm": 0.0,
               "keypoint_error_mm": 0.0, "frames_per_s": 100.0}

    def motion() -> RobotMotion:
        m = RobotMotion.load(robot_base_file)
        m.metrics = dict(figures)
        return m

    def retarget_detailed(source, robot, method, options=None, **kwargs):
        calls.append("smr")
        return SimpleNamespace(motion=motion())

    def run_tmr(m, settings_, address, parallel):
        calls.append("tmr")
        summary = {"alpha": [1.0], "duration_s": {"before": 0.2, "after": 0.2}, "bo_evaluations": 1,
                   "replay_fell": False, "tracking_error_mm": 0.0, "dtw_keypoint_l1_pct": 0.0, "wall_time_s": 0.0}
        return SimpleNamespace(motion=motion(), summary=summary, evaluations=[])

    monkeypatch.setattr(pipeline, "retarget_detailed", retarget_detailed)
    monkeypatch.setattr(cli_tmr, "run_tmr", run_tmr)
    return calls


def run_cli(args: list[str], capsys, source: Path, out: Path) -> int:
    """``studio ARGS``: exit 0, or exit 2 with one line naming ``source``; never a traceback; no output file and
    no temporary left when it fails."""
    try:
        rc = cli.main(args)
    except SystemExit as exc:  # argparse
        rc = int(exc.code or 0)
    captured = capsys.readouterr()
    assert rc in (0, 2), (rc, captured.err[-2000:])
    assert "Traceback" not in captured.err and "Traceback" not in captured.out
    if rc == 2:
        lines = captured.err.strip().splitlines()
        assert len(lines) == 1, captured.err
        one_line(lines[0], f"studio: error: {source.name}")
        assert not out.exists(), f"{out.name} written although the command failed"
    assert not leftovers(out.parent), leftovers(out.parent)
    return rc


# ----------------------------------------------------------------------------- npz: the archive itself

def test_npz_reader_checks_headers_before_allocating(tmp_path):
    """The zip bomb (300 MB of zeros in 300 KB) and a header declaring 10¹² elements are refused before anything
    of that size is allocated: the traced peak stays under 16 MB (numpy's and zipfile's buffers are traced)."""
    import tracemalloc

    bomb = tmp_path / "zip_bomb_300MB.npz"
    bomb.write_bytes(mc.large_cases("keypoint_npz")["zip_bomb_300MB.npz"])
    huge = tmp_path / "header_huge_shape.npz"
    huge.write_bytes((CORPUS / "keypoint_npz" / "header_huge_shape.npz").read_bytes())
    tracemalloc.start()
    try:
        for path in (bomb, huge):
            with pytest.raises(ReadError) as info:
                read_npz(path, source=path.name)
            assert info.value.field_path == "keypoints", info.value
            assert "expected at most 256.0 MiB of array data" in info.value.detail, info.value
        peak_mb = tracemalloc.get_traced_memory()[1] / 1e6
    finally:
        tracemalloc.stop()
    assert peak_mb < 16, f"{peak_mb:.0f} MB allocated while refusing a zip bomb"


def test_npz_reader_reads_what_numpy_wrote(tmp_path):
    arrays = {"a": np.asfortranarray(np.arange(12.0).reshape(3, 4)), "b": np.array("text"), "c": np.zeros((0, 3)),
              "d": np.array([True, False]), "e": np.arange(5, dtype=np.uint16)}
    path = tmp_path / "ok.npz"
    np.savez(path, **arrays)
    got = read_npz(path)
    assert got.keys() == arrays.keys()
    for k, v in arrays.items():
        assert got[k].dtype == v.dtype and np.array_equal(got[k], v)
        assert got[k].flags.writeable


@pytest.mark.parametrize("case", corpus("keypoint_npz"), ids=lambda p: p.name)
def test_npz_archive_errors_name_the_file_and_array(case):
    """Every corpus file is refused by the keypoint-motion loader with a ReadError whose parts are filled in."""
    with pytest.raises(MotionFormatError) as info:
        KeypointMotion.load(case)
    err = info.value
    assert isinstance(err, ReadError) and err.source == case.name and err.detail, err
    one_line(str(err), case.name)


# ----------------------------------------------------------------------------- keypoint npz (sources)

@pytest.mark.parametrize("case", corpus("keypoint_npz"), ids=lambda p: p.name)
def test_keypoint_npz_corpus_studio_retarget(case, tmp_path, capsys, stubbed):
    out = tmp_path / "out.npz"
    rc = run_cli(["retarget", "--source", str(case), "--robot", "go2", "--out", str(out)], capsys, case, out)
    assert rc == 2 and not stubbed, f"{case.name} was accepted"
    from engine.motion_files import motion_kind

    assert motion_kind(case) in ("", "keypoint-motion/1", "robot-motion/1")  # the studio's lists never raise


@pytest.mark.parametrize("name", ["zip_bomb_300MB.npz", "huge_file.npz"])
def test_keypoint_npz_large_cases(name, tmp_path, capsys, stubbed):
    path = tmp_path / name
    if name in mc.large_cases("keypoint_npz"):
        path.write_bytes(mc.large_cases("keypoint_npz")[name])
    else:
        write_huge(path, *mc.huge_files("keypoint_npz")[name])
    out = tmp_path / "out.npz"
    assert run_cli(["retarget", "--source", str(path), "--robot", "go2", "--out", str(out)], capsys, path, out) == 2


def test_valid_keypoint_npz_is_retargeted(tmp_path, capsys, stubbed):
    """The base of the mutations is accepted (the fuzz tests reach the stages behind the reader)."""
    src = tmp_path / "trot.npz"
    src.write_bytes(mc.npz_bytes(KEYPOINT_BASE))
    out = tmp_path / "out.npz"
    assert run_cli(["retarget", "--source", str(src), "--robot", "go2", "--out", str(out)], capsys, src, out) == 0
    assert stubbed == ["smr"] and RobotMotion.load(out).frames == 11


_dtypes = st.sampled_from(["<f8", "<f4", "<i8", "|b1", "<U6", "|S4", "<c16", "<M8[s]", "|u1"])
_junk_arrays = st.one_of(
    hnp.arrays(dtype=_dtypes, shape=hnp.array_shapes(min_dims=0, max_dims=3, min_side=0, max_side=5)),
    st.sampled_from([np.array(np.nan), np.array(np.inf), np.array(-1.0), np.array(1e308), np.array(""),
                     np.array("keypoint-motion/1"), np.array("robot-motion/1"), np.array("{}"),
                     np.array('{"a": [[[[1]]]]}'), np.array("go2"), np.array("../x"), np.zeros((0, 16, 3))]),
)


def _mutated(base: dict[str, np.ndarray], data) -> dict[str, np.ndarray]:
    """``base`` with 1-3 arrays replaced by junk, resized, poisoned with NaN, or deleted (or junk added)."""
    arrays = dict(base)
    for _ in range(data.draw(st.integers(1, 3), label="changes")):
        key = data.draw(st.sampled_from([*sorted(base), "extra", "pd_kp", "qvel", "base_quat"]), label="key")
        action = data.draw(st.sampled_from(["junk", "delete", "shrink", "nan", "transpose", "astype"]), label="action")
        current = arrays.get(key)
        if action == "junk" or current is None:
            arrays[key] = data.draw(_junk_arrays, label="junk")
        elif action == "delete":
            del arrays[key]
        elif action == "shrink":
            arrays[key] = current[: data.draw(st.integers(0, 2))] if current.ndim else current
        elif action == "nan" and current.dtype.kind == "f" and current.size:
            flat = current.copy().reshape(-1)
            flat[data.draw(st.integers(0, flat.size - 1))] = data.draw(st.sampled_from([np.nan, np.inf, -np.inf, 1e308]))
            arrays[key] = flat.reshape(current.shape)
        elif action == "transpose":
            arrays[key] = current.T
        else:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # complex → real drops the imaginary part: fine for junk
                arrays[key] = current.astype(data.draw(_dtypes))
    return arrays


def _corrupt_bytes(raw: bytes, data) -> bytes:
    if not data.draw(st.booleans(), label="corrupt bytes"):
        return raw
    cut = data.draw(st.integers(0, len(raw)), label="cut")
    junk = data.draw(st.binary(max_size=24), label="junk")
    drop = data.draw(st.integers(0, 64), label="drop")
    return raw[:cut] + junk + raw[cut + drop:]


@FUZZ
@given(data=st.data())
def test_keypoint_npz_mutations(tmp_path_factory, capsys, stubbed, data):
    folder = tmp_path_factory.mktemp("kp")
    src = folder / "src.npz"
    try:
        raw = mc.npz_bytes(_mutated(KEYPOINT_BASE, data))
    except (TypeError, ValueError):  # numpy cannot write that junk: nothing to read
        assume(False)
    src.write_bytes(_corrupt_bytes(raw, data))
    try:
        KeypointMotion.load(src)
        loaded = True
    except MotionFormatError as exc:
        one_line(str(exc), src.name)
        loaded = False
    out = folder / "out.npz"
    rc = run_cli(["retarget", "--source", str(src), "--robot", "go2", "--out", str(out)], capsys, src, out)
    assert rc == (0 if loaded else 2)
    if rc == 0:
        assert RobotMotion.load(out).frames == 11  # the (stubbed) result is written whole


# ----------------------------------------------------------------------------- robot npz (motions)

@pytest.mark.parametrize("case", corpus("robot_npz"), ids=lambda p: p.name)
def test_robot_npz_corpus_studio_tmr(case, tmp_path, capsys, stubbed):
    out = tmp_path / "out.npz"
    rc = run_cli(["tmr", "--motion", str(case), "--out", str(out), "--json"], capsys, case, out)
    assert rc == 2 and not stubbed, f"{case.name} was accepted"
    try:
        load_motion(case)
    except MotionFormatError as exc:
        one_line(str(exc), case.name)


def test_robot_npz_zip_bomb_and_huge_file(tmp_path, capsys, stubbed):
    bomb = tmp_path / "zip_bomb_300MB.npz"
    bomb.write_bytes(mc.large_cases("robot_npz")["zip_bomb_300MB.npz"])
    huge = write_huge(tmp_path / "huge_file.npz", *mc.huge_files("robot_npz")["huge_file.npz"])
    for path in (bomb, huge):
        out = tmp_path / "out.npz"
        assert run_cli(["tmr", "--motion", str(path), "--out", str(out)], capsys, path, out) == 2


def test_valid_robot_npz_reaches_tmr(tmp_path, capsys, stubbed):
    src = tmp_path / "standing.npz"
    src.write_bytes(mc.npz_bytes(ROBOT_BASE))
    out = tmp_path / "out.npz"
    assert run_cli(["tmr", "--motion", str(src), "--out", str(out), "--json"], capsys, src, out) == 0
    assert stubbed == ["tmr"]


@FUZZ
@given(data=st.data())
def test_robot_npz_mutations(tmp_path_factory, capsys, stubbed, data):
    folder = tmp_path_factory.mktemp("rm")
    src = folder / "motion.npz"
    try:
        raw = mc.npz_bytes(_mutated(ROBOT_BASE, data))
    except (TypeError, ValueError):
        assume(False)
    src.write_bytes(_corrupt_bytes(raw, data))
    try:
        RobotMotion.load(src)
    except MotionFormatError as exc:
        one_line(str(exc), src.name)
    out = folder / "out.npz"
    if run_cli(["tmr", "--motion", str(src), "--out", str(out), "--json"], capsys, src, out) == 0:
        assert RobotMotion.load(out).frames == 11


# ----------------------------------------------------------------------------- npz in the studio (engine jobs)

def _job_result(runner, job: str, params: dict) -> dict:
    runner.start(job, params, "fuzz-1")
    runner.join(120)
    results = [e.result for e in runner.drain() if e.result is not None]
    assert len(results) == 1
    return results[0]


@pytest.mark.parametrize("reader", ["keypoint_npz", "robot_npz"])
def test_npz_corpus_fails_studio_jobs_with_one_line(reader, tmp_path, capsys):
    """The Retarget workspace's jobs (retarget from a source, view a result) fail with the one line the panel
    shows as its status; the engine prints no traceback and writes nothing."""
    from engine.jobs import JobRunner

    for sub in ("source", "go2"):
        (tmp_path / sub).mkdir()
    runner = JobRunner(root=tmp_path)
    for case in corpus(reader):
        folder = "source" if reader == "keypoint_npz" else "go2"
        (tmp_path / folder / case.name).write_bytes(case.read_bytes())
        if reader == "keypoint_npz":
            result = _job_result(runner, "retarget", {"source": f"source/{case.name}", "robot": "go2",
                                                     "method": "smr", "name": "fuzz_out"})
        else:
            result = _job_result(runner, "poses", {"motion": f"go2/{case.name}"})
        assert result["ok"] is False and not result["cancelled"], (case.name, result)
        one_line(result["error"], case.name)
    err = capsys.readouterr().err
    assert "Traceback" not in err, err[-3000:]
    assert not (tmp_path / "go2" / "fuzz_out.npz").exists() and not leftovers(tmp_path / "go2")


# ----------------------------------------------------------------------------- BVH

@pytest.fixture
def shared(tmp_path, monkeypatch):
    """A shared data folder for the Puppeteer's clip source (open_source reads clips only from there)."""
    from engine.retarget.humanoid_arm import sources

    root = tmp_path / "shared"
    (root / "mocap-src").mkdir(parents=True)
    monkeypatch.setattr(sources, "shared_dir", lambda: root)
    return root


def _open_clip(shared: Path, name: str, data: bytes) -> str:
    """The studio's Puppeteer source for a clip: '' when accepted, else its one-line status message."""
    from engine.retarget.humanoid_arm.puppet_session import open_source

    (shared / "mocap-src" / name).write_bytes(data)
    try:
        open_source({"source": "clip", "clip": f"mocap-src/{name}"}).close()
    except ValueError as exc:
        return str(exc)
    return ""


@pytest.mark.parametrize("case", corpus("bvh"), ids=lambda p: p.name)
def test_bvh_corpus(case, tmp_path, capsys, shared):
    out = tmp_path / "out.npz"
    rc = run_cli(["puppet", "--robot", "g1", "--bvh", str(case), "--out", str(out)], capsys, case, out)
    assert rc == 2, f"{case.name} was accepted"
    message = _open_clip(shared, case.name, case.read_bytes())
    assert message, f"the Puppeteer accepted {case.name}"
    one_line(message, case.name)


@pytest.mark.parametrize("name", ["deep_100000.bvh", "huge_file.bvh"])
def test_bvh_large_cases(name, tmp_path, capsys):
    path = tmp_path / name
    if name in mc.large_cases("bvh"):
        path.write_bytes(mc.large_cases("bvh")[name])
    else:
        write_huge(path, *mc.huge_files("bvh")[name])
    with pytest.raises(BvhError) as info:
        load_bvh(path)
    one_line(str(info.value), name)
    out = tmp_path / "out.npz"
    assert run_cli(["puppet", "--robot", "g1", "--bvh", str(path), "--out", str(out)], capsys, path, out) == 2


def test_valid_bvh_streams_a_datagram(tmp_path, capsys):
    path = tmp_path / "tiny.bvh"
    path.write_text(mc.VALID_BVH)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.1", 0))
        sock.settimeout(30)
        rc = run_cli(["stream-bvh", str(path), "--to", f"udp://127.0.0.1:{sock.getsockname()[1]}",
                      "--max-frames", "1"], capsys, path, tmp_path / "none")
        assert rc == 0
        frame, pose = parse_datagram(sock.recv(65536))
    assert frame == 0 and pose.shape == (15,)


_bvh_tokens = st.sampled_from(["{", "}", "JOINT", "End", "Site", "ROOT", "OFFSET", "CHANNELS", "MOTION", "Frames:",
                               "Frame", "Time:", "0", "-1", "3", "6", "99999999", "nan", "inf", "1e308", "1e-320",
                               "Xrotation", "Yposition", "Qrotation", "x", "é", "\x00", "\t", "\n", "0.0333",
                               "RightArm", "LeftHand", "Hips"])


@FUZZ
@given(cut=st.integers(0, len(mc.VALID_BVH)), drop=st.integers(0, 40),
       junk=st.lists(_bvh_tokens, max_size=6).map(" ".join), raw=st.binary(max_size=8))
def test_bvh_mutations(tmp_path_factory, capsys, cut, drop, junk, raw):
    folder = tmp_path_factory.mktemp("bvh")
    path = folder / "clip.bvh"
    text = mc.VALID_BVH
    path.write_bytes(text[:cut].encode() + f" {junk} ".encode() + raw + text[cut + drop:].encode())
    try:
        load_bvh(path)
    except BvhError as exc:
        one_line(str(exc), path.name)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.1", 0))
        sock.settimeout(10)
        rc = run_cli(["stream-bvh", str(path), "--to", f"udp://127.0.0.1:{sock.getsockname()[1]}",
                      "--max-frames", "1"], capsys, path, folder / "none")
        if rc == 0:  # whatever the CLI streams, the receiver accepts
            _, pose = parse_datagram(sock.recv(65536))
            assert np.all(np.isfinite(pose))


# ----------------------------------------------------------------------------- live datagrams

@pytest.mark.parametrize("case", corpus("datagram"), ids=lambda p: p.name)
def test_datagram_corpus(case):
    with pytest.raises(DatagramError) as info:
        parse_datagram(case.read_bytes())
    one_line(str(info.value), "datagram")


def test_datagram_large_case():
    with pytest.raises(DatagramError) as info:
        parse_datagram(mc.large_cases("datagram")["over_64KiB.bin"])
    one_line(str(info.value), "datagram")


def test_udp_source_counts_bad_datagrams_and_keeps_the_good_one():
    """The Puppeteer's live source: every corpus datagram is counted as bad and named in one line (the engine's
    notice), none stops it, and the valid datagram sent last is the pose it returns."""
    from engine.retarget.humanoid_arm.puppet_session import UdpSource

    source = UdpSource(0)
    cases = [c.read_bytes() for c in corpus("datagram")]
    good = json.dumps(mc.valid_datagram()).encode()
    try:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
            for payload in cases + [good]:
                sock.sendto(payload, ("127.0.0.1", source.port))
            sender = sock.getsockname()
            deadline = time.monotonic() + 30
            pose = None
            while source.received < len(cases) + 1 and time.monotonic() < deadline:
                pose = source.poll()
                time.sleep(0.01)
        assert source.received == len(cases) + 1 and source.bad == len(cases)
        assert pose is not None and np.allclose(pose, parse_datagram(good)[1])
        one_line(source.last_error, f"datagram from 127.0.0.1:{sender[1]}")
    finally:
        source.close()


_json_junk = st.recursive(
    st.one_of(st.none(), st.booleans(), st.integers(-10 ** 400, 10 ** 400), st.floats(), st.text(max_size=6),
              st.sampled_from(["mocap-joints/1", "hips", "joints"])),
    lambda kids: st.lists(kids, max_size=4) | st.dictionaries(st.text(max_size=6), kids, max_size=3),
    max_leaves=8)
_DATAGRAM_PATHS = [("format",), ("frame",), ("up",), ("up", 1), ("joints",),
                   *[("joints", j) for j in mc.valid_datagram()["joints"]],
                   *[("joints", j, i) for j in ("hips", "right_hand", "left_elbow") for i in range(3)]]


@FUZZ
@given(changes=st.lists(st.tuples(st.sampled_from(_DATAGRAM_PATHS), _json_junk), min_size=1, max_size=3),
       raw=st.one_of(st.none(), st.binary(max_size=200)))
def test_datagram_mutations(changes, raw):
    doc = mc.valid_datagram()
    for path, value in changes:
        node = doc
        for k in path[:-1]:
            if isinstance(node, dict):
                node = node.get(k)
            elif isinstance(node, list) and isinstance(k, int) and k < len(node):
                node = node[k]
            else:  # an earlier change replaced this part by something else (a list by a dict, ...)
                node = None
            if node is None:
                break
        if isinstance(node, dict) or (isinstance(node, list) and isinstance(path[-1], int) and path[-1] < len(node)):
            node[path[-1]] = value
    payload = raw if raw is not None else json.dumps(doc).encode()
    try:
        frame, pose = parse_datagram(payload)
    except DatagramError as exc:
        one_line(str(exc), "datagram")
        return
    assert isinstance(frame, int) and pose.shape == (15,) and np.all(np.isfinite(pose))
    assert np.allclose(np.linalg.norm(pose.reshape(5, 3), axis=1), 1.0, atol=0.05)  # five unit bones


# ----------------------------------------------------------------------------- motion frame files (studio import)

@pytest.mark.parametrize("case", corpus("motion_frames"), ids=lambda p: p.name)
def test_motion_frames_corpus_studio_import(case, tmp_path, capsys):
    out = tmp_path / "out.npz"
    rc = run_cli(["import", str(case), "--format", "motion-imitation", "--out", str(out)], capsys, case, out)
    assert rc == 2, f"{case.name} was accepted"


@pytest.mark.parametrize("name", ["deep_100000.txt", "huge_file.txt"])
def test_motion_frames_large_cases(name, tmp_path, capsys):
    path = tmp_path / name
    if name in mc.large_cases("motion_frames"):
        path.write_bytes(mc.large_cases("motion_frames")[name])
    else:
        write_huge(path, *mc.huge_files("motion_frames")[name])
    out = tmp_path / "out.npz"
    rc = run_cli(["import", str(path), "--format", "motion-imitation", "--out", str(out)], capsys, path, out)
    assert rc == 2


_frame_junk = st.sampled_from(["NaN", "Infinity", "-Infinity", "1e999", "9" * 400, '"0"', "null", "true", "[]",
                               "{}", "[0]", "0", "-1", "1e-300", '"Frames"', ",", "]", "[", "}"])


@FUZZ
@given(cut=st.integers(0, len(mc.VALID_FRAMES)), drop=st.integers(0, 12), junk=_frame_junk,
       tail=st.booleans())
def test_motion_frames_mutations(tmp_path_factory, capsys, cut, drop, junk, tail):
    folder = tmp_path_factory.mktemp("frames")
    path = folder / "clip.txt"
    text = mc.VALID_FRAMES
    path.write_text(text[:cut] + junk + (text[cut + drop:] if tail else ""))
    out = folder / "out.npz"
    rc = run_cli(["import", str(path), "--format", "motion-imitation", "--out", str(out)], capsys, path, out)
    if rc == 0:
        assert KeypointMotion.load(out).frames >= 2
