"""interlayer export: a solved run's joint trajectories as a ROS 2 bag (read back with the same
library) and as CSV, and one-sentence errors for what cannot be exported."""
import csv
import json
from pathlib import Path

import pytest

from interlayer.cli import main

ROOT = Path(__file__).resolve().parents[1]
CUBBY = str(ROOT / "examples" / "pr2_pick.toml")


@pytest.fixture(scope="module")
def cubby_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("cubby") / "run"
    assert main(["plan", CUBBY, "-q", "--out", str(out)]) == 0
    return out


def _segments(run):
    """trajectory.json's JointTrajectory-shaped segments, in order."""
    return _segments_of(json.loads((run / "trajectory.json").read_text()))


def _segments_of(trajectory):
    return [seg for step in trajectory["steps"] for seg in step["segments"] if seg.get("joint_names")]


def _ns(seconds):
    return round(seconds * 1e9)


def test_rosbag2_export_reads_back_as_the_trajectory(cubby_run, tmp_path, capsys):
    pytest.importorskip("rosbags", reason="the rosbags library (extra 'export') is not installed")
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore

    bag = tmp_path / "bag"
    assert main(["export", str(cubby_run), "--format", "rosbag2", "-o", str(bag), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    expected = _segments(cubby_run)
    assert summary["segments"] == len(expected) > 0 and summary["format"] == "rosbag2"
    store = get_typestore(Stores.ROS2_HUMBLE)
    with Reader(bag) as reader:
        assert [c.msgtype for c in reader.connections] == ["trajectory_msgs/msg/JointTrajectory"]
        messages = [(t, store.deserialize_cdr(raw, c.msgtype)) for c, t, raw in reader.messages()]
    assert len(messages) == len(expected)
    start = 0.0
    for (stamp, msg), seg in zip(messages, expected):
        assert msg.joint_names == seg["joint_names"]
        assert stamp == _ns(start)  # segments end to end on the plan's clock
        assert [p.time_from_start.sec * 10**9 + p.time_from_start.nanosec for p in msg.points] == \
            [_ns(p["time_from_start"]) for p in seg["points"]]
        assert [p.positions.tolist() for p in msg.points] == [p["positions"] for p in seg["points"]]
        assert [p.velocities.tolist() for p in msg.points] == [p["velocities"] for p in seg["points"]]
        start += seg["points"][-1]["time_from_start"]


def test_csv_export_has_one_row_per_point(cubby_run, tmp_path):
    path = tmp_path / "plan.csv"
    assert main(["export", str(cubby_run), "--format", "csv", "-o", str(path)]) == 0
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    expected = _segments(cubby_run)
    assert len(rows) == sum(len(seg["points"]) for seg in expected)
    i, start = 0, 0.0
    for k, seg in enumerate(expected):
        for p in seg["points"]:
            row = rows[i]
            assert int(row["segment"]) == k and float(row["time_from_start"]) == p["time_from_start"]
            assert float(row["time"]) == start + p["time_from_start"]
            assert [float(row[j]) for j in seg["joint_names"]] == p["positions"]
            assert all(row[j] == "" for j in row if j not in seg["joint_names"] and j not in
                       ("segment", "step", "action", "time_from_start", "time"))
            i += 1
        start += seg["points"][-1]["time_from_start"]


def test_export_errors_are_one_sentence(cubby_run, tmp_path, capsys):
    unsolved = tmp_path / "unsolved"
    assert main(["plan", CUBBY, "-q", "--set", "problem.target_radius=0.05", "--out", str(unsolved)]) == 1
    capsys.readouterr()
    cases = [(unsolved, "did not solve its problem (status unsolvable)"),
             (tmp_path / "nowhere", "No such folder"),
             (tmp_path, "has no result.json")]
    for folder, says in cases:
        assert main(["export", str(folder), "--format", "csv", "-o", str(tmp_path / "x.csv")]) == 2
        err = capsys.readouterr().err
        assert says in err and "Traceback" not in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "x.csv").exists()


@pytest.mark.parametrize("damage", [lambda p: p.pop("time_from_start"), lambda p: p["positions"].pop(),
                                    lambda p: p.update(positions=None), lambda p: p.update(velocities="fast")],
                         ids=["no time", "a position short", "no positions", "velocities not numbers"])
def test_a_damaged_trajectory_is_named(cubby_run, tmp_path, capsys, damage):
    import shutil

    run = tmp_path / "run"
    shutil.copytree(cubby_run, run)
    trajectory = json.loads((run / "trajectory.json").read_text())
    damage(_segments_of(trajectory)[-1]["points"][-1])
    (run / "trajectory.json").write_text(json.dumps(trajectory))
    assert main(["export", str(run), "--format", "csv", "-o", str(tmp_path / "x.csv")]) == 2
    err = capsys.readouterr().err
    assert "trajectory.json of" in err and "is damaged" in err and len(err.strip().splitlines()) == 1


def test_gripper2d_paths_are_not_joint_trajectories(gripper_example, tmp_path, capsys):
    run = tmp_path / "g"
    assert main(["plan", gripper_example, "-q", "--out", str(run)]) == 0
    capsys.readouterr()
    assert main(["export", str(run), "--format", "csv", "-o", str(tmp_path / "g.csv")]) == 2
    assert "has no joint trajectories" in capsys.readouterr().err


def test_missing_rosbags_names_the_extra(cubby_run, tmp_path, capsys, monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "rosbags", None)  # as if not installed: importing it raises ImportError
    monkeypatch.setitem(sys.modules, "rosbags.rosbag2", None)
    assert main(["export", str(cubby_run), "--format", "rosbag2", "-o", str(tmp_path / "bag")]) == 2
    assert 'pip install "interlayer[export]"' in capsys.readouterr().err
    assert not (tmp_path / "bag").exists()
