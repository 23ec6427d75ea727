"""A TaskPlanner backed by any Unified-Planning OneshotPlanner engine."""
from __future__ import annotations

import functools
import importlib
import importlib.util
import inspect
import logging
import multiprocessing
import os
import subprocess
import sys
import tempfile
import threading
import time
import types
from dataclasses import dataclass, field

from interlayer.planning import TaskPlanner

from . import compat

# FF's algorithm in Fast Downward: enforced hill-climbing with the FF heuristic and helpful actions,
# then, when EHC fails (it is incomplete), greedy best-first search, as FF does. Fast Downward's
# iterated() search would do this in one call, but it numbers its plan files (plan.txt.1), which
# up-fast-downward does not read; so the fallback is a second call. No spaces: up-fast-downward
# splits the search string on whitespace.
FF_SEARCHES = ("let(hff,ff(),ehc(hff,preferred=[hff],preferred_usage=PRUNE_BY_PREFERRED))",
               "let(hff,ff(),lazy_greedy([hff],preferred=[hff]))")

log = logging.getLogger("interlayer")

# Engines that ignore UP's timeout: run them in a child process we can stop.
UNBOUNDED_ENGINES = ("pyperplan", "pyperplan-opt")

# Unified-Planning is imported once per process, by one thread.
_setup_lock = threading.Lock()
# UP's expressions live in one process-wide environment whose expression manager is not safe for
# threads (up-fast-downward's optimal engine builds in the global one whatever the problem's), so UP's
# work runs under this lock, released while an engine's own process runs (_run_command).
_UP_LOCK = threading.Lock()


def _quiet_environment():
    _import_up()
    from unified_planning.environment import get_environment

    env = get_environment()
    env.credits_stream = None
    env.error_used_name = False
    return env


def _import_up():
    """Import Unified-Planning and its engines without ConfigSpace and networkx: UP 1.3 imports ConfigSpace
    (and with it scipy.stats, most of UP's import time) only to describe engines' tuning parameters, which
    we never ask for, and networkx (a third of the rest) for plan graphs we never build. While UP loads,
    stand-in modules answer; each imports the real one on first use. Then the parts of UP the adapter
    relies on beyond its shortcuts are checked (compat.py)."""
    if "unified_planning.shortcuts" not in sys.modules:
        with _setup_lock:
            if "unified_planning.shortcuts" not in sys.modules:
                _import_up_without_configspace()
    compat.check()


# module -> the classes UP's modules name while they load (bound by name, or in annotations)
_STAND_INS = {"ConfigSpace": ("ConfigurationSpace",), "networkx": ("DiGraph",)}


def _import_up_without_configspace():
    stubs = {name: _stand_in(name, classes) for name, classes in _STAND_INS.items() if name not in sys.modules}
    before = set(sys.modules)
    sys.modules.update(stubs)
    failed = None
    try:
        _load_up(shallow=True)
    except Exception as exc:  # a UP that needs more of them than the stand-ins answer: forget what it loaded
        failed = f"{type(exc).__name__}: {exc}"
        for name in set(sys.modules) - before:
            del sys.modules[name]
    finally:
        for name, stub in stubs.items():
            if sys.modules.get(name) is stub:
                del sys.modules[name]
        if "networkx" in stubs:  # only annotations kept the stand-in class: later uses get the real one
            del stubs["networkx"].DiGraph
    if failed is not None:
        log.warning("Unified-Planning did not load beside the UP adapter's stand-ins for ConfigSpace and networkx "
                    "(%s); it loads with the real ones instead, a slower start.", failed)
        _load_up(shallow=False)


def _load_up(shallow: bool):
    import unified_planning.engines.factory as factory
    import unified_planning.shortcuts  # noqa: F401
    from unified_planning.environment import get_environment

    if shallow and getattr(factory, "inspect", None) is inspect:  # else UP no longer looks: nothing to save
        factory.inspect = _ShallowInspect("inspect")
    get_environment()  # its engine factory imports every installed engine (up_pyperplan too)


