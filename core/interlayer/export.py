"""Hand a solved run's trajectory to a robot stack (``interlayer export``): a ROS 2 bag of
``trajectory_msgs/msg/JointTrajectory`` messages, or CSV.

Exported are the segments of ``trajectory.json`` shaped like a JointTrajectory (``joint_names`` and
``points`` with ``positions`` and ``time_from_start``); gripper and attach events are not joint
trajectories. Segments run end to end: each starts on the plan's clock where the previous one ended.
"""
from __future__ import annotations

import csv
from pathlib import Path

from .errors import UserError

FORMATS = ("rosbag2", "csv")
TOPIC = "/interlayer/joint_trajectory"
MSGTYPE = "trajectory_msgs/msg/JointTrajectory"


def joint_segments(trajectory: dict) -> list[dict]:
    """Every JointTrajectory-shaped segment, in order, with its step, action and start on the plan's clock;
    points as floats (positions, velocities and accelerations lists, time_from_start)."""
    out, start = [], 0.0
    for i, step in enumerate(trajectory.get("steps", [])):
        for seg in step.get("segments", []):
            if not seg.get("joint_names") or not seg.get("points"):
                continue
            names = [str(n) for n in seg["joint_names"]]
            points = [{"time_from_start": float(p["time_from_start"]),
                       **{key: _floats(p.get(key), len(names), key) for key in ("positions", "velocities", "accelerations")}}
                      for p in seg["points"]]
            if not all(p["positions"] for p in points):
                raise ValueError("a point has no positions")
            out.append({"step": i, "action": step.get("action", ""), "start": start, "joint_names": names, "points": points})
            start += points[-1]["time_from_start"]
    return out


def _floats(values, n: int, key: str) -> list[float]:
    """One number per joint, or [] when the point leaves ``key`` out."""
    values = [float(v) for v in values or ()]
    if values and len(values) != n:
        raise ValueError(f"a point has {len(values)} {key} for {n} joint names")
    return values


def export(out_dir, fmt: str, path) -> dict:
    """Write the run in ``out_dir`` as ``fmt`` to ``path``; returns what was written."""
    from .api import read_trajectory

    if fmt not in FORMATS:
        raise UserError(f"Unknown export format '{fmt}'; choose one of: {', '.join(FORMATS)}.")
    trajectory = read_trajectory(out_dir)
    try:
        segments = joint_segments(trajectory)
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        raise UserError(f"The trajectory.json of {out_dir} is damaged ({type(exc).__name__}: {exc}); "
                        f"write the run again with 'interlayer plan --out'.") from None
    if not segments:
        raise UserError(f"The trajectory of {out_dir} has no joint trajectories (segments with joint_names and timed "
                        f"points): the domain '{trajectory.get('domain', '?')}' writes none, so there is nothing to export.")
    path = Path(path)
    (write_rosbag2 if fmt == "rosbag2" else write_csv)(segments, path)
    return {"format": fmt, "path": str(path), "segments": len(segments), "points": sum(len(s["points"]) for s in segments)}


def _nanoseconds(seconds: float) -> int:
    return round(float(seconds) * 1e9)


def write_rosbag2(segments: list[dict], path: Path) -> None:
    """A ROS 2 bag (folder, sqlite3 storage): one JointTrajectory message per segment on TOPIC, its bag
    time the segment's start; the header stamp is zero (a controller starts it on receipt)."""
    try:
        import numpy as np
        from rosbags.rosbag2 import Writer
        from rosbags.typesys import Stores, get_typestore
    except ImportError:
        raise UserError("Writing a ROS 2 bag needs the rosbags library: pip install \"interlayer[export]\".") from None
    if path.exists():
        raise UserError(f"{path} exists already; a bag is a new folder: remove it or give another -o.")
    store = get_typestore(Stores.ROS2_HUMBLE)
    types = store.types
    msg, point = types[MSGTYPE], types["trajectory_msgs/msg/JointTrajectoryPoint"]
    header, stamp, duration = (types["std_msgs/msg/Header"], types["builtin_interfaces/msg/Time"],
                               types["builtin_interfaces/msg/Duration"])

    def values(p, key):
        return np.asarray(p[key], dtype=np.float64)

    try:
        with Writer(path, version=8) as writer:
            connection = writer.add_connection(TOPIC, MSGTYPE, typestore=store)
            for seg in segments:
                points = [point(positions=values(p, "positions"), velocities=values(p, "velocities"),
                                accelerations=values(p, "accelerations"), effort=np.zeros(0),
                                time_from_start=duration(*divmod(_nanoseconds(p["time_from_start"]), 10**9)))
                          for p in seg["points"]]
                data = msg(header=header(stamp=stamp(sec=0, nanosec=0), frame_id=""),
                           joint_names=seg["joint_names"], points=points)
                writer.write(connection, _nanoseconds(seg["start"]), store.serialize_cdr(data, MSGTYPE))
    except OSError as exc:
        raise UserError(f"Cannot write the bag {path}: {exc.strerror or exc}.") from None


def write_csv(segments: list[dict], path: Path) -> None:
    """One row per point: segment, step, action, time_from_start, time (on the plan's clock), then a
    column per joint (empty where the segment does not move that joint)."""
    joints = list(dict.fromkeys(j for seg in segments for j in seg["joint_names"]))
    try:
        with open(path, "w", newline="") as f:
            out = csv.writer(f)
            out.writerow(["segment", "step", "action", "time_from_start", "time", *joints])
            for k, seg in enumerate(segments):
                for p in seg["points"]:
                    row = dict(zip(seg["joint_names"], p["positions"]))
                    t = p["time_from_start"]
                    out.writerow([k, seg["step"], seg["action"], repr(t), repr(seg["start"] + t),
                                  *(repr(row[j]) if j in row else "" for j in joints)])
    except OSError as exc:
        raise UserError(f"Cannot write {path}: {exc.strerror or exc}.") from None
