"""The ``interlayer`` command. Exit codes: 0 solved/ok, 1 not solved/invalid, 2 user error, 130 interrupted
(Ctrl-C, SIGTERM, SIGHUP).

With ``--json`` only one JSON object goes to stdout; logs and progress go to stderr.
"""
from __future__ import annotations

import argparse
import json
import os
import sys

from .errors import UserError
from .faults import PluginFault
from .names import relabel, step_text
from .result import MEANING

EXIT_OK, EXIT_NOT_SOLVED, EXIT_USER_ERROR, EXIT_INTERRUPTED = 0, 1, 2, 130


def log(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def shortened_text(e: dict, labels=None) -> str:
    """The 'shortened' trace event in words: how many steps were refined and which were dropped."""
    dropped = e["dropped"]
    return (f"refined {e['refined']} steps, dropped {len(dropped)} as not needed: "
            + "; ".join(step_text(s, labels) for s in dropped))


def progress_printer(verbose: bool):
    """Turn trace events into short human-readable lines on stderr, in the problem's names (the
    "start" event's ``names``: symbol -> name where they differ)."""
    labels = {}

    def show(e):
        if e["type"] == "start":
            labels.update(e.get("names") or {})
        if e["type"] == "attempt" and not verbose:
            return
        t = f"[{e['t']:7.2f}s]"
        kind = e["type"]
        if kind == "task_plan":
            if e["status"] == "solved":
                steps = "; ".join(step_text(s, labels) for s in e["plan"])
                cost = f", cost {e['cost']:g}" if e.get("cost") is not None else ""
                log(f"{t} task plan #{e['call']} from step {e['from_step']} ({e['time']:.2f} s{cost}): {steps}")
            else:
                log(f"{t} task planner call #{e['call']}: {e['status']} {e['reason']}".rstrip())
        elif kind == "failure":
            log(relabel(f"{t} refinement failed at step {e['step']} {e['action']}: {e['failure']['kind']}", labels)
                + f" {', '.join(labels.get(o, o) for o in e['failure']['objects'])}"
                f" -> learned {relabel(', '.join(e['facts']), labels)}")
        elif kind == "replan":
            log(f"{t} replanned from step {e.get('from_step', e['fail_step'])}, kept a prefix of {len(e['prefix'])} action(s)")
        elif kind == "known_dead_end":
            log(f"{t} the state from step {e['from_step']} has no plan: task-planner call #{e['proved_by']} proved it "
                "(the same state, or one with fewer of the facts that only forbid actions)")
        elif kind == "earlier":
            log(f"{t} the updated state at step {e['step']} has no plan: planning from before step {e['from_step']} "
                f"{relabel(e['action'], labels)} with the same facts")
        elif kind == "dead_end":
            why = "the task planner timed out on it" if e.get("status") == "timeout" else "it has no plan"
            log(f"{t} the updated state at step {e['step']} is a dead end ({why}); trying the next partial refinement")
        elif kind == "recurring":
            log(f"{t} the failure at step {e['step']} recurs ({relabel(', '.join(e['facts']), labels)} learned {e['limit']} times in "
                f"this epoch already); trying the next partial refinement")
        elif kind == "reset":
            log(f"{t} reset (epoch {e['epoch']}): {e['reason']}; learned facts cleared, generators reseeded")
        elif kind == "refined":
            log(f"{t} refinement found for all {e['steps']} steps")
        elif kind == "shortened" and e["dropped"]:
            log(f"{t} {shortened_text(e, labels)}")
        elif kind == "warning":
            log(f"warning: {e['message']}")
        elif kind == "attempt":
            verdict = "ok" if e["ok"] else relabel((e["failure"] or {}).get("detail") or "failed", labels)
            log(relabel(f"{t}   {e['mode']} step {e['step']} {e['action']} [{e['candidate']}]: ", labels) + verdict)

    show.verbose = verbose
    return show


class StatusLine:
    """On a terminal: one status line at the bottom of stderr, redrawn in place (elapsed time, phase,
    task-planner calls, replans, the current step, the longest refined prefix), with the event lines
    printed above it; a daemon thread redraws it while a step takes long."""

    TICK = 0.25  # s between redraws of the elapsed time

    def __init__(self, events, stream=None):
        import threading

        from .trace import process_start

        self.events, self.stream = events, stream or sys.stderr
        self.start = process_start()  # the wait so far, imports included
        self.phase, self.calls, self.replans = "starting (imports, plugins, scene)", 0, 0
        self.step, self.plan_length, self.best = None, 0, 0
        self.lock, self.shown, self.stopped = threading.Lock(), False, threading.Event()
        threading.Thread(target=self._tick, daemon=True, name="interlayer-status").start()

    def _tick(self):
        while not self.stopped.wait(self.TICK):
            self.draw()

    def text(self) -> str:
        import time

        parts = [f"[{time.perf_counter() - self.start:7.1f}s] {self.phase}"]
        if self.plan_length:
            if self.step is not None:
                parts.append(f"step {self.step}/{self.plan_length}")
            parts.append(f"refined prefix {self.best}/{self.plan_length}")
        parts.append(f"task-planner calls {self.calls}, replans {self.replans}")
        return " | ".join(parts)

    def draw(self):
        import shutil

        width = shutil.get_terminal_size((100, 20)).columns - 1
        with self.lock:
            if not self.stopped.is_set():
                self.stream.write("\r\x1b[K" + self.text()[:width])
                self.stream.flush()
                self.shown = True

    def clear(self):
        with self.lock:
            if self.shown:
                self.stream.write("\r\x1b[K")
                self.stream.flush()
                self.shown = False

    def set_phase(self, phase: str):
        self.phase = phase
        self.draw()

    def stop(self):
        self.stopped.set()
        self.clear()

    def __call__(self, e):
        kind = e["type"]
        if kind in ("start", "failure"):
            self.phase = "task planning"
        elif kind == "task_plan":
            self.calls = e["call"]
            if e["status"] == "solved":
                self.plan_length = e["from_step"] + len(e["plan"])
                self.phase = "refinement"
        elif kind == "refine":
            self.phase, self.plan_length = f"{e['mode']} refinement", len(e["plan"])
            self.best = min(self.best, e["from_step"])
        elif kind == "attempt":
            self.step = e["step"]
            if e["ok"]:
                self.best = max(self.best, e["step"] + 1)
        elif kind == "replan":
            self.replans += 1
            self.plan_length, self.best = len(e["plan"]), e["fail_step"]
        elif kind == "reset":
            self.best, self.phase = 0, f"reset (epoch {e['epoch']})"
        elif kind == "refined":
            self.phase, self.step = "shortcutting", None
        elif kind == "shortened":
            self.plan_length = self.best = len(e["plan"])
            self.phase = "validating"
        elif kind == "end":
            self.phase = "done"
        if kind != "attempt" or self.events.verbose:  # the event lines go above the status line
            self.clear()
            with self.lock:
                self.events(e)
        self.draw()


def cmd_plan(args) -> int:
    from . import api
    from .loop import Interrupted
    from .trace import process_start

    if args.verbose:  # libraries' own messages (e.g. OMPL's) too
        import logging

        logging.getLogger("interlayer").setLevel(logging.INFO)
    if args.dump_pddl and not args.out:
        raise UserError("--dump-pddl writes into OUT_DIR/pddl/: give --out DIR as well.")
    if args.out:  # found now, not after the whole plan ran
        from .runfolder import check_writable

        check_writable(args.out, "The output folder (--out)", folder=True)
    lines = progress_printer(args.verbose)
    status = StatusLine(lines) if not args.quiet and sys.stderr.isatty() else None
    listeners = [] if args.quiet else [status or lines]
    viewer = None
    if args.viz:  # streams the search; its server stops with the run
        from .viz import live_stream

        viewer = live_stream(host=args.viz_host)
        listeners.append(viewer)
    pddl_dir = f"{args.out}/pddl" if args.dump_pddl else None

    def stuck(result):  # a plugin call overran the time limit in C code or a sleep: end the process
        try:
            log(f"Not solved ({result.status}): {result.reason}")
            if args.out:
                api.write_outputs(result, args.out)
            if args.json:
                print(json.dumps(result.to_json()), flush=True)
        finally:
            sys.stderr.flush()
            os._exit(EXIT_NOT_SOLVED)

    try:
        try:
            result = api.solve(args.source, overrides=args.set, listeners=listeners, pddl_dir=pddl_dir,
                               origin=process_start(), on_stuck=stuck, export=bool(args.out))
        except Interrupted as stop:  # keep what was done: the trace so far explains the run
            stopped, when = stop.result, ""
        else:
            stopped = None
            try:
                if args.out:
                    if status:
                        status.set_phase(f"writing {args.out}/" + (" (exporting the trajectory)" if result.solved else ""))
                    api.write_outputs(result, args.out)
            except KeyboardInterrupt:  # after the solve: the whole set is written (again, if the signal came first)
                stopped, when = result, " after the problem was solved"
        if stopped is not None:
            if status:
                status.stop()
            if viewer:
                viewer.close()
            return _interrupted(args, stopped, when)
    except BaseException:
        if viewer:
            viewer.close()
        raise
    finally:
        if status:
            status.stop()
    data = result.to_json()
    if args.json:
        print(json.dumps(data))
    else:
        log("")
        if result.solved:
            log(f"Solved in {data['times']['total']:.2f} s with {result.task_planner_calls} task-planner call(s) and "
                f"{result.replans} replan(s).")
            for i, s in enumerate(result.plan):
                log(f"  {i}: {step_text(s, data['names'])}")
        else:
            log(f"Not solved ({result.status}: {MEANING.get(result.status, 'not solved')}): {result.reason}")
        if result.learned_facts:
            log("Learned facts: " + relabel(", ".join(data["learned_facts"]), data["names"]))
        if args.out:
            log(f"Wrote {args.out}/ (result.json, trace.json, config.toml, problem.json"
                f"{', trajectory.json' if result.solved else ''}).")
    if viewer:  # after the summary: in a terminal the live viewer waits for Ctrl-C
        viewer.finish(result)
    return EXIT_OK if result.solved else EXIT_NOT_SOLVED


def _interrupted(args, result, when: str) -> int:
    from . import api

    if args.out:
        api.write_outputs(result, args.out)
    what = "the run" if result.solved else "the trace so far"
    log(f"interrupted{when}{f'; wrote {what} to {args.out}/' if args.out else ''}")
    if args.json:
        print(json.dumps(result.to_json()))
    return EXIT_INTERRUPTED


def cmd_check(args) -> int:
    from . import api
    from .logic import atom_str
    from .plugins import PluginHost

    host = PluginHost()
    for warning in host.warnings:
        log(f"warning: {warning}")
    prepared = api.prepare(args.source, args.set, host)  # everything 'plan' would check
    model = prepared.model
    describe = getattr(prepared.problem.geometry, "describe", None)  # the domain's own summary of the scene
    scene = describe() if callable(describe) else None
    refs: dict = {}
    for ref, (sk, _) in model.references.items():
        refs.setdefault(sk, []).append(ref)
    report = {
        "references": refs,
        "reference_facts": sorted(atom_str(a) for a in model.static_facts),
        "names": model.labels,  # symbol -> the name a person gave it, where they differ
        "geometric_predicates": {p: {"occurs": form, "default": form == "positive"} for p, form in model.geometric.items()},
        "default_true_atoms": len(model.default_true),
        "uniform": not model.uniformity,
        "uniformity_violations": model.uniformity,
        "parameters": model.parameter_roles,
        "task_view": {a.name: [f"{v} - {t}" for v, t in a.parameters] for a in model.actions.values()},
        **({"scene": scene} if scene else {}),
        "scene_issues": [{"kind": kind, "message": sentence} for kind, sentence in prepared.scene_issues],
    }
    refused = any(kind == "error" for kind, _ in prepared.scene_issues)  # 'plan' would refuse the scene
    for kind, sentence in prepared.scene_issues:
        log(f"{kind}: {sentence}")
    if args.json:
        print(json.dumps(report, indent=1))
        return EXIT_USER_ERROR if refused else EXIT_OK
    if scene:
        print(f"Scene: {scene}")
    print(f"Pose references ({len(model.references)}):")
    for sk, names in refs.items():
        print(f"  {sk}: {', '.join(model.labels.get(n, n) for n in names)}")
    facts = [relabel(f, model.labels) for f in report["reference_facts"][:12]]
    print("Reference facts: " + " ".join(facts) + (" ..." if len(report["reference_facts"]) > 12 else ""))
    print("Geometric predicates and their Prop. 1 defaults:")
    for p, info in report["geometric_predicates"].items():
        print(f"  {p}: occurs {info['occurs']}ly -> default {'true' if info['default'] else 'false'}")
    print("Action parameters:")
    for a, roles in model.parameter_roles.items():
        for v, role in roles.items():
            print(f"  {a} {v}: {role}")
    if model.uniformity:
        print("Not uniform w.r.t. the goal and geometric predicates (Def. 1), so Theorem 1 does not apply:")
        for v in model.uniformity:
            print(f"  - {v}")
    else:
        print("Uniform w.r.t. the goal and the geometric predicates (Def. 1): Theorem 1's completeness holds "
              "if the problem also has no reachable dead ends (not checked).")
    return EXIT_USER_ERROR if refused else EXIT_OK


def cmd_plugins(args) -> int:
    from .plugins import PluginHost

    host = PluginHost()
    plugins = []
    for info in host.plugins():
        comps = {}
        for kind, names in info.components.items():
            reg = host[kind]
            comps[kind] = [{"name": n, "available": reg.components[n].available, "reason": reg.components[n].reason,
                            "description": reg.components[n].description} for n in names]
        plugins.append({"name": info.name, "distribution": info.distribution, "version": info.version,
                        "hooks": info.hooks, "components": comps})
    broken = host.broken
    if args.json:
        print(json.dumps({"plugins": plugins, "broken": broken, "warnings": host.warnings}, indent=1))
        return EXIT_OK
    for p in plugins:
        print(f"{p['name']}  ({p['distribution']} {p['version']})  hooks: {', '.join(h.replace('interlayer_', '') for h in p['hooks'])}")
        for kind, comps in p["components"].items():
            for c in comps:
                state = "" if c["available"] else f"  [unavailable: {c['reason']}]"
                print(f"    {kind[:-1].replace('_', ' ')}: {c['name']}{state}")
    for name, why in broken.items():
        print(f"{name}: failed to load, skipped: {why}")
    for warning in host.warnings:
        print(f"warning: {warning}")
    return EXIT_OK


def cmd_validate(args) -> int:
    from . import api

    report = api.validation(args.out_dir)
    violations = report.violations
    if args.json:
        print(json.dumps({"valid": not violations, "violations": violations, "checked": report.checked}))
    elif violations:
        log(f"INVALID: {len(violations)} violation(s):")
        for v in violations:
            log(f"  - {v}")
    else:
        log(f"{args.out_dir}: valid ({'; '.join(report.checked)}).")
    return EXIT_OK if not violations else EXIT_NOT_SOLVED


def cmd_viz(args) -> int:
    from .runfolder import check_writable
    from .viz import write_plan_html

    check_writable(args.output, "The page (-o)", folder=False)
    write_plan_html(args.out_dir, args.output, args.visualizer)
    log(f"Wrote {args.output}")
    return EXIT_OK


def cmd_explain(args) -> int:
    from .runfolder import check_writable
    from .viz import write_explain_html

    check_writable(args.output, "The page (-o)", folder=False)
    write_explain_html(args.out_dir, args.output, args.visualizer)
    log(f"Wrote {args.output}")
    return EXIT_OK


def distribution_version() -> str:
    """The installed distribution's version; the package's own in a source checkout that is not installed."""
    from importlib import metadata

    try:
        return metadata.version("interlayer")
    except metadata.PackageNotFoundError:
        from . import __version__

        return __version__


class _Version(argparse.Action):
    """--version, looked up only when asked for (metadata lookups cost start-up time)."""

    def __init__(self, option_strings, dest=argparse.SUPPRESS, default=argparse.SUPPRESS, help=None):
        super().__init__(option_strings, dest, nargs=0, default=default, help=help)

    def __call__(self, parser, namespace, values, option_string=None):
        print(f"interlayer {distribution_version()}")
        parser.exit()


def cmd_export(args) -> int:
    from .export import export

    written = export(args.out_dir, args.format, args.output)
    log(f"Wrote {written['path']} ({written['segments']} joint trajectories, {written['points']} points).")
    if args.json:
        print(json.dumps(written))
    return EXIT_OK


def cmd_robot_check(args) -> int:
    from .plugins import PluginHost

    report = PluginHost().pm.hook.interlayer_check_robot(path=args.robot)
    if report is None:
        raise UserError("no installed plugin checks robot descriptions (the robot layer interlayer_pinocchio "
                        "registers one: is the interlayer package installed with its entry points?)")
    if args.json:
        print(json.dumps(report))
    else:
        print("\n".join(_outline(report)))
    return EXIT_OK


def _outline(value, indent: str = "") -> list[str]:
    """A JSON-ready report as indented ``key: value`` lines (lists of plain values on one line)."""
    lines = []
    for key, item in value.items():
        if isinstance(item, (dict, list)) and not item:
            lines.append(f"{indent}{key}: none")
        elif isinstance(item, dict):
            lines += [f"{indent}{key}:"] + _outline(item, indent + "  ")
        elif isinstance(item, list) and any(isinstance(x, dict) for x in item):
            for x in item:
                lines += [f"{indent}{key}:"] + _outline(x, indent + "  ")
        else:
            shown = ", ".join(map(str, item)) if isinstance(item, list) else item
            lines.append(f"{indent}{key}: {shown}")
    return lines


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="interlayer", description=__doc__.splitlines()[0])
    parser.add_argument("--version", action=_Version, help="print the installed version and exit")
    sub = parser.add_subparsers(dest="command", required=True)
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="override a config value, e.g. --set planner.task=pyperplan")
    common.add_argument("--json", action="store_true", help="print one JSON object to stdout")

    p = sub.add_parser("plan", parents=[common], help="solve a problem (config file, problem file or output folder)")
    p.add_argument("source", metavar="CONFIG_OR_PROBLEM")
    p.add_argument("--out", metavar="DIR", help="write result.json, trace.json, trajectory.json, ... to DIR")
    p.add_argument("--viz", action="store_true",
                   help="stream the search into a live 3D viewer (each failure's world, then the solution)")
    p.add_argument("--viz-host", default="127.0.0.1", metavar="ADDRESS",
                   help="the address the live viewer's server listens on (default 127.0.0.1: this machine only)")
    p.add_argument("--dump-pddl", action="store_true",
                   help="write each task-planner call's problem to OUT_DIR/pddl/ (call-NNN-domain.pddl, call-NNN-problem.pddl)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress lines")
    p.add_argument("-v", "--verbose", action="store_true", help="show every refinement attempt and the libraries' own messages (OMPL's)")
    p.set_defaults(func=cmd_plan)

    c = sub.add_parser("check", parents=[common], help="show pose references, Prop. 1 defaults and uniformity (Def. 1)")
    c.add_argument("source", metavar="CONFIG_OR_PROBLEM")
    c.set_defaults(func=cmd_check)

    pl = sub.add_parser("plugins", help="list plugins and the components they register")
    pl.add_argument("--json", action="store_true")
    pl.set_defaults(func=cmd_plugins)

    v = sub.add_parser("validate", help="independently re-check a solved run written with --out")
    v.add_argument("out_dir", metavar="OUT_DIR")
    v.add_argument("--json", action="store_true")
    v.set_defaults(func=cmd_validate)

    for name, func, default, what in (("viz", cmd_viz, "plan.html", "a self-contained 3D animation of the refined plan"),
                                      ("explain", cmd_explain, "explain.html", "a page explaining every task plan, failure and replan")):
        page = sub.add_parser(name, help=f"write {what}")
        page.add_argument("out_dir", metavar="OUT_DIR")
        page.add_argument("-o", "--output", default=default, help=f"the HTML file to write (default {default})")
        page.add_argument("--visualizer", default="meshcat", help="the registered visualizer to use")
        page.set_defaults(func=func, json=False)

    from .export import FORMATS

    e = sub.add_parser("export", help="write a solved run's joint trajectories for a robot (a ROS 2 bag or CSV)")
    e.add_argument("out_dir", metavar="OUT_DIR")
    e.add_argument("--format", required=True, choices=FORMATS,
                   help="rosbag2: one trajectory_msgs/msg/JointTrajectory per segment (extra 'export'); csv: one row per point")
    e.add_argument("-o", "--output", required=True, metavar="PATH", help="the bag folder or CSV file to write")
    e.add_argument("--json", action="store_true", help="print what was written as one JSON object to stdout")
    e.set_defaults(func=cmd_export)

    r = sub.add_parser("robot", help="robot descriptions (see docs/robots.md)")
    rsub = r.add_subparsers(dest="robot_command", required=True)
    rc = rsub.add_parser("check", help="load a robot description and report what it found, or the error naming the field")
    rc.add_argument("robot", metavar="NAME_OR_FILE", help="a shipped robot's name (pr2, panda, ...) or a description file")
    rc.add_argument("--json", action="store_true", help="print the report as one JSON object to stdout")
    rc.set_defaults(func=cmd_robot_check)

    from .bench.commands import add_commands  # bench, report

    add_commands(sub)
    return parser


