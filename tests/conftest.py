import sys
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
