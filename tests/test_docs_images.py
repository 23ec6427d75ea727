"""Every image README.md and docs/*.md show exists and is made by docs/make_images.py (issue 23:
pictures of runs that the code no longer makes), and each stays small."""
from __future__ import annotations

import importlib.util
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
IMAGES = ROOT / "docs" / "images"
MAX_BYTES = 400_000


def _make_images():
    spec = importlib.util.spec_from_file_location("make_images", ROOT / "docs" / "make_images.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _shown() -> dict:
    """{image file: the doc showing it} for every local image of README.md and docs/*.md."""
    out = {}
    for doc in [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]:
        text = doc.read_text(encoding="utf-8")
        for ref in re.findall(r"!\[[^\]]*\]\(([^)\s]+)", text) + re.findall(r'<img[^>]*\ssrc="([^"]+)"', text):
            if not re.match(r"[a-z]+:", ref):
                out[(doc.parent / ref).resolve()] = doc.name
    return out


def test_every_image_in_the_docs_is_made_by_the_script():
    made = {(IMAGES / p).resolve() for p in _make_images().outputs()}
    shown = _shown()
    assert shown, "no image found in README.md or docs/*.md"
    missing = [f"{p.relative_to(ROOT)} (in {doc})" for p, doc in shown.items() if not p.exists()]
    assert not missing, f"images the docs show but the repository lacks: {missing}"
    unmade = [f"{p.relative_to(ROOT)} (in {doc})" for p, doc in shown.items() if p not in made]
    assert not unmade, f"images docs/make_images.py does not make: {unmade}"
    unshown = [str(p.relative_to(ROOT)) for p in made if p not in shown]
    assert not unshown, f"docs/make_images.py makes images no doc shows: {unshown}"


def test_images_are_small_pngs():
    for p in _make_images().outputs():
        data = (IMAGES / p).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n", p
        assert len(data) <= MAX_BYTES, f"docs/images/{p} is {len(data)} bytes"
