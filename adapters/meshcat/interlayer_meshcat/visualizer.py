"""The "meshcat" visualizer of Interlayer runs: a plan animation page, an
explanation page of the whole search, and a live viewer.

Domains draw themselves; this module knows no domain. It looks up, in order:

1. methods on the problem's geometry object::

       geometry.draw_scene(scene, world_snapshot_or_None) -> {object: scene name} | None
       geometry.animation_frames(scene, trajectory_json) -> [{scene name: pose, "@step": i}, ...]

2. else functions of the module the domain declares as its drawing
   (``registry.add(name, factory, drawing="my_plugin.draw")`` or ``Problem(drawing=...)``),
   with the geometry as first argument::

       draw_scene(geometry, scene, world) / animation_frames(geometry, scene, trajectory)

``draw_scene`` adds the static scene and the objects at ``world`` (a snapshot
as written in trace.json failure events; None = the initial world) using the
generic Scene methods only. Its optional return value maps problem objects to
the scene names to recolour (default: the object's own name). Frames are
dicts name -> pose (4x4 / xyz / xyz+quat); keys starting with "@" are metadata
("@step": index of the plan step shown, used for the caption) and are removed
before animating.
"""
from __future__ import annotations

import difflib
import importlib
import json
import os
import sys
from html import escape
from pathlib import Path

FPS = 10  # frames drawn per second of motion; the page interpolates between them
KEYFRAME_TOLERANCE = (0.002, 0.01)  # m, rad: the page interpolates between keyframes this close to every frame
MAX_FAILURE_VIEWS = 40  # 3D views on one explanation page (each a lazy WebGL context)
OBSTRUCTING = (0.90, 0.12, 0.12, 1.0)
ACTED_ON = (1.0, 0.55, 0.0, 1.0)


# ---------------------------------------------------------------- run data
class Run:
    """Everything written to an OUT_DIR, plus the rebuilt problem (or why not)."""

    def __init__(self, out_dir, need_trace: bool = False, need_problem: bool = False):
        from interlayer import api, runfolder
        from interlayer.errors import UserError
        from interlayer.plugins import PluginHost

        self.dir = Path(out_dir)
        self.result = runfolder.read_result(self.dir)
        self.labels = self.result.get("names") or {}  # symbol -> the name a person gave it (interlayer.names)
        self.events = runfolder.read_trace(self.dir, required=need_trace) or []
        self.trajectory = runfolder.read_trajectory(self.dir, required=False)
        self.problem_json = runfolder.read_json(self.dir / "problem.json", required=False) or {}
        self.problem, self.problem_error = None, None
        config = api.resolve_config(self.dir)  # a damaged config.toml is the folder's fault: named
        try:
            self.problem = api.build_problem(PluginHost(), config)
        except Exception as exc:  # e.g. its plugin is not installed here: still explain the run, without 3D views
            if need_problem and isinstance(exc, UserError):
                raise
            self.problem_error = f"{type(exc).__name__}: {exc}"
        if (self.result["status"] == "solved" and self.trajectory is None
                and hasattr(getattr(self.problem, "geometry", None), "trajectory_json")):
            raise UserError(f"{self.dir} has no trajectory.json although its result.json says solved; "
                            f"{runfolder.REWRITE}.")

    @property
    def name(self) -> str:
        return str(self.problem_json.get("name") or (self.problem.name if self.problem else self.dir.name))

    def reading(self, name: str):
        """Content of ``name`` in a shape this page did not expect: the file's fault, named."""
        from interlayer.runfolder import reading

        return reading(self.dir / name)


def drawer(problem):
    """(draw_scene(scene, world), animation_frames(scene, traj)) for a problem; None when unknown."""
    if problem is None:
        return None, None
    geometry = problem.geometry
    draw = getattr(geometry, "draw_scene", None)
    frames = getattr(geometry, "animation_frames", None)
    mod = getattr(problem, "drawing", None)
    if isinstance(mod, str):  # declared by the domain as a dotted module name: imported when drawn
        mod = importlib.import_module(mod)
    if mod is not None:
        if draw is None and hasattr(mod, "draw_scene"):
            draw = lambda scene, world, _f=mod.draw_scene: _f(geometry, scene, world)  # noqa: E731
        if frames is None and hasattr(mod, "animation_frames"):
            frames = lambda scene, traj, _f=mod.animation_frames: _f(geometry, scene, traj)  # noqa: E731
    return draw, frames


def step_str(s, labels=None) -> str:
    """A step (its JSON, or as the trace writes it) in the names a person gave things."""
    from interlayer.names import relabel, step_text

    return relabel(s, labels) if isinstance(s, str) else step_text(s, labels)


# ------------------------------------------------------------------ scenes
def _new_scene(title):
    from .scene import Scene

    return Scene(title)


def _camera(scene):
    # a slightly tilted top view: 2D-ish domains read well, 3D ones still look 3D. A domain's
    # draw_scene may prefer another viewing direction: scene.view_direction = (x, y, z).
    direction = getattr(scene, "view_direction", None) or (0.0, -0.5, 1.0)
    return scene.auto_camera(direction=direction, margin=0.95)


