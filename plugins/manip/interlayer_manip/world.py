"""The manipulation geometry: the refinement runtime of the manipulation domains (interlayer.refine.Geometry).

World state: base (x, y, theta), both arm vectors, gripper states, resting object poses (4x4),
held objects per arm with their grasp (tool_T_object), and the put-down spot (tloc) chosen by the
move_base that precedes a place (state.py). One robot + CollisionWorld per geometry, synced lazily
to the world being refined (here); motion queries (queries.py), IK and grasp helpers (reach.py), the
pick / place / move_base refiners (refiners.py), articulated bodies and pulls (articulated.py) and the
timed trajectory output (timing.py) are mixins of ManipulationGeometry. Arm motions are planned in
the joint space of the arm (continuous joints bounded to [-pi, pi]), base motions in SE(2) with the
arms in their driving posture.

Every action returns its arm to a driving posture: tucked when empty, a carry posture (the hand
raised beside the shoulder) when holding, so that move_base never sweeps an outstretched arm.
"""
from __future__ import annotations

import math
from contextlib import contextmanager

import numpy as np

from interlayer.motion import ConfigSpace, InterpolatingPlanner
from interlayer.refine import ROBOT_MOVED
from interlayer.trace import Stats

from .articulated import Articulated
from .queries import MotionQueries
from .reach import Reach
from .refiners import Refiners
from .scene import Layout, base_limits
from .state import LINE_PADDING, OPEN_CLEARANCE, PADDING, RES_ARM, RES_BASE, World, is_open, pose4
from .timing import Output


