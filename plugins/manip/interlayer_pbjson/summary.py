"""The scene and task summary ``interlayer check FILE`` prints for a pybullet-planning file."""
from __future__ import annotations

import math


def describe(geometry) -> str:
    """The summary in the file's names."""
    layout = geometry.layout
    extra = layout.extra
    labels, body_of = extra.get("labels", {}), extra.get("body_of", {})

    def show(*symbols):
        return ", ".join(labels.get(s, s) for s in symbols)

    bodies = sorted({show(body_of.get(o.name, o.name)) for o in layout.fixed + extra.get("floors", [])})
    lines = [f"{len(layout.objects) - len(extra.get('floor_handling', {}))} movable object(s), {len(bodies)} fixed bod{'y' if len(bodies) == 1 else 'ies'} "
             f"({len(layout.fixed)} collision shapes: {', '.join(bodies)})"]
    kinds = {}
    for s in geometry.surfaces.values():
        kinds.setdefault(s.kind, []).append(s)
    for kind, label in (("table", "tables"), ("region", "regions"), ("sink", "sinks"), ("stove", "stoves"), ("top", "object tops")):
        if kind in kinds:
            lines.append(f"  {label}: " + ", ".join(f"{show(s.name)} (z {s.z:.3f}" + (f", {len(s.polygon)}-gon" if kind == "region" else "")
                                                    + ")" for s in kinds[kind]))
    world = geometry.initial_world()
    floor = extra.get("floor_handling", {})
    for o in layout.objects:
        if o.name in floor:
            continue
        size = "x".join(f"{v:.3f}" for v in (o.size if o.shape == "box" else (2 * o.size[0], o.size[1])))
        on = show(*geometry.supports_of(o.name, world.objects[o.name], world)) or "nothing known"
        lines.append(f"  {show(o.name)}: {o.shape} {size} m at ({o.pose[0]:.3f}, {o.pose[1]:.3f}, {o.pose[2]:.3f}), "
                     f"yaw {math.degrees(o.pose[3]):.0f} deg, on {on}")
    stuck = extra.get("floor_fixed", [])
    if floor or stuck:
        lines.append(f"  floor obstacles ({len(floor) + len(stuck)}), moved only where a drive finds them in the way:")
    for name, how in floor.items():
        o = geometry.specs[name]
        size = "x".join(f"{v:.3f}" for v in (o.size if o.shape == "box" else (2 * o.size[0], o.size[1])))
        can = "pick (a grasp fits the gripper) or push with the base" if how == "pick" else \
            f"push with the base (no grasp fits the gripper's {geometry.robot.max_gripper_opening:.3f} m opening)"
        lines.append(f"    {show(name)}: {o.shape} {size} m at ({o.pose[0]:.3f}, {o.pose[1]:.3f}), "
                     f"yaw {math.degrees(o.pose[3]):.0f} deg: {can}")
    for name, wall, depth in stuck:
        lines.append(f"    {show(name)}: nothing (it stands {depth * 1000:.0f} mm inside {show(wall)}: kept fixed as part of it)")
    b = layout.base
    torso = extra.get("torso_conf")
    torso_note = "" if torso is None or abs(torso - extra["torso_height"]) < 1e-9 else f" (raised from {torso:.3f})"
    lines.append(f"Robot: PR2 base ({b[0]:.3f}, {b[1]:.3f}, {math.degrees(b[2]):.0f} deg), torso {extra['torso_height']:.3f} m"
                 f"{torso_note}, arms from robots[0].conf: " +
                 ", ".join(f"{a} [{' '.join(f'{v:.2f}' for v in geometry.start_arms[a])}]" for a in ("left", "right")))
    lines.append(f"Grasps: {', '.join(g.upper() for g in layout.grasps)}")
    g = geometry.goals
    goals = []
    if g["holding"]:  # as the file writes it, then the objects it names when that differs
        named = g["holding_as"] if isinstance(g["holding_as"], str) else " or ".join(g["holding_as"])
        goals.append(f"hold {named}" + ("" if show(*g["holding"]) == named else f" (any one of {show(*g['holding'])})"))
    goals += [f"{show(o)} on {show(s)}" + ("" if g["members"][o] == (o,) else f" (any one of {show(*g['members'][o])})")
              for o, s in g["on"].items()]
    goals += [f"{show(o)} stacked on {show(b)}" for o, b in g["stackings"].items()]
    goals += [f"{show(o)} at " + ("its initial pose" if isinstance(p, str) else f"{show(g['pose_of'][o])}'s initial pose"
                                  if o in g.get("pose_of", {}) else "({:.3f}, {:.3f}, {:.3f})".format(*p[:3, 3]))
              for o, p in g["poses"].items()]
    goals += [f"{show(o)} cleaned (put on a sink)" for o in g["cleaned"]]
    goals += [f"{show(o)} cooked (put on a stove once clean)" for o in g["cooked"]]
    if g["home"]:
        goals.append("the robot back at its start configuration")
    if g["base"]:
        goals.append("the robot's base at ({:.3f}, {:.3f}, {:.0f} deg)".format(*g["base"][:2], math.degrees(g["base"][2])))
    lines.append("Goals: " + "; ".join(goals))
    for note in extra.get("notes", []):
        lines.append(f"Note: {note}")
    from types import SimpleNamespace

    from interlayer_manip.grasps import stuck_sentence, stuck_together

    problem = SimpleNamespace(geometry=geometry)  # all that stuck_together reads of a problem
    members, walled, walls = stuck_together(problem, world, geometry.floor_objects)
    if set(members) - set(walled):  # what a pick of one of them proves (fixed obstacles alone: when it finds nothing)
        lines.append(f"Stuck: {stuck_sentence(problem, members, walls)}")
    return "\n".join(lines)

