"""The docs match the code: every CLI option is documented, and every path the README and docs
name exists in a clone."""
import argparse
import re
from pathlib import Path

import pytest

from interlayer.cli import build_parser

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
TOP = ("core", "adapters", "plugins", "examples", "benchmarks", "docs", "tests")


def _options(parser: argparse.ArgumentParser, prefix="interlayer"):
    """(command, option string) for every option of the parser and its subcommands, but -h/--help."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from _options(sub, f"{prefix} {name}")
        elif not isinstance(action, argparse._HelpAction):
            yield from ((prefix, opt) for opt in action.option_strings)


def test_every_cli_option_is_documented():
    text = "\n".join(p.read_text() for p in PAGES)
    options = sorted(set(_options(build_parser())))
    assert ("interlayer plan", "--dump-pddl") in options  # the walk reaches the subcommands
    missing = [f"{cmd} {opt}" for cmd, opt in options if not re.search(rf"(?<![\w-]){re.escape(opt)}(?![\w-])", text)]
    assert not missing, f"undocumented in README.md and docs/*.md: {missing}"


def _metavars(parser: argparse.ArgumentParser):
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in action.choices.values():
                yield from _metavars(sub)
        elif action.metavar:
            yield action.metavar


def _named_paths(page: Path):
    """Relative link targets and image sources, paths into the repository's top folders and
    upper-case Markdown names (README.md, ...) but the CLI's placeholders (FILE.md)."""
    text = page.read_text()
    placeholders = set(_metavars(build_parser()))
    for target in re.findall(r"\]\(([^)\s]+)\)|src=\"([^\"]+)\"", text):
        target = next(t for t in target if t)
        if not re.match(r"[a-z]+:|#", target):
            yield page.parent / target.split("#")[0]
    for path in re.findall(rf"(?<![\w./-])((?:{'|'.join(TOP)})/[\w./-]*\w/?)", text):
        yield ROOT / path
    for name in set(re.findall(r"(?<![\w./-])([A-Z][A-Z_]+\.md)\b", text)) - placeholders:
        yield ROOT / name


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.name)
def test_every_named_path_exists_in_a_clone(page):
    missing = sorted({str(p.relative_to(ROOT)) if p.is_relative_to(ROOT) else str(p)
                      for p in _named_paths(page) if not p.exists()})
    assert not missing, f"{page.name} names files a clone lacks: {missing}"


def test_version_prints_the_distribution_version(capsys):
    from interlayer import __version__  # the core distribution's version (hatch reads it there)
    from interlayer.cli import main

    with pytest.raises(SystemExit) as stop:
        main(["--version"])
    assert stop.value.code == 0
    assert capsys.readouterr().out == f"interlayer {__version__}\n"
