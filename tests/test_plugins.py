"""The plugin system: entry points, registries, a third-party plugin selectable from config."""
import inspect
from pathlib import Path

import pytest

from interlayer import api, hookspecs
from interlayer.errors import UserError
from interlayer.plugins import PluginHost

THIRD_PARTY = Path(__file__).parent / "third_party"
ROOT = Path(__file__).resolve().parent.parent


def test_builtin_plugins_register_through_entry_points(host):
    names = {p.name: p for p in host.plugins()}
    assert {"builtin", "unified-planning", "ompl", "gripper2d"} <= set(names)
    assert names["gripper2d"].distribution in ("interlayer-gripper2d", "interlayer-workspace")  # its own, or the dev install
    assert "fast-downward" in host["task_planners"].names()
    assert "ompl:RRTConnect" in host["motion_planners"].names()
    assert "gripper2d" in host["domains"].names()


def test_unknown_names_list_the_available_ones(host):
    with pytest.raises(UserError, match=r"Unknown task planner 'fast-downwrd' \(did you mean 'fast-downward'\?\); available: .*pyperplan"):
        host["task_planners"].get("fast-downwrd")


def test_third_party_plugin_selectable_from_config_without_core_changes(monkeypatch, gripper_example):
    monkeypatch.syspath_prepend(str(THIRD_PARTY))  # makes its dist-info (and entry point) visible
    host = PluginHost()
    info = {p.name: p for p in host.plugins()}["hello"]
    assert info.distribution == "interlayer-hello" and info.version == "0.1"
    assert info.components["motion_planners"] == ["hello:waypoint"]
    result = api.solve(gripper_example, ["planner.motion=hello:waypoint",
                                         'planner.translators=["templates", "hello:blocked"]'], host=host)
    assert result.status == "solved", result.reason
    assert result.config["planner"]["motion"] == "hello:waypoint"


def test_every_hook_is_documented():
    doc = (ROOT / "docs" / "plugins.md").read_text()
    for name, fn in inspect.getmembers(hookspecs, inspect.isfunction):
        if name.startswith("interlayer_"):
            assert fn.__doc__ and ":param" in fn.__doc__, name
            assert name in doc, f"{name} is not described in docs/plugins.md"


def test_overrides_as_in_the_docstring_a_dict_or_a_list():
    import interlayer

    assert '{"planner.task": "pyperplan"}' in interlayer.__doc__
    by_dict = api.resolve_config(ROOT / "examples" / "gripper2d.toml", {"planner.task": "pyperplan", "problem.obstructions": 2})
    by_list = api.resolve_config(ROOT / "examples" / "gripper2d.toml", ["planner.task=pyperplan", "problem.obstructions=2"])
    assert by_dict == by_list and by_dict["planner"]["task"] == "pyperplan" and by_dict["problem"]["obstructions"] == 2


def test_the_plugin_api_documents_everything_it_exports():
    from interlayer import plugin_api

    doc = (ROOT / "docs" / "plugins.md").read_text()
    for name in plugin_api.__all__:
        obj = getattr(plugin_api, name)
        assert (obj.__doc__ or "").strip(), f"{name} has no docstring"
        assert f"`{name}" in doc, f"{name} is not in docs/plugins.md's reference"
    for key in api.cfg.PLANNER_DEFAULTS:
        assert f"`planner.{key}`" in doc, f"planner.{key} is missing from the config schema"
    for section in api.cfg.SECTIONS:
        assert f"`{section}." in doc, f"[{section}] is missing from the config schema"


def test_builtin_domains_declare_their_drawing(host):
    assert host["domains"].get("gripper2d").drawing == "interlayer_gripper2d.draw"
    assert host["domains"].get("pr2").drawing == "interlayer_manip.draw"


def test_discovery_reads_each_distributions_metadata_once(monkeypatch):
    """Every ``Distribution.name`` / ``.version`` parses the distribution's metadata file again: the
    plugin host reads each once (start-up time)."""
    import importlib.metadata as md

    read = []
    for kind in {type(ep.dist) for ep in md.entry_points(group="interlayer.plugins")}:  # the classes in use
        metadata = kind.metadata.fget
        monkeypatch.setattr(kind, "metadata", property(lambda dist, get=metadata: read.append(dist) or get(dist)))
    host = PluginHost()
    parsed = list(read)
    dist, version = host.dists["gripper2d"]
    assert len(host.dists) > 1 and dist in ("interlayer-gripper2d", "interlayer-workspace") and version == md.version(dist)
    assert len(parsed) == len({id(d) for d in parsed}) == len({ep.dist.name for ep in md.entry_points(group="interlayer.plugins")})
