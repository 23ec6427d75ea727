"""'interlayer check' checks everything 'plan' would check, without planning."""
import textwrap
from pathlib import Path

import pytest

from interlayer.cli import main

ROOT = Path(__file__).resolve().parent.parent
EXAMPLE = str(ROOT / "examples" / "gripper2d.toml")

# A Gripper-2D variant whose pick action has a mistake in its precondition (the plugin author's).
BROKEN_DOMAIN = """
    import dataclasses
    from interlayer import hookimpl

    @hookimpl
    def interlayer_register_domains(registry):
        from interlayer_gripper2d.domain import DOMAIN
        from interlayer_gripper2d.plugin import PARAMS, make_problem

        def make(params, seed):
            problem = make_problem(params, seed)
            pick = dataclasses.replace(DOMAIN.actions[0], precondition=PRECONDITION)
            problem.domain = dataclasses.replace(DOMAIN, actions=(pick, DOMAIN.actions[1]))
            return problem

        registry.add("g2d-broken", make, "Gripper-2D with a broken pick precondition", params=PARAMS)
"""


@pytest.mark.parametrize("precondition, message", [
    ("(and (Empty) (GripperAt ?p1) (IsGP ?gp ?b) (IsMP ?t ?p1 ?g))",
     "The variable '?g' in the precondition of action 'pick' is not bound (variables in scope: ?b, ?gp, ?p1, ?t)"),
    ("(and (Empty) (GripperAt ?p1) (IsGrasp ?gp ?b) (IsMP ?t ?p1 ?gp))",
     "Unknown predicate 'IsGrasp' in the precondition of action 'pick' (did you mean 'IsGP'?)"),
])
def test_domain_mistakes_are_found_by_check_and_plan_alike(plugin_dir, capsys, precondition, message):
    plugin_dir("il_g2d_broken", textwrap.dedent(BROKEN_DOMAIN) + f"\nPRECONDITION = {precondition!r}\n")
    for command in ("check", "plan"):
        code = main([command, EXAMPLE, "-q" if command == "plan" else "--json", "--set", "problem.domain=g2d-broken"])
        err = capsys.readouterr().err
        assert code == 2 and message in err and "internal error" not in err, (command, err)


@pytest.mark.parametrize("override, message", [
    ("planner.motion=ompl:RRTconnect", "Unknown motion planner 'ompl:RRTconnect' (did you mean 'ompl:RRTConnect'?)"),
    ("planner.task=fastdownward", "Unknown task planner 'fastdownward' (did you mean 'fast-downward'?)"),
    ("pose_generators.pick=gripper2d:pik", "Unknown pose generator 'gripper2d:pik' (did you mean 'gripper2d:pick'?)"),
    ('planner.translators=["templates", "templats"]', "Unknown failure translator 'templats'"),
    ("task_planner.fast-downward.serch=astar", "Unknown option(s) ['serch'] for task planner 'fast-downward'"),
])
def test_check_rejects_unknown_component_names(capsys, override, message):
    assert main(["check", EXAMPLE, "--set", override]) == 2
    assert message in capsys.readouterr().err


def test_check_reports_the_failed_plugin_a_config_needs(plugin_dir, capsys):
    plugin_dir("il_gone", "raise RuntimeError('built for another Interlayer version')\n")
    assert main(["check", EXAMPLE, "--set", "planner.motion=gone:rrt"]) == 2
    err = capsys.readouterr().err
    assert "Unknown motion planner 'gone:rrt'" in err
    assert "the plugin 'il_gone' failed to load (importing il_gone raised RuntimeError: built for another" in err


def test_a_goal_naming_an_unknown_object_is_a_user_error():
    from interlayer import api
    from interlayer.abstraction import abstract
    from interlayer.errors import UserError
    from interlayer.plugins import PluginHost

    problem = api.build_problem(PluginHost(), api.resolve_config(EXAMPLE))
    problem.goal = "(InRegion b1 SS)"
    with pytest.raises(UserError, match=r"The goal names 'SS', which is not an object of the problem \(did you mean 'S'\?\)"):
        abstract(problem)
