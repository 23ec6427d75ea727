"""Test-only plugin for tests/test_bench.py: two domains whose problem factory never returns, one
sleeping forever, one allocating without bound, to check that `interlayer bench` kills such runs
(hard wall-clock limit, memory cap); and a pose generator that yields nothing (the loop gives up). Never installed: the tests put it on PYTHONPATH with a
throw-away dist-info so that the run processes load it through the entry-point group."""
import time

from interlayer import hookimpl


def hang(params, seed):
    while True:
        time.sleep(1)


def hog(params, seed):
    chunks = []
    while True:
        chunks.append(bytearray(64 * 2**20))


@hookimpl
def interlayer_register_domains(registry):
    registry.add("test-hang", hang, "sleeps forever (test only)")
    registry.add("test-hog", hog, "allocates memory without bound (test only)")


def empty(problem, step, world, rng):
    return iter(())


@hookimpl
def interlayer_register_pose_generators(registry):
    registry.add("test-empty:pick", empty, "yields no candidates (test only)")