def solution_scene(run_or_problem, trajectory, title="plan"):
    """(scene, step start times in seconds) animating ``trajectory``; None if the domain cannot draw."""
    problem = getattr(run_or_problem, "problem", run_or_problem)
    draw, anim = drawer(problem)
    if draw is None:
        return None, []
    scene = _new_scene(title)
    draw(scene, (trajectory or {}).get("initial") if trajectory else None)
    starts = []
    if trajectory and anim is not None:
        frames = list(anim(scene, trajectory))
        clean = []
        for i, f in enumerate(frames):
            st = f.get("@step")
            if st is not None and (not starts or starts[-1][0] != st):
                starts.append((st, i / FPS))
            clean.append({k: v for k, v in f.items() if not str(k).startswith("@")})
        if clean:
            scene.animate(clean, fps=FPS, autoplay=True, loop=True, tolerance=KEYFRAME_TOLERANCE)
        starts.append((None, len(clean) / FPS))
    _camera(scene)
    return scene, starts


def failure_scene(problem, event):
    """The world at a failing step: obstructing objects red, the acted-on object orange."""
    draw, _ = drawer(problem)
    if draw is None or event.get("world") is None:
        return None
    scene = _new_scene(f"failure at step {event.get('step')}")
    names = draw(scene, event["world"]) or {}
    acted = [a for a in _action_args(event.get("action", "")) if a in names or a in (problem.objects or {})]
    obstructing = list((event.get("failure") or {}).get("objects") or [])
    for a in acted[:1]:
        if a not in obstructing:
            _recolor(scene, names.get(a, a), ACTED_ON)
    for o in obstructing:
        _recolor(scene, names.get(o, o), OBSTRUCTING)
    for o in obstructing + acted[:1]:  # their tags win where tags would overlap
        scene.label_priority(o, 3)
    focus = [names.get(o, o) for o in obstructing + acted[:1]]
    if not _focus_camera(scene, focus):
        _camera(scene)
    return scene


def _focus_camera(scene, names, direction=(0.0, -0.7, 1.0), pad=0.22) -> bool:
    """Camera on the objects ``names`` (plus ``pad`` metres around them); False if none is known."""
    import math

    import numpy as np

    pts = []
    info = getattr(scene, "_info", {})
    for name in names:
        for k, inf in info.items():
            if (k == name or k.startswith(name + "/")) and inf.bbox is not None:
                T = scene._world_pose(k)
                lo, hi = inf.bbox
                c = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
                pts.extend(c @ T[:3, :3].T + T[:3, 3])
    if not pts:
        return False
    P = np.asarray(pts)
    lo, hi = P.min(axis=0) - pad, P.max(axis=0) + pad
    centre = 0.5 * (lo + hi)
    radius = 0.5 * float(np.linalg.norm(hi - lo))
    d = np.asarray(direction, float)
    d /= np.linalg.norm(d)
    dist = radius / math.tan(math.radians(scene.fov) / 2)
    scene.camera(centre + d * dist, centre)
    return True


def _recolor(scene, name, color):
    try:
        scene.highlight(name, color)
    except Exception:
        pass


def _action_args(action: str) -> list[str]:
    if "(" not in action:
        return []
    inner = action[action.index("(") + 1:action.rindex(")")]
    return [a.strip() for a in inner.split(",") if a.strip()]


# ------------------------------------------------------------------- pages
_PLAN_CSS = """
html, body { margin: 0; padding: 0; height: 100%; overflow: hidden; }
body { margin: 0; display: flex; }
/* the step list beside the 3D view, never over it; folding it gives the view the whole window */
#caption { flex: 0 0 auto; width: min(340px, 36vw); box-sizing: border-box; height: 100vh; overflow: auto;
           background: #fafbfc; border-right: 1px solid #ccd3dc; padding: 10px 12px 10px 12px; font-size: 13px; position: relative; }
#caption.folded { width: 30px; padding: 0; overflow: hidden; }
#caption.folded > :not(#fold) { display: none; }
#fold { position: absolute; right: 4px; top: 6px; border: 1px solid #ccd3dc; background: #fff; border-radius: 4px;
        cursor: pointer; font-size: 12px; padding: 0 5px; line-height: 18px; }
#caption h1 { font-size: 15px; margin: 0 22px 4px 0; }
#caption ol { margin: 4px 0 0 0; padding-left: 22px; }
#caption li { font-family: ui-monospace, Menlo, Consolas, monospace; font-size: 12px; padding: 1px 3px; border-radius: 3px; }
#caption li.now { background: #ffe08a; }
#caption .note { color: #5a6470; font-size: 12px; }
#view { flex: 1 1 auto; min-width: 0; height: 100vh; position: relative; }
#view .il-scene { border: none; border-radius: 0; display: block; position: absolute; left: 0; top: 0; }
"""

_FOLD_JS = """
document.getElementById("fold").onclick = function () {
  var c = document.getElementById("caption"), folded = c.classList.toggle("folded");
  this.textContent = folded ? "\u00bb" : "\u00ab";
  this.title = folded ? "show the steps" : "hide the steps";
  window.dispatchEvent(new Event("resize"));  // the 3D view takes the freed width
};
"""

