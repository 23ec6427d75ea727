import sys
from collections import Counter
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
SHARED = ROOT.parent / "shared"
sys.path.insert(0, str(Path(__file__).resolve().parent))  # tests/browser.py


@pytest.fixture(scope="session")
def host():
    from interlayer.plugins import PluginHost

    return PluginHost()


@pytest.fixture(scope="session")
def gripper_example():
    return str(ROOT / "examples" / "gripper2d.toml")


# What the robustness tests (pytest -m robustness) did, printed at the end of the run.
ROBUSTNESS: Counter = Counter()


def pytest_terminal_summary(terminalreporter):
    if ROBUSTNESS:
        terminalreporter.write_line("robustness: " + ", ".join(f"{k} {v}" for k, v in sorted(ROBUSTNESS.items())))


def pytest_report_header(config):
    return f"shared/ benchmarks: {'present' if SHARED.exists() else 'absent (tests that read them skip)'}"


def write_pages(out_dir):
    """plan.html and explain.html for a run folder, through the CLI (beside the folder)."""
    from interlayer.cli import main

    plan, explain = out_dir.parent / "plan.html", out_dir.parent / "explain.html"
    assert main(["viz", str(out_dir), "-o", str(plan)]) == 0
    assert main(["explain", str(out_dir), "-o", str(explain)]) == 0
    return plan, explain


def solved_run(tmp_path_factory, example, name):
    """Solve an example with the real planners and write its OUT_DIR (for page and validator tests)."""
    from interlayer import api

    out = tmp_path_factory.mktemp(name) / name
    result = api.solve(str(example))
    assert result.solved, result.reason
    api.write_outputs(result, out)
    return out


def write_plugin(folder, name: str, source: str, dist: str | None = None, requires: tuple = ()):
    """A third-party plugin as an installed distribution would look on sys.path: the module
    ``name`` and a ``*.dist-info`` with its ``interlayer.plugins`` entry point and ``requires``
    (``Requires-Dist`` strings) (no pip needed). Returns the folder to put on sys.path (or PYTHONPATH
    for a subprocess)."""
    import textwrap

    folder.mkdir(parents=True, exist_ok=True)
    (folder / f"{name}.py").write_text(textwrap.dedent(source))
    dist = dist or name.replace("_", "-")
    info = folder / f"{dist.replace('-', '_')}-0.1.dist-info"
    info.mkdir(exist_ok=True)
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {dist}\nVersion: 0.1\n"
                                   + "".join(f"Requires-Dist: {r}\n" for r in requires))
    (info / "entry_points.txt").write_text(f"[interlayer.plugins]\n{name} = {name}\n")
    return folder


@pytest.fixture
def plugin_dir(tmp_path, monkeypatch):
    """``plugin_dir(name, source)``: install a throwaway plugin for this test only."""
    import importlib

    added = []

    def make(name, source):
        folder = write_plugin(tmp_path / "site", name, source)
        if str(folder) not in sys.path:
            monkeypatch.syspath_prepend(str(folder))
        importlib.invalidate_caches()
        added.append(name)
        return folder

    yield make
    for name in added:
        sys.modules.pop(name, None)
