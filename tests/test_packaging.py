"""One distribution per layer (issue 24): each folder's pyproject.toml, the workspace that installs them
all for development, the lock CI installs from, and the plugin-API check of plugin discovery."""
import tomllib
from pathlib import Path

import pytest

from interlayer import __version__
from interlayer.apiversion import API_VERSION, admits, core_specifier, mismatch
from interlayer.plugins import PluginHost

ROOT = Path(__file__).resolve().parents[1]
DISTRIBUTIONS = sorted(p.parent for p in [ROOT / "core" / "pyproject.toml", *ROOT.glob("adapters/*/pyproject.toml"),
                                          *ROOT.glob("plugins/*/pyproject.toml")])
NEXT = f"{API_VERSION.split('.')[0]}.{int(API_VERSION.split('.')[1]) + 1}"


def _project(folder: Path) -> dict:
    return tomllib.loads((folder / "pyproject.toml").read_text())


def _name(requirement: str) -> str:
    from packaging.requirements import Requirement

    return Requirement(requirement).name


def test_the_distributions_partition_the_workspace():
    """The workspace's editable install holds exactly the distributions' packages and entry points."""
    root = _project(ROOT)
    packages, entry_points, names = [], {}, []
    for folder in DISTRIBUTIONS:
        config = _project(folder)
        names.append(config["project"]["name"])
        for package in config["tool"]["hatch"]["build"]["targets"]["wheel"]["packages"]:
            assert (folder / package / "__init__.py").is_file(), f"{folder.name}: no package {package}"
            packages.append(str((folder / package).relative_to(ROOT)))
        for name, value in config["project"].get("entry-points", {}).get("interlayer.plugins", {}).items():
            assert name not in entry_points, f"two distributions register the plugin {name}"
            entry_points[name] = value
    assert len(names) == 9 and "interlayer" in names
    assert sorted(packages) == sorted(root["tool"]["hatch"]["build"]["targets"]["wheel"]["packages"])
    assert entry_points == root["project"]["entry-points"]["interlayer.plugins"]
    assert sorted(Path(p).name for p in packages) == sorted(root["tool"]["importlinter"]["root_packages"])
    core_all = _project(ROOT / "core")["project"]["optional-dependencies"]["all"]
    assert sorted(n for n in names if n != "interlayer") == sorted(_name(r) for r in core_all if _name(r) != "interlayer")


def test_the_workspace_declares_the_distributions_requirements():
    """Its dependencies are the union of theirs (first-party ones aside), range for range."""
    root = _project(ROOT)["project"]
    third_party = set()
    extras = {}
    for folder in DISTRIBUTIONS:
        project = _project(folder)["project"]
        third_party |= {r for r in project["dependencies"] if not _name(r).startswith("interlayer")}
        for extra, reqs in project.get("optional-dependencies", {}).items():
            extras.setdefault(extra, set()).update(r for r in reqs if not _name(r).startswith("interlayer"))
    assert set(root["dependencies"]) == third_party
    for extra, reqs in extras.items():
        if extra != "all":
            assert set(root["optional-dependencies"][extra]) == reqs, extra


def test_every_distribution_but_the_core_is_made_for_this_plugin_api():
    for folder in DISTRIBUTIONS:
        project = _project(folder)["project"]
        assert project.get("version", __version__) == __version__, folder
        if project["name"] != "interlayer":
            assert core_specifier(project["dependencies"]) == f">={API_VERSION},<{NEXT}", project["name"]


def test_the_lock_pins_every_requirement_within_its_range():
    from packaging.requirements import Requirement

    lock = {}
    for line in (ROOT / "requirements.lock").read_text().splitlines():
        if line and not line.startswith("#"):
            name, _, version = line.partition("==")
            lock[Requirement(name).name.lower().replace("_", "-")] = version
    root = _project(ROOT)["project"]
    required = [*root["dependencies"], *(r for extra in ("bench", "export", "test") for r in root["optional-dependencies"][extra])]
    for text in required:
        req = Requirement(text)
        if req.name.startswith("interlayer"):
            continue
        version = lock.get(req.name.lower().replace("_", "-"))
        assert version is not None, f"requirements.lock has no {req.name}"
        assert req.specifier.contains(version), f"requirements.lock pins {req.name}=={version}, outside {req.specifier}"


