"""docs/plugins.md's tutorial plugin, built from the text of the page, installed by pip, solved."""
import importlib
import importlib.util
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "plugins.md"
FILE_BLOCK = re.compile(r"```(?:python|toml)\n# interlayer-sweep/(\S+)\n(.*?)```", re.S)


def tutorial_files() -> dict:
    return {path: body for path, body in FILE_BLOCK.findall(DOC.read_text())}


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    """The tutorial's package, written from the docs and installed with pip into its own folder."""
    files = tutorial_files()
    src = tmp_path_factory.mktemp("interlayer-sweep")
    for path, body in files.items():
        (src / path).parent.mkdir(parents=True, exist_ok=True)
        (src / path).write_text(body)
    site = tmp_path_factory.mktemp("site")
    isolation = [] if importlib.util.find_spec("setuptools") is None else ["--no-build-isolation"]
    pip = subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--no-deps", *isolation, "--target", str(site),
                          str(src)], capture_output=True, text=True, timeout=300)
    assert pip.returncode == 0, pip.stderr
    return src, site


def test_the_tutorial_has_every_file_it_lists():
    assert set(tutorial_files()) == {"pyproject.toml", "sweep.toml", *(f"interlayer_sweep/{m}.py" for m in (
        "__init__", "domain", "geometry", "generators", "draw", "plugin"))}


def test_the_tutorial_plugin_installs_solves_validates_and_draws(installed, tmp_path, monkeypatch):
    src, site = installed
    env = dict(os.environ, PYTHONPATH=str(site))
    out = tmp_path / "run"

    def cli(*args):
        proc = subprocess.run([sys.executable, "-m", "interlayer.cli", *args], capture_output=True, text=True,
                              env=env, timeout=300)
        return proc.returncode, proc.stdout, proc.stderr

    code, _, err = cli("plan", str(src / "sweep.toml"), "--out", str(out))
    assert code == 0, err
    assert "learned (Obstructs b2 cp_b1 b1)" in err  # the tutorial's point: a fact learned, a replan
    code, _, err = cli("validate", str(out))
    assert code == 0 and "trajectory re-checked by the domain" in err, err

    # The core's own planners (what an install of the core alone has) solve it too.
    code, _, err = cli("plan", str(src / "sweep.toml"), "--set", "planner.task=bfs", "--set", "planner.motion=interpolate",
                       "--out", str(tmp_path / "core"))
    assert code == 0 and "learned (Obstructs b2 cp_b1 b1)" in err, err

    # The drawing is the one the domain declared (found by declaration, not by package name).
    monkeypatch.syspath_prepend(str(site))
    importlib.invalidate_caches()
    from interlayer import api
    from interlayer.plugins import PluginHost
    from interlayer_meshcat.visualizer import Run, solution_scene

    host = PluginHost()
    assert host["domains"].get("sweep").drawing == "interlayer_sweep.draw"
    run = Run(out)
    assert run.problem is not None, run.problem_error
    scene, starts = solution_scene(run, run.trajectory)
    assert scene is not None and [s for s, _ in starts if s is not None] == [0, 1]
    problem = api.build_problem(host, api.resolve_config(out))
    assert problem.drawing == "interlayer_sweep.draw"
    for name in [n for n in sys.modules if n.startswith("interlayer_sweep")]:
        del sys.modules[name]