_CAPTION_JS = """
(function () {
  var starts = %s, el = document.getElementById("plan-view");
  var items = document.querySelectorAll("#caption li");
  function tick() {
    var v = el.meshcatViewer, a = v && v.animator;
    if (a && a.duration > 0 && a.actions && a.actions.length && starts.length) {
      var t = 0, cur = -1;  // the clip time being shown (what meshcat's scrubber shows)
      for (var j = 0; j < a.actions.length; j++) t = Math.max(t, a.actions[j].time);
      for (var i = 0; i < starts.length - 1; i++) if (t >= starts[i][1]) cur = starts[i][0];
      for (var k = 0; k < items.length; k++) items[k].className = (k === cur ? "now" : "");
    }
    requestAnimationFrame(tick);  // in step with the rendering
  }
  tick();
})();
"""


class MeshcatVisualizer:
    """``plan_page(out_dir, path)``, ``explain_page(out_dir, path)``, ``live(result)``."""

    def __init__(self, **options):
        self.options = options

    # -- interlayer viz ---------------------------------------------------------------------
    def plan_page(self, out_dir, path) -> Path:
        from .page import html_page, scene_embed, write_page

        run = Run(out_dir, need_problem=True)  # the page is its 3D view
        plan = run.result.get("plan") or []
        solved = run.result.get("status") == "solved"
        title = f"{run.name}: refined plan" if solved else f"{run.name}: not solved"
        with run.reading("trajectory.json"):
            scene, starts = solution_scene(run, run.trajectory if solved else None, title)
        cap = ['<button id="fold" title="hide the steps">&laquo;</button>', f"<h1>{escape(title)}</h1>"]
        if solved:
            cap.append(f'<div class="note">{len(plan)} step(s), solved in {_secs(run.result.get("times", {}).get("total"))}; '
                       f'{run.result.get("replans", 0)} replan(s). The current step is highlighted.</div>')
            cap.append("<ol start=\"0\">" + "".join(f"<li>{escape(step_str(s, run.labels))}</li>" for s in plan) + "</ol>")
        else:
            cap.append(f'<div class="note">Status {escape(str(run.result.get("status")))}: '
                       f'{escape(run.result.get("reason") or "")}. No trajectory to animate; the initial world is shown. '
                       "See <code>interlayer explain</code> for what happened.</div>")
        if scene is None:
            why = run.problem_error or "the domain has no draw_scene"
            cap.append(f'<div class="note">No 3D view: {escape(why)}</div>')
            body = f'<div id="caption">{"".join(cap)}</div><script>{_FOLD_JS}</script>'
        else:
            body = (f'<div id="caption">{"".join(cap)}</div><div id="view">'
                    + scene_embed(scene, "100%", "100%", element_id="plan-view", lazy=False)
                    + f"</div><script>{_FOLD_JS}{_CAPTION_JS % json.dumps(starts)}</script>")
        return write_page(path, html_page(title, body, _PLAN_CSS))

    write_html = plan_page  # the name in the hookspec's docstring

    # -- interlayer explain -----------------------------------------------------------------
    def explain_page(self, out_dir, path) -> Path:
        from .page import html_page, write_page

        run = Run(out_dir, need_trace=True)
        title = f"{run.name}: how the plan was found" if run.result.get("status") == "solved" \
            else f"{run.name}: what the planner tried"
        body = _Explainer(run).render(title)
        return write_page(path, html_page(title, body, _EXPLAIN_CSS))

    # -- interlayer plan --viz --------------------------------------------------------------
    def stream(self, host: str = "127.0.0.1"):
        """A live viewer that follows a run (``plan --viz``); see :class:`LiveRun`."""
        return LiveRun(host)

    def live(self, result):
        """Show the solution (or the initial world) in a live meshcat viewer.

        The URL goes to stderr. When stdin and stderr are terminals, waits for
        Ctrl-C (then stops the viewer's server and returns); otherwise returns
        at once and the server is stopped when the process exits."""
        import atexit

        scene = _result_scene(result)
        if scene is None:
            print("interlayer: this domain cannot draw itself; no live view", file=sys.stderr)
            return None
        scene.live()
        atexit.register(scene.close)
        if _interactive():
            _until_ctrl_c("Viewer running; press Ctrl-C to stop it and continue.")
            scene.close()
        else:
            print("(not a terminal: the viewer stops when this command exits)", file=sys.stderr, flush=True)
        return scene


class LiveRun:
    """A trace listener that streams a run into one live meshcat viewer: the initial world once the
    problem is built (``prepared``), the world of each failing refinement as it happens (obstructing
    objects red, the object acted on orange; as on the explain page), then ``finish(result)``: the
    refined plan's animation. Its server listens on ``host`` only and stops with ``close()`` (and with
    this process, however it ends)."""

    def __init__(self, host: str = "127.0.0.1"):
        self.host, self.problem, self.scene, self.url = host, None, None, None

    def prepared(self, problem):
        self.problem = problem
        scene, _ = solution_scene(problem, None, f"{problem.name}: initial world")
        if scene is None:
            print("interlayer: this domain cannot draw itself; no live view", file=sys.stderr)
            return
        import atexit

        self.url = scene.live(host=self.host)
        self.scene = scene
        atexit.register(self.close)

    def __call__(self, event):
        if self.scene is not None and event["type"] == "failure":
            self._show(failure_scene(self.problem, event))

    def _show(self, scene):
        if scene is not None:
            scene.replace_live(self.scene)
            self.scene = scene

    def finish(self, result, wait: bool | None = None):
        """The refined plan (or the last world shown, when not solved); then, in a terminal, wait for
        Ctrl-C before the server stops (``wait`` overrides)."""
        if self.scene is None:
            return
        if result.solved:
            self._show(_result_scene(result))
        if _interactive() if wait is None else wait:
            _until_ctrl_c(f"Viewer running at {self.url}; press Ctrl-C to stop it.")
        self.close()

    def close(self):
        scene, self.scene = self.scene, None
        if scene is not None:
            scene.close()


