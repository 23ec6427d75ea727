"""Robot descriptions: one small TOML file per robot (format: docs/robots.md), read into frozen dataclasses.

Reading a description needs no Pinocchio (``describe``); the names it gives (joints, frames, links) are
checked against the URDF by :func:`check_names` once the model is built. Every error is a ``UserError``
of one sentence naming the file and the field, e.g. ``panda.toml: arms[0].tool_frame: no frame 'foo' in
the URDF (frames with 'hand': panda_hand, ...)``.
"""
from __future__ import annotations

import importlib.metadata
import math
import tomllib
from dataclasses import dataclass
from pathlib import Path

from interlayer.errors import UserError, closest

__all__ = ["RobotDescription", "ArmDescription", "GripperDescription", "describe", "shipped_robots", "check_names",
           "resolve_resource", "urdf_text"]

SHIPPED = Path(__file__).with_name("robots")
_ERD = "example-robot-data:"
_AXES = {"x": 0, "y": 1, "z": 2}


@dataclass(frozen=True)
class GripperDescription:
    joints: tuple[tuple[str, float], ...]  # (joint, multiplier of the gripper's one DOF)
    fingers: tuple[str, str] | None = None  # links whose collision geometry the opening is measured between
    opening: tuple[float, float] | None = None  # pad gap (m) at the DOF's lower and upper limit


@dataclass(frozen=True)
class ArmDescription:
    name: str
    joints: tuple[str, ...]
    tool_frame: str
    approach: tuple[float, float, float]  # unit axis of the tool frame pointing out of the hand
    closing: tuple[float, float, float]  # unit axis of the tool frame along which the fingers close
    home: tuple[float, ...]
    gripper: GripperDescription
    reach_seed: tuple[float, ...] | None = None
    carry: tuple[tuple[float, float, float, float], ...] = ()
    tool_offset: tuple[float, float, float] = (0.0, 0.0, 0.0)  # tool point in the tool frame's axes (m)


@dataclass(frozen=True)
class RobotDescription:
    name: str
    path: Path  # the TOML file
    urdf: Path
    srdf: Path | None
    package_dirs: tuple[str, ...]
    mobile: bool  # base kind "planar" (True) or "fixed"
    arms: tuple[ArmDescription, ...]
    hold: tuple[tuple[str, float], ...] = ()  # joints in no group, held at these values
    torso: str | None = None  # a held joint whose value ``Robot.load(torso_height=...)`` overrides
    velocity: tuple[tuple[str, float], ...] = ()  # overrides of the URDF's velocity limits
    acceleration: tuple[tuple[str, float], ...] = ()  # default: 2 x velocity
    skip: tuple[tuple[str, str], ...] | None = None  # self-collision pairs never checked (None: not given)
    base_height: float = 0.0  # the root link's height above the floor (a fixed arm's mount)

    def where(self, field: str) -> str:
        return f"{self.path.name}: {field}"


def shipped_robots() -> tuple[str, ...]:
    """Names of the descriptions shipped with this package (``robots/*.toml``)."""
    return tuple(sorted(p.stem for p in SHIPPED.glob("*.toml")))


def resolve_resource(spec: str, base: Path, field: str, where: str) -> tuple[Path, tuple[str, ...]]:
    """(file, package_dirs) for ``example-robot-data:<path under robots/>`` or a path relative to ``base``."""
    if spec.startswith(_ERD):
        try:
            share = Path(importlib.metadata.distribution("example-robot-data").locate_file("cmeel.prefix/share"))
        except importlib.metadata.PackageNotFoundError:
            raise UserError(f"{where}: {field}: the package example-robot-data is not installed "
                            "(pip install example-robot-data, or give a path to the file)") from None
        path, dirs = share / "example-robot-data" / "robots" / spec[len(_ERD):], (str(share),)
    else:
        path = (base / spec).resolve()
        dirs = tuple(dict.fromkeys(str(p) for p in (path.parent, path.parent.parent, path.parent.parent.parent)))
    if not path.is_file():
        raise UserError(f"{where}: {field}: no file {path}")
    return path, dirs


