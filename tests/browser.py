"""Headless-Chromium helpers for tests: screenshots of local HTML files and a
dependency-free PNG decoder to judge whether a screenshot is blank.

* :func:`chromium_path` - executable or ``None`` (env ``CHROMIUM`` wins).
* :func:`screenshot` - render a file:// page to PNG (fresh profile, no
  network services, SwiftShader GL, hard timeout).
* :func:`dump_dom` / :func:`probe_page` - serialized DOM after load; a probe
  listing the resources the page fetched and the JS errors it raised.
* :func:`paused_at` - a copy of a page whose animations stand still at a given
  time: the test, not the clock, chooses the frame a screenshot shows.
* :func:`read_png` - PNG -> ``uint8`` array ``(H, W, C)`` with zlib + numpy
  (Pillow is used instead when importable, it is faster).
* :func:`is_blank` / :func:`dominant_fraction` / :func:`color_fraction` /
  :func:`diff_fraction` - simple image statistics.
"""

from __future__ import annotations

import os
import shutil
import struct
import subprocess
import tempfile
import zlib
from pathlib import Path

import numpy as np

__all__ = ["chromium_path", "screenshot", "dump_dom", "probe_page", "paused_at", "read_png", "is_blank", "dominant_fraction",
           "color_fraction", "diff_fraction", "CHROMIUM_MISSING"]

CHROMIUM_MISSING = "chromium not installed: apt-get install chromium"

_FLAGS = [
    "--headless=new", "--no-sandbox", "--use-gl=swiftshader", "--enable-unsafe-swiftshader",
    "--no-first-run", "--no-default-browser-check", "--disable-background-networking",
    "--disable-component-update", "--disable-sync", "--disable-extensions",
    "--disable-default-apps", "--hide-scrollbars", "--mute-audio",
]


def chromium_path() -> str | None:
    env = os.environ.get("CHROMIUM")
    if env and os.path.exists(env):
        return env
    for name in ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable"):
        p = shutil.which(name)
        if p:
            return p
    return None


def screenshot(html_path, png_path, size=(800, 600), budget_ms: int = 3000, *, timeout: float = 120.0,
               net_log=None, extra_args=()) -> Path:
    """Render ``html_path`` (a local file, or an http(s) URL) with headless Chromium into
    ``png_path``. ``budget_ms`` is Chromium's virtual-time budget (animations
    and timers advance that far). ``net_log`` optionally records Chromium's
    network log (JSON) to that path. Raises ``RuntimeError`` when Chromium is
    missing, fails or produces no PNG. A Chromium that hangs (it did, once in
    many runs, for the whole timeout) is started once more."""
    exe = chromium_path()
    if exe is None:
        raise RuntimeError(CHROMIUM_MISSING)
    url = str(html_path) if str(html_path).startswith(("http://", "https://")) \
        else Path(html_path).resolve().as_uri()
    png_path = Path(png_path).resolve()
    png_path.parent.mkdir(parents=True, exist_ok=True)
    if png_path.exists():
        png_path.unlink()
    with tempfile.TemporaryDirectory(prefix="il-chromium-") as profile:
        cmd = [exe, *_FLAGS, f"--user-data-dir={profile}", f"--screenshot={png_path}",
               f"--window-size={int(size[0])},{int(size[1])}", f"--virtual-time-budget={int(budget_ms)}"]
        if net_log is not None:
            cmd += [f"--log-net-log={Path(net_log).resolve()}", "--net-log-capture-mode=Everything"]
        cmd += [*extra_args, url]
        proc = _run(cmd, timeout, env={**os.environ, "HOME": profile})
    if not png_path.exists() or png_path.stat().st_size == 0:
        tail = proc.stderr.decode("utf-8", "replace")[-2000:]
        raise RuntimeError(f"chromium produced no screenshot (rc={proc.returncode}):\n{tail}")
    return png_path