def _result_scene(result):
    """The refined plan's animation (the initial world when there is none); None if the domain cannot draw."""
    problem, traj = result.problem, None
    if result.solved and hasattr(problem.geometry, "trajectory_json"):
        traj = json.loads(json.dumps(problem.geometry.trajectory_json(result.plan, result.refinement),
                                     default=_json_default))
    return solution_scene(problem, traj, f"{problem.name}: refined plan")[0]


def _interactive() -> bool:
    """A user at a terminal, who can stop a live viewer with Ctrl-C."""
    return sys.stdin is not None and sys.stdin.isatty() and sys.stderr.isatty() \
        and not os.environ.get("INTERLAYER_VIZ_NO_WAIT")


def _until_ctrl_c(message: str) -> None:
    import time

    print(message, file=sys.stderr, flush=True)
    try:
        while True:
            time.sleep(3600)
    except KeyboardInterrupt:
        pass


def _json_default(o):
    import numpy as np

    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    raise TypeError(type(o).__name__)


def _secs(x) -> str:
    if x is None:
        return "?"
    return f"{x:.2f} s" if x < 100 else f"{x:.0f} s"


# ------------------------------------------------------------ explanation
_EXPLAIN_CSS = """
body { max-width: 1100px; margin: 1.2em auto; padding: 0 1em; font-size: 14.5px; }
h1 { font-size: 1.5em; margin-bottom: 0.2em; }
h2 { font-size: 1.15em; margin-top: 1.6em; border-bottom: 1px solid #dde2e8; padding-bottom: 3px; }
code, .mono { font-family: ui-monospace, Menlo, Consolas, monospace; font-size: 0.92em; }
.badge { display: inline-block; padding: 1px 9px; border-radius: 10px; color: #fff; font-weight: 600; font-size: 0.85em; }
.ok { background: #2e9d4a; } .bad { background: #c9302c; } .warn { background: #d98a00; }
.cards { display: flex; flex-wrap: wrap; gap: 8px; margin: 10px 0; }
.card { border: 1px solid #dde2e8; border-radius: 6px; padding: 6px 12px; min-width: 90px; background: #fafbfc; }
.card b { display: block; font-size: 1.35em; }
.card span { color: #5a6470; font-size: 0.85em; }
.bar { display: flex; height: 18px; border-radius: 4px; overflow: hidden; border: 1px solid #ccd3dc; margin: 6px 0 4px; }
.bar div { height: 100%; }
.legend span { display: inline-block; margin-right: 14px; font-size: 0.85em; }
.legend i { display: inline-block; width: 10px; height: 10px; border-radius: 2px; margin-right: 4px; vertical-align: -1px; }
.timeline { position: relative; height: 22px; background: #f1f3f6; border: 1px solid #ccd3dc; border-radius: 4px; margin: 6px 0; }
.timeline div { position: absolute; top: 0; height: 100%; min-width: 1px; }
.timeline div.fail { background: #c9302c; width: 2px !important; }
.ev { border-left: 4px solid #ccd3dc; padding: 4px 10px 6px 12px; margin: 8px 0; background: #fff; }
.ev .t { color: #7a8490; font-size: 0.82em; float: right; }
.ev.task { border-color: #3f6fd8; } .ev.refine { border-color: #8a94a3; }
.ev.failure { border-color: #c9302c; background: #fff7f7; } .ev.replan { border-color: #2e9d4a; }
.ev.dead { border-color: #d98a00; background: #fffaf0; } .ev.reset { border-color: #7a4fc4; background: #faf7ff; }
.ev.done { border-color: #2e9d4a; background: #f4fbf5; }
.ev h3 { font-size: 1em; margin: 2px 0 4px; }
ol.plan { margin: 2px 0; padding-left: 2.6em; }
ol.plan li { font-family: ui-monospace, Menlo, Consolas, monospace; font-size: 0.9em; }
ol.plan li.added { color: #1d7a35; background: #e6f6ea; }
ol.plan li.kept { color: #6b7580; }
ol.plan li.removed { color: #b02a26; text-decoration: line-through; list-style-type: none; }
.tag { font-family: system-ui, sans-serif; font-size: 0.78em; border-radius: 3px; padding: 0 4px; margin-left: 6px; }
.tag.added { background: #2e9d4a; color: #fff; } .tag.kept { background: #dde2e8; color: #333; }
.tag.removed { background: #c9302c; color: #fff; }
.fact { font-weight: 700; font-family: ui-monospace, Menlo, Consolas, monospace; }
.failure-body { display: flex; gap: 14px; align-items: flex-start; flex-wrap: wrap; }
.failure-text { flex: 1 1 320px; }
details summary { cursor: pointer; color: #3f4a57; }
table.attempts { border-collapse: collapse; font-size: 0.85em; margin: 4px 0; }
table.attempts td, table.attempts th { border-bottom: 1px solid #eceff3; padding: 2px 8px; text-align: left; vertical-align: top; }
td.okc { color: #2e9d4a; } td.badc { color: #c9302c; }
.key i { display: inline-block; width: 10px; height: 10px; border-radius: 2px; margin: 0 4px 0 8px; vertical-align: -1px; }
.muted { color: #6b7580; }
.failure-body .dg { display: none; }
"""

