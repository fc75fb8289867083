"""Robot configuration files (robots/<name>.toml): schema, loading and validation.

One file per robot names everything the studio needs to build the robot from the
``example-robot-data`` package: the URDF/SRDF source, the robot kind, contact geometry
(sole rectangles for bipeds, foot points for quadrupeds), the standing pose, joint PD
gains and armature, the upper-body joints an animator may curve, and the per-model fixes
that these URDFs need. A malformed file raises :class:`RobotConfigError` with one line
naming the file, the field path and what was expected.
"""

from __future__ import annotations

import difflib
import math
import os
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

REPO_ROOT = Path(__file__).resolve().parents[2]
# The gap live puppeteering keeps between the arms' capsules unless [upper_body] puppet_clearance_m says otherwise.
DEFAULT_PUPPET_CLEARANCE_M = 0.01


def robots_dir() -> Path:
    """The robot library folder; ``MOTION_STUDIO_ROBOTS`` overrides ``<repo>/robots``."""
    env = os.environ.get("MOTION_STUDIO_ROBOTS")
    return Path(env) if env else REPO_ROOT / "robots"


RobotKind = Literal["biped", "quadruped", "source-skeleton"]
KINDS: tuple[str, ...] = ("biped", "quadruped", "source-skeleton")
SOURCE_PACKAGES: tuple[str, ...] = ("example-robot-data", "local")


class RobotConfigError(ValueError):
    """A robot config file is missing, malformed or names something that does not exist."""


@dataclass(frozen=True)
class GainRule:
    """PD gains and armature for every actuated joint whose name matches ``pattern``."""

    pattern: str
    kp: float
    kd: float
    armature: float = 0.0


@dataclass(frozen=True)
class Sole:
    """A flat foot: a sole rectangle in the ankle link frame.

    ``center`` is the rectangle centre on the sole plane (the foot frame of the paper,
    "defined at the geometric center of each sole"), x forward, z up.
    """

    link: str
    center: tuple[float, float, float]
    length_m: float
    width_m: float

    def corners(self) -> list[tuple[float, float, float]]:
        """Corners in the link frame, ordered front-left, front-right, back-right, back-left."""
        cx, cy, cz = self.center
        hl, hw = 0.5 * self.length_m, 0.5 * self.width_m
        return [(cx + hl, cy + hw, cz), (cx + hl, cy - hw, cz), (cx - hl, cy - hw, cz), (cx - hl, cy + hw, cz)]


@dataclass(frozen=True)
class FootPoint:
    """A point foot (quadrupeds): a sphere of ``radius_m`` centred at ``link``'s origin offset."""

    name: str
    link: str
    offset: tuple[float, float, float]
    radius_m: float


@dataclass(frozen=True)
class CurveRateLimits:
    """How fast a style's curves may change on this robot, in curve time (``[gait.curve_rates]``;
    engine/gait/curve_rates.py): the rate and acceleration per channel kind. The defaults are about
    twice the peaks of the shipped styles (G1 and TALOS); a robot whose random styles show that
    they are too loose sets its own (README, *Curve rates are part of what is feasible*)."""

    foot_position_mps: float = 2.0  # left_foot/right_foot x, y, z
    foot_position_mps2: float = 50.0
    foot_angle_radps: float = 8.0  # yaw, roll, heel_pitch, toe_pitch
    foot_angle_radps2: float = 220.0
    pelvis_height_mps: float = 0.2  # pelvis.z
    pelvis_height_mps2: float = 6.0
    pelvis_angle_radps: float = 1.5  # pelvis yaw, pitch, roll
    pelvis_angle_radps2: float = 20.0
    # joints.*: the joint's velocity limit in the robot model, at most ``joint_max_radps``
    # (inf: the model's limit alone)
    joint_max_radps: float = math.inf
    joint_radps2: float = 60.0


@dataclass(frozen=True)
class GaitLimits:
    """What the controller can track on this robot: bounds for style validation and defaults."""

    pelvis_height_m: float = 0.0  # default walking pelvis (root link) height
    pelvis_height_range_m: tuple[float, float] = (0.0, 0.0)
    stance_width_m: float = 0.2  # default distance between the feet centres
    stance_width_range_m: tuple[float, float] = (0.1, 0.5)
    min_single_support_s: float = 0.25
    min_double_support_s: float = 0.05
    max_cycle_s: float = 3.0
    max_swing_height_m: float = 0.3
    curve_rates: CurveRateLimits = field(default_factory=CurveRateLimits)


