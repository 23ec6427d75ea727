"""Record a meshcat scene (objects, poses, colours, one animation) and write it
as ONE self-contained HTML file, or mirror it into a live meshcat viewer.

Conventions
-----------
* World frame is z-up (as in meshcat and pinocchio). Units are metres.
* ``name`` is a "/"-separated path below meshcat's ``/meshcat`` root:
  ``"pr2/base_link_0"`` is a child of the group ``"pr2"``, so
  ``set_pose("pr2", T)`` / ``set_color("pr2", c)`` / ``delete("pr2")`` act on
  the whole subtree. Poses of children are relative to their parent group.
* ``pose`` accepts ``None`` (identity), a 4x4 homogeneous matrix, anything with
  a ``.homogeneous`` attribute (``pinocchio.SE3``), a 3-vector (translation)
  or a 7-vector ``[x, y, z, qx, qy, qz, qw]`` (pinocchio's quaternion order).
* ``color`` accepts RGB/RGBA floats in [0, 1] (or 0..255 ints), ``0xRRGGBB``,
  ``"#rrggbb"``/``"#rrggbbaa"``, or a few names (``"red"``, ``"grey"``...).
  Alpha < 1 makes the material transparent.
* Cylinders, cones and capsules have their axis along **z** and are centred at
  their pose (three.js/meshcat cylinders are along y; converted here with an
  intrinsic RotX(+90 deg) baked into the object's matrix).

Backends
--------
Every command goes through a single meshcat ``Visualizer(window=...)`` whose
window records it (compacting superseded commands) and, after :meth:`Scene.live`,
also forwards it to a real meshcat server. So the HTML page and the live
viewer are driven by the same code and the same meshcat command dicts.
"""

from __future__ import annotations

import contextlib
import io
import math
import os
import sys
from pathlib import Path as _FsPath
from typing import Mapping, Sequence

import numpy as np
import umsgpack

import meshcat
import meshcat.geometry as _mg

from . import _viewer
from .meshes import capsule_mesh, load_mesh, mesh_bbox, simplify_mesh

__all__ = ["Scene", "HtmlScene", "SceneRecorder", "as_pose", "as_rgba", "DEFAULT_COLOR"]

DEFAULT_COLOR = (0.72, 0.74, 0.78, 1.0)
ROOT = "/meshcat"

_NAMED = {
    "red": (0.86, 0.15, 0.15), "green": (0.20, 0.70, 0.25), "blue": (0.15, 0.35, 0.85),
    "yellow": (0.95, 0.80, 0.10), "orange": (1.0, 0.55, 0.0), "purple": (0.55, 0.25, 0.75),
    "cyan": (0.0, 0.75, 0.85), "magenta": (0.9, 0.2, 0.7), "white": (1.0, 1.0, 1.0),
    "black": (0.0, 0.0, 0.0), "grey": (0.6, 0.6, 0.6), "gray": (0.6, 0.6, 0.6),
    "brown": (0.55, 0.35, 0.2),
}

# three.js loop modes
_LOOP_ONCE, _LOOP_REPEAT = 2200, 2201

# cylinder-like meshcat geometry is along +y; RotX(+90deg) maps +y -> +z
_Y_TO_Z = np.array([[1.0, 0, 0, 0], [0, 0, -1, 0], [0, 1, 0, 0], [0, 0, 0, 1]])


