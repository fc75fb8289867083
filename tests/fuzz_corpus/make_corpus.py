"""Regenerate the malformed-input corpus of issue 14: ``python tests/fuzz_corpus/make_corpus.py``.

Small cases are committed under ``tests/fuzz_corpus/<reader>/``; large ones (a huge file, 100 000-deep
nesting) are only built at test time by :func:`large_cases` so the repository stays small.
Each case is one way a user file goes wrong: truncated, wrong types, NaN/inf, huge numbers, deep
nesting, wrong encoding, binary junk, duplicate keys, an empty file.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

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
        "latin1.toml": text.replace("Unitree G1", "Unitr\u00e9e").encode("latin-1"),
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


READERS = {"style": _style_cases, "robot_toml": _toml_cases, "keyframes": _keyframe_cases}


def large_cases(reader: str) -> dict[str, bytes]:
    """Cases too large to commit, built in memory (a few MB at most)."""
    ext = ".toml" if reader == "robot_toml" else ".json"
    return {
        f"huge_file{ext}": b"[" + b"0," * 9_000_000 + b"0]",  # 18 MB: over every reader's limit
        f"deep_100000{ext}": (b"x = " if ext == ".toml" else b"") + b"[" * 100_000 + b"]" * 100_000,
    }


def main() -> None:
    for reader, make in READERS.items():
        folder = HERE / reader
        folder.mkdir(exist_ok=True)
        for old in folder.iterdir():
            old.unlink()
        for name, data in make().items():
            (folder / name).write_bytes(data)
        print(f"{reader}: {len(list(folder.iterdir()))} files")


if __name__ == "__main__":
    main()