def _run(exe_args, timeout, env=None, attempts: int = 2):
    for attempt in range(attempts):
        try:
            return subprocess.run(exe_args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, timeout=timeout, env=env)
        except subprocess.TimeoutExpired as exc:
            if attempt + 1 == attempts:
                raise RuntimeError(f"chromium timed out after {timeout}s, {attempts} times") from exc


def dump_dom(html_path, budget_ms: int = 2000, *, size=(800, 600), timeout: float = 120.0) -> str:
    """The page's serialized DOM after ``budget_ms`` of virtual time."""
    exe = chromium_path()
    if exe is None:
        raise RuntimeError(CHROMIUM_MISSING)
    with tempfile.TemporaryDirectory(prefix="il-chromium-") as profile:
        proc = _run([exe, *_FLAGS, f"--user-data-dir={profile}", "--dump-dom",
                     f"--window-size={int(size[0])},{int(size[1])}", f"--virtual-time-budget={int(budget_ms)}",
                     Path(html_path).resolve().as_uri()], timeout)
    if proc.returncode != 0 and not proc.stdout:
        raise RuntimeError(f"chromium --dump-dom failed (rc={proc.returncode}): "
                           f"{proc.stderr.decode('utf-8', 'replace')[-2000:]}")
    return proc.stdout.decode("utf-8", "replace")


_PROBE_HEAD = """<script>(function(){window.__ilErrors=[];
var ce=console.error; console.error=function(){try{window.__ilErrors.push(Array.prototype.map.call(arguments,String).join(" "));}catch(e){} return ce.apply(console,arguments);};
window.addEventListener("error",function(e){window.__ilErrors.push("error: "+(e.message||e));});
window.addEventListener("unhandledrejection",function(e){window.__ilErrors.push("rejection: "+e.reason);});
})();</script>"""

_PROBE_TAIL = """<script>setTimeout(function(){
var res=performance.getEntriesByType("resource").map(function(e){return e.name;});
var canv=Array.prototype.map.call(document.querySelectorAll("canvas"),function(c){return [c.width,c.height];});
var pre=document.createElement("pre"); pre.id="il-probe";
pre.textContent=JSON.stringify({resources:res,errors:window.__ilErrors,canvases:canv});
document.body.appendChild(pre);}, %d);</script>"""


def probe_page(html_path, budget_ms: int = 2500, *, wait_ms: int = 1200) -> dict:
    """Load a copy of the page instrumented to record JS errors (``errors``),
    every resource it fetched (``resources``: URLs from the Resource Timing
    API; data: URLs are not listed) and its canvases' sizes (``canvases``)."""
    import json
    import re

    src = Path(html_path).read_text(encoding="utf-8")
    m = re.search(r"<head[^>]*>", src, re.I)
    src = src[:m.end()] + _PROBE_HEAD + src[m.end():] if m else _PROBE_HEAD + src
    i = src.lower().rfind("</body>")
    tail = _PROBE_TAIL % int(wait_ms)
    src = src[:i] + tail + src[i:] if i >= 0 else src + tail
    with tempfile.TemporaryDirectory(prefix="il-probe-") as d:
        copy = Path(d) / Path(html_path).name
        copy.write_text(src, encoding="utf-8")
        dom = dump_dom(copy, budget_ms)
    m = re.search(r'<pre id="il-probe">(.*?)</pre>', dom, re.S)
    if not m:
        raise RuntimeError("probe result missing from the DOM (page did not finish loading?)")
    import html as _html

    return json.loads(_html.unescape(m.group(1)))


