"""Problem keys that every manipulation domain accepts: the trajectory timing limits (TOPP-RA) and the
robot (``problem.robot``), with small helpers the domains share. Light: the domains' plugin modules
import it when plugins are discovered."""
import math

# Arm joints at most their URDF velocity limits; the domains accept these keys too.
TIMING = {"arm_acceleration": 1.5,  # rad/s^2, every arm joint
          "base_velocity": [0.5, 0.5, 1.0],  # m/s, m/s, rad/s (x, y, theta; the URDF gives none)
          "base_acceleration": [0.5, 0.5, 1.0]}  # m/s^2, m/s^2, rad/s^2


def timing(params):
    """The timing keys, checked: positive numbers (three for the base: x, y, theta)."""
    from interlayer.errors import UserError

    out = {}
    for key, n in (("arm_acceleration", 1), ("base_velocity", 3), ("base_acceleration", 3)):
        value = params.get(key, TIMING[key])
        items = value if n > 1 and isinstance(value, list) else [value]
        if len(items) != n or any(isinstance(v, bool) or not isinstance(v, (int, float)) or not 0 < v < math.inf
                                  for v in items):
            what = "a positive number" if n == 1 else "a list of three positive numbers (x, y, theta)"
            raise UserError(f"problem.{key} must be {what}, got {value!r}.")
        out[key] = value
    return out


def robot_for(params, domain: str, two_arms: bool = False, mobile: bool = False):
    """The robot description that ``problem.robot`` names (a shipped robot or a description's path;
    default "pr2"), refused in one sentence when it lacks what ``domain`` needs (two arms, a mobile base)."""
    from interlayer.errors import UserError
    from interlayer_pinocchio import describe

    name = params.get("robot", "pr2")
    if not isinstance(name, str) or not name.strip():
        raise UserError(f"problem.robot must be a shipped robot's name or the path of a robot description (.toml), "
                        f"got {name!r}.")
    try:
        desc = describe(name)
    except UserError as exc:
        raise UserError(f"problem.robot: {str(exc).rstrip('.')}.") from None
    if two_arms and len(desc.arms) < 2:
        raise UserError(f"The {domain} domain needs a robot with two arms, and the {desc.name} has "
                        f"{len(desc.arms)}; choose another problem.robot (e.g. \"pr2\").")
    if mobile and not desc.mobile:
        raise UserError(f"The {domain} domain needs a robot with a mobile base, and the {desc.name}'s base is fixed; "
                        f"choose another problem.robot (e.g. \"pr2\").")
    return desc


def held_by_some_arm(obj: str, arms) -> str:
    """The goal "some arm holds ``obj``" over the robot's ``arms``."""
    atoms = [f"(Holding {obj} {a})" for a in arms]
    return atoms[0] if len(atoms) == 1 else f"(or {' '.join(atoms)})"


def fixed_placement(desc, edge: float, x: float, top: float, height: float, kind: str) -> tuple[float, float]:
    """(x, reach): where a fixed-base robot stands (its base facing +x) in front of a table whose near
    edge is at ``edge``, with the object at ``x`` (``height`` above the top) within its reach for
    grasps of ``kind`` (side: 0.1 m inside the far end, where an arm reaching into a cubby goes in
    nearly straight; top: in the middle), never closer to the edge than its footprint; and how far it
    reaches there."""
    from .placement import EDGE_GAP, reach_band

    near, far = reach_band(desc, desc.arms[0].name, top, height, kind)
    return min(edge - EDGE_GAP, x - (far - 0.1 if kind == "side" else (near + far) / 2)), far