_TIME_COLORS = {"task_planning": "#3f6fd8", "motion_planning": "#e07b24", "pose_generation": "#2e9d4a",
                "validation": "#7a4fc4", "collision_checking": "#c9302c", "interface": "#8a94a3"}
_NICE = {"task_planning": "task planning", "motion_planning": "motion planning", "pose_generation": "pose generation",
         "validation": "validation", "interface": "interface layer", "collision_checking": "collision checks"}
_PALETTE = ["#17becf", "#bcbd22", "#e377c2", "#8c564b", "#9467bd"]


def _plan_list(steps, start=0, marks=None, removed=(), labels=None):
    """Numbered plan; ``marks`` {index: "kept"|"added"}; ``removed`` [(position, step)]: dropped
    steps of the previous plan, shown struck through before the step at ``position``."""
    marks = marks or {}
    gone = {}
    for pos, s in removed:
        gone.setdefault(pos, []).append(s)
    items = []
    for i in range(len(steps) + 1):
        for s in gone.get(i, []):
            items.append(f'<li class="removed">{escape(step_str(s, labels))}<span class="tag removed">dropped</span></li>')
        if i == len(steps):
            break
        m = marks.get(i)
        tag = f'<span class="tag {m}">{m}</span>' if m else ""
        items.append(f'<li value="{start + i}" class="{m or ""}">{escape(step_str(steps[i], labels))}{tag}</li>')
    return f'<ol class="plan">{"".join(items)}</ol>'


def _span(steps) -> str:
    """Step numbers as "3" or "3-7" (consecutive)."""
    return "" if not steps else str(steps[0]) if len(steps) == 1 else f"{steps[0]}-{steps[-1]}"


def _diff_marks(old, new, keep):
    """Marks for ``new`` vs ``old``: the kept prefix (< keep), added steps, and the old
    steps dropped (with the position in ``new`` they would have been at)."""
    a = [step_str(s) for s in old]
    b = [step_str(s) for s in new]
    marks = {i: "kept" for i in range(min(keep, len(b)))}
    removed = []
    sm = difflib.SequenceMatcher(a=a[keep:], b=b[keep:], autojunk=False)
    for op, i1, i2, j1, j2 in sm.get_opcodes():
        if op in ("replace", "delete"):
            removed += [(keep + j1, old[keep + k]) for k in range(i1, i2)]
        if op in ("replace", "insert"):
            marks.update({keep + j: "added" for j in range(j1, j2)})
    return marks, removed


