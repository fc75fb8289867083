"""Regenerate the malformed-input corpus of issue 14: ``PYTHONPATH=. python tests/fuzz_corpus/make_corpus.py [READER…]``.

Small cases are committed under ``tests/fuzz_corpus/<reader>/``; large ones (a huge file, 100 000-deep
nesting, a zip bomb) are only built at test time by :func:`large_cases` so the repository stays small.
Each case is one way a user file goes wrong: truncated, wrong types, NaN/inf, huge numbers, deep
nesting, wrong encoding, binary junk, duplicate keys, an empty file.

Readers: ``style`` (style JSON), ``robot_toml``, ``keyframes`` (``--command`` files), ``keypoint_npz`` (source
motions: ``studio retarget --source``, the Retarget workspace), ``robot_npz`` (robot motions: ``studio tmr
--motion``, results the studio plays), ``bvh`` (``studio puppet`` / ``stream-bvh``, the Puppeteer's clips),
``datagram`` (live mocap datagrams, one file = one UDP payload), ``motion_frames`` (motion_imitation /
AMP_for_hardware frame files, ``studio import``), ``dog_keypoints`` (motion_imitation's ``dog_*_joint_pos.txt``)
and ``dog_bvh`` (MANN dog BVH clips) — both ``studio import / retarget --source`` and the Retarget workspace's
Import. The valid files the mutations start from are :func:`valid_keypoint_npz`, :func:`valid_robot_npz`,
:data:`VALID_BVH`, :func:`valid_datagram`, :data:`VALID_FRAMES`, :data:`VALID_DOG_KEYPOINTS` and
:data:`VALID_DOG_BVH`.
"""

from __future__ import annotations

import functools
import io
import json
import re
import struct
import warnings
import zipfile
import zlib
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]