class _ShallowInspect(types.ModuleType):
    """``inspect`` for UP's engine factory, which calls ``inspect.stack()`` to find its callers' file
    names (the outermost one's folders are searched for up.ini), function names and line numbers:
    the same frames without their source lines, which it never reads (reading them, and finding each
    frame's module among all loaded ones, took 35 ms of every run's start)."""

    def __getattr__(self, name):
        return getattr(inspect, name)

    @staticmethod
    def stack(context=1):
        return inspect.getouterframes(sys._getframe(1), 0)


def _stand_in(name: str, classes) -> types.ModuleType:
    """A module for ``name`` whose attributes are the real module's, imported on first use; ``classes``
    are stand-in classes whose instances are the real classes' (a name bound while UP loads)."""
    stub = types.ModuleType(name)

    def real():
        if sys.modules.get(name) is stub:
            del sys.modules[name]
        return importlib.import_module(name)

    def attribute(attr):  # not dunders: the import machinery asks for those
        if attr.startswith("__"):
            raise AttributeError(attr)
        return getattr(real(), attr)

    for cls in classes:
        setattr(stub, cls, type(cls, (), {"__new__": lambda _, *args, _cls=cls, **kw: getattr(real(), _cls)(*args, **kw)}))
    stub.__getattr__ = attribute
    return stub


@functools.cache
def _in_folder_class():
    """The adapter's part of each PDDL engine class it makes (``_engine``)."""
    from unified_planning.engines.pddl_planner import PDDLPlanner
    from unified_planning.engines.results import LogLevel, LogMessage, PlanGenerationResult
    from unified_planning.engines.results import PlanGenerationResultStatus as S
    from unified_planning.io import PDDLWriter

    class InFolder(PDDLPlanner):
        """UP's PDDLPlanner._solve for one-shot planning, except that the engine's files are written in
        a folder of its own and its command runs there, by its warm driver if it has one (UP runs every
        command in this process's working directory, where Fast Downward writes output.sas: concurrent
        calls would read each other's tasks). It comes after the engine's class, before PDDLPlanner:
        an engine's own ``_solve`` (Fast Downward's optimal one adds a goal action) calls this one."""

        warm_driver = None  # a warm.WarmDriver for this engine's command, set by _engine
        reached = False  # this _solve ran (an engine's own _solve may no longer call it: _solve_locked)

        def _solve(self, problem, heuristic=None, timeout=None, output_stream=None):
            if output_stream is not None:  # never from the adapter: UP's own way, which streams it
                return super()._solve(problem, heuristic, timeout, output_stream)
            self.reached = True
            writer = PDDLWriter(problem, self._needs_requirements, self._rewrite_bool_assignments)
            with tempfile.TemporaryDirectory(prefix="interlayer-fd-") as folder:
                domain, task, plan_file = (os.path.join(folder, f) for f in ("domain.pddl", "problem.pddl", "plan.txt"))
                writer.write_domain(domain)
                writer.write_problem(task)
                cmd = self._get_cmd(domain, task, plan_file)
                timed_out, (out, err), retval = _run_command(cmd, folder, timeout, self.warm_driver)
                logs = [LogMessage(LogLevel.INFO, "".join(out)), LogMessage(LogLevel.ERROR, "".join(err))]
                plan = self._plan_from_file(problem, plan_file, writer.get_item_named) if os.path.isfile(plan_file) else None
            # (no temporal correction, as UP's has: the adapter's problems have instantaneous actions only)
            status = S.TIMEOUT if timed_out and retval != 0 else self._result_status(problem, plan, retval, logs)
            return PlanGenerationResult(status, plan, engine_name=self.name, log_messages=logs)

        def _plan_from_str(self, problem, plan_str, get_item_named):
            """One plan reader per environment (UP builds a PDDLReader, a pyparsing grammar, 20-40 ms,
            per plan it reads; reading a plan uses only regular expressions, not the grammar)."""
            return _plan_reader(problem.environment).parse_plan_string(problem, plan_str, get_item_named)

    return InFolder