def describe(name_or_path) -> RobotDescription:
    """The description of a shipped robot (``"pr2"``) or of a TOML file."""
    text = str(name_or_path)
    path = Path(text)
    if not text.endswith(".toml") and "/" not in text and "\\" not in text:
        path = SHIPPED / f"{text}.toml"
        if not path.is_file():
            raise UserError(f"unknown robot {text!r}{closest(text, shipped_robots())}: shipped robots are "
                            f"{', '.join(shipped_robots())}, or give the path of a description (.toml)")
    if not path.is_file():
        raise UserError(f"robot description {text}: no such file")
    try:
        data = tomllib.loads(path.read_text())
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise UserError(f"{path.name}: not a readable TOML file ({exc})") from None
    return _parse(data, path.resolve())


def _parse(data: dict, path: Path) -> RobotDescription:
    r = _Reader(path.name)
    unknown = set(data) - {"robot", "base", "hold", "arms", "limits", "self_collision"}
    if unknown:
        r.fail(sorted(unknown)[0], "unknown section (known: robot, base, hold, arms, limits, self_collision)")
    robot = r.table(data, "robot", required=True)
    r.keys(robot, "robot", {"name", "urdf", "srdf", "torso", "package_dirs"})
    name = r.string(robot, "robot.name", default=path.stem)
    urdf, dirs = resolve_resource(r.string(robot, "robot.urdf"), path.parent, "robot.urdf", path.name)
    srdf = None
    if "srdf" in robot:
        srdf, more = resolve_resource(r.string(robot, "robot.srdf"), path.parent, "robot.srdf", path.name)
        dirs += more
    for k, d in enumerate(r.list(robot, "robot.package_dirs", default=[])):
        p = (path.parent / r.string({"d": d}, f"robot.package_dirs[{k}]", key="d")).resolve()
        if not p.is_dir():
            r.fail(f"robot.package_dirs[{k}]", f"no folder {p}")
        dirs += (str(p),)
    base = r.table(data, "base", required=True)
    r.keys(base, "base", {"kind", "height"})
    height = r.number(base, "base.height") if "height" in base else 0.0
    kind = r.string(base, "base.kind")
    if kind not in ("fixed", "planar"):
        r.fail("base.kind", f"{kind!r} is not a base kind: use \"fixed\" or \"planar\"")
    hold = r.table(data, "hold")
    held = tuple((j, r.number(hold, f"hold.{j}", key=j)) for j in hold)
    torso = robot.get("torso")
    if torso is not None and torso not in hold:
        r.fail("robot.torso", f"{torso!r} is not a joint of [hold] (give its value there)")
    arms_data = data.get("arms")
    if not isinstance(arms_data, list) or not arms_data or not all(isinstance(a, dict) for a in arms_data):
        r.fail("arms", "give at least one arm as [[arms]] (name, joints, tool_frame, approach, closing, home, "
                       "[arms.gripper])")
    arms = tuple(_arm(r, a, f"arms[{i}]") for i, a in enumerate(arms_data))
    names = [a.name for a in arms]
    if len(set(names)) != len(names):
        r.fail("arms", f"two arms are named {next(n for n in names if names.count(n) > 1)!r}")
    limits = r.table(data, "limits")
    r.keys(limits, "limits", {"velocity", "acceleration"})
    vel, acc = (tuple((j, r.positive(table, f"limits.{k}.{j}", key=j)) for j in table)
                for k in ("velocity", "acceleration") for table in [r.table(limits, k, field=f"limits.{k}")])
    sc = r.table(data, "self_collision")
    r.keys(sc, "self_collision", {"skip"})
    skip = None
    if "skip" in sc:
        pairs = r.list(sc, "self_collision.skip")
        for k, p in enumerate(pairs):
            if not (isinstance(p, list) and len(p) == 2 and all(isinstance(x, str) for x in p)):
                r.fail(f"self_collision.skip[{k}]", "give a pair of link names, e.g. [\"link_a\", \"link_b\"]")
        skip = tuple((a, b) for a, b in pairs)
    return RobotDescription(name, path, urdf, srdf, tuple(dict.fromkeys(dirs)), kind == "planar", arms, held, torso,
                            vel, acc, skip, height)


