"""docs/robots.md ("Bring your own robot"): the worked example's description, written from the page's text, passes
`interlayer robot check`; the page documents every key the description reader knows and every shipped robot."""
import re
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("pinocchio")

from test_robot_check import entry_point  # noqa: E402,F401  (the robot layer's entry point, as that test installs it)

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "robots.md"
FILE_BLOCK = re.compile(r"```toml\n# my-robot/(\S+)\n(.*?)```", re.S)


def page_files(folder: Path) -> dict:
    files = {name: body for name, body in FILE_BLOCK.findall(DOC.read_text())}
    for name, body in files.items():
        (folder / name).write_text(body)
    return files


def cli(*args, site=None):
    import os

    env = dict(os.environ)
    if site is not None:
        env["PYTHONPATH"] = os.pathsep.join([str(site), env.get("PYTHONPATH", "")])
    proc = subprocess.run([sys.executable, "-m", "interlayer.cli", *args], capture_output=True, text=True, env=env,
                          timeout=900)
    return proc.returncode, proc.stdout, proc.stderr


@pytest.mark.slow  # the Kinova's self-collision pairs are sampled on its first load (about a minute)
def test_the_worked_example_passes_robot_check(tmp_path, entry_point):  # noqa: F811
    assert set(page_files(tmp_path)) == {"kinova.toml"}
    import json

    code, out, err = cli("robot", "check", str(tmp_path / "kinova.toml"), "--json", site=entry_point)
    assert code == 0, err
    report = json.loads(out)
    assert report["robot"] == "kinova" and report["base"] == "fixed" and report["dof"] == 8  # six arm joints, two fingers
    (arm,) = report["arms"]
    assert arm["tool_frame"] == "j2s6s200_end_effector" and arm["approach"] == "+x"
    assert arm["gripper"]["measured"] and arm["gripper"]["open"] == pytest.approx(0.122, abs=0.002)  # as the page says
    assert arm["gripper"]["closed"] < 0  # the fingers the URDF fixes close
    assert arm["gripper"]["fixed_in_urdf"] == ["j2s6s200_joint_finger_1", "j2s6s200_joint_finger_2"]
    assert report["self_collision"]["source"] == "sampled"


def test_every_key_of_the_description_is_documented():
    reader = (ROOT / "adapters" / "pinocchio" / "interlayer_pinocchio" / "description.py").read_text()
    known = set()
    for group in re.findall(r"r\.keys\([^{]*\{([^}]*)\}", reader):
        known |= set(re.findall(r'"(\w+)"', group))
    known -= {"gripper"}  # the [arms.gripper] table, documented as a section
    documented = set(re.findall(r"^\| `(\w+)` \|", DOC.read_text(), re.M))
    assert known and known <= documented, sorted(known - documented)


def test_the_page_lists_every_shipped_robot():
    from interlayer_pinocchio import shipped_robots

    table = DOC.read_text().split("## Shipped robots", 1)[1].split("\n## ", 1)[0]
    assert set(re.findall(r"^\| `(\w+)` \|", table, re.M)) == set(shipped_robots())


@pytest.mark.slow  # as above: the first load samples the self-collision pairs
def test_the_worked_example_plans_clutter15(tmp_path):
    """Done-when of issue 21: a robot that is not shipped, described by following this page, runs Clutter-15 with
    no Python: solved and validated (seed 1 timed out before its home angle was wrapped and its grasps seated)."""
    from interlayer import api

    page_files(tmp_path)
    result = api.solve(str(ROOT / "examples" / "clutter.toml"),
                       [f"problem.robot={tmp_path / 'kinova.toml'}", "problem.objects=15", "planner.seed=1",
                        "planner.time_limit=600"])
    assert result.status == "solved", result.reason
    api.write_outputs(result, tmp_path / "out")
    assert api.validate(tmp_path / "out") == []
    assert [s.action for s in result.plan][-1] == "pick" and result.problem.geometry.robot.description.name == "kinova"
