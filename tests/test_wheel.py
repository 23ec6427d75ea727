"""The distributions as a user installs them: built wheels, examples and benchmark suites inside the packages.

The slow tests build each distribution's wheel once, install them with their dependencies into fresh
virtual environments (through pip, as a user would, at requirements.lock's versions): everything
(interlayer[all]) for the README's tour in a folder outside the checkout, and the core alone for the
tutorial's plugin. .ci/run runs them as a step of its own."""
import json
import os
import sqlite3
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from interlayer import api, shipped
from interlayer.bench.suite import find_suite
from interlayer.errors import UserError

ROOT = Path(__file__).resolve().parents[1]


def test_shipped_names_resolve_to_the_examples_and_suites(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # no examples/ or benchmarks/ here
    example = ROOT / "examples" / "gripper2d.toml"
    for name in ("gripper2d", "gripper2d.toml", "examples/gripper2d.toml"):
        assert api.resolve_config(name) == api.resolve_config(example)
    assert find_suite("gripper2d").read_text() == (ROOT / "benchmarks" / "gripper2d.toml").read_text()
    assert shipped.names("examples") == sorted(p.stem for p in (ROOT / "examples").glob("*.toml"))
    with pytest.raises(UserError, match="No such file or folder: nope; the shipped examples are clutter, dinner"):
        api.resolve_config("nope")
    with pytest.raises(UserError, match=r"No such file or folder: elsewhere/gripper2d.toml\.$"):
        api.resolve_config("elsewhere/gripper2d.toml")  # a path elsewhere is not a shipped name


def test_a_plugin_distributions_examples_and_suites_are_found_in_its_package(tmp_path, monkeypatch):
    """An installed plugin distribution's examples/ and benchmarks/ (package data, here of a package other than
    the plugin's module) are shipped names, from any folder."""
    import importlib

    site = tmp_path / "site"
    package = site / "il_shelf_data"
    for kind, text in (("examples", "[problem]\ndomain = \"gripper2d\"\n"), ("benchmarks", "name = \"il-suite\"\n")):
        (package / kind).mkdir(parents=True)
        (package / kind / f"il_{kind}.toml").write_text(text)
    (package / "__init__.py").write_text("")
    (site / "il_shelf_data-0.1.dist-info").mkdir()
    (site / "il_shelf_data-0.1.dist-info" / "METADATA").write_text("Metadata-Version: 2.1\nName: il-shelf-data\nVersion: 0.1\n")
    (site / "il_shelf_data-0.1.dist-info" / "entry_points.txt").write_text("[interlayer.plugins]\nil_shelf = il_shelf.plugin\n")
    (site / "il_shelf_data-0.1.dist-info" / "RECORD").write_text(  # the files a wheel installed: data of another package
        "il_shelf_data/__init__.py,,\nil_shelf_data/examples/il_examples.toml,,\nil_shelf_data/benchmarks/il_benchmarks.toml,,\n")
    monkeypatch.syspath_prepend(str(site))
    importlib.invalidate_caches()
    monkeypatch.chdir(tmp_path)
    assert shipped.find("examples", "il_examples") == package / "examples" / "il_examples.toml"
    assert "il_examples" in shipped.names("examples") and "gripper2d" in shipped.names("examples")
    assert api.resolve_config("examples/il_examples.toml")["problem"]["domain"] == "gripper2d"
    assert find_suite("il_benchmarks") == package / "benchmarks" / "il_benchmarks.toml"


def _run(args, **kw):
    proc = subprocess.run(args, capture_output=True, text=True, **kw)
    assert proc.returncode == 0, f"{' '.join(map(str, args))} exited {proc.returncode}:\n{proc.stderr[-3000:]}"
    return proc


FOLDERS = sorted(p.parent for p in [ROOT / "core" / "pyproject.toml", *ROOT.glob("adapters/*/pyproject.toml"),
                                     *ROOT.glob("plugins/*/pyproject.toml")])


@pytest.fixture(scope="module")
def wheels(tmp_path_factory):
    """Each distribution's wheel, built once (not editable: what a user installs)."""
    dist = tmp_path_factory.mktemp("wheels")
    _run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(dist), *map(str, FOLDERS)])
    return dist


def _venv(path, *requirements, cwd=None):
    _run([sys.executable, "-m", "venv", str(path)])
    _run([str(path / "bin" / "pip"), "install", "-q", "-c", str(ROOT / "requirements.lock"), *requirements], cwd=cwd)
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}  # nothing from the checkout
    return lambda *args, cwd=cwd: _run([str(path / "bin" / args[0]), *args[1:]], cwd=cwd, env=env)