def _arm(r: _Reader, a: dict, at: str) -> ArmDescription:
    r.keys(a, at, {"name", "joints", "tool_frame", "tool_offset", "approach", "closing", "home", "reach_seed", "carry",
                   "gripper"})
    name = r.string(a, f"{at}.name")
    joints = tuple(r.string({"j": j}, f"{at}.joints[{k}]", key="j") for k, j in enumerate(r.list(a, f"{at}.joints")))
    if not joints:
        r.fail(f"{at}.joints", "give the arm's joints, from its base to its wrist")
    approach = _axis(r, r.string(a, f"{at}.approach"), f"{at}.approach")
    closing = _axis(r, r.string(a, f"{at}.closing"), f"{at}.closing")
    if abs(sum(x * y for x, y in zip(approach, closing))) > 1e-9:
        r.fail(f"{at}.closing", "must be perpendicular to the approach axis")
    home = r.numbers(a, f"{at}.home", len(joints))
    seed = r.numbers(a, f"{at}.reach_seed", len(joints)) if "reach_seed" in a else None
    carry = tuple(tuple(r.numbers({"c": c}, f"{at}.carry[{k}]", 4, key="c"))
                  for k, c in enumerate(r.list(a, f"{at}.carry", default=[])))
    g = r.table(a, "gripper", required=True, field=f"{at}.gripper")
    r.keys(g, f"{at}.gripper", {"joints", "fingers", "opening"})
    # no joints: fixed fingers (the DOF drives nothing, its range is [0, 0])
    gj = r.table(g, "joints", field=f"{at}.gripper.joints")
    gjoints = tuple((j, r.number(gj, f"{at}.gripper.joints.{j}", key=j)) for j in gj)
    if any(m == 0 for _, m in gjoints):
        r.fail(f"{at}.gripper.joints", "give each finger joint with a non-zero multiplier, e.g. { finger_joint = 1.0 }")
    fingers = opening = None
    if "fingers" in g:
        fingers = tuple(r.string({"f": f}, f"{at}.gripper.fingers[{k}]", key="f")
                        for k, f in enumerate(r.list(g, f"{at}.gripper.fingers")))
        if len(fingers) != 2:
            r.fail(f"{at}.gripper.fingers", "give two links, one per side of the gripper")
    if "opening" in g:
        opening = tuple(r.numbers(g, f"{at}.gripper.opening", 2))
    if (fingers is None) == (opening is None):
        r.fail(f"{at}.gripper", "give either fingers (two links) or opening (pad gap at the DOF's limits), not both")
    offset = tuple(r.numbers(a, f"{at}.tool_offset", 3)) if "tool_offset" in a else (0.0, 0.0, 0.0)
    return ArmDescription(name, joints, r.string(a, f"{at}.tool_frame"), approach, closing, tuple(home),
                          GripperDescription(gjoints, fingers, opening), None if seed is None else tuple(seed), carry,
                          offset)


def _axis(r: _Reader, text: str, field: str) -> tuple[float, float, float]:
    t = text.strip().lower()
    sign = -1.0 if t.startswith("-") else 1.0
    t = t.lstrip("+-")
    if t not in _AXES:
        r.fail(field, f"{text!r} is not an axis: use x, y or z with an optional sign (\"+z\", \"-y\")")
    out = [0.0, 0.0, 0.0]
    out[_AXES[t]] = sign
    return tuple(out)


class _Reader:
    """Typed access to the parsed TOML with one-sentence errors naming the field."""

    def __init__(self, filename: str):
        self.filename = filename

    def fail(self, field: str, why: str):
        raise UserError(f"{self.filename}: {field}: {why}")

    def keys(self, table: dict, at: str, known: set) -> None:
        extra = sorted(set(table) - known)
        if extra:
            self.fail(f"{at}.{extra[0]}", f"unknown key{closest(extra[0], known)} (known: {', '.join(sorted(known))})")

    def table(self, data: dict, key: str, required: bool = False, field: str | None = None) -> dict:
        field = field or key
        if key not in data:
            if required:
                self.fail(field, "missing")
            return {}
        if not isinstance(data[key], dict):
            self.fail(field, "must be a table")
        return data[key]

    def string(self, data: dict, field: str, key: str | None = None, default=None) -> str:
        return self._value(data, field, key, default, lambda v: isinstance(v, str) and v, "a non-empty string")

    def list(self, data: dict, field: str, key: str | None = None, default=None) -> list:
        return self._value(data, field, key, default, lambda v: isinstance(v, list), "a list")

    def _value(self, data: dict, field: str, key, default, ok, what: str):
        """``data[key]`` (key: the field's last part), ``default`` when absent (None: required), checked by ``ok``."""
        key = key or field.rsplit(".", 1)[-1]
        if key not in data:
            if default is not None:
                return default
            self.fail(field, "missing")
        if not ok(data[key]):
            self.fail(field, f"must be {what}")
        return data[key]

    def number(self, data: dict, field: str, key: str | None = None) -> float:
        key = key or field.rsplit(".", 1)[-1]
        v = data.get(key)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            self.fail(field, f"must be a number, not {v!r}")
        return float(v)

    def positive(self, data: dict, field: str, key: str | None = None) -> float:
        v = self.number(data, field, key)
        if v <= 0:
            self.fail(field, f"must be positive, not {v}")
        return v

    def numbers(self, data: dict, field: str, n: int, key: str | None = None) -> list[float]:
        values = self.list(data, field, key)
        if len(values) != n:
            self.fail(field, f"give {n} numbers, not {len(values)}")
        return [self.number({"v": v}, f"{field}[{k}]", key="v") for k, v in enumerate(values)]


