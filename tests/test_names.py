"""Names are data (interlayer.names): any string a user's file gives a body or region names it. The
task level sees safe symbols; whatever a person reads shows the file's names."""
import copy
import json
import logging
import re

import pytest
from interlayer import api
from interlayer.names import Names, relabel, step_text

from test_pbjson import SHARED, needs_shared, scene


def rename(data, new):
    """A pybullet-planning file with every body and region renamed by ``new`` (old name -> new name)."""
    data = copy.deepcopy(data)
    task = data["task"]
    for b in data["bodies"]:
        b["name"] = new(b["name"])
    for r in task.get("regions") or []:
        r["name"] = new(r["name"])
    for key in ("object_names", "table_names", "sink_names", "stove_names", "floor_object_names", "goal_cleaned", "goal_cooked"):
        if task.get(key):
            task[key] = [new(n) for n in task[key]]
    if isinstance(task.get("goal_holding"), str):
        task["goal_holding"] = new(task["goal_holding"])
    elif isinstance(task.get("goal_holding"), list):
        task["goal_holding"] = [new(n) for n in task["goal_holding"]]
    for key in ("goal_regions", "goal_stackings", "goal_poses"):
        task[key] = {new(o): new(v) if isinstance(v, str) and v != "initial" else v for o, v in (task.get(key) or {}).items()}
    return data


def test_a_symbol_is_the_name_when_safe_and_free_else_a_clean_unique_one():
    names = Names(reserved=["On", "obj"], prefixes=["grasp_"])
    arm = names.add("left")
    got = {n: names.add(n) for n in ["left", "table 1", "On", "on", "(", "and", "Either", "obj", "grasp_box", "", "a-b"]}
    assert arm == "left" and got["on"] == "on" and got["a-b"] == "a-b"  # safe names keep themselves
    assert got["left"] != "left" and got["On"] != "On" and got["obj"] != "obj"  # the arm's, a predicate's, a type's
    assert got["and"].lower() != "and" and got["Either"].lower() != "either"  # PDDL keywords, in any case
    assert not got["grasp_box"].startswith("grasp_")  # would read as a reference
    symbols = [arm, *got.values()]
    assert len(set(symbols)) == len(symbols)
    assert all(s[0].isalpha() and all(c.isalnum() or c in "_-" for c in s) for s in symbols)
    assert {names.label(s) for s in got.values()} == set(got) and names.label(arm) == "left"
    assert names.labels[got["table 1"]] == "table 1" and "on" not in names.labels  # labels: where they differ
    labels = {got["table 1"]: "table 1", got["left"]: "left"}
    assert step_text({"action": "place", "args": [got["left"], got["table 1"]]}, labels) == "place(left, table 1)"
    assert relabel(f"(On {got['left']} {got['table 1']}), (not (On a b))", labels) == "(On left table 1), (not (On a b))"


def _solve(tmp_path, data, name):
    path = tmp_path / f"{name}.json"
    path.write_text(json.dumps(data))
    return api.solve(str(path), ["planner.seed=0", "planner.time_limit=120"])


def _as_named(result):
    """The plan in the names a person reads."""
    return [step_text(s, result.to_json()["names"]) for s in result.plan]


def _plan_in_file_names(result, back=lambda n: n):
    """The plan with every body and region written by its name in the file, mapped by ``back`` (a renamed
    copy's names -> the original's); references as ``skolem(args)``; arms and slots as they are."""
    model = result.model

    def name(sym):
        if sym in model.references:
            sk, combo = model.references[sym]
            return f"{sk}({', '.join(map(name, combo))})"
        label = model.labels.get(sym, sym)
        if model.objects[sym] not in ("obj", "surf"):
            return label
        return f"{back(label[:-4])}_top" if label.endswith("_top") and sym.endswith("_top") else back(label)

    return [f"{s.action}({', '.join(map(name, s.args))})" for s in result.plan]


AWKWARD = [  # the issue's names, the arms', PDDL keywords, types, predicates, actions, a slot, spaces, parentheses
    {"a": "left", "b": "right", "table": "table 1", "goal": "bottom left", "sink": "On", "stove": "("},
    {"a": "s1", "b": "not", "table": "either", "goal": "left", "sink": "obj", "stove": "and"},
]