@functools.cache
def _engine_class(cls):
    """``cls`` with the adapter's part (``InFolder``) mixed in, if it is a PDDL engine."""
    from unified_planning.engines.pddl_planner import PDDLPlanner

    if not issubclass(cls, PDDLPlanner):
        return cls
    return type(cls.__name__, (cls, _in_folder_class()), {"__module__": cls.__module__, "__doc__": cls.__doc__})


@dataclass
class UPTaskPlanner(TaskPlanner):
    engine: str = "fast-downward"
    params: dict = field(default_factory=dict)
    fallbacks: tuple = ()  # further params to try when the engine fails without proof (FF's EHC -> GBFS)
    # UP's SequentialPlanValidator on "every" plan, the "final" one, or "off". Off by default: every plan
    # is replayed with the core's semantics anyway (TaskPlanner.plan, the loop's final check and
    # `interlayer validate`), and UP's simulator grounds forall effects at each step (0.02-0.4 s a plan).
    validate: str = "off"
    warm: bool = True  # Fast Downward engines: run the driver in a warm process (warm.py), not a new Python per call
    _builders: dict = field(default_factory=dict)

    def _builder(self, model):
        from .convert import UPProblemBuilder

        key = id(model)
        if key not in self._builders:
            self._builders = {key: UPProblemBuilder(model)}
        return self._builders[key]

    def prepare(self, model):
        if self.warm and self.engine.startswith("fast-downward"):
            _spawn_warm_driver()
        with _UP_LOCK:
            self._prepare(model)

    def _prepare(self, model):
        env = _quiet_environment()
        self._builder(model).problem_for(model.init)
        if self.engine not in UNBOUNDED_ENGINES:
            # made now, before the run's clock: the engine, its warm process, its plan reader (a
            # pyparsing grammar, 30-100 ms)
            with _engine(self.engine, self.params, warm=self.warm) as engine:
                if isinstance(engine, _in_folder_class()):
                    _plan_reader(env)

    def _plan(self, model, state, timeout):
        with _UP_LOCK:
            _quiet_environment()
            problem = _settled(self._builder(model).problem_for(state))
            if self.pddl_dir is not None:
                _dump_pddl(problem, self.pddl_dir, self.calls, self._builder(model).name_of)
        deadline = time.perf_counter() + timeout
        for params in (self.params, *self.fallbacks):
            left = deadline - time.perf_counter()
            if self.engine in UNBOUNDED_ENGINES:
                status, plan, reason = _solve_in_child(self.engine, params, problem, left)
            else:
                status, plan, reason = _solve(self.engine, params, problem, left, self.warm)
            if status != "incomplete":
                break
        if status != "solved":  # "incomplete" stays so: no plan found, none proved impossible
            return status, [], reason, None
        if self.validate == "every":
            with _UP_LOCK:
                why = _up_validate(problem, plan)
            if why:
                return "error", [], why, None
        name_of = self._builder(model).name_of
        steps = [(ai.action.name, [name_of[p.object().name] for p in ai.actual_parameters]) for ai in plan.actions]
        cost = sum(model.actions[a].cost for a, _ in steps)
        return "solved", steps, "", cost


    def validate_plan(self, model, state, plan) -> str:
        """Check a plan with Unified-Planning's own SequentialPlanValidator."""
        if self.validate == "off":
            return super().validate_plan(model, state, plan)
        return self.library_check(model, state, plan)

    def library_check(self, model, state, plan) -> str:
        with _UP_LOCK:
            return self._library_check(model, state, plan)

    def _library_check(self, model, state, plan) -> str:
        _quiet_environment()
        from unified_planning.plans import ActionInstance, SequentialPlan

        builder = self._builder(model)
        problem = _settled(builder.problem_for(state))
        up_plan = SequentialPlan([ActionInstance(problem.action(s.action), [builder.objects[o] for o in model.task_args(s)])
                                  for s in plan])
        return _up_validate(problem, up_plan)