def check_names(desc: RobotDescription, model, collision_model) -> None:
    """Every joint, frame and link the description names exists in the URDF's model (else UserError)."""
    joints = [model.names[j] for j in range(1, model.njoints)]
    frames = [f.name for f in model.frames]
    links = {f.name for f in model.frames if f.type == _body_type()}

    def need(name, known, field, what):
        if name not in known:
            raise UserError(f"{desc.where(field)}: no {what} {name!r} in the URDF{_like(name, known, what)}")

    for j, _ in desc.hold:
        need(j, joints, f"hold.{j}", "joint")
    for k, arm in enumerate(desc.arms):
        at = f"arms[{k}]"
        for i, j in enumerate(arm.joints):
            need(j, joints, f"{at}.joints[{i}]", "joint")
        need(arm.tool_frame, frames, f"{at}.tool_frame", "frame")
        for j, _ in arm.gripper.joints:
            need(j, joints, f"{at}.gripper.joints.{j}", "joint")
        for i, f in enumerate(arm.gripper.fingers or ()):
            need(f, links, f"{at}.gripper.fingers[{i}]", "link")
            if not any(g.parentFrame == model.getFrameId(f) for g in collision_model.geometryObjects):
                raise UserError(f"{desc.where(f'{at}.gripper.fingers[{i}]')}: link {f!r} has no collision geometry "
                                "to measure the opening on (give gripper.opening instead)")
    for field, table in (("limits.velocity", desc.velocity), ("limits.acceleration", desc.acceleration)):
        for j, _ in table:
            need(j, joints, f"{field}.{j}", "joint")
    for k, pair in enumerate(desc.skip or ()):
        for i, link in enumerate(pair):
            need(link, links, f"self_collision.skip[{k}][{i}]", "link")


def urdf_text(desc: RobotDescription) -> tuple[str | None, tuple[str, ...]]:
    """(text, joints): the URDF's text with the finger joints that it declares ``fixed`` made revolute within
    their ``<limit>`` (example-robot-data's Kinova: its fingers are fixed, spread open, though the real hand
    closes), and those joints; (None, ()) when every finger joint already moves (the file is read as it is)."""
    import xml.etree.ElementTree as ET

    wanted = {j: k for k, arm in enumerate(desc.arms) for j, _ in arm.gripper.joints}
    if not wanted:
        return None, ()
    root = ET.fromstring(desc.urdf.read_bytes())
    changed = []
    for joint in root.iter("joint"):
        name = joint.get("name")
        if name not in wanted or joint.get("type") != "fixed":
            continue
        limit = joint.find("limit")
        if limit is None or limit.get("lower") is None or limit.get("upper") is None:
            raise UserError(f"{desc.where(f'arms[{wanted[name]}].gripper.joints.{name}')}: the URDF declares {name!r} "
                            "fixed and gives it no <limit lower=... upper=...> to move within: give a finger joint "
                            "that moves, or leave gripper.joints out (fixed fingers)")
        joint.set("type", "revolute")
        changed.append(name)
    return (ET.tostring(root, encoding="unicode"), tuple(changed)) if changed else (None, ())


def _like(name: str, known, what: str) -> str:
    """' (frames with 'hand': panda_hand, ...)' for the longest word of ``name`` some known names contain."""
    for word in sorted((w for w in name.replace("-", "_").split("_") if len(w) >= 3), key=len, reverse=True):
        hits = [k for k in known if word in k]
        if hits:
            return f" ({what}s with {word!r}: {', '.join(hits[:6])}{', ...' if len(hits) > 6 else ''})"
    return closest(name, known)


def _body_type():
    import pinocchio as pin

    return pin.FrameType.BODY