def _style_cases() -> dict[str, bytes]:
    text = (REPO / "styles" / "g1" / "neutral.json").read_text()
    doc = json.loads(text)

    def variant(mutate) -> bytes:
        d = json.loads(text)
        mutate(d)
        return json.dumps(d, separators=(",", ":")).encode()

    def s(path: str, value):
        def mutate(d):
            keys = path.split("/")
            node = d
            for k in keys[:-1]:
                node = node[int(k)] if isinstance(node, list) else node[k]
            last = keys[-1]
            node[int(last) if isinstance(node, list) else last] = value
        return mutate

    knots = "samples/in_place/curves/left_foot.z/knots"
    cases = {
        "empty.json": b"",
        "whitespace.json": b" \n\t\n",
        "truncated_half.json": text.encode()[: len(text) // 2],
        "truncated_in_string.json": b'{"schema": "motion-studio/sty',
        "truncated_in_number.json": text.encode()[: text.index("0.5,") + 2],
        "not_an_object.json": b"[1, 2, 3]",
        "a_string.json": b'"neutral"',
        "null.json": b"null",
        "nan_velocity.json": text.replace('"x_max_mps": 0.5', '"x_max_mps": NaN').encode(),
        "inf_eta.json": text.replace('"blend_eta": 0.5', '"blend_eta": Infinity').encode(),
        "neg_inf_cycle.json": text.replace('"cycle_s": 0.7', '"cycle_s": -Infinity', 1).encode(),
        "huge_float.json": text.replace('"blend_eta": 0.5', '"blend_eta": 1e999').encode(),
        "huge_int.json": text.replace('"blend_eta": 0.5', '"blend_eta": ' + "9" * 5000).encode(),
        "bool_number.json": variant(s("blend_eta", True)),
        "string_number.json": variant(s("samples/in_place/intervals/cycle_s", "0.9")),
        "list_for_object.json": variant(s("samples/in_place/attributes", [1, 2])),
        "object_for_list.json": variant(s("samples/in_place/intervals/left_swing_s", {"a": 1})),
        "knot_row_short.json": variant(s(knots + "/1", [0.1])),
        "knot_row_strings.json": variant(s(knots + "/1", ["a", "b", "c", "d", "e"])),
        "knot_row_nested.json": variant(s(knots + "/1", [[0.1], [0.2], 0, 0, "flat"])),
        "knot_mode_number.json": variant(s(knots + "/1/4", 3)),
        "knots_empty.json": variant(s(knots, [])),
        "knots_not_list.json": variant(s(knots, "x")),
        "curve_not_object.json": variant(s("samples/in_place/curves/left_foot.z", 7)),
        "samples_null.json": variant(s("samples", None)),
        "sample_missing.json": variant(lambda d: d["samples"].pop("in_place")),
        "unknown_robot.json": variant(s("robot", "../../etc/passwd")),
        "robot_number.json": variant(s("robot", 1)),
        "schema_wrong.json": variant(s("schema", "other")),
        "version_future.json": variant(s("version", 99)),
        "duplicate_top_key.json": text.replace('"blend_eta": 0.5', '"blend_eta": 0.5, "blend_eta": 0.6').encode(),
        "duplicate_nested_key.json": text.replace('"cycle_s": 0.7', '"cycle_s": 0.7, "cycle_s": 0.8', 1).encode(),
        "deep_nesting_100.json": b'{"samples": ' + b"[" * 100 + b"]" * 100 + b"}",
        "latin1.json": text.replace("The nominal", "Th\u00e9 nominal").encode("latin-1"),
        "utf16.json": text.encode("utf-16"),
        "utf8_bom.json": b"\xef\xbb\xbf" + variant(s("blend_eta", "x")),
        "binary_junk.json": bytes(range(256)) * 4,
        "nul_bytes.json": text.encode()[:200] + b"\0\0\0",
        "trailing_garbage.json": text.encode() + b"}}}",
        "huge_string.json": b'{"description": "' + b"x" * 50_000 + b'"}',
        "control_chars.json": b'{"name": "a\x01b"}',
        "lone_surrogate.json": b'{"name": "\\ud800"}',
    }
    del doc
    return cases


def _toml_cases() -> dict[str, bytes]:
    text = (REPO / "robots" / "g1.toml").read_text()
    first_number = re.search(r"= (-?\d+\.\d+)", text)
    assert first_number
    a, b = first_number.span(1)
    return {
        "empty.toml": b"",
        "truncated.toml": text.encode()[: len(text) // 3],
        "truncated_in_table.toml": b"[feet.left\n",
        "nan.toml": (text[:a] + "nan" + text[b:]).encode(),
        "inf.toml": (text[:a] + "inf" + text[b:]).encode(),
        "string_for_number.toml": (text[:a] + '"0.3"' + text[b:]).encode(),
        "table_for_number.toml": (text[:a] + "{ x = 1 }" + text[b:]).encode(),
        "huge_int.toml": (text[:a] + "9" * 5000 + text[b:]).encode(),
        "duplicate_key.toml": text.replace('kind = "biped"', 'kind = "biped"\nkind = "biped"').encode(),
        "wrong_kind.toml": text.replace('kind = "biped"', 'kind = "tripod"').encode(),
        "name_mismatch.toml": text.replace('name = "g1"', 'name = "h1"').encode(),
        "deep_array.toml": b'name = "g1"\nx = ' + b"[" * 2000 + b"]" * 2000 + b"\n",
        "latin1.toml": text.replace("Unitree G1", "Unitr\u00e9e").encode("latin-1", errors="replace"),
        "utf16.toml": text.encode("utf-16"),
        "binary_junk.toml": bytes(range(256)) * 4,
        "gains_not_list.toml": (text + '\ngains = 3\n').encode(),
    }


def _keyframe_cases() -> dict[str, bytes]:
    return {
        "empty.json": b"",
        "no_keyframes.json": b"{}",
        "keyframes_string.json": b'{"keyframes": "fast"}',
        "row_short.json": b'{"keyframes": [[0, 0.1]]}',
        "row_nan.json": b'{"keyframes": [[0, NaN, 0, 0]]}',
        "row_huge.json": b'{"keyframes": [[0, 1e999, 0, 0]]}',
        "decreasing.json": b'{"keyframes": [[1, 0, 0, 0], [0, 0, 0, 0]]}',
        "bool_row.json": b'{"keyframes": [[0, true, 0, 0]]}',
        "deep.json": b'{"keyframes": ' + b"[" * 500 + b"]" * 500 + b"}",
        "duplicate.json": b'{"keyframes": [[0, 0, 0, 0]], "keyframes": []}',
        "truncated.json": b'{"keyframes": [[0, 0.1, 0',
        "binary_junk.json": bytes(range(256)),
    }


# ----------------------------------------------------------------------------- npz building blocks

def npz_bytes(arrays: dict[str, np.ndarray]) -> bytes:
    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays)
    return buf.getvalue()


def npy_bytes(arr: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.lib.format.write_array(buf, arr, allow_pickle=True)  # object arrays: a pickle INSIDE a test input
    return buf.getvalue()


def npy_header(shape, descr: str = "<f8", fortran: bool = False, raw: bytes | None = None,
               version: bytes = b"\x01\x00") -> bytes:
    """An .npy header declaring anything (the data that follows is up to the caller)."""
    h = raw if raw is not None else repr({"descr": descr, "fortran_order": fortran, "shape": shape}).encode("latin1")
    pad = (64 - (10 + len(h) + 1) % 64) % 64
    h = h + b" " * pad + b"\n"
    return b"\x93NUMPY" + version + struct.pack("<H", len(h)) + h


def zip_entries(entries: list[tuple[str, bytes]], compress_type: int = zipfile.ZIP_DEFLATED) -> bytes:
    buf = io.BytesIO()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # "Duplicate name": that is the point of one case
        with zipfile.ZipFile(buf, "w", compression=compress_type) as z:
            for name, data in entries:
                z.writestr(name, data)
    return buf.getvalue()


def with_arrays(base: dict[str, np.ndarray], **changes) -> bytes:
    """``base`` with arrays replaced (a value of None deletes the array)."""
    arrays = {k: v for k, v in base.items() if k not in changes}
    arrays.update({k: v for k, v in changes.items() if v is not None})
    return npz_bytes(arrays)


def _entries(base: dict[str, np.ndarray]) -> list[tuple[str, bytes]]:
    return [(f"{k}.npy", npy_bytes(v)) for k, v in base.items()]


def _patched_entries(base: dict[str, np.ndarray], key: str, data: bytes) -> list[tuple[str, bytes]]:
    return [(f"{k}.npy", data if k == key else npy_bytes(v)) for k, v in base.items()]


def _zip_declaring(entry_name: str, data: bytes, declared_size: int) -> bytes:
    """A one-entry zip whose headers declare ``declared_size`` uncompressed bytes (a lying zip)."""
    raw = zip_entries([(entry_name, data)])
    size = struct.pack("<I", declared_size)
    local = raw.index(b"PK\x03\x04")
    central = raw.index(b"PK\x01\x02")
    out = bytearray(raw)
    out[local + 22:local + 26] = size
    out[central + 24:central + 28] = size
    return bytes(out)


def _saved_arrays(motion) -> dict[str, np.ndarray]:
    import tempfile

    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "m.npz"
        motion.save(path)
        with np.load(path, allow_pickle=False) as f:
            return {k: f[k] for k in f.files}


def valid_keypoint_npz() -> dict[str, np.ndarray]:
    """The arrays of a valid keypoint motion (a 12-frame synthetic trot, keypoint-motion/1)."""
    from engine.retarget.synthetic import synthetic_trot

    return _saved_arrays(synthetic_trot(frames=12))


def valid_robot_npz() -> dict[str, np.ndarray]:
    """The arrays of a valid robot motion (go2 standing, 11 frames, robot-motion/1)."""
    from engine.retarget.quadruped.tmr.kinematic_clips import standing
    from engine.robot.model import load_robot

    return _saved_arrays(standing(load_robot("go2"), duration_s=0.2))


def _common_npz_cases(base: dict[str, np.ndarray], main: str) -> dict[str, bytes]:
    """Archive-level cases, the same for every npz reader (``main``: its largest float array)."""
    good = npz_bytes(base)
    arr = base[main]
    cases = {
        "empty.npz": b"",
        "text.npz": b"keypoints: 1 2 3\n",
        "binary_junk.npz": bytes(range(256)) * 4,
        "truncated_half.npz": good[: len(good) // 2],
        "truncated_no_directory.npz": good[:-22],
        "zip_prefix_only.npz": b"PK\x03\x04" + b"\0" * 40,
        "empty_zip.npz": zip_entries([]),
        "text_entry.npz": zip_entries(_entries(base) + [("readme.txt", b"hello")]),
        "duplicate_entry.npz": zip_entries(_entries(base) + [(f"{main}.npy", npy_bytes(arr[:1]))]),
        "object_array_pickle.npz": zip_entries(_patched_entries(base, main, npy_bytes(np.array([{"x": 1}, None],
                                                                                               dtype=object)))),
        "structured_dtype.npz": with_arrays(base, **{main: np.zeros(3, dtype=[("a", "<f8"), ("b", "<i4")])}),
        "complex_dtype.npz": with_arrays(base, **{main: arr.astype(complex)}),
        "text_numbers.npz": with_arrays(base, **{main: arr.astype(str)}),
        "bytes_numbers.npz": with_arrays(base, **{main: arr.astype(bytes)}),
        "nan.npz": with_arrays(base, **{main: np.where(np.arange(arr.size).reshape(arr.shape) == 5, np.nan, arr)}),
        "inf.npz": with_arrays(base, **{main: np.full_like(arr, np.inf)}),
        "huge_numbers.npz": with_arrays(base, **{main: np.full_like(arr, 1e308)}),
        "wrong_shape.npz": with_arrays(base, **{main: arr.reshape(-1)}),
        "scalar.npz": with_arrays(base, **{main: np.array(1.0)}),
        "zero_frames.npz": with_arrays(base, **{main: arr[:0]}),
        "missing_main.npz": with_arrays(base, **{main: None}),
        "header_huge_shape.npz": zip_entries(_patched_entries(
            base, main, npy_header((10 ** 6, 10 ** 6, 3)) + b"\0" * 64)),
        "header_shape_overflow.npz": zip_entries(_patched_entries(base, main, npy_header((2 ** 62, 2 ** 62)))),
        "header_negative_shape.npz": zip_entries(_patched_entries(base, main, npy_header((-1, 16, 3)))),
        "header_data_short.npz": zip_entries(_patched_entries(base, main, npy_header(arr.shape) + b"\0" * 16)),
        "header_data_long.npz": zip_entries(_patched_entries(base, main, npy_bytes(arr) + b"\0" * 64)),
        "header_garbage.npz": zip_entries(_patched_entries(base, main, npy_header(None, raw=b"{'descr': <f8 ((("))),
        "header_not_dict.npz": zip_entries(_patched_entries(base, main, npy_header(None, raw=b"[1, 2, 3]"))),
        "header_object_descr.npz": zip_entries(_patched_entries(base, main, npy_header((2,), descr="|O"))),
        "header_deep_tuple.npz": zip_entries(_patched_entries(base, main, npy_header(
            None, raw=b"{'descr': '<f8', 'fortran_order': False, 'shape': " + b"(" * 3000 + b")" * 3000 + b"}"))),
        "header_version_9.npz": zip_entries(_patched_entries(base, main, npy_header(arr.shape, version=b"\x09\x00")
                                                             + arr.tobytes())),
        "bad_magic.npz": zip_entries(_patched_entries(base, main, b"\x93NUMPZ" + npy_bytes(arr)[6:])),
        "bz2_entry.npz": zip_entries(_entries(base), compress_type=zipfile.ZIP_BZIP2),
        "lying_declared_size.npz": _zip_declaring(f"{main}.npy", npy_bytes(arr), 3 * 1024 ** 3),
        "bad_crc.npz": _flip_last_data_byte(zip_entries(_entries(base), compress_type=zipfile.ZIP_STORED)),
        "encrypted_flag.npz": _set_flag(zip_entries(_entries(base)), 0x1),
    }
    return cases


def _flip_last_data_byte(raw: bytes) -> bytes:
    out = bytearray(raw)
    central = raw.index(b"PK\x01\x02")
    out[central - 1] ^= 0xFF  # the last data byte of the last entry
    return bytes(out)


def _set_flag(raw: bytes, bit: int) -> bytes:
    out = bytearray(raw)
    for sig, off in ((b"PK\x03\x04", 6), (b"PK\x01\x02", 8)):
        start = 0
        while (i := raw.find(sig, start)) >= 0:
            out[i + off] |= bit
            start = i + 4
    return bytes(out)


def _keypoint_npz_cases() -> dict[str, bytes]:
    base = valid_keypoint_npz()
    kp = base["keypoints"]
    source = str(base["source"])
    cases = _common_npz_cases(base, "keypoints")
    cases.update({
        "format_missing.npz": with_arrays(base, format=None),
        "format_wrong.npz": with_arrays(base, format=np.array("robot-motion/1")),
        "format_bytes.npz": with_arrays(base, format=np.array(b"keypoint-motion/1")),
        "format_list.npz": with_arrays(base, format=np.array(["keypoint-motion/1", "x"])),
        "fps_zero.npz": with_arrays(base, fps=np.array(0.0)),
        "fps_negative.npz": with_arrays(base, fps=np.array(-30.0)),
        "fps_nan.npz": with_arrays(base, fps=np.array(np.nan)),
        "fps_huge.npz": with_arrays(base, fps=np.array(1e300)),
        "fps_text.npz": with_arrays(base, fps=np.array("30")),
        "fps_vector.npz": with_arrays(base, fps=np.array([30.0, 30.0])),
        "fps_complex.npz": with_arrays(base, fps=np.array(30 + 1j)),
        "keypoints_15.npz": with_arrays(base, keypoints=kp[:, :15]),
        "keypoints_one_frame.npz": with_arrays(base, keypoints=kp[:1], contact=base["contact"][:1]),
        "keypoints_bool.npz": with_arrays(base, keypoints=kp > 0),
        "names_wrong.npz": with_arrays(base, keypoint_names=np.array([f"k{i}" for i in range(16)])),
        "names_short.npz": with_arrays(base, keypoint_names=base["keypoint_names"][:3]),
        "names_numbers.npz": with_arrays(base, keypoint_names=np.arange(16)),
        "foot_names_reordered.npz": with_arrays(base, foot_names=np.array(["FR", "FL", "RL", "RR"])),
        "contact_shape.npz": with_arrays(base, contact=base["contact"][:, :3]),
        "contact_twos.npz": with_arrays(base, contact=base["contact"].astype(int) * 2),
        "contact_nan.npz": with_arrays(base, contact=np.full(base["contact"].shape, np.nan)),
        "contact_text.npz": with_arrays(base, contact=base["contact"].astype(str)),
        "known_wrong_size.npz": with_arrays(base, known=np.ones(3, dtype=bool)),
        "known_text.npz": with_arrays(base, known=np.array(["yes"] * 16)),
        "base_quat_zero.npz": with_arrays(base, base_quat=np.zeros_like(base["base_quat"])),
        "base_quat_shape.npz": with_arrays(base, base_quat=base["base_quat"][:, :3]),
        "base_pos_inf.npz": with_arrays(base, base_pos=np.full_like(base["base_pos"], -np.inf)),
        "source_not_json.npz": with_arrays(base, source=np.array("{not json")),
        "source_array_json.npz": with_arrays(base, source=np.array("[1, 2]")),
        "source_deep_json.npz": with_arrays(base, source=np.array("[" * 100 + "]" * 100)),
        "source_deep_100000.npz": with_arrays(base, source=np.array('{"a": ' + "[" * 100_000 + "]" * 100_000 + "}")),
        "source_duplicate_key.npz": with_arrays(base, source=np.array(source[:-1] + ', "file": "x"}')),
        "source_vector.npz": with_arrays(base, source=np.array([source, source])),
        "source_bytes.npz": with_arrays(base, source=np.array(source.encode())),
    })
    return cases


def _robot_npz_cases() -> dict[str, bytes]:
    base = valid_robot_npz()
    q = base["qpos"]
    t = len(q)
    metrics = str(base["metrics"])
    cases = _common_npz_cases(base, "qpos")
    quat_zero = q.copy()
    quat_zero[:, 3:7] = 0.0
    cases.update({
        "format_keypoint.npz": with_arrays(base, format=np.array("keypoint-motion/1")),
        "qpos_6_columns.npz": with_arrays(base, qpos=q[:, :6]),
        "qpos_extra_column.npz": with_arrays(base, qpos=np.hstack([q, q[:, :1]])),
        "qpos_zero_quat.npz": with_arrays(base, qpos=quat_zero),
        "qpos_3d.npz": with_arrays(base, qpos=q[:, :, None]),
        "joint_names_short.npz": with_arrays(base, joint_names=base["joint_names"][:-1]),
        "joint_names_other.npz": with_arrays(base, joint_names=np.array([f"j{i}" for i in range(q.shape[1] - 7)])),
        "joint_names_2d.npz": with_arrays(base, joint_names=base["joint_names"][None, :]),
        "robot_traversal.npz": with_arrays(base, robot=np.array("../../etc/passwd")),
        "robot_unknown.npz": with_arrays(base, robot=np.array("nosuch")),
        "robot_number.npz": with_arrays(base, robot=np.array(2)),
        "robot_empty.npz": with_arrays(base, robot=np.array("")),
        "robot_newline.npz": with_arrays(base, robot=np.array("go2\nrm -rf")),
        "robot_vector.npz": with_arrays(base, robot=np.array(["go2", "go1"])),
        "method_missing.npz": with_arrays(base, method=None),
        "metrics_not_json.npz": with_arrays(base, metrics=np.array("{")),
        "metrics_deep.npz": with_arrays(base, metrics=np.array('{"a": ' + "[" * 5000 + "]" * 5000 + "}")),
        "metrics_duplicate.npz": with_arrays(base, metrics=np.array('{"a": 1, "a": 2}')),
        "metrics_list.npz": with_arrays(base, metrics=np.array("[" + metrics + "]")),
        "contact_feet_mismatch.npz": with_arrays(base, foot_names=np.array(["FL", "FR"])),
        "foot_names_scalar_nan.npz": with_arrays(base, foot_names=np.array(np.nan)),  # found by hypothesis
        "foot_names_empty.npz": with_arrays(base, foot_names=np.array([], dtype="<U2")),
        "qvel_shape.npz": with_arrays(base, qvel=np.zeros((t, 3))),
        "ctrl_text.npz": with_arrays(base, ctrl=np.full((t, 12), "x")),
        "keypoints_shape.npz": with_arrays(base, keypoints=np.zeros((t, 16, 2))),
        "alpha_negative.npz": with_arrays(base, alpha=np.array([-1.0]), segment_knots_s=np.array([0.0, 0.2])),
        "knots_mismatch.npz": with_arrays(base, alpha=np.array([1.0, 1.0]), segment_knots_s=np.array([0.0, 0.2])),
        "pd_kp_shape.npz": with_arrays(base, pd_kp=np.zeros(3)),
        "contact_sim_nan.npz": with_arrays(base, contact_sim=np.full((t, 4), np.nan)),
    })
    return cases


# ----------------------------------------------------------------------------- BVH

def _bvh_joint(name: str, offset: str, children: str, indent: str) -> str:
    return (f"{indent}JOINT {name}\n{indent}{{\n{indent}  OFFSET {offset}\n{indent}  CHANNELS 3 Zrotation Xrotation "
            f"Yrotation\n{children}{indent}}}\n")


def _bvh_end(indent: str) -> str:
    return f"{indent}End Site\n{indent}{{\n{indent}  OFFSET 0 -5 0\n{indent}}}\n"


def _arm(side: str, sign: int) -> str:
    x = 6 * sign
    return _bvh_joint(f"{side}Arm", f"{x} 20 0", _bvh_joint(f"{side}ForeArm", f"{x * 2} 0 0", _bvh_joint(
        f"{side}Hand", f"{x * 2} 0 0", _bvh_end("        "), "      "), "    "), "  ")


def _leg(side: str, sign: int) -> str:
    return _bvh_joint(f"{side}UpLeg", f"{4 * sign} -4 0", _bvh_end("    "), "  ")


# A tiny CMU-named humanoid (MotionBuilder naming: Hips, *Arm, *ForeArm, *Hand, *UpLeg): 10 joints, 27 channels.
_VALID_HIERARCHY = ("HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0 0\n  CHANNELS 6 Xposition Yposition Zposition Zrotation "
                    "Xrotation Yrotation\n" + _arm("Right", -1) + _arm("Left", 1) + _leg("Right", -1)
                    + _leg("Left", 1) + "}\n")
_N_CHANNELS = 6 + 3 * 8


def _bvh_motion(frames: int, frame_time: str = "0.033333") -> str:
    rows = []
    for f in range(frames):
        values = [0.0, 90.0, 0.0, 0.0, 0.0, 0.0] + [0.0] * (_N_CHANNELS - 6)
        values[6 + 1] = 10.0 * f  # the right arm swings
        values[6 + 3 * 4 + 1] = -10.0 * f  # the left arm too
        rows.append(" ".join(f"{v:g}" for v in values))
    return f"MOTION\nFrames: {frames}\nFrame Time: {frame_time}\n" + "\n".join(rows) + "\n"


VALID_BVH = _VALID_HIERARCHY + _bvh_motion(4)


def _bvh_cases() -> dict[str, bytes]:
    text = VALID_BVH
    body = text[text.index("MOTION"):]
    nested = "HIERARCHY\nROOT Hips\n{\n OFFSET 0 0 0\n CHANNELS 3 Xposition Yposition Zposition\n"
    nested += "".join(f"JOINT j{i}\n{{\nOFFSET 0 1 0\nCHANNELS 0\n" for i in range(300))
    nested += "}\n" * 301 + "MOTION\nFrames: 1\nFrame Time: 0.1\n0 0 0\n"
    sites = ("HIERARCHY\nROOT Hips\n{\n OFFSET 0 0 0\n CHANNELS 1 Xposition\n"
             + "".join(f"JOINT s{i}\n{{\nOFFSET 0 1 0\n}}\n" for i in range(1500)) + "}\n")
    return {
        "empty.bvh": b"",
        "whitespace.bvh": b"  \n\t\n",
        "not_bvh.bvh": b"Hello, this is not motion capture\n",
        "truncated_hierarchy.bvh": text[: text.index("LeftArm") + 20].encode(),
        "truncated_motion.bvh": text[: len(text) - 40].encode(),
        "no_motion.bvh": _VALID_HIERARCHY.encode(),
        "frames_text.bvh": text.replace("Frames: 4", "Frames: four").encode(),
        "frames_negative.bvh": text.replace("Frames: 4", "Frames: -4").encode(),
        "frames_zero.bvh": text.replace("Frames: 4", "Frames: 0").encode(),
        "frames_huge.bvh": text.replace("Frames: 4", "Frames: 99999999999").encode(),
        "frames_digits_unicode.bvh": text.replace("Frames: 4", "Frames: \u0664").encode(),
        "frame_time_zero.bvh": text.replace("Frame Time: 0.033333", "Frame Time: 0").encode(),
        "frame_time_negative.bvh": text.replace("Frame Time: 0.033333", "Frame Time: -0.03").encode(),
        "frame_time_nan.bvh": text.replace("Frame Time: 0.033333", "Frame Time: nan").encode(),
        "frame_time_tiny.bvh": text.replace("Frame Time: 0.033333", "Frame Time: 5e-324").encode(),
        "frame_time_huge.bvh": text.replace("Frame Time: 0.033333", "Frame Time: 1e308").encode(),
        "channels_count_text.bvh": text.replace("CHANNELS 6", "CHANNELS six").encode(),
        "channels_count_huge.bvh": text.replace("CHANNELS 6", "CHANNELS 99999999999999999999").encode(),
        "channel_name_bad.bvh": text.replace("Zrotation", "Qrotation", 1).encode(),
        "no_channels.bvh": re.sub(r"CHANNELS \d+[^\n]*", "CHANNELS 0", text).replace(
            body, "MOTION\nFrames: 1000000\nFrame Time: 0.01\n").encode(),
        "value_nan.bvh": text.replace("\n0 90 0", "\nnan 90 0", 1).encode(),
        "value_inf.bvh": text.replace("\n0 90 0", "\n1e999 90 0", 1).encode(),
        "value_huge.bvh": text.replace("\n0 90 0", "\n1e308 1e308 1e308", 1).encode(),
        "value_text.bvh": text.replace("\n0 90 0", "\nzero 90 0", 1).encode(),
        "value_comma.bvh": text.replace("\n0 90 0", "\n0,5 90 0", 1).encode(),
        "extra_values.bvh": (text + "1 2 3\n").encode(),
        "offset_missing.bvh": text.replace("OFFSET 0 0 0\n", "", 1).encode(),
        "offset_nan.bvh": text.replace("OFFSET 0 0 0", "OFFSET nan 0 0", 1).encode(),
        "offset_text.bvh": text.replace("OFFSET 0 0 0", "OFFSET a b c", 1).encode(),
        "brace_missing.bvh": text.replace("{", "", 1).encode(),
        "end_not_site.bvh": text.replace("End Site", "End Zone", 1).encode(),
        "two_roots.bvh": (_VALID_HIERARCHY + _VALID_HIERARCHY[len("HIERARCHY\n"):] + body).encode(),
        "nested_300.bvh": nested.encode(),
        "joints_x_frames.bvh": (sites + "MOTION\nFrames: 5000\nFrame Time: 0.01\n" + "0\n" * 5000).encode(),
        "no_arm_joints.bvh": text.replace("RightForeArm", "RightElbowX").replace("LeftHand", "LeftPaw").encode(),
        "degenerate_skeleton.bvh": re.sub(r"OFFSET [^\n]*", "OFFSET 0 0 0", text).encode(),
        "latin1_name.bvh": text.replace("RightUpLeg", "RightUpLeg\u00e9").encode("latin-1"),
        "utf16.bvh": text.encode("utf-16"),
        "nul_bytes.bvh": text.encode()[:100] + b"\0\0" + text.encode()[100:],
        "binary_junk.bvh": bytes(range(256)) * 4,
    }


# ----------------------------------------------------------------------------- dog clips (MANN skeleton)

def _dog_node(name: str, offset: str, children: str = "", end: str | None = None) -> str:
    """A JOINT of the dog skeleton (3 rotation channels), with its children or an End Site at ``end``."""
    inner = children + (f"End Site\n{{\nOFFSET {end}\n}}\n" if end is not None else "")
    return f"JOINT {name}\n{{\nOFFSET {offset}\nCHANNELS 3 Zrotation Xrotation Yrotation\n{inner}}}\n"


def _dog_leg(upper: str, lower: str, foot: str, offsets: tuple[str, str, str], end: str) -> str:
    return _dog_node(upper, offsets[0], _dog_node(lower, offsets[1], _dog_node(foot, offsets[2], end=end)))


def _dog_front(side: str, z: str) -> str:
    return _dog_node(f"{side}Shoulder", f"20 -4 {z}", _dog_leg(f"{side}Arm", f"{side}ForeArm", f"{side}Hand",
                                                             ("0 -8 0", "0 -15 0", "0 -14 0"), "0 -6 0"))


# A small MANN-named dog (not the MANN data: the names and the depth-first order of its 21 joints + 6 end sites,
# with made-up centimetre offsets; Y up, body along x): Hips, Spine…Head, the front legs under Spine1, the hind
# legs and the tail under Hips. 66 channels, like the MANN clips.
_DOG_HIERARCHY = (
    "HIERARCHY\nROOT Hips\n{\nOFFSET 0 0 0\nCHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation\n"
    + _dog_node("Spine", "0 0 0", _dog_node("Spine1", "19 0 0", _dog_node("Neck", "22 1 0", _dog_node(
        "Head", "14 0 0", end="17 0 0")) + _dog_front("Left", "5") + _dog_front("Right", "-5")))
    + _dog_leg("LeftUpLeg", "LeftLeg", "LeftFoot", ("-2 -6 5", "0 -16 0", "0 -17 0"), "0 -10 0")
    + _dog_leg("RightUpLeg", "RightLeg", "RightFoot", ("-2 -6 -5", "0 -16 0", "0 -17 0"), "0 -10 0")
    + _dog_node("Tail", "-6 1 0", _dog_node("Tail1", "-12 0 0", end="-12 0 0")) + "}\n")
_DOG_CHANNELS = 6 + 3 * 20
_DOG_FRAMES = 8


def _dog_motion(frames: int = _DOG_FRAMES) -> str:
    """A walk-like clip: the root moves forward 1 cm a frame, the legs swing about z (the BVH's 'Zrotation')."""
    rows = []
    for f in range(frames):
        values = [1.0 * f, 55.0, 0.0, 0.0, 0.0, 0.0] + [0.0] * (_DOG_CHANNELS - 6)
        swing = 15.0 * np.sin(2 * np.pi * f / frames)
        for joint, sign in ((6, 1), (11, -1), (15, -1), (18, 1)):  # LeftArm, RightArm, LeftUpLeg, RightUpLeg
            values[6 + 3 * (joint - 1)] = sign * swing
        rows.append("\t".join(f"{v:.4f}" for v in values))
    return f"MOTION\nFrames: {frames}\nFrame Time: 0.0166667\n" + "\n".join(rows) + "\n"


VALID_DOG_BVH = _DOG_HIERARCHY + _dog_motion()


def _dog_points_text(bvh_text: str) -> str:
    """motion_imitation's ``dog_*_joint_pos.txt`` of a dog BVH: 27 points × (x, y, z) in metres, Y up, one row
    per frame, ``,\\t``-separated (the general BVH reader's forward kinematics)."""
    from engine.retarget.importers.bvh import parse_bvh

    points = parse_bvh(bvh_text, "dog.bvh").global_positions() * 0.01
    return "".join(",\t".join(f"{v:.5f}" for v in row) + "\n" for row in points.reshape(len(points), -1))


VALID_DOG_KEYPOINTS = _dog_points_text(VALID_DOG_BVH)


def _dog_keypoint_cases() -> dict[str, bytes]:
    text = VALID_DOG_KEYPOINTS
    rows = text.splitlines(keepends=True)
    cells = [r.rstrip("\n").split(",\t") for r in rows]

    def cell(value: str, row: int = 2, col: int = 24) -> bytes:  # col 24: the front left paw's x (a used point)
        c = [list(r) for r in cells]
        c[row][col] = value
        return "".join(",\t".join(r) + "\n" for r in c).encode()

    def row_of(row: int, values: list[str]) -> bytes:
        return "".join(rows[:row] + [",\t".join(values) + "\n"] + rows[row + 1:]).encode()

    zeros = ",".join(["0"] * 81) + "\n"
    flat_leg = [list(r) for r in cells]
    for r in flat_leg:  # the front left leg's shoulder, elbow and paw at one point
        r[21:24] = r[24:27] = r[30:33] = r[21:24]
    return {
        "empty.txt": b"",
        "whitespace.txt": b" \n\t\n\r\n",
        "one_row.txt": rows[0].encode(),
        "truncated_mid_row.txt": (text[: len(text) - len(rows[-1]) // 2]).encode(),
        "truncated_after_comma.txt": "".join(rows[:-1]).encode() + ",\t".join(cells[-1][:40]).encode() + b",",
        "row_80.txt": row_of(3, cells[3][:-1]),
        "row_82.txt": row_of(3, cells[3] + ["0.1"]),
        "rows_joined.txt": ("".join(rows[:2]).rstrip("\n") + ",\t" + "".join(rows[2:])).encode(),
        "header_row.txt": (",".join(f"p{i // 3}{'xyz'[i % 3]}" for i in range(81)) + "\n" + text).encode(),
        "single_column.txt": b"0.1\n0.2\n0.3\n",
        "very_long_line.txt": (",".join(["0.5"] * 2_000) + "\n").encode(),
        "nan.txt": cell("nan"),
        "nan_caps.txt": cell("NaN"),
        "inf.txt": cell("inf"),
        "neg_infinity.txt": cell("-Infinity"),
        "overflow_1e999.txt": cell("1e999"),
        "huge_1e308.txt": cell("1e308"),
        "beyond_1e9.txt": cell("1e10"),
        "unused_point_huge.txt": cell("1e300", row=0, col=1),  # the spine's y: not a keypoint, still checked
        "int_400_digits.txt": cell("9" * 400),
        "int_5000_digits.txt": cell("9" * 5000),
        "text_cell.txt": cell("abc"),
        "bool_cell.txt": cell("True"),
        "quoted_cell.txt": cell('"0.5"'),
        "empty_cell.txt": cell(""),
        "comma_decimal.txt": cell("0,5"),
        "dot_only.txt": cell("."),
        "exponent_only.txt": cell("1e"),
        "double_sign.txt": cell("+-1"),
        "underscore_digits.txt": cell("1_000"),
        "hex_float.txt": cell("0x1p3"),
        "unicode_digits.txt": cell("\u0664\u0665"),
        "semicolons.txt": text.replace(",\t", ";").encode(),
        "spaces.txt": text.replace(",\t", " ").encode(),
        "json_array.txt": ("[" + ", ".join(text.splitlines()[0].split(",\t")) + "]\n").encode(),
        "all_zero.txt": (zeros * 4).encode(),
        "leg_zero_length.txt": "".join(",\t".join(r) + "\n" for r in flat_leg).encode(),
        "utf16.txt": text.encode("utf-16"),
        "utf16le_no_bom.txt": text.encode("utf-16-le"),
        "latin1.txt": cell("0.5\u00e9").decode().encode("latin-1"),
        "nul_bytes.txt": text.encode()[:60] + b"\0" + text.encode()[60:],
        "binary_junk.txt": bytes(range(256)) * 4,
        "bom_then_junk.txt": b"\xef\xbb\xbf" + cell("x"),
    }


def _dog_bvh_cases() -> dict[str, bytes]:
    text = VALID_DOG_BVH
    body = text[text.index("MOTION"):]
    rows = body.splitlines(keepends=True)[3:]
    head = text[: text.index("MOTION")] + "MOTION\nFrames: 8\nFrame Time: 0.0166667\n"

    def first_value(value: str) -> bytes:  # the root's x position in frame 0
        return (head + value + rows[0][rows[0].index("\t"):] + "".join(rows[1:])).encode()

    nested = "HIERARCHY\nROOT Hips\n{\nOFFSET 0 0 0\nCHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation\n"
    nested += "".join(f"JOINT j{i}\n{{\nOFFSET 0 1 0\nCHANNELS 3 Zrotation Xrotation Yrotation\n" for i in range(300))
    nested += "}\n" * 301 + "MOTION\nFrames: 2\nFrame Time: 0.0166667\n" + ("0 " * (6 + 3 * 300) + "\n") * 2
    tail0 = "JOINT Tail0\n{\nOFFSET -6 0 0\nCHANNELS 3 Zrotation Xrotation Yrotation\n}\nJOINT Tail1"
    extra_joint = (head.replace("JOINT Tail1", tail0, 1)  # 28 nodes; 3 more values a frame (at the end: any values do)
                   + "".join(r.rstrip("\n") + "\t0\t0\t0\n" for r in rows))
    return {
        "empty.bvh": b"",
        "whitespace.bvh": b"  \n\t\n",
        "not_bvh.bvh": b"Hello, this is not motion capture\n",
        "hierarchy_word_only.bvh": b"HIERARCHY\n",
        "truncated_hierarchy.bvh": text[: text.index("LeftForeArm") + 30].encode(),
        "truncated_motion.bvh": text[: len(text) - len(rows[-1]) // 2].encode(),
        "frames_missing.bvh": (head + "".join(rows[:3])).encode(),
        "frames_none.bvh": head.encode(),
        "no_motion.bvh": _DOG_HIERARCHY.encode(),
        "frames_header_missing.bvh": text.replace("Frames: 8\n", "").encode(),
        "frame_time_missing.bvh": text.replace("Frame Time: 0.0166667\n", "").encode(),
        "frames_text.bvh": text.replace("Frames: 8", "Frames: eight").encode(),
        "frames_negative.bvh": text.replace("Frames: 8", "Frames: -8").encode(),
        "frames_zero.bvh": text.replace("Frames: 8", "Frames: 0").encode(),
        "frames_one.bvh": (head.replace("Frames: 8", "Frames: 1") + rows[0]).encode(),
        "frames_huge.bvh": text.replace("Frames: 8", "Frames: 99999999999").encode(),
        "frames_float.bvh": text.replace("Frames: 8", "Frames: 8.0").encode(),
        "frame_time_zero.bvh": text.replace("Frame Time: 0.0166667", "Frame Time: 0").encode(),
        "frame_time_negative.bvh": text.replace("Frame Time: 0.0166667", "Frame Time: -0.0166667").encode(),
        "frame_time_nan.bvh": text.replace("Frame Time: 0.0166667", "Frame Time: nan").encode(),
        "frame_time_tiny.bvh": text.replace("Frame Time: 0.0166667", "Frame Time: 5e-324").encode(),
        "frame_time_huge.bvh": text.replace("Frame Time: 0.0166667", "Frame Time: 1e308").encode(),
        "channels_count_text.bvh": text.replace("CHANNELS 6", "CHANNELS six").encode(),
        "channels_count_huge.bvh": text.replace("CHANNELS 6", "CHANNELS 99999999999999999999").encode(),
        "channels_count_negative.bvh": text.replace("CHANNELS 3", "CHANNELS -3", 1).encode(),
        "channels_count_seven.bvh": text.replace("CHANNELS 6 Xposition", "CHANNELS 7 Xposition Xposition").encode(),
        "channel_name_bad.bvh": text.replace("Zrotation", "Qrotation", 1).encode(),
        "channel_name_short.bvh": text.replace("Zrotation", "Z", 1).encode(),
        "channels_before_root.bvh": b"HIERARCHY\nCHANNELS 3 Xrotation Yrotation Zrotation\n" + text[10:].encode(),
        "no_channels.bvh": re.sub(r"CHANNELS \d+[^\n]*", "CHANNELS 0", text).encode(),
        "root_rotation_only.bvh": text.replace("CHANNELS 6 Xposition Yposition Zposition ", "CHANNELS 3 ").encode(),
        "value_nan.bvh": first_value("nan"),
        "value_inf.bvh": first_value("1e999"),
        "value_huge.bvh": first_value("1e308"),
        "value_beyond_1e9.bvh": first_value("1e10"),
        "value_text.bvh": first_value("zero"),
        "value_comma.bvh": first_value("0,5"),
        "extra_values.bvh": (text + "1 2 3\n").encode(),
        "row_short.bvh": (head + rows[0].rsplit("\t", 1)[0] + "\n" + "".join(rows[1:])).encode(),
        "offset_missing.bvh": text.replace("OFFSET 0 0 0\n", "", 1).encode(),
        "offset_nan.bvh": text.replace("OFFSET 0 0 0", "OFFSET nan 0 0", 1).encode(),
        "offset_text.bvh": text.replace("OFFSET 0 0 0", "OFFSET a b c", 1).encode(),
        "offset_huge.bvh": text.replace("OFFSET 19 0 0", "OFFSET 1e308 0 0", 1).encode(),
        "offset_two_numbers.bvh": text.replace("OFFSET 19 0 0", "OFFSET 19 0", 1).encode(),
        "brace_missing.bvh": text.replace("{", "", 1).encode(),
        "brace_extra.bvh": text.replace("{", "{\n{", 1).encode(),
        "brace_unbalanced.bvh": text.replace("}\nMOTION", "}\n}\nMOTION").encode(),
        "end_not_site.bvh": text.replace("End Site", "End Zone", 1).encode(),
        "two_roots.bvh": (_DOG_HIERARCHY + _DOG_HIERARCHY[len("HIERARCHY\n"):] + body).encode(),
        "joint_missing.bvh": text.replace("JOINT LeftForeArm", "JOINT LeftForeArmX").encode(),
        "joint_extra.bvh": extra_joint.encode(),
        "human_skeleton.bvh": VALID_BVH.encode(),
        "nested_300.bvh": nested.encode(),
        "degenerate_skeleton.bvh": re.sub(r"OFFSET [^\n]*", "OFFSET 0 0 0", text).encode(),
        "latin1_name.bvh": text.replace("RightUpLeg", "RightUpLeg\u00e9").encode("latin-1"),
        "utf16.bvh": text.encode("utf-16"),
        "nul_bytes.bvh": text.encode()[:100] + b"\0\0" + text.encode()[100:],
        "binary_junk.bvh": bytes(range(256)) * 4,
    }


# ----------------------------------------------------------------------------- live datagrams

def valid_datagram() -> dict:
    """A valid mocap-joints/1 datagram (``engine/retarget/humanoid_arm/live.py``), as a dict."""
    return {"format": "mocap-joints/1", "frame": 3, "t_s": 0.05, "up": [0, 1, 0], "joints": {
        "hips": [0, 90, 0], "right_hip": [-10, 90, 0], "left_hip": [10, 90, 0],
        "right_shoulder": [-18, 140, 0], "right_elbow": [-40, 140, 0], "right_hand": [-60, 140, 5],
        "left_shoulder": [18, 140, 0], "left_elbow": [40, 140, 0], "left_hand": [60, 140, 5]}}


def _datagram_cases() -> dict[str, bytes]:
    good = valid_datagram()
    text = json.dumps(good)

    def d(mutate) -> bytes:
        doc = json.loads(text)
        mutate(doc)
        return json.dumps(doc).encode()

    def joint(name: str, value) -> bytes:
        return d(lambda doc: doc["joints"].__setitem__(name, value))

    return {
        "empty.bin": b"",
        "not_json.bin": b"hello",
        "truncated.bin": text.encode()[: len(text) // 2],
        "array.bin": b"[1, 2, 3]",
        "null.bin": b"null",
        "deep.bin": b"[" * 5000 + b"]" * 5000,
        "duplicate_joints.bin": text.replace('"joints": {', '"joints": {}, "joints": {', 1).encode(),
        "duplicate_joint.bin": text.replace('"hips": [0, 90, 0]', '"hips": [0, 90, 0], "hips": [1, 1, 1]').encode(),
        "format_wrong.bin": d(lambda doc: doc.__setitem__("format", "mocap-joints/2")),
        "format_missing.bin": d(lambda doc: doc.pop("format")),
        "joints_list.bin": d(lambda doc: doc.__setitem__("joints", [1, 2])),
        "joint_missing.bin": d(lambda doc: doc["joints"].pop("left_hand")),
        "joint_nan.bin": text.replace('"hips": [0, 90, 0]', '"hips": [0, NaN, 0]').encode(),
        "joint_infinity.bin": text.replace('"hips": [0, 90, 0]', '"hips": [0, Infinity, 0]').encode(),
        "joint_huge_int.bin": text.replace('"hips": [0, 90, 0]', '"hips": [0, ' + "9" * 400 + ", 0]").encode(),
        "joint_int_5000_digits.bin": text.replace('"hips": [0, 90, 0]', '"hips": [0, ' + "9" * 5000 + ", 0]").encode(),
        "joint_1e999.bin": text.replace('"hips": [0, 90, 0]', '"hips": [0, 1e999, 0]').encode(),
        "joint_overflow.bin": joint("right_hand", [1e308, 1e308, 1e308]),
        "joint_bool.bin": joint("hips", [True, False, True]),
        "joint_text.bin": joint("hips", ["0", "90", "0"]),
        "joint_two.bin": joint("hips", [0, 90]),
        "joint_nested.bin": joint("hips", [[0], [90], [0]]),
        "joint_object.bin": joint("hips", {"x": 0, "y": 90, "z": 0}),
        "coincident.bin": d(lambda doc: doc.__setitem__("joints", {k: [0, 0, 0] for k in doc["joints"]})),
        "up_zero.bin": d(lambda doc: doc.__setitem__("up", [0, 0, 0])),
        "up_text.bin": d(lambda doc: doc.__setitem__("up", "y")),
        "up_along_hips.bin": d(lambda doc: doc.__setitem__("up", [1, 0, 0])),
        "frame_bool.bin": d(lambda doc: doc.__setitem__("frame", True)),
        "frame_float.bin": d(lambda doc: doc.__setitem__("frame", 1.5)),
        "frame_negative.bin": d(lambda doc: doc.__setitem__("frame", -1)),
        "frame_huge.bin": text.replace('"frame": 3', '"frame": ' + "9" * 100).encode(),
        "latin1.bin": text.replace('"t_s"', '"t_\u00e9"').encode("latin-1"),
        "utf16.bin": text.encode("utf-16"),
        "nul.bin": text.encode()[:20] + b"\0" + text.encode()[20:],
        "binary_junk.bin": bytes(range(256)),
    }


# ----------------------------------------------------------------------------- motion frame files

VALID_FRAMES = json.dumps({"LoopMode": "Wrap", "FrameDuration": 0.021, "EnableCycleOffsetPosition": True,
                           "EnableCycleOffsetRotation": True, "MotionWeight": 0.5,
                           "Frames": [[0.01 * i, 0, 0.3, 0, 0, 0, 1, 0, 0.9, -1.8, 0, 0.9, -1.8, 0, 0.9, -1.8, 0, 0.9,
                                       -1.8] for i in range(4)]}, indent=1)


def _frames_cases() -> dict[str, bytes]:
    doc = json.loads(VALID_FRAMES)

    def v(mutate) -> bytes:
        d = json.loads(VALID_FRAMES)
        mutate(d)
        return json.dumps(d).encode()

    def row(i: int, j: int, value) -> bytes:
        return v(lambda d: d["Frames"][i].__setitem__(j, value))

    del doc
    return {
        "empty.txt": b"",
        "truncated.txt": VALID_FRAMES.encode()[: len(VALID_FRAMES) // 2],
        "array.txt": b"[[0, 0, 0]]",
        "duration_missing.txt": v(lambda d: d.pop("FrameDuration")),
        "duration_zero.txt": v(lambda d: d.__setitem__("FrameDuration", 0)),
        "duration_negative.txt": v(lambda d: d.__setitem__("FrameDuration", -0.02)),
        "duration_text.txt": v(lambda d: d.__setitem__("FrameDuration", "0.02")),
        "duration_bool.txt": v(lambda d: d.__setitem__("FrameDuration", True)),
        "duration_nan.txt": VALID_FRAMES.replace('"FrameDuration": 0.021', '"FrameDuration": NaN').encode(),
        "duration_tiny.txt": v(lambda d: d.__setitem__("FrameDuration", 1e-300)),
        "duration_huge_int.txt": VALID_FRAMES.replace('"FrameDuration": 0.021', '"FrameDuration": ' + "9" * 5000).encode(),
        "frames_missing.txt": v(lambda d: d.pop("Frames")),
        "frames_empty.txt": v(lambda d: d.__setitem__("Frames", [])),
        "frames_one.txt": v(lambda d: d.__setitem__("Frames", d["Frames"][:1])),
        "frames_object.txt": v(lambda d: d.__setitem__("Frames", {"0": d["Frames"][0]})),
        "row_short.txt": v(lambda d: d["Frames"][2].pop()),
        "row_not_list.txt": v(lambda d: d["Frames"].__setitem__(1, "row")),
        "value_text.txt": row(1, 3, "0"),
        "value_null.txt": row(1, 3, None),
        "value_bool.txt": row(1, 3, True),
        "value_nested.txt": row(1, 3, [0]),
        "value_nan.txt": VALID_FRAMES.replace("0.9,", "NaN,", 1).encode(),
        "value_infinity.txt": VALID_FRAMES.replace("0.9,", "-Infinity,", 1).encode(),
        "value_1e999.txt": VALID_FRAMES.replace("0.9,", "1e999,", 1).encode(),
        "value_int_400_digits.txt": VALID_FRAMES.replace("0.9,", "9" * 400 + ",", 1).encode(),
        "value_int_5000_digits.txt": VALID_FRAMES.replace("0.9,", "9" * 5000 + ",", 1).encode(),
        "quaternion_zero.txt": v(lambda d: [r.__setitem__(6, 0) for r in d["Frames"]]),
        "deep.txt": b'{"Frames": ' + b"[" * 5000 + b"]" * 5000 + b"}",
        "duplicate_key.txt": VALID_FRAMES.replace('"FrameDuration": 0.021', '"FrameDuration": 0.021, '
                                                  '"FrameDuration": 0.5').encode(),
        "latin1.txt": VALID_FRAMES.replace('"Wrap"', '"Wr\u00e4p"').encode("latin-1"),
        "utf16.txt": VALID_FRAMES.encode("utf-16"),
        "binary_junk.txt": b"{" + bytes(range(256)) * 4,
        "nul.txt": VALID_FRAMES.encode()[:30] + b"\0" + VALID_FRAMES.encode()[30:],
    }


READERS = {"style": _style_cases, "robot_toml": _toml_cases, "keyframes": _keyframe_cases,
           "keypoint_npz": _keypoint_npz_cases, "robot_npz": _robot_npz_cases, "bvh": _bvh_cases,
           "datagram": _datagram_cases, "motion_frames": _frames_cases, "dog_keypoints": _dog_keypoint_cases,
           "dog_bvh": _dog_bvh_cases}


@functools.lru_cache(maxsize=2)
def zip_bomb_npz(data_bytes: int = 300 * 1024 ** 2) -> bytes:
    """A valid-looking npz whose one array inflates to ``data_bytes`` of zeros (built in 1 MiB chunks: nothing
    of that size is ever allocated here); its header declares the matching float64 shape. Built once per process
    (compressing the 300 MB takes a second or two; the result is immutable bytes, 300 KB)."""
    header = npy_header((data_bytes // 8,))
    comp = zlib.compressobj(9, zlib.DEFLATED, -15)
    parts = [comp.compress(header)]
    chunk = bytes(1024 ** 2)
    crc = zlib.crc32(header)
    for _ in range(data_bytes // len(chunk)):
        parts.append(comp.compress(chunk))
        crc = zlib.crc32(chunk, crc)
    parts.append(comp.flush())
    body = b"".join(parts)
    size = len(header) + data_bytes
    name = b"keypoints.npy"
    local = struct.pack("<4sHHHHHIIIHH", b"PK\x03\x04", 20, 0, 8, 0, 0, crc, len(body), size, len(name), 0) + name
    central = struct.pack("<4sHHHHHHIIIHHHHHII", b"PK\x01\x02", 20, 20, 0, 8, 0, 0, crc, len(body), size,
                          len(name), 0, 0, 0, 0, 0, 0) + name
    end = struct.pack("<4sHHHHIIH", b"PK\x05\x06", 0, 0, 1, 1, len(central), len(local) + len(body), 0)
    return local + body + central + end


def large_cases(reader: str) -> dict[str, bytes]:
    """Cases too large to commit, built in memory (a few MB at most; the zip bomb is 300 KB that inflates to
    300 MB, never inflated by the readers). Files over a reader's size limit: :func:`huge_files`."""
    if reader in ("keypoint_npz", "robot_npz"):
        return {"zip_bomb_300MB.npz": zip_bomb_npz()}
    if reader == "bvh":
        deep = ("HIERARCHY\nROOT Hips\n{\nOFFSET 0 0 0\nCHANNELS 1 Xposition\n"
                + "JOINT j\n{\nOFFSET 0 1 0\n" * 100_000 + "}\n" * 100_001 + "MOTION\nFrames: 1\nFrame Time: 0.1\n0\n")
        return {"deep_100000.bvh": deep.encode()}
    if reader == "dog_keypoints":
        return {"blank_lines_1M.txt": b"\n" * 1_000_000}
    if reader == "dog_bvh":
        head = _DOG_HIERARCHY + "MOTION\nFrames: 40000\nFrame Time: 0.0166667\n"
        deep = ("HIERARCHY\nROOT Hips\n{\nOFFSET 0 0 0\nCHANNELS 1 Xposition\n"
                + "JOINT j\n{\nOFFSET 0 1 0\n" * 100_000 + "}\n" * 100_001 + "MOTION\nFrames: 2\nFrame Time: 0.1\n0\n0\n")
        return {"deep_100000.bvh": deep.encode(),  # 40 000 frames: over the dog reader's 36 000 (10 min at 60 fps)
                "frames_40000.bvh": head.encode() + (" ".join(["0"] * _DOG_CHANNELS) + "\n").encode() * 40_000}
    if reader == "datagram":
        return {"over_64KiB.bin": json.dumps({**valid_datagram(), "pad": "x" * 70_000}).encode()}
    if reader == "motion_frames":
        return {"deep_100000.txt": b'{"Frames": ' + b"[" * 100_000 + b"]" * 100_000 + b"}"}
    ext = ".toml" if reader == "robot_toml" else ".json"
    return {
        f"huge_file{ext}": b"[" + b"0," * 9_000_000 + b"0]",  # 18 MB: over every reader's limit
        f"deep_100000{ext}": (b"x = " if ext == ".toml" else b"") + b"[" * 100_000 + b"]" * 100_000,
    }


def huge_files(reader: str) -> dict[str, tuple[bytes, int]]:
    """Files over a reader's size limit as (the valid start of the file, its size in bytes): the tests write the
    start and extend the file sparsely (os.truncate), so nothing of that size is in memory or on disk."""
    return {
        "keypoint_npz": {"huge_file.npz": (b"PK\x03\x04", 257 * 1024 ** 2)},
        "robot_npz": {"huge_file.npz": (b"PK\x03\x04", 257 * 1024 ** 2)},
        "bvh": {"huge_file.bvh": (VALID_BVH.encode(), 33 * 1024 ** 2)},
        "motion_frames": {"huge_file.txt": (VALID_FRAMES.encode(), 65 * 1024 ** 2)},
        "dog_keypoints": {"huge_file.txt": (VALID_DOG_KEYPOINTS.encode(), 17 * 1024 ** 2)},
        "dog_bvh": {"huge_file.bvh": (VALID_DOG_BVH.encode(), 33 * 1024 ** 2)},
    }.get(reader, {})


def main(readers: list[str]) -> None:
    """Regenerate the named readers' folders (all of them without arguments)."""
    for reader in readers or list(READERS):
        folder = HERE / reader
        folder.mkdir(exist_ok=True)
        for old in folder.iterdir():
            old.unlink()
        for name, data in READERS[reader]().items():
            (folder / name).write_bytes(data)
        print(f"{reader}: {len(list(folder.iterdir()))} files")


if __name__ == "__main__":
    import sys

    main(sys.argv[1:])