def _dump_pddl(problem, folder, call: int, name_of: dict) -> None:
    """Exactly what the task planner saw, so it can be rerun alone (``fast-downward domain problem``),
    and ``objects.txt``: what each object ``o<k>`` is (``o3 b2``, a line each)."""
    from pathlib import Path

    from unified_planning.io import PDDLWriter

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    problem = problem.clone()
    problem.__class__ = _sparse_problem_class()  # the engine's view (and not seconds for big reference sets)
    writer = PDDLWriter(problem)
    writer.write_domain(str(folder / f"call-{call:03d}-domain.pddl"))
    writer.write_problem(str(folder / f"call-{call:03d}-problem.pddl"))
    (folder / "objects.txt").write_text("".join(f"{o} {name}\n" for o, name in name_of.items()))


def _engine(name: str, params=None, checks: bool = False, warm: bool = False):
    """UP's engine ``name`` (a PDDL engine runs in folders of its own, ``InFolder``), made as its factory
    would but without the factory's credits notice, which walks the whole call stack with source lines
    (20-50 ms for every engine made); with ``warm``, its command goes to a warm driver if it has one."""
    engine = _engine_class(_quiet_environment().factory.engine(name))(**(params or {}))
    engine.error_on_failed_checks = checks  # the factory's setting: True only when it chose the engine
    if isinstance(engine, _in_folder_class()):
        compat.check_engine(engine)
        if warm:
            engine.warm_driver = _warm_driver(engine)
    return engine


@functools.cache
def _plan_reader(env):
    from unified_planning.io import PDDLReader

    return PDDLReader(env)


def _up_validate(problem, plan) -> str:
    with _engine("sequential_plan_validator", checks=True) as validator:
        check = validator.validate(problem, plan)
    return "" if check.status.name == "VALID" else f"UP's validator rejected the plan: {check.reason}"


def _compile_for(engine, problem, no_quantifiers=False):
    """Compile away features the engine lacks (quantifiers, conditional effects, negative conditions).
    ``no_quantifiers``: also quantified conditions, which Fast Downward turns into axioms that its
    cost-partitioning searches (seq-opt-bjolp) refuse."""
    from unified_planning.engines import CompilationKind
    from unified_planning.shortcuts import Compiler

    chain = []
    kind = problem.kind
    quantified = ("EXISTENTIAL_CONDITIONS", "UNIVERSAL_CONDITIONS", "FORALL_EFFECTS")
    if no_quantifiers and any(f in kind.features for f in quantified[:2]):
        with Compiler(problem_kind=kind, compilation_kind=CompilationKind.QUANTIFIERS_REMOVING) as compiler:
            chain.append(compiler.compile(problem, CompilationKind.QUANTIFIERS_REMOVING))
        problem = _settled(chain[-1].problem)
        kind = problem.kind
    for compilation, feature in ((CompilationKind.QUANTIFIERS_REMOVING, quantified),
                                 (CompilationKind.CONDITIONAL_EFFECTS_REMOVING, ("CONDITIONAL_EFFECTS",)),
                                 (CompilationKind.DISJUNCTIVE_CONDITIONS_REMOVING, ("DISJUNCTIVE_CONDITIONS",)),
                                 (CompilationKind.NEGATIVE_CONDITIONS_REMOVING, ("NEGATIVE_CONDITIONS",))):
        if engine.supports(kind):
            break
        if any(f in kind.features for f in feature):
            with Compiler(problem_kind=kind, compilation_kind=compilation) as compiler:
                res = compiler.compile(problem, compilation)
            chain.append(res)
            problem = _settled(res.problem)
            kind = problem.kind
    if not engine.supports(kind) and problem.quality_metrics:
        log.warning("the task planner '%s' ignores action costs: its plans may not be cheapest", engine.name)
        problem = problem.clone()
        problem.clear_quality_metrics()
        problem = _settled(problem)
        kind = problem.kind
    return problem, chain, kind


@functools.cache
def _settled_problem_class():
    from unified_planning.model import Problem

    class SettledProblem(Problem):
        """A problem that is no longer changed: UP computes ``kind`` from scratch at every access (5-20
        ms), and a validation or an engine call asks for it three or four times. Computed once here;
        each access gets a copy, because UP's validator edits the kind it is given."""

        @property
        def kind(self):
            cached = self.__dict__.get("_settled_kind")
            if cached is None:
                cached = self.__dict__["_settled_kind"] = Problem.kind.fget(self)
            return cached.clone()

    return SettledProblem


