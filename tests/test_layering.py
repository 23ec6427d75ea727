"""The layering the folders promise (plugins -> adapters -> core), checked by import-linter on the
contracts in pyproject.toml: a domain plugin may build on adapters and core, never the other way."""
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_import_contracts_are_kept():
    lint = shutil.which("lint-imports", path=str(Path(sys.executable).parent))
    assert lint, "import-linter is part of the test extra: pip install -e '.[test]'"
    run = subprocess.run([lint, "--no-cache"], cwd=ROOT, capture_output=True, text=True)
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-2000:]
    assert "0 broken" in run.stdout


def test_every_package_is_under_contract():
    """A new plugin or adapter package must be listed in the import-linter root packages."""
    import tomllib

    config = tomllib.loads((ROOT / "pyproject.toml").read_text())
    wheel = {Path(p).name for p in config["tool"]["hatch"]["build"]["targets"]["wheel"]["packages"]}
    assert wheel == set(config["tool"]["importlinter"]["root_packages"])
