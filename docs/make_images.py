"""Regenerate every image of README.md and docs/*.md from today's code.

    python docs/make_images.py                    # all of them (a few minutes: plans, pages, a quick bench)
    python docs/make_images.py pr2-plan drawer-plan   # only these (names as in IMAGES)
    python docs/make_images.py --bench-db table1.sqlite   # bench plots from a finished database, not a quick run
    python docs/make_images.py --list             # what each image is made from

Each picture of a run plans the example with `interlayer plan --out`, writes its page with
`interlayer viz` / `interlayer explain` and photographs the page with headless Chromium (as the
browser tests do: tests/browser.py). The bench plots are `interlayer report`'s, from
`interlayer bench --suite table1 --quick` (2 seeds per row, 60 s limit) unless --bench-db names a
database. tests/test_docs_images.py checks that every image the docs show is one of IMAGES.
The kitchen picture needs pybullet-planning's kitchen.json (--pbjson DIR, default the shared
benchmarks folder beside the checkout)."""
from __future__ import annotations

import argparse
import json
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PBJSON = ROOT.parent / "shared" / "benchmarks" / "pybullet-planning-json"

# name: (output under docs/images, what is run, page, window size, when the shot is taken)
# "what is run" is a config or problem file and its --set overrides; {pbjson} is the --pbjson folder.
# "when": (step, fraction) = the animation paused that far into that plan step's motion, or the
# milliseconds (of the browser's virtual time) after loading when the page is photographed.
IMAGES = {
    "gripper2d-plan": ("gripper2d-plan.png", ["examples/gripper2d.toml"], "viz", (1000, 700), (3, 0.5)),
    "gripper2d-explain": ("gripper2d-explain.png", ["examples/gripper2d.toml"], "explain", (1000, 1400), 6000),
    "pr2-plan": ("pr2-plan.png", ["examples/pr2_pick.toml"], "viz", (1000, 700), (3, 0.6)),
    "pr2-explain": ("pr2-explain.png", ["examples/pr2_pick.toml"], "explain", (1000, 1400), 6000),
    "drawer-plan": ("drawer-plan.png", ["examples/drawer.toml", "--set", "problem.variant=N",
                                        "--set", "planner.seed=3"], "viz", (1000, 700), (3, 0.9)),
    "pbjson-kitchen": ("pbjson-kitchen.png", ["{pbjson}/kitchen.json"], "viz", (1000, 800), (2, 0.5)),
    "bench-histogram": ("bench/histogram.png", None, "bench", None, None),
    "bench-time-split": ("bench/time-split.png", None, "bench", None, None),
}


def outputs() -> list[Path]:
    """Every file this script writes (relative to docs/images)."""
    return [Path(v[0]) for v in IMAGES.values()]


def _interlayer(*args, cwd=ROOT) -> None:
    cmd = [sys.executable, "-m", "interlayer.cli", *args]
    print("+ interlayer " + " ".join(str(a) for a in args), file=sys.stderr, flush=True)
    proc = subprocess.run(cmd, cwd=cwd)
    if proc.returncode != 0:
        raise SystemExit(f"make_images: 'interlayer {' '.join(map(str, args))}' exited {proc.returncode}")


def _instant(page: Path, when):
    """Seconds into the animation to pause it at for ``when`` = (step, fraction), read off the
    page's step start times (the caption's ``starts``); None for a page photographed as loaded."""
    if isinstance(when, int):
        return None
    step, fraction = when
    m = re.search(r"var starts = (\[.*?\]), el", page.read_text(encoding="utf-8"))
    starts = json.loads(m.group(1)) if m else []
    times = {s: t for s, t in starts}
    if step not in times:
        raise SystemExit(f"make_images: {page.name} has no step {step}; the plan has {len(starts) - 1} step(s).")
    end = next((t for s, t in starts if t > times[step]), times[step])
    return times[step] + fraction * (end - times[step])


def _shoot(page: Path, png: Path, size, when) -> None:
    sys.path.insert(0, str(ROOT / "tests"))
    import browser  # tests/browser.py: how the tests start headless Chromium

    if browser.chromium_path() is None:
        raise SystemExit(f"make_images: {browser.CHROMIUM_MISSING}")
    seconds = _instant(page, when)
    if seconds is not None:  # the animation paused at that instant, however long loading takes
        page = browser.paused_at(page, seconds, page.with_name(page.stem + "-paused.html"))
    browser.screenshot(page, png, size=size, budget_ms=when if seconds is None else 4000)
    _shrink(png)


def _shrink(png: Path) -> None:
    """Fewer colours, same look: the pictures stay a few hundred KB at most."""
    try:
        from PIL import Image
    except ImportError:
        return
    img = Image.open(png).convert("RGB")
    img.quantize(colors=256, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE).save(png, optimize=True)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("names", nargs="*", metavar="NAME", help=f"images to make (default all): {', '.join(IMAGES)}")
    ap.add_argument("--pbjson", type=Path, default=PBJSON, metavar="DIR", help="folder holding kitchen.json")
    ap.add_argument("--bench-db", type=Path, metavar="FILE.sqlite", help="bench plots from this database")
    ap.add_argument("--list", action="store_true", help="print what each image is made from and stop")
    args = ap.parse_args(argv)
    unknown = [n for n in args.names if n not in IMAGES]
    if unknown:
        ap.error(f"unknown image {', '.join(unknown)}; the images are {', '.join(IMAGES)}")
    names = args.names or list(IMAGES)
    if args.list:
        for n in names:
            out, src, page, _, _ = IMAGES[n]
            print(f"docs/images/{out}: {page} of {' '.join(src) if src else 'interlayer bench --suite table1 --quick'}")
        return 0
    images = ROOT / "docs" / "images"
    with tempfile.TemporaryDirectory(prefix="il-images-") as tmp:
        tmp = Path(tmp)
        runs: dict = {}
        for n in names:
            out, src, page, size, budget = IMAGES[n]
            if page == "bench":
                continue
            src = [s.format(pbjson=args.pbjson) for s in src]
            if not Path(src[0] if Path(src[0]).is_absolute() else ROOT / src[0]).exists():
                raise SystemExit(f"make_images: {src[0]} is missing; give the folder holding it with --pbjson DIR.")
            key = tuple(src)
            if key not in runs:
                runs[key] = tmp / f"{Path(src[0]).stem}-{len(runs)}"  # the explain page shows it
                _interlayer("plan", *src, "--out", runs[key], "-q")
            html = tmp / f"{n}.html"
            _interlayer(page, runs[key], "-o", html)
            _shoot(html, images / out, size, budget)
            print(f"wrote docs/images/{out} ({(images / out).stat().st_size // 1024} KB)", file=sys.stderr)
        if any(IMAGES[n][2] == "bench" for n in names):
            db = args.bench_db
            if db is None:
                db = tmp / "quick.sqlite"
                _interlayer("bench", "--suite", "table1", "--quick", "--db", db, "--jobs", "2")
            _interlayer("report", db, "--out", tmp / "report")
            for n in names:
                out, _, page, _, _ = IMAGES[n]
                if page == "bench":
                    (images / out).parent.mkdir(parents=True, exist_ok=True)
                    shutil.copyfile(tmp / "report" / Path(out).name, images / out)
                    print(f"wrote docs/images/{out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
