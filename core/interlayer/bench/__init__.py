"""Benchmarks: ``interlayer bench`` runs a suite into a SQLite database, ``interlayer report`` turns
the database into Table I / Fig. 7 style Markdown, HTML and PNGs.

Python API (the CLI is a thin layer over it)::

    from interlayer.bench import load_suite, run_suite, write_report
    suite = load_suite("table1", quick=True)
    run_suite(suite, "r.sqlite", jobs=2)
    write_report("r.sqlite", "report/")
"""


def __getattr__(name):  # lazily: `interlayer --help` must not import the runner's dependencies
    if name in ("load_suite", "parse_seeds", "parse_combos"):
        from . import suite

        return getattr(suite, name)
    if name == "run_suite":
        from .runner import run_suite

        return run_suite
    if name == "write_report":
        from .report import write_report

        return write_report
    raise AttributeError(name)


__all__ = ["load_suite", "run_suite", "write_report", "parse_seeds", "parse_combos"]