@pytest.fixture(scope="module")
def original(tmp_path_factory):
    return _solve(tmp_path_factory.mktemp("original"), scene(goal_regions={"b": "goal"}, goal_config="initial"), "scene")


@pytest.mark.parametrize("region", ["left", "bottom left"])
def test_a_region_named_like_an_arm_or_with_a_space_solves_like_the_original(tmp_path, original, region):
    """move.json's region 'left' (a UP type error in planning before) and walls.json's 'bottom left'
    (three PDDL arguments before)."""
    result = _solve(tmp_path, rename(scene(goal_regions={"b": "goal"}, goal_config="initial"), lambda n: region if n == "goal" else n),
                    "renamed")
    assert result.status == "solved", result.reason
    assert _plan_in_file_names(result, lambda n: "goal" if n == region else n) == _plan_in_file_names(original)
    assert f"place(b, right, {region}, s1, " in "; ".join(_as_named(result))
    api.write_outputs(result, tmp_path / "out")
    assert api.validate(tmp_path / "out") == []


@pytest.mark.parametrize("names", AWKWARD, ids=["left-table_1-On", "keywords-types-slot"])
def test_awkward_names_solve_like_the_original_and_show_in_the_plan(tmp_path, original, names):
    data = rename(scene(goal_regions={"b": "goal"}, goal_config="initial"), names.get)
    result = _solve(tmp_path, data, "renamed")
    assert original.status == "solved", original.reason
    assert result.status == "solved", result.reason
    back = {v: k for k, v in names.items()}
    assert _plan_in_file_names(result, back.get) == _plan_in_file_names(original)
    place = next(s for s in _as_named(result) if s.startswith("place("))
    assert place.startswith(f"place({names['b']}, ") and f", {names['goal']}, s1, " in place, place
    api.write_outputs(result, tmp_path / "out")
    assert api.validate(tmp_path / "out") == []


def test_a_scene_warning_names_the_files_body(tmp_path, capsys):
    from interlayer.cli import main

    data = rename(scene(goal_regions={"b": "goal"}), AWKWARD[0].get)
    data["bodies"][3]["point"]["z"] += 0.03  # 'left' (a) floats 3 cm above the table
    path = tmp_path / "floating.json"
    path.write_text(json.dumps(data))
    assert main(["check", str(path)]) == 0
    err = capsys.readouterr().err
    assert "The object left floats" in err and "above table 1_0" in err and "left_1" not in err, err


def test_the_plan_check_and_pages_show_the_files_names(tmp_path, capsys):
    from interlayer.cli import main

    path = tmp_path / "renamed.json"
    path.write_text(json.dumps(rename(scene(goal_regions={"b": "goal"}, goal_config="initial"), AWKWARD[0].get)))
    assert main(["check", str(path)]) == 0
    out = capsys.readouterr().out
    for text in ("tables: table 1 (z 0.750)", "regions: bottom left", "sinks: On", "stoves: (", "left: box", "on table 1",
                 "Goals: right on bottom left;", "bpfpd(right, left, bottom left, s1)"):
        assert text in out, text
    path.write_text(json.dumps(rename(scene(goal_regions={"b": "goal"}), lambda n: {"goal": "left"}.get(n, n))))  # move.json's case
    assert main(["check", str(path)]) == 0
    out = capsys.readouterr().out  # every reference written alike, whether its objects were renamed or not
    assert "Goals: b on left" in out and "bpfg(a, left)" in out and "bpfpd(b, right, left, s2)" in out, out
    path.write_text(json.dumps(rename(scene(goal_regions={"b": "goal"}, goal_config="initial"), AWKWARD[0].get)))
    assert main(["plan", str(path), "--out", str(tmp_path / "out")]) == 0
    err = capsys.readouterr().err
    assert "task plan #1" in err and ": place(right, right, bottom left, s1, bpfpd(right, right, bottom left, s1)" in err
    data = json.loads((tmp_path / "out" / "result.json").read_text())
    assert {"left_1": "left", "right_1": "right", "table_1": "table 1", "bottom_left": "bottom left"}.items() <= data["names"].items()
    assert main(["explain", str(tmp_path / "out"), "-o", str(tmp_path / "explain.html")]) == 0
    page = (tmp_path / "explain.html").read_text()
    assert "place(right, right, bottom left, s1, " in page and "bottom_left, s1" not in page