@dataclass(frozen=True)
class RobotConfig:
    name: str
    display_name: str
    kind: RobotKind
    path: Path
    urdf: str
    srdf: str | None
    root_link: str
    up_axis: Literal["z", "y"]
    standing_pose: dict[str, float]
    standing_srdf_state: str | None
    gains: tuple[GainRule, ...]
    upper_body_joints: tuple[str, ...]
    trunk_link: str | None
    soles: dict[str, Sole] = field(default_factory=dict)  # "left"/"right" for bipeds
    feet: tuple[FootPoint, ...] = ()  # quadrupeds
    dae_up_axis: str | None = None
    regularize_inertia_links: tuple[str, ...] = ()
    srdf_collision_excludes: bool = False
    self_collision: bool = True
    visual_face_budget: int = 30000
    collision_face_budget: int = 400
    default_style: str | None = None
    gait: GaitLimits | None = None  # bipeds
    # Per-robot tuning of the controllers: [control.wbc] overrides engine.control.wbc.WbcGains
    # (field name → number; the names are checked when the controller is built).
    wbc_gains: dict[str, float] = field(default_factory=dict)
    # Where source.urdf/srdf live: "example-robot-data" (the package's share folder) or
    # "local" (relative to this config file's folder: project-made robots such as the dino).
    source_package: str = "example-robot-data"
    # [control.gait_feedback]: per-robot gait feedback gains (engine/control/gait_feedback.py names).
    gait_feedback: dict[str, float | tuple[float, float]] = field(default_factory=dict)
    # [control.walking]: overrides of engine.control.walking_parameters.WalkingParameters (checked there).
    walking: dict[str, object] = field(default_factory=dict)
    # [upper_body] puppet_clearance_m: the gap live puppeteering keeps between the arms' capsules in its targets, so
    # that the simulated arms, which lag their targets, stay collision-free too (engine/retarget/humanoid_arm).
    puppet_clearance_m: float = DEFAULT_PUPPET_CLEARANCE_M

    @property
    def simulated(self) -> bool:
        return self.kind != "source-skeleton"

    def gain_rule(self, joint: str) -> GainRule | None:
        for rule in self.gains:
            if re.fullmatch(rule.pattern, joint):
                return rule
        return None


# ----------------------------------------------------------------------------- parsing


class _Reader:
    """Typed field access that reports ``file: field.path: expected ...`` on error."""

    def __init__(self, path: Path, data: dict[str, Any]):
        self.path = path
        self.data = data

    def fail(self, field_path: str, message: str) -> RobotConfigError:
        from engine.safe_io import one_line

        return RobotConfigError(one_line(self.path.name, field_path, message))  # clipped: user keys can be long

    def get(self, table: dict[str, Any], key: str, prefix: str, kind: type | tuple[type, ...], default: Any = ...) -> Any:
        where = f"{prefix}{key}"
        if key not in table:
            if default is ...:
                raise self.fail(where, f"missing required field (expected {_kind_name(kind)})")
            return default
        value = table[key]
        if kind is float and isinstance(value, int) and not isinstance(value, bool):
            value = float(value)
        if not isinstance(value, kind) or (isinstance(value, bool) and kind is not bool):
            raise self.fail(where, f"expected {_kind_name(kind)}, got {type(value).__name__} {value!r}")
        if isinstance(value, float) and not math.isfinite(value):
            raise self.fail(where, f"expected a finite number, got {value!r}")
        return value

    def vec3(self, table: dict[str, Any], key: str, prefix: str, default: Any = ...) -> tuple[float, float, float]:
        value = self.get(table, key, prefix, list, default)
        if value is default and default is not ...:
            return default
        if len(value) != 3 or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value):
            raise self.fail(f"{prefix}{key}", f"expected 3 numbers [x, y, z], got {value!r}")
        return (float(value[0]), float(value[1]), float(value[2]))

    def unknown(self, table: dict[str, Any], allowed: set[str], prefix: str) -> None:
        for key in table:
            if key not in allowed:
                hint = difflib.get_close_matches(key, sorted(allowed), n=1)
                extra = f" (did you mean {hint[0]!r}?)" if hint else ""
                raise self.fail(f"{prefix}{key}", f"unknown field{extra}; expected one of {', '.join(sorted(allowed))}")


def _kind_name(kind: type | tuple[type, ...]) -> str:
    names = {str: "a string", float: "a number", int: "an integer", bool: "true/false", list: "a list", dict: "a table"}
    if isinstance(kind, tuple):
        return " or ".join(names.get(k, k.__name__) for k in kind)
    return names.get(kind, kind.__name__)