@pytest.mark.parametrize("specifier, version, expected", [
    (">=0.2,<0.3", "0.2.0", True), (">=0.2,<0.3", "0.2.7", True), (">=0.2,<0.3", "0.3.0", False),
    (">=0.2,<0.3", "0.1.9", False), ("~=0.2.1", "0.2.5", True), ("~=0.2.1", "0.3.0", False), ("~=0.2.1", "0.2.0", False),
    ("==0.2.*", "0.2.4", True), ("==0.2.*", "0.20.0", False), ("!=0.2.1", "0.2.1", False), ("<=0.2", "0.2.0", True),
    (">0.2", "0.2.0", False), ("", "0.2.0", True), (">=banana", "0.2.0", True),  # unreadable: not held against it
])
def test_the_specifiers_a_plugin_writes(specifier, version, expected):
    assert admits(specifier, version) is expected


def test_the_requirement_on_the_core_is_found_among_a_distributions():
    assert core_specifier(["numpy>=2.1,<3", "interlayer>=0.2,<0.3"]) == ">=0.2,<0.3"
    assert core_specifier(["Interlayer (>=0.2, <0.3)"]) == ">=0.2, <0.3"
    assert core_specifier(["interlayer-up>=0.2", 'interlayer[bench]>=0.9; extra == "bench"']) is None
    assert core_specifier(["interlayer"]) == ""
    assert mismatch("interlayer-sweep", "1.0", ["interlayer"]) == ""


def test_a_plugin_made_for_another_core_is_skipped_with_one_line(tmp_path, monkeypatch, capsys):
    """Discovery reads the plugin distribution's requirement on interlayer from its metadata and skips a
    plugin that is not made for the running core, naming the versions and the fix; the others load."""
    import importlib

    from conftest import write_plugin
    from interlayer.cli import main

    source = """
        from interlayer import hookimpl

        @hookimpl
        def interlayer_register_motion_planners(registry):
            registry.add("{name}:line", "interlayer.motion:InterpolatingPlanner")
    """
    site = tmp_path / "site"
    write_plugin(site, "il_future", source.format(name="future"), requires=(f"interlayer>={NEXT},<9", "numpy>=2"))
    write_plugin(site, "il_current", source.format(name="current"), requires=(f"interlayer>={API_VERSION},<{NEXT}",))
    write_plugin(site, "il_extra", source.format(name="extra"), requires=('interlayer>=99; extra == "x"',))
    monkeypatch.syspath_prepend(str(site))
    importlib.invalidate_caches()
    host = PluginHost()
    assert host.broken["il_future"] == (
        f"il-future 0.1 requires interlayer>={NEXT},<9, but interlayer {__version__} is installed; upgrade it to a release "
        f"made for this core (pip install -U il-future) or install such a core (pip install 'interlayer>={NEXT},<9')")
    assert "il_future" not in {p.name for p in host.plugins()} and "future:line" not in host["motion_planners"].names()
    assert {"current:line", "extra:line", "interpolate"} <= set(host["motion_planners"].names())
    assert main(["plugins"]) == 0
    out = capsys.readouterr().out
    assert f"il_future: failed to load, skipped: il-future 0.1 requires interlayer>={NEXT},<9" in out
    assert "il_current  (il-current 0.1)" in out
    for name in ("il_future", "il_current", "il_extra"):
        import sys

        sys.modules.pop(name, None)


def test_the_up_adapters_ranges_are_the_ones_it_checks():
    """interlayer-up's requirements name the versions its compatibility check supports (interlayer_up.compat)."""
    from packaging.requirements import Requirement

    from interlayer_up.compat import SUPPORTED

    project = _project(ROOT / "adapters" / "up")["project"]
    declared = {Requirement(r).name: str(Requirement(r).specifier)
                for r in [*project["dependencies"], *project["optional-dependencies"]["symk"]]}
    for dist, specifier in SUPPORTED.items():
        assert declared[dist] == str(Requirement(f"{dist}{specifier}").specifier), dist