def _settled(problem):
    """``problem`` (our own clone, not changed from now on) with its kind computed once."""
    from unified_planning.model import Problem

    if type(problem) is Problem:
        problem.__class__ = _settled_problem_class()
    return problem


@functools.cache
def _sparse_problem_class():
    class SparseProblem(_settled_problem_class()):
        """UP's PDDL writer asks ``initial_values`` for every grounding of every fluent just to write
        the true ones (seconds for big reference sets). All our fluents default to false, so the
        explicit (true) values are the whole initial state."""

        @property
        def initial_values(self):
            return dict(self.explicit_initial_values)

    return SparseProblem


def _spawn_warm_driver():
    """Start Fast Downward's warm process before Unified-Planning is imported, so that both start up at
    once (its script is found without importing up_fast_downward; ``_warm_driver`` waits for it)."""
    from pathlib import Path

    from . import warm

    spec = importlib.util.find_spec("up_fast_downward")
    if spec is None or not spec.submodule_search_locations:
        return
    script = Path(list(spec.submodule_search_locations)[0]) / "downward" / "fast-downward.py"
    if script.exists():
        try:
            warm.driver_for(str(script)).spawn()
        except OSError:  # _warm_driver tries again, and says why
            pass


def _warm_driver(engine):
    """The warm process for a Fast Downward engine (None for other engines, or if it cannot start)."""
    from . import warm

    if not type(engine).__module__.startswith("up_fast_downward."):
        return None
    cmd = engine._get_cmd("domain.pddl", "problem.pddl", "plan.txt")
    if cmd[0] != sys.executable or not str(cmd[1]).endswith("fast-downward.py"):
        return None
    driver = warm.driver_for(str(cmd[1]))
    if driver.broken:
        return None
    try:
        driver.start()
    except warm.WorkerFailed as exc:  # it is marked broken
        log.warning("%s; every Fast Downward call runs its own driver instead.", exc)
        return None
    return driver


def _run_command(cmd, folder, timeout, driver):
    """Run an engine's command in ``folder`` (by its warm ``driver``, if any), as UP's ``run_command``
    answers: (timed out, (stdout, stderr), exit code). Its process is killed at ``timeout``."""
    from .warm import WorkerFailed

    _UP_LOCK.release()  # held by _solve, the engine's only caller: the process needs no UP
    try:
        if driver is not None:
            start = time.perf_counter()
            try:
                return driver.run(cmd, folder, timeout)
            except WorkerFailed as exc:
                log.warning("%s; Fast Downward's own driver runs this call instead.", exc)
            timeout = None if timeout is None else max(0.0, timeout - (time.perf_counter() - start))
        return _run_in(folder, cmd, timeout)
    finally:
        _UP_LOCK.acquire()


def _run_in(folder, cmd, timeout):
    """The command in ``folder``, in a session of its own; the whole session killed at ``timeout``."""
    from .warm import kill_group

    proc = subprocess.Popen(cmd, cwd=folder, stdout=subprocess.PIPE, stderr=subprocess.PIPE, start_new_session=True)
    timed_out = False
    try:
        out, err = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        kill_group(proc.pid)
        out, err = proc.communicate()
        timed_out = True
    except BaseException:  # Ctrl-C: the engine's process does not outlive us
        kill_group(proc.pid)
        proc.wait()
        raise
    return timed_out, ([out.decode(errors="replace")], [err.decode(errors="replace")]), proc.returncode


def _solve(engine_name, params, problem, timeout, warm=False):
    with _UP_LOCK:
        return _solve_locked(engine_name, params, problem, timeout, warm)