FOLDER = ["move_several_4.json", "kitchen.json", "stacking.json", "nonmonotonic_4_1.json"]  # replans, clean/cook, tops, unsolvable


def _awkward(data):
    """Every body and region of a file renamed: the issue's names and keywords first, then '<name> (copy)'."""
    pool = ["left", "right", "On", "table 1", "(", "and", "not", "either", "obj", "surf", "s1", "pick", "bottom left"]
    old = [b["name"] for b in data["bodies"]] + [r["name"] for r in data["task"].get("regions") or []]
    new = dict(zip(old, pool + [f"{n} (copy)" for n in old[len(pool):]]))
    return new


@needs_shared
@pytest.mark.slow
@pytest.mark.parametrize("name", FOLDER)
def test_a_renamed_copy_of_a_folder_file_solves_like_the_original(tmp_path, name):
    data = json.loads((SHARED / name).read_text())
    new = _awkward(data)
    original = _solve(tmp_path, data, "original")
    renamed = _solve(tmp_path, rename(data, new.__getitem__), "renamed")
    assert renamed.status == original.status, (original.reason, renamed.reason)
    back = {v: k for k, v in new.items()}
    assert _plan_in_file_names(renamed, back.get) == _plan_in_file_names(original)
    words = re.sub(r"[A-Za-z0-9_-]+", lambda m: new.get(m.group(0), m.group(0)), original.reason)
    assert renamed.reason == words  # a domain's sentence names the file's bodies


def test_random_streams_count_objects_by_their_place_not_their_names(tmp_path):
    """The loop's seed of a step's generator and an EpochState's rng_for: the same for a renamed copy."""
    from interlayer.abstraction import abstract
    from interlayer.domain import GroundStep
    from interlayer.loop import InterfaceLayer, LoopSettings
    from interlayer.refine import EpochState

    from test_pbjson import load

    data = scene(goal_regions={"b": "goal"})
    models = [abstract(load(tmp_path, d)) for d in (data, rename(data, AWKWARD[0].get))]
    a, renamed = "a", next(s for s, name in models[1].labels.items() if name == "left")
    draws = []
    for model, obj in zip(models, (a, renamed)):
        state = EpochState([7])
        state.ordinal = model.ordinal  # as the loop sets it
        layer = InterfaceLayer(model, None, None, {"pick": lambda problem, step, world, rng: [rng.random()]}, [], LoopSettings())
        first = layer.make_generator(0, GroundStep("pick", (obj, "right")), None).reset_and_get_first()
        draws.append((state.rng_for(obj, "right", 3).random(4).tolist(), first))
    assert draws[0] == draws[1]


@needs_shared
def test_no_symbol_shows_where_a_person_reads(tmp_path, capsys):
    """A renamed copy of move_several_4.json (two failures translated into facts, two replans): the
    progress lines with every attempt, the summary and the explain page name things as the file does."""
    from interlayer.cli import main

    data = json.loads((SHARED / "move_several_4.json").read_text())
    path, out = tmp_path / "renamed.json", tmp_path / "out"
    path.write_text(json.dumps(rename(data, _awkward(data).__getitem__)))
    logger = logging.getLogger("interlayer")
    before = logger.level
    try:
        assert main(["plan", str(path), "--verbose", "--out", str(out)]) == 0
    finally:
        logger.setLevel(before)  # --verbose raised it for the process
    err = capsys.readouterr().err
    pages = []
    for command in ("explain", "viz"):
        assert main([command, str(out), "-o", str(tmp_path / f"{command}.html")]) == 0
        pages.append(re.sub(r"<script.*?</script>", "", (tmp_path / f"{command}.html").read_text(), flags=re.S))
    symbols = set(json.loads((out / "result.json").read_text())["names"])  # the ones that differ from their names
    assert "refinement failed at step" in err and "Failure 1" in pages[0] and "place(table 1, " in pages[1]
    for text in (err, *pages):
        shown = symbols & set(re.findall(r"[A-Za-z0-9_-]+", text))
        assert not shown, sorted(shown)[:5]
