"""``interlayer report``: a bench database as Table I (with the paper's numbers and the ratio), a
per-combination comparison, Fig. 7 style histograms and a time-split chart (Markdown, HTML, PNG)."""
from __future__ import annotations

import base64
import html
import os
import statistics
from collections import defaultdict
from pathlib import Path

from . import db

BEGIN, END = "<!-- BENCH-REPORT BEGIN -->", "<!-- BENCH-REPORT END -->"
FAILED = ("unsolvable", "gave_up", "timeout", "refused", "error", "invalid", "killed")


def _fmt(x, digits=1) -> str:
    return "-" if x is None else f"{x:.{digits}f}"


def _median(xs):
    return statistics.median(xs) if xs else None


def _mean(xs):
    return statistics.fmean(xs) if xs else None


def _groups(runs):
    """(suite, row, combo, time_limit) -> runs, in the order first seen."""
    out = defaultdict(list)
    for r in runs:
        out[(r["suite"], r["row"], r["combo"], r["time_limit"])].append(r)
    return out


def _ordered(rows, groups):
    """Group keys in each suite's row order; rows with no runs (skipped) as (suite, row, None, None)."""
    position = {(r["suite"], r["row"]): r["position"] for r in rows}
    keys = sorted(groups, key=lambda k: (k[0], position.get(k[:2], 1e9), k[1], k[3], k[2]))
    have = {k[:2] for k in keys}
    missing = [(r["suite"], r["row"], None, None) for r in rows if (r["suite"], r["row"]) not in have]
    return sorted(keys + missing, key=lambda k: (k[0], position.get(k[:2], 1e9)))


def _label(key, groups, suite: bool = True) -> str:
    """The row's name, with its suite when several suites have a row of that name, the combination
    and the time limit when the database holds several."""
    label = key[1]
    if suite and len({k[0] for k in groups if k[1] == key[1]}) > 1:
        label = f"{key[0]}: {label}"
    if len({k[2] for k in groups}) > 1:
        label += f" [{key[2]}]"
    if len({k[3] for k in groups if k[0] == key[0]}) > 1:
        label += f" ({key[3]:g} s)"
    return label


def table1(runs, rows) -> list:
    """Blocks for one Table I per suite: ours, the paper's, the ratio of the mean times."""
    info = {(r["suite"], r["row"]): r for r in rows}
    groups = _groups(runs)
    blocks = []
    header = ["problem", "runs", "% solved", "paper % solved", "mean / median time of solved (s)",
              "paper mean (s)", "time ratio (ours / paper)", "plan length / cost (median)", "not solved"]
    for suite in sorted({k[0] for k in groups} | {r["suite"] for r in rows}):
        lines = []
        for key in _ordered([r for r in rows if r["suite"] == suite], {k: v for k, v in groups.items() if k[0] == suite}):
            paper = (info.get(key[:2]) or {}).get("paper") or {}
            p_solved, p_mean = paper.get("solved"), paper.get("mean_time")
            if key[2] is None:
                why = (info.get(key[:2]) or {}).get("skipped")
                lines.append([key[1], "0", f"skipped: {why}" if why else "no runs yet", _fmt(p_solved, 0), "", _fmt(p_mean, 0), "", "", ""])
                continue
            rs = groups[key]
            ok = [r for r in rs if r["status"] == "solved"]
            times = [r["time_total"] for r in ok]
            mean = _mean(times)
            fails = defaultdict(int)
            for r in rs:
                if r["status"] != "solved":
                    fails[r["status"]] += 1
            lines.append([_label(key, groups, suite=False), str(len(rs)), _fmt(100 * len(ok) / len(rs), 0), _fmt(p_solved, 0),
                          f"{_fmt(mean)} / {_fmt(_median(times))}", _fmt(p_mean, 0),
                          _fmt(mean / p_mean, 3) if mean is not None and p_mean else "-",
                          f"{_fmt(_median([r['plan_length'] for r in ok]), 0)} / "
                          f"{_fmt(_median([r['plan_cost'] for r in ok if r['plan_cost'] is not None]), 0)}",
                          ", ".join(f"{n} {s}" for s, n in sorted(fails.items())) or "-"])
        limits = sorted({k[3] for k in groups if k[0] == suite})
        blocks.append(("h2", f"Suite `{suite}`: Table I"))
        cited = any(r["paper"] for r in rows if r["suite"] == suite)
        blocks.append(("p", f"Time limit per run: {', '.join(f'{x:g}' for x in limits)} s. Times are the planner's own "
                            "`times.total` of the runs solved within the limit and confirmed by `interlayer validate`."
                            + (" Paper: Srivastava et al., ICRA 2014, Table I (Intel i7-4770K, 600 s limit, 100 problems "
                               "per Clutter row, 10 per other row)." if cited else "")))
        blocks.append(("table", header, lines))
    return blocks


