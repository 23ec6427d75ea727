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
