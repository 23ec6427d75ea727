"""Problem keys that every manipulation domain accepts: the trajectory timing limits (TOPP-RA). Light:
the domains' plugin modules import it when plugins are discovered."""
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
