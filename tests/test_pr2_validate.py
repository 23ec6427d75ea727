"""The pr2 validator rejects corrupted trajectories and names the step and the reason."""
import copy
import json
import shutil


from interlayer.api import validate

from test_pr2_plan import hold_run, place_run  # noqa: F401  (module-scoped fixtures: one solve each)


def _corrupt(out, tmp_path, edit):
    dst = tmp_path / "corrupt"
    shutil.copytree(out, dst)
    traj = json.loads((dst / "trajectory.json").read_text())
    edit(traj)
    (dst / "trajectory.json").write_text(json.dumps(traj))
    return validate(dst)


def _segments(traj, kind=None, group=None):
    for i, step in enumerate(traj["steps"]):
        for seg in step["segments"]:
            if (kind is None or seg["kind"] == kind) and (group is None or seg.get("group", "").endswith(group)):
                yield i, seg


def test_joint_past_its_limit(hold_run, tmp_path):
    def edit(traj):
        _, seg = next(_segments(traj, "transit", "arm"))
        bad = copy.deepcopy(seg["points"][-1])
        bad["positions"][3] = 0.5  # elbow flex: upper limit 0
        bad["time_from_start"] = seg["points"][0]["time_from_start"]
        seg["points"].insert(1, bad)

    errors = _corrupt(hold_run[1], tmp_path, edit)
    assert errors and "joint limit" in errors[0] and "elbow_flex" in errors[0], errors


def test_waypoint_inside_the_table(hold_run, tmp_path):
    def edit(traj):
        _, seg = next(_segments(traj, "base"))
        seg["points"].insert(1, {"positions": [0.85, 0.0, 0.0], "time_from_start": seg["points"][0]["time_from_start"]})

    errors = _corrupt(hold_run[1], tmp_path, edit)
    assert errors and "collision" in errors[0] and "table" in errors[0], errors


def test_teleported_object(place_run, tmp_path):
    def edit(traj):
        _, seg = next(_segments(traj, "release"))
        seg["pose"][0][3] += 0.2

    errors = _corrupt(place_run[1], tmp_path, edit)
    assert errors and "teleported" in errors[0] and "place" in errors[0], errors


def test_grasp_of_an_object_away_from_the_gripper(hold_run, tmp_path):
    def edit(traj):
        _, seg = next(_segments(traj, "grasp"))
        seg["grasp"][1][3] += 0.1

    errors = _corrupt(hold_run[1], tmp_path, edit)
    assert errors and "not at the gripper" in errors[0], errors


def test_teleported_robot(hold_run, tmp_path):
    def edit(traj):
        i, seg = list(_segments(traj, "transit", "arm"))[-1]
        for p in seg["points"]:
            p["positions"][0] += 0.3

    errors = _corrupt(hold_run[1], tmp_path, edit)
    assert errors and "teleport" in errors[0], errors


def test_goal_not_reached(hold_run, tmp_path):
    def edit(traj):
        for step in traj["steps"]:
            step["segments"] = [s for s in step["segments"] if s["kind"] != "grasp" or s["object"] != "target"]

    errors = _corrupt(hold_run[1], tmp_path, edit)
    assert errors, errors


def test_a_gripper_opened_narrower_than_the_object(hold_run, place_run, tmp_path):
    def narrow_open(traj):
        _, seg = next(_segments(traj, "gripper"))
        assert seg["command"] == "open" and "width" in seg  # opened only as wide as the grasp needs
        seg["width"] = 0.02

    errors = _corrupt(hold_run[1], tmp_path / "open", narrow_open)  # the approaching fingers run into the object
    assert errors and "(approach): collision" in errors[0] and "finger_tip_link-blocker" in errors[0], errors

    def narrow_release(traj):
        _, seg = next(_segments(traj, "release"))
        seg["width"] = 0.02

    errors = _corrupt(place_run[1], tmp_path / "release", narrow_release)
    assert errors and "does not let go" in errors[0], errors