def combo_table(runs) -> list:
    """Rows x combinations: % solved and median time of the solved runs, when a suite crossed combos."""
    groups = _groups(runs)
    blocks = []
    for suite in sorted({k[0] for k in groups}):
        combos = sorted({k[2] for k in groups if k[0] == suite})
        if len(combos) < 2:
            continue
        row_names = list(dict.fromkeys(k[1] for k in groups if k[0] == suite))
        lines = []
        for row in row_names:
            cells = [row]
            for c in combos:
                rs = [r for k, v in groups.items() if k[:3] == (suite, row, c) for r in v]
                ok = [r["time_total"] for r in rs if r["status"] == "solved"]
                cells.append(f"{100 * len(ok) / len(rs):.0f}% / {_fmt(_median(ok), 2)} s" if rs else "-")
            lines.append(cells)
        blocks.append(("h2", f"Suite `{suite}`: planner combinations (% solved / median time of solved)"))
        blocks.append(("table", ["problem", *combos], lines))
    return blocks


def split_table(runs) -> tuple[list, dict]:
    """Median time per category over the solved runs of each row; also returns the data for the chart."""
    groups = _groups(runs)
    cats = sorted({c for r in runs if r["status"] == "solved" for c in (r["times"] or {}) if c != "total"})
    data, lines = {}, []
    for key, rs in groups.items():
        ok = [r for r in rs if r["status"] == "solved"]
        if not ok:
            continue
        label = _label(key, groups)
        data[label] = {c: _mean([(r["times"] or {}).get(c, 0.0) for r in ok]) for c in cats}
        lines.append([label, *(_fmt(_median([(r["times"] or {}).get(c, 0.0) for r in ok]), 2) for c in cats),
                      _fmt(_median([r["time_total"] for r in ok]), 2),
                      *(_fmt(_median(xs), 2) if xs else "-" for xs in (_wall(ok, k) for k, _ in WAIT)),
                      *(_median_max([r[k] for r in ok]) for k in ("task_planner_calls", "replans")),
                      _fmt(max((r["peak_memory_mb"] or 0) for r in ok), 0)])
    if not lines:
        return [], data
    return [("h2", "Where the time goes (medians over the solved runs, s): the planner's categories and total, then "
                   "the wait around it (the run's process: start-up, trajectory export, writing; then the validator's "
                   "process), and the loop's effort"),
            ("table", ["problem", *(c.replace("_", " ") for c in cats), "total", *(h for _, h in WAIT),
                       "task-planner calls (median / max)", "replans (median / max)", "peak memory (max, MB)"], lines)], data


# The wait beside the planner's time: (key of the run's ``wall``, column heading)
WAIT = (("startup", "start-up"), ("export", "export"), ("writing", "writing"), ("process", "process wall"),
        ("validation", "validation process"))


def _wall(runs, key) -> list:
    return [r["wall"][key] for r in runs if (r.get("wall") or {}).get(key) is not None]


def _median_max(xs) -> str:
    xs = [x for x in xs if x is not None]
    return f"{_fmt(_median(xs), 0)} / {max(xs)}" if xs else "-"


