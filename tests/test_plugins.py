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
    assert names["gripper2d"].distribution == "interlayer"
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