def evaluate(html_path, js_function: str, *, wait_ms: int = 1500, budget_ms: int = 2500, size=(800, 600)):
    """The JSON value ``js_function`` (JS source of a function of no argument) returns in a copy of
    the page, called ``wait_ms`` after loading (within ``budget_ms`` of virtual time)."""
    import html as _html
    import json
    import re

    src = Path(html_path).read_text(encoding="utf-8")
    tail = ('<script>setTimeout(function(){var pre=document.createElement("pre");pre.id="il-eval";'
            f'pre.textContent=JSON.stringify(({js_function})());document.body.appendChild(pre);}}, {int(wait_ms)});</script>')
    i = src.lower().rfind("</body>")
    src = src[:i] + tail + src[i:] if i >= 0 else src + tail
    with tempfile.TemporaryDirectory(prefix="il-eval-") as d:
        copy = Path(d) / Path(html_path).name
        copy.write_text(src, encoding="utf-8")
        dom = dump_dom(copy, budget_ms, size=size)
    m = re.search(r'<pre id="il-eval">(.*?)</pre>', dom, re.S)
    if not m:
        raise RuntimeError("evaluate: no result in the DOM (page did not finish loading?)")
    return json.loads(_html.unescape(m.group(1)))


# Pauses every mounted meshcat viewer's animation at a time given in seconds; polls (on the page's
# clock, whatever its speed) until the viewers exist, as lazily mounted ones appear only when visible.
_PAUSE_TAIL = """<script>(function(){var t=%r;function pause(){
var found=false, els=document.querySelectorAll("*");
for(var i=0;i<els.length;i++){var v=els[i].meshcatViewer; if(v){v.animator.pause(); v.animator.seek(t); found=true;}}
if(!found) setTimeout(pause, 10);}
pause();})();</script>"""


def paused_at(html_path, seconds: float, out_path) -> Path:
    """Write to ``out_path`` a copy of the page whose viewers' animations are paused at ``seconds``
    (meshcat's ``Animator.pause`` and ``seek``): a screenshot of it shows that instant of the
    animation however long the browser took to load and render, unlike a time budget."""
    src = Path(html_path).read_text(encoding="utf-8")
    i = src.lower().rfind("</body>")
    tail = _PAUSE_TAIL % float(seconds)
    src = src[:i] + tail + src[i:] if i >= 0 else src + tail
    out_path = Path(out_path)
    out_path.write_text(src, encoding="utf-8")
    return out_path


# ------------------------------------------------------------------ PNG decode
def _paeth_row(cur: bytearray, prev: bytes, bpp: int) -> None:
    for i in range(len(cur)):
        a = cur[i - bpp] if i >= bpp else 0
        b = prev[i]
        c = prev[i - bpp] if i >= bpp else 0
        p = a + b - c
        pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
        if pa <= pb and pa <= pc:
            pred = a
        elif pb <= pc:
            pred = b
        else:
            pred = c
        cur[i] = (cur[i] + pred) & 0xFF


def _read_png_pure(data: bytes) -> np.ndarray:
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        raise ValueError("not a PNG file")
    pos, idat, header, palette = 8, [], None, None
    while pos < len(data):
        (length,) = struct.unpack(">I", data[pos:pos + 4])
        ctype = data[pos + 4:pos + 8]
        body = data[pos + 8:pos + 8 + length]
        pos += 12 + length
        if ctype == b"IHDR":
            header = struct.unpack(">IIBBBBB", body)
        elif ctype == b"PLTE":
            palette = np.frombuffer(body, np.uint8).reshape(-1, 3)
        elif ctype == b"IDAT":
            idat.append(body)
        elif ctype == b"IEND":
            break
    w, h, depth, color_type, _, _, interlace = header
    if depth != 8 or interlace != 0:
        raise ValueError(f"unsupported PNG (bit depth {depth}, interlace {interlace})")
    channels = {0: 1, 2: 3, 3: 1, 4: 2, 6: 4}[color_type]
    bpp, stride = channels, w * channels
    raw = zlib.decompress(b"".join(idat))
    out = np.empty((h, stride), dtype=np.uint8)
    prev = np.zeros(stride, dtype=np.uint8)
    for y in range(h):
        f = raw[y * (stride + 1)]
        line = np.frombuffer(raw, np.uint8, stride, y * (stride + 1) + 1)
        if f == 0:
            cur = line.copy()
        elif f == 1:  # Sub: running sum per channel
            cur = np.cumsum(line.reshape(w, bpp).astype(np.uint32), axis=0).astype(np.uint8).reshape(-1)
        elif f == 2:  # Up
            cur = line + prev
        elif f == 3:  # Average: sequential
            cur = bytearray(line)
            pv = prev.tobytes()
            for i in range(stride):
                a = cur[i - bpp] if i >= bpp else 0
                cur[i] = (cur[i] + ((a + pv[i]) >> 1)) & 0xFF
            cur = np.frombuffer(bytes(cur), np.uint8)
        elif f == 4:  # Paeth: sequential
            cur = bytearray(line)
            _paeth_row(cur, prev.tobytes(), bpp)
            cur = np.frombuffer(bytes(cur), np.uint8)
        else:
            raise ValueError(f"bad PNG filter {f}")
        out[y] = cur
        prev = out[y]
    img = out.reshape(h, w, channels)
    if color_type == 3:
        img = palette[img[..., 0]]
    return img