def histogram_png(runs, path: Path) -> bool:
    """Fig. 7: a histogram of solution times per row, log-scale y axis."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker
    import numpy as np

    groups = _groups(runs)
    solved = {k: [r["time_total"] for r in v if r["status"] == "solved"] for k, v in groups.items()}
    solved = {k: v for k, v in solved.items() if v}
    if not solved:
        return False
    top = max(max(v) for v in solved.values()) or 1.0
    bins = np.linspace(0.0, top, 21)  # its last edge is exactly top: the slowest run is counted
    cols = min(3, len(solved))
    rows = -(-len(solved) // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(3.2 * cols, 2.4 * rows), squeeze=False, sharex=True)
    for ax, (key, times) in zip(axes.flat, solved.items()):
        ax.hist(times, bins=bins, color="#4477aa", edgecolor="white")
        ax.set_yscale("log")
        ax.set_ylim(0.7, max(10, 1.5 * len(times)))
        ax.yaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())  # decades only
        ax.set_title(f"{_label(key, groups)} ({len(times)}/{len(groups[key])} solved)", fontsize=9)
        ax.tick_params(labelsize=7)
    for ax in list(axes.flat)[len(solved):]:
        ax.axis("off")
    for ax in axes[-1]:
        ax.set_xlabel("solution time (s)", fontsize=8)
    for ax in axes[:, 0]:
        ax.set_ylabel("problems (log)", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=72)
    plt.close(fig)
    return True


def split_png(data: dict, path: Path) -> bool:
    """Stacked bars: mean seconds per category of the solved runs of each row."""
    if not data:
        return False
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    labels = list(data)
    cats = sorted({c for d in data.values() for c in d})
    fig, ax = plt.subplots(figsize=(6.4, 0.35 * len(labels) + 1.6))
    left = [0.0] * len(labels)
    for i, c in enumerate(cats):
        widths = [data[label].get(c) or 0.0 for label in labels]
        ax.barh(labels, widths, left=left, label=c.replace("_", " "), color=plt.cm.tab10(i % 10))
        left = [a + b for a, b in zip(left, widths)]
    ax.invert_yaxis()
    ax.set_xlabel("mean time of the solved runs (s)", fontsize=8)
    ax.tick_params(labelsize=7)
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.25), ncol=4, frameon=False)
    fig.tight_layout()
    fig.savefig(path, dpi=72)
    plt.close(fig)
    return True


def failures(runs) -> list:
    """Every run not solved with its status and reason (a folder suite's table of files), after the counts."""
    bad = [r for r in runs if r["status"] != "solved"]
    if not bad:
        return []
    counts = defaultdict(int)
    for r in runs:
        counts[r["status"]] += 1
    items = [f"{r['row']} [{r['combo']}] seed {r['seed']}: {r['status']}: {_one_line(r['reason'])}" for r in bad]
    return [("h2", "Runs not solved"),
            ("p", f"{len(runs)} runs: " + ", ".join(f"{n} {s}" for s, n in sorted(counts.items(), key=lambda c: -c[1])) + "."),
            ("list", items)]


def _one_line(text: str, limit: int = 300) -> str:
    text = " ".join(text.split())
    return text if len(text) <= limit else text[: limit - 3] + "..."


def build(runs, rows, image_dir: Path) -> list:
    hosts = sorted({r["host"] for r in runs})
    versions = dict(next((r["versions"] for r in runs if r["versions"]), {}))
    versions.pop("commit", None)
    commits = sorted({(r["versions"] or {}).get("commit") for r in runs} - {None})
    dates = sorted(r["finished"] for r in runs)
    blocks = [("p", f"{len(runs)} runs on {', '.join(hosts) or '-'}"
                    + (f", {dates[0][:16]} to {dates[-1][:16]} UTC" if dates else "") + ". "
                    + ("Versions: " + ", ".join(f"{k} {v}" for k, v in versions.items()) + ". " if versions else "")
                    + (f"Source commit{'s' if len(commits) > 1 else ''}: {', '.join(commits)}." if commits else ""))]
    blocks += table1(runs, rows) + combo_table(runs)
    if histogram_png(runs, image_dir / "histogram.png"):
        blocks += [("h2", "Solution times (the paper's Fig. 7: histogram per row, log-scale y axis)"),
                   ("img", image_dir / "histogram.png", "Histogram of solution times per row")]
    split_blocks, data = split_table(runs)
    blocks += split_blocks
    if split_png(data, image_dir / "time-split.png"):
        blocks.append(("img", image_dir / "time-split.png", "Mean time per category of the solved runs"))
    return blocks + failures(runs)


def to_markdown(blocks, base: Path) -> str:
    out = []
    for b in blocks:
        if b[0] == "h2":
            out.append(f"### {b[1]}")
        elif b[0] == "p":
            out.append(b[1])
        elif b[0] == "table":
            out.append("\n".join(["| " + " | ".join(b[1]) + " |", "|" + "---|" * len(b[1]),
                                  *("| " + " | ".join(c.replace("|", "/") for c in line) + " |" for line in b[2])]))
        elif b[0] == "img":
            out.append(f"![{b[2]}]({Path(os.path.relpath(b[1], base)).as_posix()})")
        elif b[0] == "list":
            out.append("\n".join(f"- {item}" for item in b[1]))
    return "\n\n".join(out) + "\n"


def to_html(blocks, title: str) -> str:
    out = [f"<!doctype html><html><head><meta charset='utf-8'><title>{html.escape(title)}</title><style>"
           "body{font-family:sans-serif;max-width:1100px;margin:2em auto}table{border-collapse:collapse}"
           "td,th{border:1px solid #ccc;padding:3px 8px;font-size:14px}th{background:#eee}</style></head><body>",
           f"<h1>{html.escape(title)}</h1>"]
    for b in blocks:
        if b[0] == "h2":
            out.append(f"<h2>{html.escape(b[1])}</h2>")
        elif b[0] == "p":
            out.append(f"<p>{html.escape(b[1])}</p>")
        elif b[0] == "table":
            out.append("<table><tr>" + "".join(f"<th>{html.escape(h)}</th>" for h in b[1]) + "</tr>"
                       + "".join("<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in line) + "</tr>" for line in b[2])
                       + "</table>")
        elif b[0] == "img":  # embedded, so the page is one self-contained file
            data = base64.b64encode(Path(b[1]).read_bytes()).decode()
            out.append(f"<p><img alt='{html.escape(b[2])}' src='data:image/png;base64,{data}'></p>")
        elif b[0] == "list":
            out.append("<ul>" + "".join(f"<li>{html.escape(i)}</li>" for i in b[1]) + "</ul>")
    return "\n".join(out) + "</body></html>\n"


def write_report(db_path, out_dir, doc=None) -> list[Path]:
    """DIR/report.md, DIR/report.html (images embedded), DIR/histogram.png, DIR/time-split.png; with
    ``doc``, the Markdown also goes between the BENCH-REPORT markers of that file (appended if absent)."""
    con = db.connect(db_path, create=False)
    runs, rows = db.load(con)
    con.close()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    blocks = build(runs, rows, out)
    title = f"Interlayer benchmark report ({Path(db_path).name})"
    (out / "report.md").write_text(f"# {title}\n\n" + to_markdown(blocks, out))
    (out / "report.html").write_text(to_html(blocks, title))
    written = [out / "report.md", out / "report.html", *(b[1] for b in blocks if b[0] == "img")]
    if doc:
        doc = Path(doc)
        text = doc.read_text() if doc.exists() else "# Benchmarks\n"
        block = f"{BEGIN}\n{to_markdown(blocks, doc.parent)}{END}"
        if BEGIN in text and END in text:
            text = text[: text.index(BEGIN)] + block + text[text.index(END) + len(END):]
        else:
            text = text.rstrip("\n") + "\n\n" + block + "\n"
        doc.write_text(text)
        written.append(doc)
    return written
