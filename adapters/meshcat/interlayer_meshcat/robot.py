"""Add a Pinocchio robot (its ``GeometryModel``) to a :class:`~.scene.Scene`
and turn configurations into animation frames.

Each geometry object becomes one scene object ``"<prefix>/<geometry name>"``
placed by ``pin.updateGeometryPlacements``; poses are relative to the group
``prefix`` (i.e. world poses unless you ``scene.set_pose(prefix, ...)``).

Meshes (coal ``BVHModel``/``Convex``) are exported from the already-loaded
coal geometry as indexed float32 triangles (pinocchio applied ``meshScale``
when it loaded them), so no mesh file is read again and DAE/STL/OBJ are
treated alike; ``max_faces`` decimates big meshes.
"""

from __future__ import annotations

import logging
import os
from typing import Iterable, Sequence

import numpy as np

from .meshes import coal_to_arrays
from .scene import Scene, _norm_name

__all__ = ["PinocchioRobot", "add_pinocchio_robot", "robot_frame"]

log = logging.getLogger(__name__)


class PinocchioRobot:
    """Handle returned by :func:`add_pinocchio_robot`."""

    def __init__(self, scene: Scene, prefix: str, model, geom_model, names: list):
        import pinocchio as pin

        self.scene = scene
        self.prefix = prefix
        self.model = model
        self.geom_model = geom_model
        #: scene name per geometry object (``None`` where skipped), same order
        #: as ``geom_model.geometryObjects``
        self.names = names
        self._pin = pin
        self._data = model.createData()
        self._gdata = geom_model.createData() if hasattr(geom_model, "createData") \
            else pin.GeometryData(geom_model)

    def robot_frame(self, q) -> dict[str, np.ndarray]:
        """``{scene name: 4x4 pose}`` of every geometry at configuration ``q``
        (pinocchio FK + ``updateGeometryPlacements``)."""
        q = np.asarray(q, dtype=np.float64)
        self._pin.updateGeometryPlacements(self.model, self._data, self.geom_model, self._gdata, q)
        # .homogeneous is a fresh array (no copy needed)
        return {n: M.homogeneous for n, M in zip(self.names, self._gdata.oMg) if n is not None}

    def frames(self, qs: Iterable) -> list[dict[str, np.ndarray]]:
        """One :meth:`robot_frame` per configuration (for ``Scene.animate``)."""
        return [self.robot_frame(q) for q in qs]

    def set_configuration(self, q) -> None:
        """Static pose of the robot (``scene.set_pose`` on every geometry)."""
        for name, T in self.robot_frame(q).items():
            self.scene.set_pose(name, T)

    def animate(self, qs: Sequence, fps: float = 10.0, **kwargs) -> None:
        """``scene.animate(self.frames(qs), fps, **kwargs)`` (replaces the scene's animation)."""
        self.scene.animate(self.frames(qs), fps=fps, **kwargs)


def robot_frame(robot: PinocchioRobot, q) -> dict[str, np.ndarray]:
    """Function form of :meth:`PinocchioRobot.robot_frame`."""
    return robot.robot_frame(q)


def _resolve_mesh(path: str, package_dirs: Sequence) -> str | None:
    if path and os.path.exists(path):
        return path
    if path.startswith("package://"):
        rel = path[len("package://"):]
        for d in package_dirs:
            cand = os.path.join(os.fspath(d), rel)
            if os.path.exists(cand):
                return cand
    return None


def add_pinocchio_robot(scene: Scene, prefix: str, model, geom_model, package_dirs: Sequence = (), *,
                        q=None, color=None, max_faces: int | None = None,
                        mesh_mode: str = "bvh") -> PinocchioRobot:
    """Add every object of ``geom_model`` (collision or visual model from
    ``pin.buildModelsFromUrdf``) below group ``prefix``; returns a
    :class:`PinocchioRobot`.

    * ``q``: initial configuration (default ``pin.neutral(model)``).
    * ``color``: override for all objects (default: each ``meshColor``).
    * ``max_faces``: decimate meshes above this many triangles.
    * ``mesh_mode``: ``"bvh"`` (default) exports coal's triangles;
      ``"file"`` embeds the mesh file itself (``meshPath``, ``package://``
      resolved against ``package_dirs``; STL/DAE/OBJ) with ``meshScale``.

    Handles coal Box, Sphere, Cylinder, Capsule, Cone, Ellipsoid, Convex and
    BVHModel; other types (Plane, Halfspace, OcTree, HeightField) are skipped
    with a log message.
    """
    import coal
    import pinocchio as pin

    prefix = _norm_name(prefix)
    names: list = []
    for go in geom_model.geometryObjects:
        g = go.geometry
        name = f"{prefix}/{go.name.replace('/', '_')}"
        rgba = color if color is not None else [float(c) for c in go.meshColor]
        try:
            if isinstance(g, coal.Box):
                scene.box(name, 2 * np.asarray(g.halfSide), None, rgba)
            elif isinstance(g, coal.Sphere):
                scene.sphere(name, g.radius, None, rgba)
            elif isinstance(g, coal.Capsule):
                scene.capsule(name, g.radius, 2 * g.halfLength, None, rgba)
            elif isinstance(g, coal.Cylinder):
                scene.cylinder(name, g.radius, 2 * g.halfLength, None, rgba)
            elif isinstance(g, coal.Cone):
                scene.cone(name, g.radius, 2 * g.halfLength, None, rgba)
            elif isinstance(g, coal.Ellipsoid):
                scene.ellipsoid(name, np.asarray(g.radii), None, rgba)
            elif isinstance(g, (coal.BVHModelBase, coal.ConvexBase)):
                path = _resolve_mesh(go.meshPath, package_dirs) if mesh_mode == "file" else None
                if path is not None and os.path.splitext(path)[1].lower() in (".stl", ".dae", ".obj"):
                    scene.mesh(name, path, None, np.asarray(go.meshScale), rgba, embed="file")
                else:
                    V, F = coal_to_arrays(g)
                    scene.triangles(name, V, F, None, rgba, max_faces=max_faces)
            else:
                log.info("interlayer_meshcat: skipping %s (%s)", go.name, type(g).__name__)
                names.append(None)
                continue
        except Exception as exc:  # one odd geometry must not kill the page
            log.warning("interlayer_meshcat: could not convert %s (%s): %s", go.name, type(g).__name__, exc)
            names.append(None)
            continue
        names.append(name)
    robot = PinocchioRobot(scene, prefix, model, geom_model, names)
    robot.set_configuration(pin.neutral(model) if q is None else q)
    return robot
