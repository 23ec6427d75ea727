"""Timing and trajectory output of the manipulation geometry: segments, their TOPP-RA timing within
the limits (params.TIMING, overridden by the problem's keys), trajectory.json and its validation."""
from __future__ import annotations

import numpy as np

from .params import TIMING
from .state import FOLLOWS, wrap


class Output:
    def limits(self, group) -> tuple[np.ndarray, np.ndarray]:
        """(velocity, acceleration) limits per joint of ``group`` that trajectories respect."""
        timing = {**TIMING, **{k: v for k, v in self.layout.extra.items() if k in TIMING}}
        if group == "base":
            return np.array(timing["base_velocity"], float), np.array(timing["base_acceleration"], float)
        vmax = self.robot.velocity_limits(group)
        return vmax, np.full(len(vmax), float(timing["arm_acceleration"]))

    def _segment(self, kind, group, path, holding):
        """A motion segment; its points get their timing when the plan is written (``timed``)."""
        names = ["x", "y", "theta"] if group == "base" else list(self.robot.group(group).dof_names)
        points = [{"positions": [float(v) for v in p]} for p in path]
        segment = {"kind": kind, "group": group, "joint_names": names, "points": points, "holding": holding}
        if self._exporting:  # timed by the worker while the run goes on
            from interlayer_optim.timing import prefetch

            prefetch(*self._timing_args(segment))
        return segment

    def prepare_export(self):
        """The run's trajectory will be written: a worker process times segments as they are made."""
        from interlayer_optim.timing import start_worker

        start_worker()
        self._exporting = True

    def timed(self, segment) -> dict:
        """``segment`` with TOPP-RA timing: positions (densified to the planning resolution),
        velocities, accelerations and time_from_start within :meth:`limits`."""
        from interlayer_optim.timing import time_parameterize

        path, vmax, amax, step = self._timing_args(segment)
        with self.stats.timer("timing"):
            points = time_parameterize(path, vmax, amax, step=step)
        if segment["group"] == "base":
            for p in points:
                p["positions"][2] = wrap(p["positions"][2])
        return {**segment, "points": points}

    def _timing_args(self, segment):
        """What :meth:`timed` asks TOPP-RA: the path, the velocity and acceleration limits, the step."""
        group = segment["group"]
        space = self.base_space if group == "base" else self.arm_space[self.robot.arm_of(group)]
        path = [np.asarray(p["positions"], float) for p in segment["points"]]
        if group == "base":  # unwrap the heading, so that the timing follows the short way round
            raw, path = path, path[:1]
            for p in raw[1:]:
                path.append(path[-1] + space.difference(path[-1], p))
        vmax, amax = self.limits(group)
        extra = len(path[0]) - len(vmax)
        if extra > 0:  # a pull: the articulated body's joints follow the hand; the arm's limits bind
            vmax, amax = np.append(vmax, [FOLLOWS] * extra), np.append(amax, [FOLLOWS] * extra)
        return path, vmax, amax, space.resolution

    def trajectory_json(self, plan, outcomes) -> dict:
        return {"domain": "pr2", "frame": "world, metres / radians; base joints x, y, theta",
                "format": "per segment a trajectory_msgs/JointTrajectory (joint_names, points with positions and "
                          "time_from_start); gripper open/close, grasp (attach) and release (detach) events between",
                "initial": self.initial_world().to_json(),
                "steps": [{"action": s.action, "args": list(s.args),
                           "segments": [self.timed(seg) if "points" in seg else seg for seg in o.segments]}
                          for s, o in zip(plan, outcomes)]}

    def validate(self, plan, trajectory: dict) -> list[str]:
        from .validate import validate_trajectory

        return validate_trajectory(type(self)(self.layout, padding=0.0), plan, trajectory)