# --------------------------------------------------------------------------- utils
def as_pose(pose) -> np.ndarray:
    """Normalise a pose to a float 4x4 matrix (see module docstring)."""
    if pose is None:
        return np.eye(4)
    if hasattr(pose, "homogeneous"):
        pose = pose.homogeneous
    a = np.asarray(pose, dtype=np.float64)
    if a.shape == (4, 4):
        return a.copy()
    if a.shape == (3, 4):
        return np.vstack([a, [0, 0, 0, 1]])
    T = np.eye(4)
    if a.shape == (3,):
        T[:3, 3] = a
        return T
    if a.shape == (7,):
        x, y, z, w = a[3:] / np.linalg.norm(a[3:])
        T[:3, :3] = [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
        T[:3, 3] = a[:3]
        return T
    raise ValueError(f"cannot interpret pose of shape {a.shape}")


def as_rgba(color, default=DEFAULT_COLOR) -> tuple[float, float, float, float]:
    """Normalise a colour to an RGBA tuple of floats in [0, 1]."""
    if color is None:
        return tuple(float(c) for c in default)
    if isinstance(color, str):
        s = color.strip().lower()
        if s in _NAMED:
            return (*_NAMED[s], 1.0)
        if s.startswith("#") and len(s) in (7, 9):
            vals = [int(s[i:i + 2], 16) / 255.0 for i in range(1, len(s), 2)]
            return tuple(vals) if len(vals) == 4 else (*vals, 1.0)
        raise ValueError(f"unknown colour {color!r}")
    if isinstance(color, (int, np.integer)) and not isinstance(color, bool):
        c = int(color)
        return ((c >> 16 & 255) / 255.0, (c >> 8 & 255) / 255.0, (c & 255) / 255.0, 1.0)
    vals = [float(c) for c in np.asarray(color, dtype=np.float64).reshape(-1)]
    if len(vals) not in (3, 4):
        raise ValueError(f"colour needs 3 or 4 components, got {color!r}")
    if max(vals) > 1.0:
        vals = [v / 255.0 for v in vals]
    if len(vals) == 3:
        vals.append(1.0)
    return tuple(min(max(v, 0.0), 1.0) for v in vals)


def _hex(rgba) -> int:
    r, g, b = (int(round(255 * c)) for c in rgba[:3])
    return (r << 16) | (g << 8) | b


def _path(name: str) -> str:
    parts = [p for p in str(name).split("/") if p]
    if not parts:
        raise ValueError(f"empty object name {name!r}")
    return ROOT + "/" + "/".join(parts)


def _norm_name(name: str) -> str:
    return "/".join(p for p in str(name).split("/") if p)


def _colmajor(M) -> list[float]:
    """three.js Matrix4.fromArray wants column-major order."""
    return [float(x) for x in np.asarray(M, dtype=np.float64).T.reshape(-1)]


class _Raw:
    """A pre-lowered command (what ViewerWindow.send expects: an object with lower())."""
    __slots__ = ("data",)

    def __init__(self, data):
        self.data = data

    def lower(self):
        return self.data


class _Object(_mg.Object):
    """meshcat Object with a correct (column-major) intrinsic matrix and an
    optional extra material/type. (meshcat 0.3.2's Object.lower flattens the
    geometry's intrinsic transform row-major, i.e. transposed; harmless for its
    diagonal Ellipsoid, wrong for rotations.)"""

    def __init__(self, geometry, material, matrix=None, kind="Mesh"):
        super().__init__(geometry, material)
        self._type = kind
        self.matrix = np.eye(4) if matrix is None else np.asarray(matrix, dtype=np.float64)

    def lower(self):
        data = super().lower()
        data["object"]["matrix"] = _colmajor(self.matrix)
        return _content_uuids(data)


def _content_uuids(data: dict) -> dict:
    """Replace meshcat's random uuids by digests of what they name, so an object drawn alike in
    several views of a page is the same bytes (pages store such a command once)."""
    import hashlib
    import uuid

    ids: dict = {}

    def sub(x):
        if isinstance(x, str):
            return ids.get(x, x)
        if isinstance(x, dict):
            return {k: sub(v) for k, v in x.items()}
        if isinstance(x, list):
            return [sub(v) for v in x]
        return x

    for kind in ("images", "textures", "geometries", "materials"):
        entries = []
        for e in data.get(kind, []):
            e = sub(e)
            body = umsgpack.packb({k: v for k, v in e.items() if k != "uuid"}, force_float_precision="single")
            new = str(uuid.UUID(bytes=hashlib.sha1(body).digest()[:16]))
            ids[e["uuid"]] = new
            entries.append({**e, "uuid": new})
        if kind in data:
            data[kind] = entries
    obj = sub(data["object"])
    body = umsgpack.packb({k: v for k, v in obj.items() if k != "uuid"}, force_float_precision="single")
    data["object"] = {**obj, "uuid": str(uuid.UUID(bytes=hashlib.sha1(body).digest()[:16]))}
    return data


class _TextTexture(_mg.Texture):
    """meshcat viewer's ``_text`` canvas texture (256x256 canvas, black text)."""

    def __init__(self, text, font_size=48, font_face="sans-serif"):
        super().__init__()
        self.text, self.font_size, self.font_face = text, font_size, font_face

    def lower(self, object_data):
        return {"uuid": self.uuid, "type": "_text", "text": self.text,
                "font_size": self.font_size, "font_face": self.font_face}


# ----------------------------------------------------------------- command log
class _CommandLog:
    """Ordered meshcat commands with superseded ones dropped, so a page holds
    the final state rather than the whole history:
    a set_transform / set_property(prop) / set_object / set_animation replaces
    the previous one with the same key; delete(path) drops every earlier
    command on path or below it."""

    def __init__(self):
        self._entries: list = []           # (key, path, packed) or None
        self._index: dict = {}

    @staticmethod
    def _key(cmd):
        t = cmd.get("type")
        p = cmd.get("path", "")
        if t == "set_transform":
            return ("T", p)
        if t == "set_property":
            return ("P", p, cmd.get("property"))
        if t == "set_object":
            return ("O", p)
        if t == "set_animation":
            return ("A",)
        return None

    def add(self, cmd: dict):
        t = cmd.get("type")
        path = cmd.get("path", "")
        if t == "delete":
            pre = path.rstrip("/") + "/"
            for i, e in enumerate(self._entries):
                if e is not None and e[0] != ("A",) and (e[1] == path or e[1].startswith(pre)):
                    self._entries[i] = None
                    self._index.pop(e[0], None)
        key = self._key(cmd)
        if key is not None and key in self._index:
            self._entries[self._index.pop(key)] = None
        packed = umsgpack.packb(cmd, force_float_precision="single")
        self._entries.append((key, path, packed, cmd))
        if key is not None:
            self._index[key] = len(self._entries) - 1
        if len(self._entries) > 64 and len(self._index) * 4 < len(self._entries):
            self._compact()

    def _compact(self):
        live = [e for e in self._entries if e is not None]
        self._entries = live
        self._index = {e[0]: i for i, e in enumerate(live) if e[0] is not None}

    def packed(self) -> list[bytes]:
        return [e[2] for e in self._entries if e is not None]

    def commands(self) -> list[dict]:
        return [e[3] for e in self._entries if e is not None]

    def clear(self):
        self._entries.clear()
        self._index.clear()


class _TeeWindow:
    """The ``window`` given to ``meshcat.Visualizer``: records every command,
    forwards it to a live meshcat ``ViewerWindow`` when one is attached."""

    def __init__(self):
        self.log = _CommandLog()
        self.live = None

    def send(self, command):
        data = command.lower()
        self.log.add(data)
        if self.live is not None:
            self.live.send(_Raw(data))


class _Info:
    __slots__ = ("kind", "bbox", "color")

    def __init__(self, kind, bbox, color):
        self.kind, self.bbox, self.color = kind, bbox, color


# ------------------------------------------------------------------------ Scene
class Scene:
    """A 3D scene that can be written as a self-contained HTML page
    (:meth:`write_html`) and/or shown in a live meshcat viewer (:meth:`live`).

    Parameters: ``title`` (page title), ``background`` ("light" | "meshcat" |
    (top_rgb, bottom_rgb)), ``grid``/``axes`` (meshcat's default 20 m grid and
    0.5 m world axes), ``controls`` (open meshcat's control panel on load),
    ``fov`` (vertical field of view in degrees; meshcat's default is a very
    wide 75, we use 45 for less perspective distortion).
    """

    def __init__(self, title: str = "Interlayer scene", *, background="light", grid: bool = True,
                 axes: bool = False, controls: bool = False, fov: float = 45.0):
        self.title = title
        self.controls = controls
        self.fov = float(fov)
        self._window = _TeeWindow()
        self._vis = meshcat.Visualizer(window=self._window)
        self._info: dict[str, _Info] = {}
        self._poses: dict[str, np.ndarray] = {}
        self._highlighted: dict[str, dict[str, tuple]] = {}
        self._labels: dict[str, list] = {}  # name -> [text, priority, height]
        self._camera = None            # (position, target) when set explicitly
        self._anim_frames: list[dict] = []
        self._has_animation = False
        self._live_window = None
        self._live_proc = None
        if background == "light":
            self.set_background((0.97, 0.975, 0.985), (0.80, 0.83, 0.88))
        elif background not in (None, "meshcat"):
            self.set_background(*background)
        if not grid:
            self._raw_property("/Grid", "visible", False)
        if not axes:
            self._raw_property("/Axes", "visible", False)
        if self.fov != 75.0:
            self._raw_property("/Cameras/default/rotated/<object>", "fov", self.fov)

    # ------------------------------------------------------------- internals
    def _send(self, data: dict):
        self._window.send(_Raw(data))

    def _raw_property(self, path, prop, value):
        self._send({"type": "set_property", "path": path, "property": prop, "value": value})

    def _material(self, rgba, flat=False, **extra):
        props = dict(extra)
        if flat:
            props["flatShading"] = True
        return _mg.MeshPhongMaterial(color=_hex(rgba), opacity=float(rgba[3]),
                                     transparent=bool(rgba[3] < 1.0), **props)

    def _add(self, name, obj, kind, bbox, rgba, pose):
        name = _norm_name(name)
        self._vis[_path(name)].set_object(obj)
        self._info[name] = _Info(kind, None if bbox is None else np.asarray(bbox, float), rgba)
        for k in [k for k in self._highlighted if k == name or k.startswith(name + "/")]:
            self._highlighted.pop(k, None)
        if pose is not None or name not in self._poses:
            self.set_pose(name, pose)
        return name

    # ------------------------------------------------------------ primitives
    def box(self, name: str, size, pose=None, color=None) -> str:
        """Axis-aligned (in its own frame) box of full extents ``size=(sx, sy, sz)``
        (a scalar gives a cube), centred at ``pose``."""
        s = np.broadcast_to(np.asarray(size, dtype=np.float64), (3,))
        rgba = as_rgba(color)
        obj = _Object(_mg.Box([float(x) for x in s]), self._material(rgba))
        return self._add(name, obj, "box", np.stack([-s / 2, s / 2]), rgba, pose)

    def sphere(self, name: str, radius: float, pose=None, color=None) -> str:
        rgba = as_rgba(color)
        obj = _Object(_mg.Sphere(float(radius)), self._material(rgba))
        r = float(radius)
        return self._add(name, obj, "sphere", [[-r] * 3, [r] * 3], rgba, pose)

    def ellipsoid(self, name: str, radii, pose=None, color=None) -> str:
        r = np.broadcast_to(np.asarray(radii, dtype=np.float64), (3,))
        rgba = as_rgba(color)
        obj = _Object(_mg.Sphere(1.0), self._material(rgba), matrix=np.diag([*r, 1.0]))
        return self._add(name, obj, "ellipsoid", np.stack([-r, r]), rgba, pose)

    def cylinder(self, name: str, radius: float, height: float, pose=None, color=None) -> str:
        """Cylinder with axis along **z** (not meshcat's y), centred at ``pose``."""
        rgba = as_rgba(color)
        geom = _mg.Cylinder(float(height), float(radius))
        obj = _Object(geom, self._material(rgba), matrix=_Y_TO_Z)
        r, h = float(radius), float(height) / 2
        return self._add(name, obj, "cylinder", [[-r, -r, -h], [r, r, h]], rgba, pose)

    def cone(self, name: str, radius: float, height: float, pose=None, color=None) -> str:
        """Cone along z, base at z=-height/2, apex at +height/2 (coal's convention)."""
        rgba = as_rgba(color)
        geom = _mg.Cylinder(float(height), radiusTop=0.0, radiusBottom=float(radius))
        obj = _Object(geom, self._material(rgba), matrix=_Y_TO_Z)
        r, h = float(radius), float(height) / 2
        return self._add(name, obj, "cone", [[-r, -r, -h], [r, r, h]], rgba, pose)

    def capsule(self, name: str, radius: float, length: float, pose=None, color=None) -> str:
        """Capsule along z: cylinder part of ``length`` (= coal ``2*halfLength``)
        plus hemispherical caps; total height ``length + 2*radius``."""
        V, F = capsule_mesh(float(radius), float(length))
        return self.triangles(name, V, F, pose, color, flat=False)

    def triangles(self, name: str, vertices, faces, pose=None, color=None, *, flat: bool = True,
                  max_faces: int | None = None) -> str:
        """Indexed triangle mesh (``vertices`` Nx3, ``faces`` Mx3), stored as
        float32/uint32 arrays (~18 bytes per triangle before base64). ``flat``
        uses per-face shading (good for CAD/STL meshes). ``max_faces`` decimates
        (vertex clustering) before storing."""
        V = np.asarray(vertices, dtype=np.float64).reshape(-1, 3)
        F = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
        if max_faces is not None and len(F) > max_faces:
            V, F = _simplified(V, F, max_faces)
        rgba = as_rgba(color)
        geom = _mg.TriangularMeshGeometry(np.asarray(V, np.float32), np.asarray(F, np.uint32))
        obj = _Object(geom, self._material(rgba, flat=flat))
        return self._add(name, obj, "mesh", mesh_bbox(V), rgba, pose)

    def mesh(self, name: str, path, pose=None, scale=1.0, color=None, *, embed: str = "auto",
             max_faces: int | None = None) -> str:
        """Mesh from a file (STL, DAE, OBJ; anything assimp reads in
        ``embed="triangles"`` mode).

        ``embed="triangles"`` (default when coal is importable) loads the file
        with coal/assimp and stores indexed float32 triangles: smallest pages
        (binary STL is ~50 B/triangle, DAE text far more), single colour.
        ``embed="file"`` embeds the file bytes (meshcat ``_meshfile``: STL, DAE
        or OBJ only), scale applied via the object matrix.
        """
        path = os.fspath(path)
        ext = os.path.splitext(path)[1].lower().lstrip(".")
        if embed == "auto":
            try:
                import coal  # noqa: F401
                embed = "triangles"
            except ImportError:
                embed = "file"
        if embed == "triangles":
            V, F = load_mesh(path, scale)
            return self.triangles(name, V, F, pose, color, max_faces=max_faces)
        if embed != "file":
            raise ValueError("embed must be 'auto', 'triangles' or 'file'")
        s = np.broadcast_to(np.asarray(scale, dtype=np.float64), (3,))
        bbox = None
        if ext == "stl":
            geom = _mg.StlMeshGeometry.from_file(path)
            bbox = _stl_bbox(path)
        elif ext == "dae":
            geom = _mg.DaeMeshGeometry.from_file(path)
        elif ext == "obj":
            geom = _mg.ObjMeshGeometry.from_file(path)
            bbox = _obj_bbox(path)
        else:
            raise ValueError(f"embed='file' supports stl/dae/obj, not {ext!r}")
        rgba = as_rgba(color)
        obj = _Object(geom, self._material(rgba), matrix=np.diag([*s, 1.0]))
        if bbox is not None:
            bbox = np.sort(bbox * s, axis=0)
        return self._add(name, obj, "meshfile", bbox, rgba, pose)

    def line(self, name: str, points, color=None, *, closed: bool = False, pose=None,
             width: float = 1.0) -> str:
        """Polyline through ``points`` (Nx3) e.g. a planned path. Note: WebGL
        draws lines 1 px wide whatever ``width`` says (three.js limitation)."""
        P = np.asarray(points, dtype=np.float32).reshape(-1, 3)
        rgba = as_rgba(color, default=(0.1, 0.1, 0.1, 1.0))
        mat = _mg.LineBasicMaterial(color=_hex(rgba), linewidth=float(width), opacity=float(rgba[3]),
                                    transparent=bool(rgba[3] < 1.0))
        obj = _Object(_mg.PointsGeometry(P.T), mat, kind="LineLoop" if closed else "Line")
        return self._add(name, obj, "line", mesh_bbox(P), rgba, pose)

    def points(self, name: str, points, color=None, *, size: float = 0.02, pose=None) -> str:
        """Point cloud (Nx3) drawn as squares of ``size`` metres."""
        P = np.asarray(points, dtype=np.float32).reshape(-1, 3)
        rgba = as_rgba(color, default=(0.1, 0.1, 0.1, 1.0))
        C = np.tile(np.asarray(rgba[:3], np.float32), (len(P), 1))
        obj = _Object(_mg.PointsGeometry(P.T, C.T), _mg.PointsMaterial(size=float(size)), kind="Points")
        return self._add(name, obj, "points", mesh_bbox(P), rgba, pose)

    def frame_axes(self, name: str, pose=None, length: float = 0.2) -> str:
        """RGB = xyz triad."""
        L = float(length)
        P = np.array([[0, 0, 0], [L, 0, 0], [0, 0, 0], [0, L, 0], [0, 0, 0], [0, 0, L]], np.float32)
        C = np.array([[1, 0, 0], [1, .6, 0], [0, 1, 0], [.6, 1, 0], [0, 0, 1], [0, .6, 1]], np.float32)
        obj = _Object(_mg.PointsGeometry(P.T, C.T), _mg.LineBasicMaterial(vertexColors=True),
                      kind="LineSegments")
        return self._add(name, obj, "axes", [[0, 0, 0], [L, L, L]], None, pose)

    def label(self, name: str, text: str, pose=None, height: float = 0.08, *, priority: int = 0) -> str:
        """Text label at ``pose`` (a point that moves with its parent group).

        In pages it is an HTML tag that follows the point on screen at a legible
        size whatever the scene's scale; where tags would overlap, the one of
        higher ``priority`` (then the earlier) keeps its text and the other
        becomes a dot showing its text on hover. In a live viewer it is a
        camera-facing sprite whose cap height is about ``height`` metres."""
        name = _norm_name(name)
        self._labels[name] = [str(text), int(priority), float(height)]
        self._info[name] = _Info("label", None, None)
        self.set_pose(name, pose)      # the anchor: a transform node, no object in pages
        if self._live_window is not None:
            self._live_window.send(_Raw(_sprite(name, text, height)))
        return name

    def label_priority(self, group: str, priority: int) -> None:
        """Priority of the labels at or below ``group`` (see :meth:`label`)."""
        group = _norm_name(group)
        for k, lab in self._labels.items():
            if k == group or k.startswith(group + "/"):
                lab[1] = int(priority)

    def labels(self) -> list:
        """``[[path, text, priority], ...]``: the labels a page draws."""
        return [[_path(k), t, p] for k, (t, p, _h) in self._labels.items()]

    # -------------------------------------------------------------- changes
    def set_pose(self, name: str, pose) -> None:
        """Pose of an object or group relative to its parent group."""
        name = _norm_name(name)
        T = as_pose(pose)
        self._poses[name] = T
        self._vis[_path(name)].set_transform(T)

    def get_pose(self, name: str) -> np.ndarray:
        return self._poses.get(_norm_name(name), np.eye(4)).copy()

    def set_color(self, name: str, color) -> None:
        """Colour (RGBA) of an object, or of every object below a group."""
        name = _norm_name(name)
        rgba = as_rgba(color)
        self._vis[_path(name)].set_property("color", [float(c) for c in rgba])
        for k, info in self._info.items():
            if (k == name or k.startswith(name + "/")) and info.color is not None:
                info.color = rgba
                for saved in self._highlighted.values():
                    saved.pop(k, None)

    def highlight(self, name: str, color=(1.0, 0.1, 0.1, 1.0)) -> None:
        """Recolour ``name`` (object or group); :meth:`unhighlight` restores."""
        name = _norm_name(name)
        saved = self._highlighted.setdefault(name, {})
        for k, info in self._info.items():
            if (k == name or k.startswith(name + "/")) and info.color is not None:
                saved.setdefault(k, info.color)
        self._vis[_path(name)].set_property("color", [float(c) for c in as_rgba(color)])

    def unhighlight(self, name: str) -> None:
        name = _norm_name(name)
        for k, rgba in self._highlighted.pop(name, {}).items():
            self._vis[_path(k)].set_property("color", [float(c) for c in rgba])

    def set_visible(self, name: str, visible: bool = True) -> None:
        self._vis[_path(name)].set_property("visible", bool(visible))

    def delete(self, name: str) -> None:
        """Remove an object or a whole group."""
        name = _norm_name(name)
        self._vis[_path(name)].delete()
        for d in (self._info, self._poses, self._highlighted, self._labels):
            for k in [k for k in d if k == name or k.startswith(name + "/")]:
                del d[k]

    def clear(self) -> None:
        """Delete all user objects (keeps background/grid settings and camera)."""
        self._vis[ROOT].delete()
        self._info.clear()
        self._labels.clear()
        self._poses.clear()
        self._highlighted.clear()
        self.clear_animation()

    def set_background(self, top_rgb, bottom_rgb=None) -> None:
        top = as_rgba(top_rgb)[:3]
        bottom = top if bottom_rgb is None else as_rgba(bottom_rgb)[:3]
        self._raw_property("/Background", "top_color", [float(c) for c in top])
        self._raw_property("/Background", "bottom_color", [float(c) for c in bottom])

    def set_grid(self, visible: bool) -> None:
        self._raw_property("/Grid", "visible", bool(visible))

    def set_axes(self, visible: bool) -> None:
        self._raw_property("/Axes", "visible", bool(visible))

    # --------------------------------------------------------------- camera
    def camera(self, position, target=(0.0, 0.0, 0.0)) -> None:
        """Orbit camera at world ``position`` looking at world ``target``
        (z up). In the HTML page both are exact; in a live meshcat 0.3.2
        viewer only the position is applied and the orbit centre stays at the
        world origin (its command set cannot move OrbitControls' target)."""
        pos = np.asarray(position, dtype=np.float64).reshape(3)
        tgt = np.asarray(target, dtype=np.float64).reshape(3)
        self._camera = (pos, tgt)
        if self._live_window is not None:
            self._send_live_camera(pos, tgt)

    def auto_camera(self, direction=(1.0, 0.55, 0.6), margin: float = 1.0):
        """Camera looking at the bounding box of all objects (including their
        animated poses) from ``direction``; returns ``(position, target)``.
        (Pages do this automatically unless :meth:`camera` was called.)
        With a live viewer attached the fit is around the world origin."""
        center = (0.0, 0.0, 0.0) if self._live_window is not None else None
        pos, tgt = self._auto_camera(direction, margin, center)
        self.camera(pos, tgt)
        return pos, tgt

    def _auto_camera(self, direction=(1.0, 0.55, 0.6), margin: float = 1.0, center=None):
        lo, hi = self.bounds()
        center = 0.5 * (lo + hi) if center is None else np.asarray(center, dtype=np.float64)
        d = np.asarray(direction, dtype=np.float64)
        d = d / np.linalg.norm(d)
        # camera basis (z up); fit the 8 bbox corners in the (vertical) fov
        # frustum, horizontally assuming a square view (aspect 1, conservative)
        right = np.cross([0.0, 0.0, 1.0], d)
        if np.linalg.norm(right) < 1e-6:
            right = np.array([0.0, 1.0, 0.0])
        right /= np.linalg.norm(right)
        up = np.cross(d, right)
        t = math.tan(math.radians(self.fov) / 2)
        dist = 0.5
        for c in [[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]:
            v = np.asarray(c) - center
            need = float(v @ d) + max(abs(float(v @ up)), abs(float(v @ right))) / t
            dist = max(dist, need)
        dist *= 1.1 * margin
        return center + d * dist, center

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """World AABB ``(lo, hi)`` of all objects over the static poses and the
        animation frames (a unit-ish box around the origin if empty)."""
        pts = []
        frames = [{}] + self._anim_frames[:: max(1, len(self._anim_frames) // 25)]
        if self._anim_frames:
            frames.append(self._anim_frames[-1])
        corners = np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)], dtype=float)
        for frame in frames:
            for name, info in self._info.items():
                T = self._world_pose(name, frame)
                if info.bbox is None:
                    pts.append(T[:3, 3])
                    continue
                lo, hi = info.bbox
                c = lo + corners * (hi - lo)
                pts.extend((c @ T[:3, :3].T) + T[:3, 3])
        if not pts:
            return np.array([-0.5, -0.5, 0.0]), np.array([0.5, 0.5, 1.0])
        P = np.asarray(pts)
        return P.min(axis=0), P.max(axis=0)

    def _world_pose(self, name, frame=None):
        parts = name.split("/")
        T = np.eye(4)
        for i in range(1, len(parts) + 1):
            k = "/".join(parts[:i])
            local = frame.get(k) if frame else None
            if local is None:
                local = self._poses.get(k)
            if local is not None:
                T = T @ local
        return T

    def _send_live_camera(self, pos, tgt):
        # position only (see camera()); rotated frame maps world (x,y,z)->(x,z,-y)
        self._live_window.send(_Raw({"type": "set_transform", "path": "/Cameras/default",
                                     "matrix": _colmajor(np.eye(4))}))
        self._live_window.send(_Raw({"type": "set_property", "path": "/Cameras/default/rotated/<object>",
                                     "property": "position",
                                     "value": [float(pos[0]), float(pos[2]), float(-pos[1])]}))

    # ------------------------------------------------------------ animation
    def animate(self, frames: Sequence[Mapping[str, object]], fps: float = 10.0, *,
                autoplay: bool = True, loop: bool = True, repetitions: int | None = None,
                tolerance: tuple[float, float] | None = None) -> None:
        """Replace the scene's animation by ``frames``: a list whose i-th entry
        maps names (objects or groups) to poses at time ``i/fps``. A name keeps
        its last given pose in later frames and its current static pose in
        frames before its first mention. Between frames poses are linearly
        interpolated (slerp for rotations). ``autoplay`` starts playback on
        load; ``loop`` repeats forever (else ``repetitions`` times, default
        once, then holds the last frame). The viewer's "Animations" folder in
        the control panel (top right) has play/pause/reset and a time
        scrubber; without autoplay the page shows frame 0.

        ``tolerance=(metres, radians)`` keeps only the keyframes needed for the
        page's interpolation to pass within that distance of every frame's
        position and angle of its rotation (small pages for long runs); without
        it every frame where a pose changes is kept.

        Only one animation exists per scene: to move a robot and objects
        together merge the dicts, e.g. ``[{**robot.robot_frame(q), "cup": T}
        for q, T in ...]``. Static ``set_pose`` calls on animated objects are
        overridden while the animation plays."""
        frames = list(frames)
        if not frames:
            self.clear_animation()
            return
        if len(frames) == 1:
            frames = frames * 2          # a zero-length clip breaks three's looping
        n = len(frames)
        col: dict = {}                   # raw key -> column (names normalised once, not per frame)
        names: list[str] = []
        for fr in frames:
            for k in fr:
                if k not in col:
                    nk = _norm_name(k)
                    if nk not in names:
                        names.append(nk)
                    col[k] = names.index(nk)
        cur = [self._poses.get(nk, np.eye(4)) for nk in names]
        rows = np.empty((n, len(names), 4, 4))
        for i, fr in enumerate(frames):
            for k, v in fr.items():
                cur[col[k]] = v if isinstance(v, np.ndarray) and v.shape == (4, 4) else as_pose(v)
            if cur:
                rows[i] = cur
        # the few frames bounds() looks at (the camera fit), not every frame
        sample = sorted(set(range(0, n, max(1, n // 25))) | {n - 1})
        self._anim_frames = [dict(zip(names, rows[i])) for i in sample]
        changed = np.abs(np.diff(rows, axis=0)).max(axis=(2, 3)) > 1e-9 if n > 1 else np.zeros((0, len(names)), bool)
        animations = []
        moving = [j for j, name in enumerate(names)
                  if changed[:, j].any() or not np.allclose(rows[0, j], self._poses.get(name, np.eye(4)), atol=1e-9)]
        if tolerance is not None and moving:
            kept = _keyframes(rows[:, moving].transpose(1, 0, 2, 3), *tolerance)
        for c, j in enumerate(moving):     # names that never move have no track
            name, seq = names[j], rows[:, j]
            if tolerance is None:
                # keep the ends of every constant run (exact hold + interpolation)
                moves = changed[:, j]
                keep = np.zeros(n, bool)
                keep[[0, n - 1]] = True
                keep[1:] |= moves
                keep[:-1] |= moves
                idx = np.flatnonzero(keep)
            else:
                idx = kept[c]
            pos = seq[idx, :3, 3]
            quat = _quaternions(seq[idx, :3, :3])
            times = _f32(idx)
            animations.append({"path": _path(name), "clip": {"fps": fps, "name": "default", "tracks": [
                {"name": ".position", "type": "vector3", "times": times, "values": _f32(pos)},
                {"name": ".quaternion", "type": "quaternion", "times": times, "values": _f32(quat)}]}})
        if not animations:
            self.clear_animation()
            self._anim_frames = [dict(zip(names, rows[i])) for i in sample]
            return
        if loop:
            loop_mode, reps = _LOOP_REPEAT, float("inf")
        else:
            loop_mode, reps = _LOOP_ONCE, 1
        if repetitions is not None:
            loop_mode, reps = _LOOP_REPEAT, int(repetitions)
        data = {"type": "set_animation", "path": "", "animations": animations,
                "options": {"play": bool(autoplay), "repetitions": reps, "loopMode": loop_mode,
                            "clampWhenFinished": True}}
        self._send(data)
        self._has_animation = True

    def clear_animation(self) -> None:
        """Remove the animation (objects stay where the animation left them in
        a live viewer; a page shows the static poses)."""
        self._anim_frames = []
        if self._has_animation:
            self._has_animation = False
            self._send({"type": "set_animation", "path": "", "animations": [],
                        "options": {"play": False}})

    # --------------------------------------------------------------- output
    def commands(self) -> list[dict]:
        """The compacted meshcat command dicts (what the page replays)."""
        return self._window.log.commands()

    def packed_commands(self) -> list[bytes]:
        """The compacted commands, msgpack-encoded (single-precision floats)."""
        return self._window.log.packed()

    def camera_or_auto(self):
        """Explicit camera if set, else the automatic one (position, target)."""
        return self._camera if self._camera is not None else self._auto_camera()

    def html(self, title: str | None = None, *, controls: bool | None = None) -> str:
        """The self-contained HTML page as a string."""
        return _viewer.standalone_html(self.packed_commands(), title=title or self.title, labels=self.labels(),
                                       camera=self.camera_or_auto(),
                                       controls=self.controls if controls is None else controls)

    def write_html(self, path, title: str | None = None, *, controls: bool | None = None) -> _FsPath:
        """Write the page (UTF-8); returns the path. Opens from file:// with
        no network access."""
        p = _FsPath(path)
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(self.html(title, controls=controls), encoding="utf-8")
        return p

    # ----------------------------------------------------------------- live
    def live(self, zmq_url: str | None = None, *, open_browser: bool = False, host: str = "127.0.0.1",
             quiet: bool = False) -> str:
        """Mirror the scene into a live meshcat viewer and return its web URL.

        Starts a meshcat server (:mod:`.server`) listening on ``host`` only
        (ports from 7000/6000 upward; it stops with this process) unless
        ``zmq_url`` names a running one. meshcat's own stdout chatter is
        captured; the URL is printed to **stderr** (unless ``quiet``). The
        recorded state is replayed, later calls are forwarded as they happen
        (and still recorded for write_html)."""
        if self._live_window is not None:
            return self._live_window.web_url
        proc = None
        if zmq_url is None:
            from .server import start

            proc, zmq_url, _ = start(host)
        buf = io.StringIO()
        with contextlib.redirect_stdout(buf):
            from meshcat.visualizer import ViewerWindow
            win = ViewerWindow(zmq_url=zmq_url, start_server=False, server_args=[])
        self._live_proc = proc
        for cmd in self._window.log.commands():
            win.send(_Raw(cmd))
        for k, (text, _p, height) in self._labels.items():
            win.send(_Raw(_sprite(k, text, height)))
        self._live_window = win
        self._window.live = win
        if self._camera is not None:
            pos, tgt = self._camera
        else:  # the live orbit centre is the world origin: fit around it
            pos, tgt = self._auto_camera(center=(0.0, 0.0, 0.0))
        self._send_live_camera(pos, tgt)
        if not quiet:
            print(f"meshcat viewer: {win.web_url}", file=sys.stderr, flush=True)
        if open_browser:
            win.open()
        return win.web_url

    @property
    def url(self) -> str | None:
        return None if self._live_window is None else self._live_window.web_url

    def replace_live(self, other: "Scene") -> str:
        """Show this scene in ``other``'s live viewer instead of ``other`` (whose objects are deleted
        there); the server, if ``other`` started it, is handed over. Returns the viewer's URL."""
        other.clear()
        zmq_url, proc = other.detach()
        url = self.live(zmq_url, quiet=True)
        self._live_proc = proc
        return url

    def detach(self):
        """Stop mirroring into the live viewer and hand its server over (``(zmq_url, process)``: the
        process is None when this scene did not start it), e.g. to the next scene shown there."""
        win, self._live_window, self._window.live = self._live_window, None, None
        proc, self._live_proc = self._live_proc, None
        if win is None:
            return None, proc
        try:
            win.zmq_socket.close(linger=0)
        except Exception:
            pass
        return win.zmq_url, proc

    def close(self) -> None:
        """Detach the live viewer; stops the server if this scene started it."""
        win, self._live_window, self._window.live = self._live_window, None, None
        if win is not None:
            try:
                win.zmq_socket.close(linger=0)
            except Exception:
                pass
        proc, self._live_proc = self._live_proc, None
        if proc is not None and proc.poll() is None:
            proc.kill()
            proc.wait(timeout=10)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


#: aliases (the design notes used these names)
HtmlScene = Scene
SceneRecorder = Scene


def _stl_bbox(path):
    data = open(path, "rb").read()
    if len(data) >= 84:
        n = int(np.frombuffer(data[80:84], dtype="<u4")[0])
        if 84 + 50 * n == len(data):
            rec = np.frombuffer(data[84:], dtype=np.dtype([("n", "<f4", 3), ("v", "<f4", (3, 3)),
                                                            ("a", "<u2")]), count=n)
            return mesh_bbox(rec["v"].reshape(-1, 3))
    vals = [list(map(float, ln.split()[1:4])) for ln in data.decode("latin1").splitlines()
            if ln.strip().startswith("vertex")]
    return mesh_bbox(vals) if vals else None


def _obj_bbox(path):
    vals = []
    with open(path, encoding="latin1") as f:
        for ln in f:
            if ln.startswith("v "):
                vals.append([float(x) for x in ln.split()[1:4]])
    return mesh_bbox(vals) if vals else None


def _sprite(name, text, height) -> dict:
    """A live viewer's label: a camera-facing text sprite (always on top), cap height ~``height`` m."""
    font = 48
    sc = float(height) * 256.0 / font
    mat = _mg.GenericMaterial(map=_TextTexture(str(text), font_size=font), transparent=True, depthTest=False)
    mat._type = "SpriteMaterial"  # material fields SpriteMaterial doesn't know are ignored by three
    data = _Object(_mg.Box([1, 1, 1]), mat, matrix=np.diag([sc, sc, 1.0, 1.0]), kind="Sprite").lower()
    data["object"]["renderOrder"] = 10
    return {"type": "set_object", "path": _path(name), "object": data}


_SIMPLIFIED: dict = {}  # digest -> decimated (V, F): a page draws the same robot in every view


def _simplified(V, F, max_faces):
    import hashlib

    key = (hashlib.sha1(V.tobytes() + F.tobytes()).hexdigest(), max_faces)
    if key not in _SIMPLIFIED:
        _SIMPLIFIED[key] = simplify_mesh(V, F, max_faces)
    return _SIMPLIFIED[key]


def _f32(a):
    """A float32 array as msgpack's Float32Array extension (what meshcat's viewer decodes natively)."""
    return umsgpack.Ext(0x17, np.ascontiguousarray(a, dtype="<f4").tobytes())


def _quaternions(R):
    """(N,3,3) rotation matrices -> (N,4) unit quaternions, three.js order (x, y, z, w)."""
    R = np.asarray(R, dtype=np.float64)
    t = R[:, 0, 0] + R[:, 1, 1] + R[:, 2, 2]
    q = np.empty((len(R), 4))
    # Shepperd: divide by the largest of 4w^2, 4x^2, 4y^2, 4z^2 for accuracy
    d = np.stack([t, R[:, 0, 0], R[:, 1, 1], R[:, 2, 2]], axis=1)
    k = np.argmax(d, axis=1)
    for case in range(4):
        m = k == case
        if not m.any():
            continue
        r = R[m]
        if case == 0:
            s = 2.0 * np.sqrt(np.maximum(1.0 + t[m], 1e-300))
            q[m] = np.stack([(r[:, 2, 1] - r[:, 1, 2]) / s, (r[:, 0, 2] - r[:, 2, 0]) / s,
                             (r[:, 1, 0] - r[:, 0, 1]) / s, 0.25 * s], axis=1)
        else:
            i = case - 1
            j, kk = (i + 1) % 3, (i + 2) % 3
            s = 2.0 * np.sqrt(np.maximum(1.0 + r[:, i, i] - r[:, j, j] - r[:, kk, kk], 1e-300))
            v = np.empty((len(r), 4))
            v[:, i] = 0.25 * s
            v[:, j] = (r[:, j, i] + r[:, i, j]) / s
            v[:, kk] = (r[:, kk, i] + r[:, i, kk]) / s
            v[:, 3] = (r[:, kk, j] - r[:, j, kk]) / s
            q[m] = v
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    # one hemisphere along the sequence (three slerps the short way anyway; this keeps error checks simple)
    if len(q) > 1:
        flip = np.cumprod(np.where(np.sum(q[1:] * q[:-1], axis=1) < 0, -1.0, 1.0))
        q[1:] *= flip[:, None]
    return q


def _keyframes(seqs, tol_pos: float, tol_rot: float) -> list:
    """For each of the ``seqs`` (M,N,4,4: M tracks of N frames), the indices of the frames to keep
    so that interpolating between them (linear positions, slerp rotations, as three.js does) passes
    within ``tol_pos`` metres and ``tol_rot`` radians of every frame. Each round splits every span
    that strays at its worst frame (Douglas-Peucker, all spans of all tracks at once: the tracks
    are laid end to end with both ends of each kept)."""
    m, n = seqs.shape[:2]
    seq = seqs.reshape(m * n, 4, 4)
    P, Q = seq[:, :3, 3], _quaternions(seq[:, :3, :3])
    keep = np.zeros((m, n), bool)
    keep[:, [0, n - 1]] = True
    if n > 2:  # and where a track starts or stops moving: holds are exact, and far fewer rounds
        moves = np.abs(np.diff(seqs, axis=1)).max(axis=(2, 3)) > 1e-9
        keep[:, 1:-1] |= moves[:, :-1] != moves[:, 1:]
    keep = keep.reshape(-1)
    active = ~keep                    # frames in spans not yet known to be within the tolerance
    while True:
        k, f = np.flatnonzero(keep), np.flatnonzero(active)
        if not len(f):
            return [np.flatnonzero(row) for row in keep.reshape(m, n)]
        seg = np.searchsorted(k, f, side="right") - 1
        a, b = k[seg], k[seg + 1]
        u = ((f - a) / (b - a))[:, None]
        err_p = np.linalg.norm(P[f] - (P[a] + u * (P[b] - P[a])), axis=1) / tol_pos
        dot = np.sum(Q[a] * Q[b], axis=1)
        qb = Q[b] * np.where(dot < 0, -1.0, 1.0)[:, None]
        th = np.arccos(np.clip(np.abs(dot), 0.0, 1.0))[:, None]
        small = th < 1e-9
        sin_th = np.where(small, 1.0, np.sin(th))
        Qi = (np.where(small, 1 - u, np.sin((1 - u) * th) / sin_th) * Q[a]
              + np.where(small, u, np.sin(u * th) / sin_th) * qb)
        Qi /= np.linalg.norm(Qi, axis=1, keepdims=True)
        err_r = 2.0 * np.arccos(np.clip(np.abs(np.sum(Qi * Q[f], axis=1)), 0.0, 1.0)) / tol_rot
        err = np.maximum(err_p, err_r)
        # f is sorted, so each span's frames are one run of it: the worst frame of each run
        starts = np.flatnonzero(np.r_[True, seg[1:] != seg[:-1]])
        counts = np.diff(np.r_[starts, len(f)])
        top = np.maximum.reduceat(err, starts)
        split = top > 1.0
        at = np.flatnonzero(err == np.repeat(top, counts))
        first = at[np.r_[True, seg[at][1:] != seg[at][:-1]]]  # one frame per span
        keep[f[first[split]]] = True
        active[f] = np.repeat(split, counts)            # only the spans just split are looked at again
        active[keep] = False