class _Explainer:
    def __init__(self, run: Run):
        self.run = run
        self.views = 0

    def shown(self, text: str) -> str:
        """A fact, step or object as the trace writes it, in the names a person gave things."""
        from interlayer.names import relabel

        return relabel(text, self.run.labels)

    def render(self, title) -> str:
        from interlayer.result import MEANING

        r = self.run.result
        status = r.get("status", "?")
        cls = "ok" if status == "solved" else "warn" if status in ("gave_up", "timeout", "interrupted") else "bad"
        out = [f"<h1>{escape(title)}</h1>",
               f'<p><span class="badge {cls}" title="{escape(MEANING.get(status, status))}">{escape(status)}</span> '
               f'{escape(r.get("reason") or "")} <span class="muted">{escape(str(self.run.dir))}</span></p>']
        with self.run.reading("trace.json"):
            out.append(self.summary())
            out.append(self.timeline_section())
        with self.run.reading("trajectory.json"):
            out.append(self.solution())
        return "\n".join(out)

    # -- summary ---------------------------------------------------------------------------
    def summary(self) -> str:
        r, ev = self.run.result, self.run.events
        n = lambda t: sum(1 for e in ev if e.get("type") == t)  # noqa: E731
        attempts = [e for e in ev if e.get("type") == "attempt"]
        cards = [("total time", _secs(r.get("times", {}).get("total"))),
                 ("task-planner calls", r.get("task_planner_calls", n("task_plan"))),
                 ("replans", r.get("replans", n("replan"))),
                 ("learned facts", len(r.get("learned_facts") or [])),
                 ("refinement attempts", len(attempts)),
                 ("failed attempts", sum(1 for a in attempts if not a.get("ok"))),
                 ("failures translated", n("failure")),
                 ("dead ends", n("dead_end")), ("resets", n("reset")),
                 ("plan length", len(r.get("plan") or []) if r.get("status") == "solved" else "-"),
                 ("plan cost", r.get("plan_cost") if r.get("plan_cost") is not None else "-")]
        html = ['<h2>Summary</h2><div class="cards">']
        html += [f"<div class=card><b>{escape(str(v))}</b><span>{escape(k)}</span></div>" for k, v in cards]
        html.append("</div>")
        html.append(self.time_split())
        facts = r.get("learned_facts") or []
        if facts:
            html.append("<p>Learned facts (from refinement failures): "
                        + ", ".join(f'<span class="fact">{escape(self.shown(f))}</span>' for f in facts) + "</p>")
        return "\n".join(html)

    def time_split(self) -> str:
        times = dict(self.run.result.get("times") or {})
        total = times.pop("total", None) or sum(times.values()) or 1.0
        parts = [(k, v) for k, v in sorted(times.items(), key=lambda kv: -kv[1]) if v > 0]
        bar, legend = [], []
        for i, (k, v) in enumerate(parts):
            col = _TIME_COLORS.get(k, _PALETTE[i % len(_PALETTE)])
            pct = 100.0 * v / total
            bar.append(f'<div style="width:{pct:.2f}%;background:{col}" title="{escape(_NICE.get(k, k))}: {v:.3f} s"></div>')
            legend.append(f'<span><i style="background:{col}"></i>{escape(_NICE.get(k, k))} {v:.2f} s ({pct:.0f}%)</span>')
        return ('<div><b>Where the time went</b> (exclusive times; total ' + _secs(total) + ')</div>'
                + f'<div class="bar">{"".join(bar)}</div><div class="legend">{"".join(legend)}</div>'
                + self.run_timeline())

    def run_timeline(self) -> str:
        """The run on a time axis: task-planner calls (blue), refinement phases (grey/orange), failures (red)."""
        ev = self.run.events
        if not ev:
            return ""
        end = max(e.get("t", 0) for e in ev) or 1.0
        segs = []
        for i, e in enumerate(ev):
            t = e.get("t", 0.0)
            if e["type"] == "task_plan":
                t0 = max(0.0, t - float(e.get("time") or 0))
                segs.append((t0, t, "#3f6fd8", f"task plan #{e.get('call')}: {t - t0:.2f} s"))
            elif e["type"] == "refine":
                nxt = next((x.get("t", t) for x in ev[i + 1:] if x["type"] not in ("attempt",)), end)
                col = "#a6afbb" if e.get("mode") == "error-free" else "#e0a060"
                segs.append((t, nxt, col, f"{e.get('mode')} refinement from step {e.get('from_step')}: {nxt - t:.2f} s"))
            elif e["type"] == "failure":
                segs.append((t, t, "fail", f"failure at step {e.get('step')}: {self.shown(', '.join(e.get('facts') or []))}"))
        divs = []
        for t0, t1, col, label in segs:
            left, width = 100 * t0 / end, max(0.15, 100 * (t1 - t0) / end)
            if col == "fail":
                divs.append(f'<div class="fail" style="left:{left:.2f}%" title="{escape(label)}"></div>')
            else:
                divs.append(f'<div style="left:{left:.2f}%;width:{width:.2f}%;background:{col}" title="{escape(label)}"></div>')
        return ('<div style="margin-top:10px"><b>The run over time</b> <span class="muted">(0 - '
                f'{end:.2f} s; hover for details)</span></div><div class="timeline">{"".join(divs)}</div>'
                '<div class="legend"><span><i style="background:#3f6fd8"></i>task planner</span>'
                '<span><i style="background:#a6afbb"></i>error-free refinement</span>'
                '<span><i style="background:#e0a060"></i>partial refinement (searching for failures)</span>'
                '<span><i style="background:#c9302c"></i>failure translated into facts</span></div>')

    # -- solution ----------------------------------------------------------------------------
    def solution(self) -> str:
        from .page import scene_embed

        r = self.run.result
        if r.get("status") != "solved":
            return ""
        html = ["<h2>Final plan</h2>", _plan_list(r.get("plan") or [], labels=self.run.labels)]
        scene, _ = solution_scene(self.run, self.run.trajectory, "solution") if self.run.trajectory else (None, [])
        if scene is not None:
            html.append(scene_embed(scene, 640, 400, lazy=True))
            self.views += 1
        return "\n".join(html)

    # -- timeline ---------------------------------------------------------------------------
    def timeline_section(self) -> str:
        ev = self.run.events
        html = ["<h2>Step by step</h2>",
                '<p class="muted">Every task plan, every refinement phase (attempts collapsed), every failure with '
                "the facts it taught the task planner, and every replan, in order. In the 3D views the "
                '<span class="key"><i style="background:#e61f1f"></i>obstructing objects</span> are red and the '
                '<span class="key"><i style="background:#ff8c00"></i>object being acted on</span> is orange.</p>']
        plan, i, nfail = [], 0, 0
        pending_task = None
        while i < len(ev):
            e = ev[i]
            kind = e.get("type")
            t = f'<span class="t">t = {e.get("t", 0):.2f} s</span>'
            if kind == "task_plan":
                frm = e.get("from_step", 0)
                if e.get("status") == "solved":
                    new_full = plan[:frm] + list(e.get("plan") or [])
                    if e.get("call", 1) == 1 or not plan:
                        marks, removed, note = {}, [], ""
                    else:
                        marks, removed = _diff_marks(plan, new_full, frm)
                        added = sum(1 for m in marks.values() if m == "added")
                        keep = f"keeps the first {frm} step(s)" if frm else "a new plan from the start"
                        note = f" <span class=muted>- {keep}; {added} step(s) added, {len(removed)} dropped</span>"
                    cost = f", cost {e['cost']:g}" if e.get("cost") is not None else ""
                    html.append(f'<div class="ev task">{t}<h3>Task plan #{e.get("call")} '
                                f'<span class="muted">(planning from step {frm}, {e.get("time", 0):.2f} s{cost})</span>{note}</h3>'
                                + _plan_list(new_full, 0, marks, removed, self.run.labels) + "</div>")
                    pending_task = new_full
                else:
                    html.append(f'<div class="ev dead">{t}<h3>Task planner call #{e.get("call")} from step {frm}: '
                                f'{escape(str(e.get("status")))}</h3>{escape(e.get("reason") or "")}</div>')
                if e.get("call", 1) == 1 and pending_task is not None:
                    plan = pending_task
            elif kind == "refine":
                j = i + 1
                attempts, jumps = [], []
                while j < len(ev) and ev[j].get("type") in ("attempt", "backjump"):
                    (attempts if ev[j]["type"] == "attempt" else jumps).append(ev[j])
                    j += 1
                html.append(self.refine_block(e, attempts, ev[j] if j < len(ev) else None, jumps))
                plan = list(e.get("plan") or plan)
                i = j
                continue
            elif kind == "attempt":  # outside a refine phase (should not happen)
                html.append(self.refine_block({"mode": e.get("mode"), "from_step": e.get("step")}, [e], None))
            elif kind == "failure":
                nfail += 1
                html.append(self.failure_block(e, nfail))
            elif kind == "replan":
                prefix = e.get("prefix") or []
                plan = list(e.get("plan") or plan)
                kept = (f"kept the prefix of {len(prefix)} refined step(s): "
                        + ", ".join(f"<code>{escape(step_str(s, self.run.labels))}</code>" for s in prefix)) if prefix \
                    else "no prefix kept (the failure was at the first step)"
                keep_ref = " (their motions are reused unchanged)" if prefix else ""
                start = e.get("from_step", e.get("fail_step"))
                html.append(f'<div class="ev replan">{t}<h3>Replanned from step {start}</h3>{kept}; '
                            f'the new plan has {len(plan)} step(s) and refinement resumes at step {start}'
                            f"{keep_ref}.</div>")
            elif kind == "known_dead_end":
                html.append(f'<div class="ev dead">{t}<h3>No plan from step {e.get("from_step")}: known</h3>Task-planner '
                            f'call #{e.get("proved_by")} proved it (the same state, or one with fewer of the facts that '
                            "only forbid actions): no call.</div>")
            elif kind == "earlier":
                html.append(f'<div class="ev dead">{t}<h3>No plan at step {e.get("step")}: planning from before step '
                            f'{e.get("from_step")}</h3>The same facts, from before <code>{escape(self.shown(e.get("action", "")))}</code> '
                            "(no step since moved an object they name).</div>")
            elif kind == "dead_end":
                html.append(f'<div class="ev dead">{t}<h3>Dead end at step {e.get("step")}</h3>The state with '
                            + ", ".join(f'<span class="fact">{escape(self.shown(f))}</span>' for f in e.get("facts") or [])
                            + (" timed out in the task planner" if e.get("status") == "timeout" else " has no plan")
                            + "; the next partial refinement is tried.</div>")
            elif kind == "reset":
                html.append(f'<div class="ev reset">{t}<h3>Reset (epoch {e.get("epoch")})</h3>'
                            f'{escape(e.get("reason") or "")} after {e.get("traj_count", "?")} failure(s): learned '
                            "facts cleared, pose generators reseeded, refinement restarts from step 0.</div>")
            elif kind == "refined":
                html.append(f'<div class="ev done">{t}<h3>All {e.get("steps")} steps refined</h3>'
                            "Every action has a motion plan; the task plan was validated.</div>")
            elif kind == "shortened" and e.get("dropped"):
                dropped = e["dropped"]
                html.append(f'<div class="ev done">{t}<h3>Refined {e.get("refined")} steps, dropped {len(dropped)} as not '
                            'needed</h3>Shortcutting: the plan still refines without '
                            + ", ".join(f"<code>{escape(step_str(s, self.run.labels))}</code>" for s in dropped)
                            + f"; the final plan has {len(e.get('plan') or [])} step(s).</div>")
            elif kind == "end":
                ok = e.get("status") == "solved"
                html.append(f'<div class="ev {"done" if ok else "dead"}">{t}<h3>End: {escape(str(e.get("status")))}</h3>'
                            f'{escape(e.get("reason") or "")}</div>')
            elif kind == "start":
                html.append(f'<div class="ev">{t}<h3>Start: {escape(str(e.get("problem")))}</h3>'
                            f'{e.get("references", "?")} pose references in the task model.</div>')
            i += 1
        return "\n".join(html)

    def backjump_text(self, b) -> str:
        """What a backjump of TryRefine skipped, and why (the ``backjump`` trace event)."""
        skipped = b.get("skipped") or []
        objs = ", ".join(map(self.shown, b.get("objects") or []))
        if b.get("known") is not None:
            then = ("the success counts as a failure and the step's next candidate is tried" if b.get("to") is not None
                    else "this happened before in this pass: the pass ends and the partial pass learns the obstruction")
            return (f"step {b['known']} succeeded again but left {escape(objs)} where every candidate of step "
                    f"{b.get('step')} <code>{escape(self.shown(b.get('action', '')))}</code> failed on them, whatever the "
                    f"robot's start: step(s) {escape(_span(skipped))} not refined for it; {escape(then)}.")
        where = "" if b.get("start_free") else " and did not move the robot"
        then = (f"the search goes back to step {b['to']}, which moved one of them" if b.get("to") is not None
                else "the pass ends here and the partial pass learns the obstruction")
        return (f"every candidate of step {b.get('step')} <code>{escape(self.shown(b.get('action', '')))}</code> failed "
                f"on {escape(objs)}; step(s) {escape(_span(skipped))} moved none of them{where}, "
                f"so their other candidates could not help: not re-refined; {escape(then)}.")

    def refine_block(self, e, attempts, after, jumps=()) -> str:
        ok = sum(1 for a in attempts if a.get("ok"))
        bad = len(attempts) - ok
        cached = sum(1 for a in attempts if a.get("cached"))
        t0 = e.get("t", 0.0)
        dur = (after.get("t", t0) - t0) if after else 0.0
        mode = e.get("mode", "?")
        what = ("try to refine every remaining step without moving any object" if mode == "error-free"
                else "search refinements that fail with a translatable reason")
        rows = []
        for a in attempts[:400]:
            f = a.get("failure") or {}
            res = "ok" if a.get("ok") else escape(self.shown(f.get("detail") or f.get("kind") or "failed"))
            if f.get("objects"):
                res += " <b>[" + escape(", ".join(map(self.shown, f["objects"]))) + "]</b>"
            rows.append(f'<tr><td>{a.get("step")}</td><td class="mono">{escape(self.shown(a.get("action", "")))}</td>'
                        f'<td>{escape(self.shown(str(a.get("candidate", ""))))}{" (cached)" if a.get("cached") else ""}</td>'
                        f'<td class="{"okc" if a.get("ok") else "badc"}">{res}</td></tr>')
        more = f"<p class=muted>... {len(attempts) - 400} more</p>" if len(attempts) > 400 else ""
        table = ("<details><summary>show the attempts</summary><table class=attempts><tr><th>step</th><th>action</th>"
                 f'<th>candidate</th><th>result</th></tr>{"".join(rows)}</table>{more}</details>') if attempts else ""
        return (f'<div class="ev refine"><span class="t">t = {t0:.2f} s</span><h3>{escape(mode.capitalize())} refinement '
                f'from step {e.get("from_step")} <span class="muted">(epoch {e.get("epoch", 0)}, {dur:.2f} s)</span></h3>'
                f'{escape(what)}: {len(attempts)} attempt(s), <span style="color:#2e9d4a">{ok} ok</span>, '
                f'<span style="color:#c9302c">{bad} failed</span>{f", {cached} cached" if cached else ""}.{table}'
                + "".join(f"<div>Backjump: {self.backjump_text(b)}</div>" for b in jumps) + "</div>")

    def failure_block(self, e, n) -> str:
        from .page import scene_embed

        f = e.get("failure") or {}
        objs = f.get("objects") or []
        facts = e.get("facts") or []
        text = [f'<h3>Failure {n}: step {e.get("step")} <code>{escape(self.shown(e.get("action", "")))}</code> cannot be refined</h3>',
                f'<div>candidate: {escape(self.shown(str(e.get("candidate", ""))))}</div>',
                f'<div>reason: {escape(f.get("kind", "?"))} - {escape(self.shown(f.get("detail") or ""))}</div>']
        if objs:
            text.append("<div>obstructed by: " + ", ".join(f'<b style="color:#c9302c">{escape(self.shown(o))}</b>' for o in objs) + "</div>")
        for r in f.get("related") or ():  # the same action with other objects, found in the same world (Failure.related)
            st = r.get("step") or {"action": e.get("action", "").split("(")[0], "args": [*(r.get("with") or {}).values(), "..."]}
            text.append(f'<div>also: {escape(self.shown(st["action"] + "(" + ", ".join(map(str, st["args"])) + ")"))} - '
                        f'{escape(self.shown(r.get("detail") or r.get("kind") or ""))}</div>')
        text.append("<div>learned: " + (", ".join(f'<span class="fact">{escape(self.shown(x))}</span>' for x in facts) or "nothing")
                    + "</div><div class=muted>The task planner now plans from the state before this step with these facts (a (not ...) fact is deleted).</div>")
        view = ""
        if self.views < MAX_FAILURE_VIEWS and self.run.problem is not None:
            scene = failure_scene(self.run.problem, e)
            if scene is not None:
                view = scene_embed(scene, 380, 260, lazy=True)
                self.views += 1
        return (f'<div class="ev failure"><span class="t">t = {e.get("t", 0):.2f} s</span><div class="failure-body">'
                f'<div class="failure-text">{"".join(text)}</div>{view}</div></div>')
