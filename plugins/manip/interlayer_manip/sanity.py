"""Scene sanity of a PR2 layout at its initial poses: objects that interpenetrate (an error: no plan
can start there), float above every support or lie below the ground. ``ManipulationGeometry.scene_issues``
serves it to ``interlayer check`` and ``plan``; every domain built on a Layout gets it."""
from __future__ import annotations

import math

import numpy as np

PENETRATION = 0.005  # m: deeper than a file's rounding of a resting contact
FLOATING = 0.01  # m: a gap under an object larger than this (the rest gap is 2 mm)
SAME = 0.001  # m: two objects whose boxes agree this closely fill the same place
PLURAL = {"box": "boxes", "cylinder": "cylinders"}


def _extents(o) -> tuple:
    """(half x, half y, half z) of the axis-aligned box around a spec (boxes turned by their yaw)."""
    if o.shape == "cylinder":
        r, h = o.size
        return r, r, h / 2
    c, s = abs(math.cos(o.pose[3])), abs(math.sin(o.pose[3]))
    sx, sy, sz = o.size
    return (c * sx + s * sy) / 2, (s * sx + c * sy) / 2, sz / 2


def _coal(o):
    import coal

    geometry = coal.Cylinder(*o.size) if o.shape == "cylinder" else coal.Box(*o.size)
    c, s = math.cos(o.pose[3]), math.sin(o.pose[3])
    rotation = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return geometry, coal.Transform3s(rotation, np.array(o.pose[:3], float))


def _overlapping_pairs(boxes: np.ndarray, movable: np.ndarray) -> list:
    """Index pairs (i < j, at least one movable) whose boxes overlap: a sweep along x."""
    order = np.argsort(boxes[:, 0], kind="stable")
    pairs, active = [], []
    for i in order:
        lo = boxes[i, 0]
        active = [j for j in active if boxes[j, 1] > lo]
        for j in active:
            if (movable[i] or movable[j]) and np.all(boxes[i, 2::2] < boxes[j, 3::2]) and np.all(boxes[j, 2::2] < boxes[i, 3::2]):
                pairs.append((min(i, j), max(i, j)))
        active.append(i)
    return pairs


def _boxes(specs) -> np.ndarray:
    """Rows (xmin, xmax, ymin, ymax, zmin, zmax) of the axis-aligned boxes around ``specs``."""
    centre = np.array([o.pose[:3] for o in specs], float)
    half = np.array([_extents(o) for o in specs], float)
    return np.stack([centre[:, 0] - half[:, 0], centre[:, 0] + half[:, 0], centre[:, 1] - half[:, 1],
                     centre[:, 1] + half[:, 1], centre[:, 2] - half[:, 2], centre[:, 2] + half[:, 2]], axis=1)


def penetrations(specs, movable, boxes=None) -> list:
    """(i, j, depth in m) of the pairs of ``specs`` (at least one ``movable``) whose shapes overlap."""
    import coal

    boxes = _boxes(specs) if boxes is None else boxes
    request = coal.DistanceRequest()
    shapes, out = {}, []
    for i, j in _overlapping_pairs(boxes, np.asarray(movable)):
        a, b = (shapes.setdefault(k, _coal(specs[k])) for k in (i, j))
        out.append((i, j, -coal.distance(a[0], a[1], b[0], b[1], request, coal.DistanceResult())))
    return out


def _tops(support) -> tuple:
    """(xy minima, xy maxima, top z) of the boxes around the ``support`` specs."""
    centre = np.array([o.pose[:3] for o in support], float)
    half = np.array([_extents(o) for o in support], float)
    return centre[:, :2] - half[:, :2], centre[:, :2] + half[:, :2], centre[:, 2] + half[:, 2]


def _under(tops, box, skip=None):
    """The index of the highest support (of :func:`_tops`) under the box (a row of :func:`_boxes`): its
    footprint overlaps the box's and its top is not above the box's bottom. None if there is none."""
    lo, hi, top = tops
    under = np.all(lo < box[[1, 3]], axis=1) & np.all(hi > box[[0, 2]], axis=1) & (top <= box[4] + PENETRATION)
    if skip is not None:
        under[skip] = False
    return int(np.argmax(np.where(under, top, -np.inf))) if under.any() else None


def resting_on(fixed, objects) -> set:
    """The names of the ``fixed`` specs some of ``objects`` stand on (the highest shape under an object, its
    top at most FLOATING below the object's bottom): supports, whether or not a file names them as surfaces."""
    if not fixed or not objects:
        return set()
    tops, boxes = _tops(fixed), _boxes(objects)
    found = (_under(tops, box) for box in boxes)
    return {fixed[i].name for i, box in zip(found, boxes) if i is not None and box[4] - tops[2][i] <= FLOATING}


def scene_issues(fixed, objects, floors=(), riders=()) -> list[tuple[str, str]]:
    """[("error" | "warning", sentence)]: interpenetrating pairs (a movable with a movable or a fixed
    shape) and objects under the ground are errors; floating objects warnings. ``floors`` support
    but are not obstacles; ``riders`` rest on articulated bodies (not in the layout) and are not
    checked for support."""
    specs = [*fixed, *objects]
    if not objects:
        return []
    boxes = _boxes(specs)
    movable = np.array([False] * len(fixed) + [True] * len(objects))
    issues, stuck = [], set()  # stuck: objects in another one (their support is not the question)
    for i, j, depth in penetrations(specs, movable, boxes):
        if depth > PENETRATION:
            stuck |= {i, j}
            first, second = (specs[j], specs[i]) if movable[j] and not movable[i] else (specs[i], specs[j])
            what = "the fixed body" if not movable[i] or not movable[j] else "the object"
            if movable[i] and movable[j] and np.allclose(boxes[i], boxes[j], rtol=0.0, atol=SAME):
                c = first.pose
                issues.append(("error", f"The objects {first.name} and {second.name} fill the same place: two "
                                        f"{PLURAL.get(first.shape, 'shapes')} of one size at one pose, centred at ({c[0]:.3f}, {c[1]:.3f}, "
                                        f"{c[2]:.3f}); two solid objects cannot start in one place, so delete one of "
                                        f"them or move it apart."))
                continue
            issues.append(("error", f"The object {first.name} and {what} {second.name} interpenetrate by "
                                    f"{depth * 1000:.0f} mm at their initial poses; move one of them apart."))
    # supports: every other shape (and the floors) whose top is not above the object's bottom
    support = [*specs, *floors]
    tops = _tops(support)
    riding = set(riders)
    for k, o in enumerate(objects, start=len(fixed)):
        if o.name in riding or k in stuck:
            continue
        bottom = boxes[k, 4]
        best = _under(tops, boxes[k], skip=k)
        if best is not None:
            top, below = tops[2][best], support[best].name
        elif bottom >= -PENETRATION:
            top, below = 0.0, "the ground (z = 0)"
        else:
            issues.append(("error", f"The object {o.name} lies {-bottom:.3f} m below the ground (z = 0) with nothing "
                                    f"under it; raise it onto a support."))
            continue
        if bottom - top > FLOATING:
            issues.append(("warning", f"The object {o.name} floats {bottom - top:.3f} m above {below}, the nearest "
                                      f"support under it; lower it onto a support."))
    return issues