@pytest.mark.slow
def test_the_wheels_carry_the_tour(wheels, tmp_path):
    """interlayer[all] from the built wheels: every plugin under its own distribution, the README's tour from any folder."""
    from interlayer.config import load_toml

    built = {w.name.split("-")[0].replace("_", "-") for w in wheels.glob("*.whl")}
    projects = [load_toml(folder / "pyproject.toml")["project"] for folder in FOLDERS]
    assert built == {p["name"] for p in projects} and len(built) == 9
    for package, owner in (("interlayer_gripper2d", "interlayer_gripper2d"), ("interlayer_manip", "interlayer_manip")):
        names = zipfile.ZipFile(next(wheels.glob(f"{package}-*.whl"))).namelist()
        assert f"{owner}/examples/" in "".join(names) and f"{owner}/benchmarks/" in "".join(names)
    user = tmp_path / "user"
    user.mkdir()
    run = _venv(tmp_path / "venv", "--find-links", str(wheels), "interlayer[all]", cwd=user)
    where = run("python", "-c", "import interlayer, interlayer_manip; print(interlayer.__file__, interlayer_manip.__file__)")
    assert all(p.startswith(str(tmp_path / "venv")) for p in where.stdout.split())
    assert run("interlayer", "--version").stdout.strip() == f"interlayer {_version()}"
    listed = json.loads(run("interlayer", "plugins", "--json").stdout)
    owners = {name: p["name"] for p in projects for name in p.get("entry-points", {}).get("interlayer.plugins", {})}
    assert {p["name"]: p["distribution"] for p in listed["plugins"]} == owners and not listed["broken"]
    assert {p["version"] for p in listed["plugins"]} == {_version()}
    run("interlayer", "plan", "examples/gripper2d.toml", "-q", "--out", "g")  # the README's first command, no examples/ here
    assert json.loads((user / "g" / "result.json").read_text())["status"] == "solved"
    run("interlayer", "plan", "pr2_pick", "-q", "--out", "pr2")
    assert json.loads((user / "pr2" / "result.json").read_text())["status"] == "solved"
    summary = json.loads(run("interlayer", "bench", "--suite", "gripper2d", "--quick", "--db", "g.sqlite", "--json").stdout)
    assert summary["statuses"] == {"solved": 4}
    with sqlite3.connect(user / "g.sqlite") as db:
        assert db.execute("select count(*) from runs where status = 'solved'").fetchone() == (4,)


@pytest.mark.slow
def test_the_core_wheel_alone_brings_numpy_and_pluggy_and_solves_the_tutorial(wheels, tmp_path):
    """docs/plugins.md's tutorial plugin on the core alone, with the core's bfs and interpolating planners."""
    from test_tutorial import tutorial_files

    run = _venv(tmp_path / "venv", str(next(wheels.glob("interlayer-*.whl"))), cwd=tmp_path)
    installed = {p["name"] for p in json.loads(run("pip", "list", "--format", "json").stdout)}
    assert installed - {"pip", "setuptools", "wheel"} == {"interlayer", "numpy", "pluggy"}
    src = tmp_path / "interlayer-sweep"
    for path, body in tutorial_files().items():
        (src / path).parent.mkdir(parents=True, exist_ok=True)
        (src / path).write_text(body)
    run("pip", "install", "-q", str(src))
    assert {p["name"] for p in json.loads(run("pip", "list", "--format", "json").stdout)} - installed == {"interlayer-sweep"}
    plan = run("interlayer", "plan", str(src / "sweep.toml"), "--set", "planner.task=bfs", "--set",
               "planner.motion=interpolate", "--out", "run")
    assert "learned (Obstructs b2 cp_b1 b1)" in plan.stderr
    assert json.loads((tmp_path / "run" / "result.json").read_text())["status"] == "solved"
    run("interlayer", "validate", "run")


def _version():
    from interlayer import __version__

    return __version__


def test_an_installed_copy_records_no_commit_of_a_repository_around_it(tmp_path):
    """A package installed inside some other git repository (a venv in a project) is no checkout of ours."""
    import shutil

    git = ["git", "-c", "user.name=t", "-c", "user.email=t@t", "-C", str(tmp_path)]
    _run([*git[:5], "init", "-q", str(tmp_path)])
    _run([*git, "commit", "-q", "--allow-empty", "-m", "theirs"])
    site = tmp_path / "venv" / "lib" / "python3" / "site-packages"
    shutil.copytree(ROOT / "core" / "interlayer", site / "interlayer", ignore=shutil.ignore_patterns("__pycache__"))
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env["PYTHONPATH"] = str(site)
    code = "from interlayer.bench.worker import _git_commit; print(repr(_git_commit()))"
    assert _run([sys.executable, "-c", code], env=env, cwd=tmp_path).stdout.strip() == "''"
    if (ROOT / ".git").exists():  # from the checkout: its own commit
        assert _run([sys.executable, "-c", code], cwd=ROOT).stdout.strip() != "''"
