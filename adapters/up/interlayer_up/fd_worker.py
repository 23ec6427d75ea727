"""A warm Fast Downward process: ``python fd_worker.py DOWNWARD_DIR`` (started by ``warm.py``).

It imports Fast Downward's driver and translator once, then runs each request, a driver command line
that up-fast-downward built (``fast-downward.py --plan-file ... DOMAIN PROBLEM ...``), with the driver's
own ``main()`` in a forked child: the same aliases, search binary, limits, plan files and exit codes.
The only difference is that the translator runs as a forked grandchild with its modules already
imported, instead of as a new Python process (the driver's two Python start-ups and imports cost
about 0.2 s per call; translating a task takes a few tens of ms). Every request starts from this
process's pristine state: the translator keeps module-level counters.

Protocol: one JSON line per request on stdin, ``{"argv": [...], "cwd": DIR}``; answers on stdout:
``{"pid": CHILD}`` when it starts (its own process group, so the caller can stop it), then
``{"exit": CODE}`` (negative: killed by that signal). The child's output goes to DIR/stdout.txt and
DIR/stderr.txt. Imports only the standard library and Fast Downward: this is not an interlayer process.
"""
import json
import os
import runpy
import select
import signal
import sys
import traceback

DRIVER_CRITICAL_ERROR = 35  # driver/returncodes.py


def _die_with(parent: int) -> None:
    """In a forked child: be killed when ``parent`` dies (Linux's PR_SET_PDEATHSIG), so that a killed
    worker leaves no request running."""
    import ctypes

    ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL)  # 1 = PR_SET_PDEATHSIG
    if os.getppid() != parent:  # it died before we asked
        os._exit(1)


def _translate_in_fork(run_components, original):
    """``run_components.run_translate`` with the translator forked from this process."""

    def run_translate(args):
        from driver import limits, returncodes

        time_limit = limits.get_time_limit(args.translate_time_limit, args.overall_time_limit)
        memory_limit = limits.get_memory_limit(args.translate_memory_limit, args.overall_memory_limit)
        translate = run_components.get_executable(args.build, run_components.REL_TRANSLATE_PATH)
        if time_limit is not None or memory_limit is not None or str(translate.parent) not in sys.path:
            return original(args)  # limits (set on the new process) or another build: the driver's own way
        import logging

        logging.info("Running translator.")
        logging.info("translator: forked from the warm process")
        sys.stdout.flush()
        sys.stderr.flush()
        parent = os.getpid()
        pid = os.fork()
        if pid == 0:
            def translate_here():
                _die_with(parent)
                sys.argv = ["translate", *map(str, args.translate_inputs), *map(str, args.translate_options)]
                runpy.run_module("fast_downward.translate", run_name="__main__", alter_sys=True)

            _run_then_exit(translate_here, crash=1)  # the driver reads 1 as the translator's crash
        returncode = os.waitstatus_to_exitcode(os.waitpid(pid, 0)[1])
        if returncode == 0:
            return (0, True)
        if returncode == 1:  # as run_translate: a crash without an exit code of its own
            return (returncodes.TRANSLATE_CRITICAL_ERROR, False)
        return (returncode, False)

    return run_translate


def _child(argv, cwd, worker):
    """Run the driver on ``argv`` in this forked process; never returns."""
    _run_then_exit(lambda: _drive(argv, cwd, worker), crash=DRIVER_CRITICAL_ERROR)


def _drive(argv, cwd, worker):
    """The driver's main on ``argv`` in ``cwd``, its output to stdout.txt / stderr.txt there."""
    _die_with(worker)
    os.setpgid(0, 0)
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    os.chdir(cwd)
    for fd, name, mode in ((0, os.devnull, os.O_RDONLY), (1, "stdout.txt", os.O_WRONLY | os.O_CREAT | os.O_TRUNC),
                           (2, "stderr.txt", os.O_WRONLY | os.O_CREAT | os.O_TRUNC)):
        target = os.open(name, mode, 0o644)
        os.dup2(target, fd)
        os.close(target)
    sys.stdin = open(0, closefd=False)
    sys.stdout = open(1, "w", closefd=False)
    sys.stderr = open(2, "w", closefd=False)
    from driver import main, run_components

    run_components.run_translate = _translate_in_fork(run_components, run_components.run_translate)
    sys.argv = [argv[1], *argv[2:]]
    main.main()


def _run_then_exit(body, crash: int):
    """Run ``body`` in a forked child and leave at once (no inherited cleanup), its output written, with
    the exit status Python would give it; ``crash`` for an exception it does not catch."""
    code = crash
    try:
        body()
        code = 0
    except SystemExit as stop:
        code = _exit_code(stop)
    except BaseException:
        traceback.print_exc()
    finally:
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)


def _exit_code(stop: SystemExit) -> int:
    """The exit status Python gives a SystemExit: its number, 0 for None, else 1 with the message printed."""
    if isinstance(stop.code, int):
        return stop.code
    if stop.code is not None:
        print(stop.code, file=sys.stderr)
    return 0 if stop.code is None else 1


def _answer(out, **message):
    out.write(json.dumps(message) + "\n")
    out.flush()


def serve(downward_dir: str) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the caller handles Ctrl-C and stops us
    downward_dir = os.path.realpath(downward_dir)  # as the driver's own paths
    sys.path[:0] = [downward_dir, os.path.join(downward_dir, "builds", "release", "bin")]
    import ctypes  # noqa: F401  (warm: what every request would import again)

    import driver.main  # noqa: F401
    import driver.run_components  # noqa: F401
    import fast_downward.translate.main  # noqa: F401
    import fast_downward.translate.pddl_parser  # noqa: F401

    requests, out = sys.stdin.buffer, sys.stdout
    _answer(out, ready=True)
    for line in requests:
        request = json.loads(line)
        worker = os.getpid()
        pid = os.fork()
        if pid == 0:
            _child(request["argv"], request["cwd"], worker)
        try:
            os.setpgid(pid, pid)  # as the child does: the caller may stop the group before the child runs
        except OSError:  # the child got there first, or has ended already
            pass
        _answer(out, pid=pid)
        done = os.pidfd_open(pid)
        while True:  # wait for the child; if our caller is gone (stdin closed), stop the child
            readable, _, _ = select.select([done, requests], [], [])
            if done in readable:
                break
            if not requests.peek(1):
                os.killpg(pid, signal.SIGKILL)
                break
        os.close(done)
        _answer(out, exit=os.waitstatus_to_exitcode(os.waitpid(pid, 0)[1]))


if __name__ == "__main__":
    serve(sys.argv[1])
