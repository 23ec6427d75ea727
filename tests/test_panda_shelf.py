"""The trial's Panda shelf task (issue 21), rewritten as a plugin on the manipulation layer
(examples/panda_shelf): the fixed-base Panda learns that the blocker obstructs the target's grasp, moves it,
and puts the target into the goal region; the run validates."""
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("pinocchio")

from interlayer import api  # noqa: E402
from interlayer.plugins import PluginHost  # noqa: E402

EXAMPLE = Path(__file__).resolve().parent.parent / "examples" / "panda_shelf"


@pytest.fixture
def host(monkeypatch):
    monkeypatch.syspath_prepend(str(EXAMPLE))
    import interlayer_panda_shelf.plugin as plugin

    return PluginHost(plugins=(("panda_shelf", plugin),))


def test_the_panda_takes_the_target_out_of_the_shelf_past_the_blocker(host, tmp_path):
    result = api.solve(str(EXAMPLE / "shelf.toml"), ["planner.seed=0"], host=host)
    assert result.status == "solved", result.reason
    assert ("Obstructs", "blocker", "gpfg_target_arm") in [tuple(f) for f in result.learned_facts]
    picked = [s.args[0] for s in result.plan if s.action == "pick"]
    assert picked == ["blocker", "target"]
    out = api.write_outputs(result, tmp_path / "run")
    assert api.validate(out, host=host) == []


def test_a_box_wider_than_a_region_gets_no_put_down_spot_there(host):
    """The blocker (0.36 m long) cannot stand in the 0.2 m goal region: the put-down sampler says so by
    yielding nothing (it drew from an empty range and raised before)."""
    from interlayer_manip.generators import _spots
    from interlayer_panda_shelf.plugin import PARAMS, make_problem

    problem = make_problem(dict(PARAMS), 0)
    world = problem.geometry.initial_world()
    rng = np.random.default_rng(0)
    assert list(_spots(problem, world, "blocker", "goal_spot", rng, 10)) == []
    assert list(_spots(problem, world, "target", "goal_spot", rng, 10))