class ManipulationGeometry(MotionQueries, Reach, Refiners, Articulated, Output):
    """Refinement runtime of the manipulation domains: the world model and its collision sync here; motion
    queries, IK and grasps, the refiners, articulated bodies and the trajectory output in the mixins."""

    def __init__(self, layout: Layout, padding: float = PADDING, robot=None):
        from interlayer_pinocchio import describe

        self.layout = layout
        self.padding = padding
        # the robot: problem.robot (a shipped name or a description's path), unless the domain built it
        self.robot = robot or load_robot(describe(layout.extra.get("robot", "pr2")), layout.extra)
        self.cw = self._collision_world(padding)
        self._tight = None  # [collision world, synced world, its q] of ``tight``, built when first needed
        self.specs = {o.name: o for o in layout.objects}
        self.fixed = {o.name for o in layout.fixed}
        self.approach = InterpolatingPlanner(name="interpolate")
        self.cartesian = None  # planner.cartesian, set by the run: the approach and retreat lines' planner
        self.stats = Stats()
        self.refs = {}  # reference name -> (skolem, args): filled by make_problem
        self.bodies = {}  # articulated environment bodies (interlayer_pinocchio.ArticulatedBody): add_body
        self._initial_joints, self._initial_riders = {}, {}
        self._synced = None
        self._tight_depth = 0  # nesting of ``tight`` blocks
        self._exporting = False  # prepare_export: segments are timed as they are made
        lo, hi = base_limits(layout)
        self.base_space = ConfigSpace("se2", (lo[0], hi[0], -math.pi), (lo[1], hi[1], math.pi), (False, False, True), RES_BASE)
        # Arm spaces: the continuous forearm / wrist roll joints are treated as bounded to [-pi, pi]
        # without wrap-around, so that every interpolation agrees: OMPL's (a RealVectorStateSpace
        # interpolates linearly), the core's densify (validator, straight lines) and a controller
        # reading trajectory.json (linear in joint values).
        self.arm_space = {}
        for arm in self.robot.arms:
            g = self.robot.group(f"{arm}_arm")
            self.arm_space[arm] = ConfigSpace("vector", tuple(g.lower), tuple(g.upper), (False,) * g.dof, RES_ARM)

    def _collision_world(self, padding):
        """The layout's bodies in a new CollisionWorld, fixed boxes grown by ``padding``."""
        from interlayer_pinocchio import CollisionWorld

        cw, layout = CollisionWorld(self.robot), self.layout
        for o in layout.fixed + layout.objects:
            T = pose4(*o.pose)
            if o.shape == "box":
                size = o.size
                if not o.movable and padding:  # fixed obstacles grow by `padding` (supports not upwards:
                    # objects rest on them and are put down onto them)
                    up = 0 if o.name in layout.extra.get("supports", ("table",)) else 2 * padding
                    size = (size[0] + 2 * padding, size[1] + 2 * padding, size[2] + up)
                cw.add_box(o.name, size, T, movable=o.movable)
            else:
                cw.add_cylinder(o.name, o.size[0], o.size[1], T, movable=o.movable)
        return cw

    @property
    def line_padding(self) -> float:
        """How far from fixed obstacles the checks inside ``tight`` keep."""
        return self.padding if self.bodies or self.padding <= LINE_PADDING else LINE_PADDING

    @contextmanager
    def tight(self):
        """Inside, every check (IK, lines, hand, states) sees the fixed obstacles padded by LINE_PADDING,
        not ``padding``: for the straight tool lines of grasps and put-downs and the configurations they
        end at (see state.py). A second collision world, synced to the world checked like the first; none
        when articulated bodies are added (their links keep the full padding). Do not yield inside it."""
        if self.line_padding == self.padding or self._tight_depth:
            self._tight_depth += 1
            try:
                yield
            finally:
                self._tight_depth -= 1
            return
        if self._tight is None:
            self._tight = [self._collision_world(LINE_PADDING), None, None]
        outer = [self.cw, self._synced, getattr(self, "_synced_q", None)]
        self.cw, self._synced, self._synced_q = self._tight
        self._tight_depth = 1
        try:
            yield
        finally:
            self._tight_depth = 0
            self._tight[:] = self.cw, self._synced, self._synced_q
            self.cw, self._synced, self._synced_q = outer

    def scene_issues(self) -> list:
        """Interpenetrating, floating and buried objects at their initial poses (see sanity.py)."""
        from .sanity import scene_issues

        return scene_issues(self.layout.fixed, self.layout.objects, self.layout.extra.get("floors", ()),
                            self._initial_riders)

    def initial_world(self) -> World:
        arms = self.robot.arms
        return World(tuple(self.layout.base), {a: tuple(self.robot.home(a)) for a in arms}, {a: "closed" for a in arms},
                     {o.name: pose4(*o.pose) for o in self.layout.objects}, {},
                     joints=dict(self._initial_joints), riders=dict(self._initial_riders))

    def snapshot(self, world: World) -> dict:
        return world.to_json()

    def moved(self, before: World, after: World) -> set:
        """Objects whose pose differs between two worlds (picked up or put down in between; a put-down
        within IK's tolerance of the same pose is the same place: another grasp's put-down at a goal pose),
        articulated bodies whose joints do, and ``ROBOT_MOVED`` if the robot's base, arms or grippers do."""
        a, b = before.objects, after.objects
        out = {o for o in a.keys() | b.keys() if o not in a or o not in b or not same_place(a[o], b[o])}
        a, b = before.joints, after.joints
        out |= {o for o in a.keys() | b.keys() if o not in a or o not in b or not np.array_equal(a[o], b[o])}
        if (not np.array_equal(before.base, after.base) or before.grippers != after.grippers
                or any(not np.array_equal(before.arms[a], after.arms[a]) for a in before.arms)):
            out.add(ROBOT_MOVED)
        return out

    def config(self, world: World) -> np.ndarray:
        r = self.robot
        q = r.default_q(world.base)
        for arm in r.arms:
            r.group(f"{arm}_arm").write(q, world.arms[arm])  # in place: this runs at every sync
            g = world.grippers[arm]
            if g == "open":
                q = r.open_gripper(q, arm)
            elif is_open(g):
                q = r.set_gripper_opening(q, arm, g[1])
            elif not isinstance(world.grippers[arm], str):  # closed around something that is no object (a handle)
                q = r.set_gripper_opening(q, arm, float(world.grippers[arm]))
            elif arm in world.held:
                q = r.set_gripper_opening(q, arm, max(0.0, self.grasp_width(world.held[arm][0], world.held[arm][1])))
            else:
                q = r.close_gripper(q, arm)
        return q

    def grasp_width(self, name, G) -> float:
        """The object's extent along the tool's closing (y) axis for grasp G (tool_T_object)."""
        o = self.specs[name]
        if o.shape == "cylinder":
            return 2 * o.size[0]
        y_in_obj = np.linalg.inv(G)[:3, :3] @ np.array([0.0, 1.0, 0.0])
        return float(sum(abs(y_in_obj[i]) * o.size[i] for i in range(3)))

    def opening(self, name, G):
        """The gripper state for grasping or letting go of ``name`` with grasp G (tool_T_object): open as
        wide as the object is across the fingers plus OPEN_CLEARANCE (fully, if that is wider), so that
        the fingers fit beside it where a fully opened hand would not."""
        width = self.grasp_width(name, G) + OPEN_CLEARANCE
        return "open" if width >= self.robot.max_gripper_opening else ("open", width)

    def grasp_opening(self, world, arm, name, grasp):
        """The opening for grasping ``name`` (resting in ``world``) with the arm at vector ``grasp``."""
        T = self.robot.tool_pose(self.config(world.with_arm(arm, grasp)), arm)
        return self.opening(name, np.linalg.inv(T) @ world.objects[name])

    def object_pose(self, world: World, name, q=None) -> np.ndarray:
        arm = world.holder(name)
        if arm is None:
            return world.objects[name]
        q = self.config(world) if q is None else q
        return self.robot.tool_pose(q, arm) @ world.held[arm][1]

    def sync(self, world: World) -> np.ndarray:
        """Make the collision world match ``world``; returns its configuration."""
        last = self._synced
        if world is last:
            return self._synced_q.copy()
        if last is not None and world.arms is last.arms and world.grippers is last.grippers and world.held is last.held:
            q = self._synced_q.copy()  # only the base moved (replace(world, base=...)): base samplers do this a lot
            self.robot.group("base").write(q, world.base)
        else:
            q = self.config(world)
        self._synced_q = q.copy()
        if world.joints is not (last.joints if last is not None else None):
            for name, values in world.joints.items():
                self.bodies[name].update(self.cw, values)
        if last is not None and world.objects is last.objects and world.held is last.held:
            # the same resting objects and grasps (World.with_arm / with_gripper / replace(base=...)
            # share these dicts): nothing in the collision world changes
            self._synced = world
            return q
        cw = self.cw
        want = {o: (a, G) for a, (o, G) in world.held.items()}
        for att in cw.held():
            w = want.get(att.name)
            if w is None or w[0] != att.arm or not np.allclose(w[1], att.tool_T_object, atol=1e-9):
                cw.detach(att.name, q)
        attached = {att.name for att in cw.held()}
        for name, T in world.objects.items():
            if name not in want:
                cw.set_pose(name, T)
        for name, (arm, G) in want.items():
            if name not in attached:
                cw.set_pose(name, self.robot.tool_pose(q, arm) @ G)
                cw.attach(name, arm, q)
        self._synced = world
        return q


# IK's tolerance (interlayer_pinocchio.solve_ik: 1 mm, 1 degree), twice: object poses closer than this are one place
SAME_PLACE = (0.002, 0.035)


def same_place(P, Q) -> bool:
    """Poses P and Q within IK's tolerance of each other (SAME_PLACE): an arm that reached a put-down leaves the
    object that close to it."""
    return P is Q or (np.allclose(P[:3, 3], Q[:3, 3], rtol=0, atol=SAME_PLACE[0])
                      and np.allclose(P[:3, :3], Q[:3, :3], rtol=0, atol=SAME_PLACE[1]))


def load_robot(desc, extra: dict):
    """The robot of ``desc`` as a layout's ``extra`` sets it up: its base limits and torso height (if it has a torso)."""
    from interlayer_pinocchio import Robot

    from .scene import BASE_LIMITS

    torso = extra.get("torso_height", 0.2) if desc.torso else None
    return Robot(desc, torso_height=torso, base_limits=extra.get("base_limits", BASE_LIMITS))