def _solve_locked(engine_name, params, problem, timeout, warm):
    from unified_planning.engines import PlanGenerationResultStatus as S

    with _engine(engine_name, params, warm=warm) as engine:
        # Fast Downward's optimal searches (LM-cut, bjolp) take no axioms
        optimal = engine_name == "fast-downward-opt" or str((params or {}).get("fast_downward_alias", "")).startswith("seq-opt")
        compiled, chain, kind = _compile_for(engine, problem, no_quantifiers=optimal)
        if not engine.supports(kind):
            return "error", None, f"the engine '{engine_name}' cannot handle this problem's features ({sorted(kind.features)})"
        if not chain:
            compiled.__class__ = _sparse_problem_class()  # our own clone: only the PDDL writer reads it
        res = engine.solve(compiled, timeout=timeout)
        if isinstance(engine, _in_folder_class()) and not engine.reached:
            raise compat.bypassed(engine)
    if res.status in (S.SOLVED_SATISFICING, S.SOLVED_OPTIMALLY) and res.plan is not None:
        plan = res.plan
        for step in reversed(chain):
            plan = plan.replace_action_instances(step.map_back_action_instance)
        return "solved", plan, ""
    if res.status == S.TIMEOUT:
        return "timeout", None, f"the task planner timed out after {timeout:.0f} s"
    if res.status == S.UNSOLVABLE_PROVEN:
        return "unsolvable", None, "the task planner proved the state has no plan"
    if res.status == S.UNSOLVABLE_INCOMPLETELY:
        return "incomplete", None, "the task planner's (incomplete) search found no plan"
    logs = " ".join(str(l.message)[-300:] for l in (res.log_messages or [])[-1:])
    if res.status in (S.INTERNAL_ERROR, S.UNSUPPORTED_PROBLEM):  # the engine failed: no word on the state
        last = [line.strip() for line in logs.splitlines() if line.strip()][-2:]
        return "error", None, f"the engine '{engine_name}' failed ({res.status.name}): {' '.join(last) or 'no message'}"
    return "incomplete", None, f"the task planner ended with {res.status.name} {logs}".strip()  # e.g. out of memory


def _child(conn, engine_name, params, problem, timeout):
    import signal
    import warnings

    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):  # sent to the whole group (Ctrl-C, timeout):
        signal.signal(sig, signal.SIG_DFL)  # end at once, without a traceback; the parent reports the stop
    global _UP_LOCK, _setup_lock
    _UP_LOCK = threading.Lock()  # the parent's, copied while its forking thread held it
    _setup_lock = threading.Lock()  # copied in whatever state another of the parent's threads left it
    warnings.filterwarnings("ignore", message=".*does not support timeout")  # we enforce it here
    try:
        _quiet_environment()
        status, plan, reason = _solve(engine_name, params, problem, timeout)
        names = [(ai.action.name, [p.object().name for p in ai.actual_parameters]) for ai in plan.actions] if plan else None
        conn.send((status, names, reason))
    except Exception as exc:  # reported to the parent as an error
        conn.send(("error", None, f"{type(exc).__name__}: {exc}"))


def _solve_in_child(engine_name, params, problem, timeout):
    """Run an engine that ignores timeouts in a forked child and stop it at the deadline."""
    from unified_planning.plans import ActionInstance, SequentialPlan

    ctx = multiprocessing.get_context("fork")
    parent, child = ctx.Pipe(duplex=False)
    proc = ctx.Process(target=_child, args=(child, engine_name, params, problem, timeout), daemon=True)
    with _UP_LOCK:  # no other thread is half-way through UP's work as the child's copy of it is made
        proc.start()
    child.close()  # the parent's copy: a child that dies must close the pipe's last write end
    ready = parent.poll(timeout)
    if not ready:
        proc.kill()
        proc.join()
        return "timeout", None, f"the task planner '{engine_name}' timed out after {timeout:.0f} s"
    try:
        status, names, reason = parent.recv()
    except EOFError:  # the child died without answering (a crash in the engine)
        proc.join()
        return "error", None, f"the task planner process '{engine_name}' died (exit code {proc.exitcode})"
    proc.join()
    if status != "solved":
        return status, None, reason
    actions = {a.name: a for a in problem.actions}
    with _UP_LOCK:
        plan = SequentialPlan([ActionInstance(actions[a], [problem.object(o) for o in args]) for a, args in names])
    return "solved", plan, ""