_TOP_FIELDS = {
    "name", "display_name", "kind", "source", "model", "standing", "gains", "upper_body",
    "feet", "fixes", "mesh", "default_style", "gait", "control",
}


def _curve_rate_limits(r: _Reader, table: dict[str, Any]) -> CurveRateLimits:
    """``[gait.curve_rates]``: positive numbers; a field left out keeps its default."""
    prefix = "gait.curve_rates."
    r.unknown(table, set(CurveRateLimits.__dataclass_fields__), prefix)
    values: dict[str, float] = {}
    for key in table:
        value = table[key]
        if key == "joint_max_radps" and isinstance(value, float) and value == math.inf:
            values[key] = value  # (toml ``inf``: no cap beyond the model's velocity limit)
            continue
        values[key] = r.get(table, key, prefix, float)
        if values[key] <= 0:
            raise r.fail(f"{prefix}{key}", f"expected a positive number, got {value!r}")
    return CurveRateLimits(**values)


def load_config(path: Path) -> RobotConfig:
    """Parse and validate one robot config file."""
    path = Path(path)
    from engine.safe_io import ReadError, read_text

    try:
        data = tomllib.loads(read_text(path, max_bytes=1024 * 1024, source=path.name))
    except ReadError as exc:
        raise RobotConfigError(str(exc)) from None
    except tomllib.TOMLDecodeError as exc:
        raise RobotConfigError(f"{path.name}: expected valid TOML ({exc})") from None
    except (RecursionError, ValueError) as exc:  # deep nesting; integers beyond Python's digit limit
        raise RobotConfigError(f"{path.name}: expected valid TOML ({type(exc).__name__}: too deeply nested or too large)"
                               ) from None
    r = _Reader(path, data)
    r.unknown(data, _TOP_FIELDS, "")

    name = r.get(data, "name", "", str)
    if name != path.stem:
        raise r.fail("name", f"expected {path.stem!r} (the file name), got {name!r}")
    display_name = r.get(data, "display_name", "", str, name)
    kind = r.get(data, "kind", "", str)
    if kind not in KINDS:
        raise r.fail("kind", f"expected one of {', '.join(KINDS)}, got {kind!r}")

    source = r.get(data, "source", "", dict)
    r.unknown(source, {"urdf", "srdf", "package"}, "source.")
    source_package = r.get(source, "package", "source.", str, "example-robot-data")
    if source_package not in SOURCE_PACKAGES:
        raise r.fail("source.package", f"expected one of {', '.join(SOURCE_PACKAGES)}, got {source_package!r}")
    urdf = r.get(source, "urdf", "source.", str)
    srdf = r.get(source, "srdf", "source.", str, None)

    model = r.get(data, "model", "", dict)
    r.unknown(model, {"root_link", "up_axis", "trunk_link", "self_collision"}, "model.")
    root_link = r.get(model, "root_link", "model.", str)
    up_axis = r.get(model, "up_axis", "model.", str, "z")
    if up_axis not in ("z", "y"):
        raise r.fail("model.up_axis", f"expected 'z' or 'y', got {up_axis!r}")
    trunk_link = r.get(model, "trunk_link", "model.", str, None)
    self_collision = r.get(model, "self_collision", "model.", bool, True)

    standing = r.get(data, "standing", "", dict, {})
    r.unknown(standing, {"srdf_state", "joints"}, "standing.")
    standing_state = r.get(standing, "srdf_state", "standing.", str, None)
    joints_table = r.get(standing, "joints", "standing.", dict, {})
    standing_pose = {j: r.get(joints_table, j, "standing.joints.", float) for j in joints_table}

    gains: list[GainRule] = []
    for i, rule in enumerate(r.get(data, "gains", "", list, [])):
        prefix = f"gains[{i}]."
        if not isinstance(rule, dict):
            raise r.fail(f"gains[{i}]", "expected a table {pattern, kp, kd, armature}")
        r.unknown(rule, {"pattern", "kp", "kd", "armature"}, prefix)
        pattern = r.get(rule, "pattern", prefix, str)
        try:
            re.compile(pattern)
        except re.error as exc:
            raise r.fail(prefix + "pattern", f"expected a regular expression: {exc}") from None
        kp = r.get(rule, "kp", prefix, float)
        kd = r.get(rule, "kd", prefix, float)
        armature = r.get(rule, "armature", prefix, float, 0.0)
        if kp < 0 or kd < 0 or armature < 0:
            raise r.fail(prefix + "kp", "expected non-negative kp, kd and armature")
        gains.append(GainRule(pattern, kp, kd, armature))
    if kind != "source-skeleton" and not gains:
        raise r.fail("gains", "missing required field (expected a list of {pattern, kp, kd} tables)")

    upper = r.get(data, "upper_body", "", dict, {})
    r.unknown(upper, {"joints", "puppet_clearance_m"}, "upper_body.")
    puppet_clearance_m = r.get(upper, "puppet_clearance_m", "upper_body.", float, DEFAULT_PUPPET_CLEARANCE_M)
    if not 0.0 <= puppet_clearance_m <= 0.1:
        raise r.fail("upper_body.puppet_clearance_m", f"expected metres in [0, 0.1], got {puppet_clearance_m!r}")
    upper_joints = tuple(r.get(upper, "joints", "upper_body.", list, []))
    for i, j in enumerate(upper_joints):
        if not isinstance(j, str):
            raise r.fail(f"upper_body.joints[{i}]", f"expected a joint name, got {j!r}")

    soles: dict[str, Sole] = {}
    feet: list[FootPoint] = []
    feet_table = r.get(data, "feet", "", dict, {})
    if kind == "biped":
        r.unknown(feet_table, {"left", "right"}, "feet.")
        for side in ("left", "right"):
            prefix = f"feet.{side}."
            t = r.get(feet_table, side, "feet.", dict)
            r.unknown(t, {"link", "sole_center", "sole_length_m", "sole_width_m"}, prefix)
            length = r.get(t, "sole_length_m", prefix, float)
            width = r.get(t, "sole_width_m", prefix, float)
            if length <= 0 or width <= 0:
                raise r.fail(prefix + "sole_length_m", "expected positive sole dimensions")
            soles[side] = Sole(r.get(t, "link", prefix, str), r.vec3(t, "sole_center", prefix), length, width)
    elif kind == "quadruped":
        r.unknown(feet_table, {"points"}, "feet.")
        points = r.get(feet_table, "points", "feet.", list)
        if len(points) != 4:
            raise r.fail("feet.points", f"expected 4 foot points, got {len(points)}")
        for i, p in enumerate(points):
            prefix = f"feet.points[{i}]."
            if not isinstance(p, dict):
                raise r.fail(f"feet.points[{i}]", "expected a table {name, link, offset, radius_m}")
            r.unknown(p, {"name", "link", "offset", "radius_m"}, prefix)
            feet.append(FootPoint(r.get(p, "name", prefix, str), r.get(p, "link", prefix, str),
                                  r.vec3(p, "offset", prefix, (0.0, 0.0, 0.0)), r.get(p, "radius_m", prefix, float)))
    elif feet_table:
        raise r.fail("feet", "a source skeleton has no feet contact model")

    fixes = r.get(data, "fixes", "", dict, {})
    r.unknown(fixes, {"dae_up_axis", "regularize_inertia_links", "srdf_collision_excludes"}, "fixes.")
    dae_up = r.get(fixes, "dae_up_axis", "fixes.", str, None)
    if dae_up is not None and dae_up not in ("Z_UP", "Y_UP"):
        raise r.fail("fixes.dae_up_axis", f"expected 'Z_UP' or 'Y_UP', got {dae_up!r}")
    reg_links = tuple(r.get(fixes, "regularize_inertia_links", "fixes.", list, []))
    srdf_excludes = r.get(fixes, "srdf_collision_excludes", "fixes.", bool, False)
    if srdf_excludes and srdf is None:
        raise r.fail("fixes.srdf_collision_excludes", "needs source.srdf")
    if standing_state is not None and srdf is None:
        raise r.fail("standing.srdf_state", "needs source.srdf")

    mesh = r.get(data, "mesh", "", dict, {})
    r.unknown(mesh, {"visual_face_budget", "collision_face_budget"}, "mesh.")
    visual_budget = r.get(mesh, "visual_face_budget", "mesh.", int, 30000)
    collision_budget = r.get(mesh, "collision_face_budget", "mesh.", int, 400)

    gait: GaitLimits | None = None
    gait_table = r.get(data, "gait", "", dict, None)
    if kind == "biped" and gait_table is None:
        raise r.fail("gait", "missing required field (expected a table with pelvis_height_m, pelvis_height_range_m)")
    if gait_table is not None:
        fields = {f for f in GaitLimits.__dataclass_fields__}
        r.unknown(gait_table, fields, "gait.")
        values: dict[str, Any] = {}
        for key in fields:
            if key == "curve_rates":
                rates_table = r.get(gait_table, key, "gait.", dict, None)
                if rates_table is not None:
                    values[key] = _curve_rate_limits(r, rates_table)
            elif key.endswith("_range_m"):
                rng = r.get(gait_table, key, "gait.", list, ...) if key == "pelvis_height_range_m" else \
                    r.get(gait_table, key, "gait.", list, None)
                if rng is None:
                    continue
                if len(rng) != 2 or not all(isinstance(v, (int, float)) for v in rng) or not rng[0] < rng[1]:
                    raise r.fail(f"gait.{key}", f"expected [low, high] with low < high, got {rng!r}")
                values[key] = (float(rng[0]), float(rng[1]))
            elif key == "pelvis_height_m":
                values[key] = r.get(gait_table, key, "gait.", float)
            elif key in gait_table:
                values[key] = r.get(gait_table, key, "gait.", float)
                if values[key] <= 0:
                    raise r.fail(f"gait.{key}", f"expected a positive number, got {values[key]!r}")
        gait = GaitLimits(**values)
        lo, hi = gait.pelvis_height_range_m
        if not lo <= gait.pelvis_height_m <= hi:
            raise r.fail("gait.pelvis_height_m", f"expected within pelvis_height_range_m [{lo}, {hi}]")

    control = r.get(data, "control", "", dict, {})
    r.unknown(control, {"wbc", "gait_feedback", "walking"}, "control.")
    walking = dict(r.get(control, "walking", "control.", dict, {}))
    wbc_table = r.get(control, "wbc", "control.", dict, {})
    wbc_gains = {k: r.get(wbc_table, k, "control.wbc.", float) for k in wbc_table}
    feedback_table = r.get(control, "gait_feedback", "control.", dict, {})
    gait_feedback: dict[str, float | tuple[float, float]] = {}
    for key, value in feedback_table.items():
        where = f"control.gait_feedback.{key}"
        if isinstance(value, list):
            if len(value) != 2 or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value) \
                    or not 0 < value[0] < value[1]:
                raise r.fail(where, f"expected [low, high] with 0 < low < high, got {value!r}")
            gait_feedback[key] = (float(value[0]), float(value[1]))
        else:
            number = r.get(feedback_table, key, "control.gait_feedback.", float)
            gait_feedback[key] = number
            if number < 0:
                raise r.fail(where, f"expected a non-negative number, got {value!r}")

    return RobotConfig(
        gait=gait, wbc_gains=wbc_gains, source_package=source_package, gait_feedback=gait_feedback, walking=walking,
        puppet_clearance_m=puppet_clearance_m,
        name=name, display_name=display_name, kind=kind, path=path, urdf=urdf, srdf=srdf,
        root_link=root_link, up_axis=up_axis, standing_pose=standing_pose,
        standing_srdf_state=standing_state, gains=tuple(gains), upper_body_joints=upper_joints,
        trunk_link=trunk_link, soles=soles, feet=tuple(feet), dae_up_axis=dae_up,
        regularize_inertia_links=reg_links, srdf_collision_excludes=srdf_excludes,
        self_collision=self_collision, visual_face_budget=visual_budget,
        collision_face_budget=collision_budget, default_style=r.get(data, "default_style", "", str, None),
    )


def robot_names(folder: Path | None = None) -> list[str]:
    """Names of the robots with a config file, default robot first."""
    names = sorted(p.stem for p in (folder or robots_dir()).glob("*.toml"))
    if DEFAULT_ROBOT in names:
        names.remove(DEFAULT_ROBOT)
        names.insert(0, DEFAULT_ROBOT)
    return names


DEFAULT_ROBOT = "g1"


def config_path(name: str, folder: Path | None = None) -> Path:
    """Path of robot ``name``'s config; an unknown name raises with the known names."""
    folder = folder or robots_dir()
    path = folder / f"{name}.toml"
    if not re.fullmatch(r"[A-Za-z0-9_\-]+", name) or not path.is_file():
        known = robot_names(folder)
        hint = difflib.get_close_matches(name, known, n=1)
        extra = f" Did you mean {hint[0]!r}?" if hint else ""
        raise RobotConfigError(f"unknown robot {name!r}; known robots: {', '.join(known)}.{extra}")
    return path


def load_robot_config(name: str, folder: Path | None = None) -> RobotConfig:
    return load_config(config_path(name, folder))