def _signals_interrupt():
    """SIGTERM (kill, timeout, systemd, CI) and SIGHUP (a closed terminal) stop a run as Ctrl-C does.
    Returns the handlers to restore."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        return {}
    sigs = [signal.SIGTERM] + ([signal.SIGHUP] if hasattr(signal, "SIGHUP") else [])
    return {sig: signal.signal(sig, signal.default_int_handler) for sig in sigs}


def main(argv=None) -> int:
    import signal

    args = build_parser().parse_args(argv)
    saved = _signals_interrupt()
    try:
        return _run(args)
    finally:
        for sig, handler in saved.items():
            signal.signal(sig, handler)


def _run(args) -> int:
    try:
        return args.func(args)
    except UserError as exc:
        log(f"error: {exc}")
        if getattr(args, "json", False):
            print(json.dumps({"status": "error", "reason": str(exc)}))
        return EXIT_USER_ERROR
    except KeyboardInterrupt:
        log("interrupted")
        return EXIT_INTERRUPTED
    except PluginFault as fault:  # a bug in a plugin: its name, the component, one line
        if os.environ.get("INTERLAYER_DEBUG"):
            raise
        log(f"error: {fault} (set INTERLAYER_DEBUG=1 for the traceback)")
        if getattr(args, "json", False):
            print(json.dumps({"status": "error", "reason": str(fault), "plugin": fault.plugin}))
        return EXIT_NOT_SOLVED
    except Exception as exc:  # an internal error: one sentence, the details only with INTERLAYER_DEBUG
        if os.environ.get("INTERLAYER_DEBUG"):
            raise
        log(f"internal error: {type(exc).__name__}: {exc} (set INTERLAYER_DEBUG=1 for the traceback; please report it)")
        if getattr(args, "json", False):
            print(json.dumps({"status": "error", "reason": f"{type(exc).__name__}: {exc}"}))
        return EXIT_NOT_SOLVED


def exit_after(entry) -> None:
    """Run ``entry()`` and exit with its code without tearing the interpreter down: freeing hundreds of
    modules and the C++ libraries' objects one by one takes 0.2-0.5 s that a user would wait for after
    the last line. atexit handlers registered since still run (e.g. stopping a warm task planner)."""
    import atexit

    code = []

    def leave():  # registered first, so it runs last (after non-daemon threads ended and every later handler)
        if code:
            os._exit(code[0])

    atexit.register(leave)
    code.append(entry())
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):  # a closed pipe
            pass
    sys.exit(code[0])


def run() -> None:
    """The ``interlayer`` command."""
    exit_after(main)


if __name__ == "__main__":
    run()
