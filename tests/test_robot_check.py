"""`interlayer robot check NAME_OR_FILE`: the core CLI asks the robot layer (hook interlayer_check_robot,
implemented by interlayer_pinocchio.plugin) and prints its report, or the error naming the field (exit 2)."""
import importlib
import importlib.metadata
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("pinocchio")

from interlayer.cli import main  # noqa: E402
from interlayer.plugins import ENTRY_POINT_GROUP  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
PANDA = ROOT / "adapters" / "pinocchio" / "interlayer_pinocchio" / "robots" / "panda.toml"


@pytest.fixture
def entry_point(tmp_path, monkeypatch):
    """The folder to put on the path so that the ``pinocchio`` entry point is installed (pyproject.toml
    declares it; a virtual environment installed before it was added does not know it yet)."""
    if any(ep.name == "pinocchio" for ep in importlib.metadata.entry_points(group=ENTRY_POINT_GROUP)):
        return None
    info = tmp_path / "site" / "interlayer_robot_layer-0.1.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: interlayer-robot-layer\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(f"[{ENTRY_POINT_GROUP}]\npinocchio = interlayer_pinocchio.plugin\n")
    monkeypatch.syspath_prepend(str(tmp_path / "site"))
    importlib.invalidate_caches()
    return tmp_path / "site"


def test_pyproject_declares_the_entry_point():
    assert 'pinocchio = "interlayer_pinocchio.plugin"' in (ROOT / "pyproject.toml").read_text()


def test_robot_check_reports_the_panda(entry_point, capsys):
    assert main(["robot", "check", "panda", "--json"]) == 0
    out, err = capsys.readouterr()
    report = json.loads(out)  # alone on stdout
    assert report["robot"] == "Panda" and report["base"] == "fixed" and report["dof"] == 9
    (arm,) = report["arms"]
    assert arm["joints"] == [f"panda_joint{i}" for i in range(1, 8)]
    assert (arm["tool_frame"], arm["approach"], arm["closing"]) == ("panda_hand_tcp", "+z", "y")
    assert arm["gripper"]["open"] == pytest.approx(0.08, abs=1e-3) and 0.8 < arm["reach"] < 1.2
    assert report["self_collision"]["source"] == "srdf" and report["self_collision"]["checked"] > 0
    assert main(["robot", "check", str(PANDA)]) == 0
    text = capsys.readouterr().out
    assert "tool_frame: panda_hand_tcp" in text and "approach: +z" in text and "base: fixed" in text
    assert "joints: panda_joint1, panda_joint2" in text and "\nheld: none\n" in text  # the Panda holds no joint


def test_robot_check_names_the_field_and_exits_2(entry_point, tmp_path):
    bad = tmp_path / "mine.toml"
    bad.write_text(PANDA.read_text().replace('tool_frame = "panda_hand_tcp"', 'tool_frame = "hand_tcp"'))
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(entry_point)] * (entry_point is not None) + [os.environ.get("PYTHONPATH", "")]))
    run = subprocess.run([sys.executable, "-m", "interlayer.cli", "robot", "check", str(bad), "--json"],
                         capture_output=True, text=True, env=env)
    assert run.returncode == 2, run.stderr
    reason = json.loads(run.stdout)["reason"]
    assert reason.startswith("mine.toml: arms[0].tool_frame: no frame 'hand_tcp' in the URDF (frames with 'hand': "), reason
    assert "panda_hand_tcp" in reason
    assert run.stderr.strip().splitlines() == [f"error: {reason}"]


def test_robot_check_without_the_robot_layer_says_so(monkeypatch, capsys):
    from interlayer import plugins

    monkeypatch.setattr(plugins.importlib.metadata, "entry_points", lambda group: [])  # nothing installed
    assert main(["robot", "check", "panda"]) == 2
    assert "no installed plugin checks robot descriptions" in capsys.readouterr().err
