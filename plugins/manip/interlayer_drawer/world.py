"""The Drawer domain's refinement runtime: the PR2 geometry plus the cabinet (an articulated body whose
drawer is a prismatic joint) and the open_drawer refinement (drive is a separate move_base).

open_drawer's candidate waypoints (see generators.open_drawer): (approach, pull, retreat), where
approach runs from the pre-handle pose to the handle, pull holds arm vectors with the drawer's joint
value appended, and retreat backs the open gripper off the handle. The refinement plans the transit
to the pre-handle pose, opens the gripper, approaches, closes it around the bar (HANDLE_GRIP wide),
pulls (every state checked with the drawer and what rides in it moving), opens the gripper, retreats
and tucks the arm.
"""
from __future__ import annotations

from dataclasses import replace


from interlayer.refine import Failure, StepOutcome
from interlayer_manip.state import PADDING, _failure, _holding
from interlayer_manip.world import ManipulationGeometry

from .scene import cabinet_placement, cabinet_urdf

CABINET, DRAWER_LINK, HANDLE_LINK = "cabinet", "drawer", "handle"
HANDLE_GRIP = 0.03  # m between the finger pads around the 2 cm handle bar


class DrawerGeometry(ManipulationGeometry):
    def __init__(self, layout, padding: float = PADDING, robot=None):
        from interlayer_pinocchio import ArticulatedBody

        super().__init__(layout, padding=padding, robot=robot)
        body = ArticulatedBody(CABINET, cabinet_urdf(), cabinet_placement())
        self.add_body(body, body.zero(), riders=[("inner", DRAWER_LINK)], exact_links=(DRAWER_LINK, HANDLE_LINK))  # the drawer carries objects: no padding

    @property
    def cabinet(self):
        return self.bodies[CABINET]

    def refine_step(self, step, world, candidate, motion) -> StepOutcome:
        if step.action != "open_drawer":
            return super().refine_step(step, world, candidate, motion)
        acc = [0.0]
        try:
            return self._open_drawer(step, world, candidate, motion, acc)
        finally:
            self.stats.add_time("collision_checking", acc[0])

    def _open_drawer(self, step, world, cand, motion, acc):
        arm = step.args[1]
        approach, pull, retreat = cand.waypoints
        group, segs, w = f"{arm}_arm", [], world
        blockers = self.sweep_blockers(w, CABINET, pull[-1][7:])
        if blockers:
            return StepOutcome(False, failure=Failure("obstruction", tuple(sorted(blockers)),
                                                      "pull: the drawer runs into " + ", ".join(sorted(blockers))))
        res = self._plan(motion, self.arm_query(w, arm, w.arms[arm], approach[0], "handle transit", acc), "transit",
                         group, segs, _holding(w), w, acc)
        if not res.ok:
            return _failure(res, "handle transit")
        w, stuck = self.set_gripper(w.with_arm(arm, approach[0]), arm, "open", segs,
                                    "opening the gripper before the handle")
        if stuck:
            return stuck
        res = self._line(w, arm, approach, "approach", segs, acc)
        if not res.ok:
            return _failure(res, "handle approach")
        w, stuck = self.set_gripper(w.with_arm(arm, approach[-1]), arm, HANDLE_GRIP, segs,
                                    "closing the gripper around the handle")
        if stuck:
            return stuck
        out = self.pull(step, w, arm, CABINET, HANDLE_LINK, pull, segs)
        if not out.ok:
            return out
        w = out.world
        segs.append({"kind": "articulation", "body": CABINET, "joint_names": list(self.cabinet.joint_names),
                     "positions": list(w.joints[CABINET])})
        w = w.with_gripper(arm, "open")
        segs.append({"kind": "gripper", "arm": arm, "command": "open"})
        out = self.retreat_and_tuck(motion, w, arm, group, retreat, "handle", segs, acc)
        return replace(out, world=replace(out.world, tloc={})) if out.ok else out

    def describe(self) -> str:
        """The scene's (O)/(N) property, checked on a fine grid (``interlayer check``)."""
        from .check import check_property

        exact = self if not self.padding else type(self)(self.layout, padding=0.0)
        return check_property(exact).summary()

    def trajectory_json(self, plan, outcomes) -> dict:
        out = super().trajectory_json(plan, outcomes)
        out["domain"] = "pr2-drawer"
        out["articulated"] = {name: {"joint_names": list(b.joint_names), "lower": b.lower.tolist(),
                                     "upper": b.upper.tolist()} for name, b in self.bodies.items()}
        out["format"] += ("; a pull segment moves an arm together with an articulated body's joints "
                          "(joint_names \"<body>/<joint>\"), an articulation event gives the body's joint values after it")
        return out

    def draw_scene(self, scene, world=None):
        from interlayer_manip import draw

        names = draw.draw_scene(self, scene, world)
        scene.view_direction = (0.15, -1.0, 0.85)  # from the cabinet's side: the drawer slides across the view
        names["top_drawer"] = f"bodies/{CABINET}/{DRAWER_LINK}"  # open_drawer's object: the drawer itself
        return names

    def animation_frames(self, scene, trajectory):
        from interlayer_manip import draw

        return draw.animation_frames(self, scene, trajectory)


__all__ = ["DrawerGeometry", "Failure"]