def read_png(path, *, use_pil: bool | None = None) -> np.ndarray:
    """Decode an 8-bit non-interlaced PNG into ``uint8 (H, W, C)``. Uses Pillow
    when available (``use_pil=None``), else the stdlib/numpy decoder."""
    data = Path(path).read_bytes()
    if use_pil is not False:
        try:
            import io

            from PIL import Image
        except ImportError:
            if use_pil:
                raise
        else:
            return np.asarray(Image.open(io.BytesIO(data)))
    return _read_png_pure(data)


def _rgb(img: np.ndarray) -> np.ndarray:
    if img.ndim == 2:
        img = img[..., None]
    if img.shape[2] == 1 or img.shape[2] == 2:
        return np.repeat(img[..., :1], 3, axis=2)
    return img[..., :3]


def dominant_fraction(png_or_array, tol: int = 8) -> float:
    """Fraction of pixels within ``tol`` (per channel) of the most common
    colour (colours quantised to ``tol``-wide bins)."""
    img = read_png(png_or_array) if not isinstance(png_or_array, np.ndarray) else png_or_array
    rgb = _rgb(img).reshape(-1, 3).astype(np.int32) // max(1, tol)
    keys = (rgb[:, 0] << 16) | (rgb[:, 1] << 8) | rgb[:, 2]
    _, counts = np.unique(keys, return_counts=True)
    return float(counts.max()) / len(keys)


def is_blank(png_path, *, threshold: float = 0.995, tol: int = 8) -> bool:
    """True if (nearly) all pixels are one colour: >= ``threshold`` of the
    pixels in the dominant ``tol``-quantised colour bin."""
    return dominant_fraction(png_path, tol) >= threshold


def color_fraction(png_or_array, rgb, tol: int = 40) -> float:
    """Fraction of pixels within ``tol`` (max-abs per channel) of ``rgb`` (0..255)."""
    img = read_png(png_or_array) if not isinstance(png_or_array, np.ndarray) else png_or_array
    d = np.abs(_rgb(img).astype(np.int32) - np.asarray(rgb, dtype=np.int32)[None, None, :]).max(axis=2)
    return float((d <= tol).mean())


def diff_fraction(png_a, png_b, tol: int = 24) -> float:
    """Fraction of pixels differing by more than ``tol`` in some channel."""
    a = _rgb(read_png(png_a) if not isinstance(png_a, np.ndarray) else png_a).astype(np.int32)
    b = _rgb(read_png(png_b) if not isinstance(png_b, np.ndarray) else png_b).astype(np.int32)
    if a.shape != b.shape:
        raise ValueError(f"image sizes differ: {a.shape} vs {b.shape}")
    return float((np.abs(a - b).max(axis=2) > tol).mean())
