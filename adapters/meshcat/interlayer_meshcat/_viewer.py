"""Viewer assets and HTML assembly shared by :mod:`.scene` and :mod:`.page`.

Nothing here imports meshcat (only its installed files are located), so this
module is cheap to import.

Serialisation: every scene command is the dict produced by meshcat's
``Command.lower()``, packed with ``umsgpack`` (floats forced to single
precision) exactly as meshcat's ZMQ server forwards it to the browser, then
base64-encoded into a JS string array. The boot script below decodes each
string to a ``Uint8Array`` and feeds it *synchronously and in order* to
``viewer.handle_command_bytearray`` (meshcat's own ``static_html`` uses one
asynchronous ``fetch(data:...)`` per command instead, whose completion order
is not guaranteed and which is slower).
"""

from __future__ import annotations

import base64
import functools
import hashlib
import importlib.util
import json
import os
import re
import zlib
from html import escape

__all__ = ["viewer_js_path", "viewer_js", "BOOT_JS", "encode_commands", "standalone_html",
           "mount_call", "EMBED_MARKER"]

#: attribute placed on every embedded-viewer container; :func:`page.html_page`
#: looks for it to decide whether to inline the viewer JS.
EMBED_MARKER = "data-interlayer-meshcat"


def viewer_js_path() -> str:
    """Path of meshcat's bundled viewer ``viewer/dist/main.min.js`` (not importing meshcat)."""
    spec = importlib.util.find_spec("meshcat")
    if spec is None or not spec.submodule_search_locations:
        raise RuntimeError("meshcat is not installed")
    root = list(spec.submodule_search_locations)[0]
    path = os.path.join(root, "viewer", "dist", "main.min.js")
    if not os.path.exists(path):
        raise RuntimeError(f"meshcat viewer bundle not found at {path}")
    return path


@functools.lru_cache(maxsize=1)
def viewer_js() -> str:
    """The meshcat viewer bundle (~850 KB of ASCII JS, contains no ``</script``)."""
    with open(viewer_js_path(), encoding="utf-8") as f:
        src = f.read()
    # Defensive: inlined into <script>, the text must not close the element.
    return src.replace("</script", "<\\/script")


# Sets an orbit camera in meshcat's z-up coordinates.  meshcat's three.js
# Scene carries RotX(-90deg) and the camera lives at
# /Cameras/default/rotated/<object> below a RotX(+90deg) node, so the camera's
# parent frame is the y-up three.js world: scene (x, y, z) -> (x, z, -y).
# OrbitControls keep `target` in the camera's parent frame but call
# camera.lookAt(target), which three interprets in world coordinates; the two
# only agree while /Cameras/default is untransformed, so lookAt is patched to
# map the target through the parent first (robust if someone moves that node).
_SET_CAMERA_JS = r"""
function(viewer, pos, target) {
  var cam = viewer.camera, V = cam.position.constructor;
  if (!cam.__ilPatched) {
    cam.__ilPatched = true;
    var orig = cam.lookAt;
    cam.lookAt = function(x, y, z) {
      var v = (x && x.isVector3) ? x.clone() : new V(x, y, z);
      if (cam.parent) { cam.parent.updateWorldMatrix(true, false); cam.parent.localToWorld(v); }
      return orig.call(cam, v);
    };
  }
  // pos/target are in meshcat's z-up scene frame (the three.js Scene object
  // itself carries RotX(-90deg)); map scene -> three world -> camera parent.
  viewer.scene.updateWorldMatrix(true, false);
  if (cam.parent) cam.parent.updateWorldMatrix(true, false);
  var p = new V(pos[0], pos[1], pos[2]), t = new V(target[0], target[1], target[2]);
  viewer.scene.localToWorld(p); viewer.scene.localToWorld(t);
  if (cam.parent) { cam.parent.worldToLocal(p); cam.parent.worldToLocal(t); }
  cam.position.copy(p);
  viewer.controls.target.copy(t);
  viewer.controls.update();
  viewer.set_dirty();
}
"""

BOOT_JS = r"""
(function () {
  if (window.InterlayerMeshcat) return;
  function decode(s) {
    var b = atob(s), n = b.length, u = new Uint8Array(n);
    for (var i = 0; i < n; i++) u[i] = b.charCodeAt(i);
    return u;
  }
  // "#<digest>": a command stored once per page, deflated, in a script element of type x-interlayer-blob
  var blobs = {};
  function blob(h) {
    if (!blobs[h]) {
      var bytes = decode(document.getElementById("il-blob-" + h).textContent);
      var stream = new Blob([bytes]).stream().pipeThrough(new DecompressionStream("deflate"));
      blobs[h] = new Response(stream).arrayBuffer().then(function (b) { return new Uint8Array(b); });
    }
    return blobs[h];
  }
  var setCamera = %(set_camera)s;
  // opts: {camera: [[x,y,z],[tx,ty,tz]] | null, controls: bool, fit: bool}
  function mount(el, cmds, opts) {
    if (typeof el === "string") el = document.getElementById(el);
    var shared = false;
    for (var i = 0; i < cmds.length; i++) if (cmds[i].charAt(0) === "#") shared = true;
    if (!shared) return mountBytes(el, cmds.map(decode), opts);
    return Promise.all(cmds.map(function (c) {
      return c.charAt(0) === "#" ? blob(c.slice(1)) : decode(c);
    })).then(function (bytes) { return mountBytes(el, bytes, opts); },
             function (e) { console.error("interlayer_meshcat: cannot read the scene", e); });
  }
  function mountBytes(el, cmds, opts) {
    opts = opts || {};
    var viewer = new MeshCat.Viewer(el);
    if (opts.fit) {
      // meshcat sizes the canvas to window.innerHeight; use the element instead
      var orig = viewer.set_3d_pane_size;
      viewer.set_3d_pane_size = function (w, h) {
        return orig.call(viewer, w === undefined ? el.clientWidth : w,
                         h === undefined ? el.clientHeight : h);
      };
      viewer.set_3d_pane_size();
    }
    for (var i = 0; i < cmds.length; i++) {
      try { viewer.handle_command_bytearray(cmds[i]); }
      catch (e) { console.error("interlayer_meshcat: command " + i + " failed", e); }
    }
    if (opts.camera) setCamera(viewer, opts.camera[0], opts.camera[1]);
    if (opts.controls) viewer.gui.open();
    if (opts.labels && opts.labels.length) labelOverlay(viewer, el, opts.labels);
    el.meshcatViewer = viewer;
    return viewer;
  }
  // Labels: HTML tags that follow their anchor on screen. Each frame they are placed by priority
  // (then order): above, below, right or left of the point, whichever overlaps no tag placed
  // before; a tag that fits nowhere becomes a dot showing its text on hover.
  var LABEL_CSS = ".il-labels{position:absolute;left:0;top:0;width:100%%;height:100%%;pointer-events:none;overflow:hidden}" +
    ".il-label{position:absolute;left:0;top:0;font:600 11px/1.25 system-ui,sans-serif;color:#1d232b;" +
    "background:rgba(255,255,255,.82);border:1px solid rgba(29,35,43,.25);border-radius:3px;padding:0 3px;" +
    "white-space:nowrap;pointer-events:auto;cursor:default;z-index:1}" +
    ".il-label.il-dot{width:6px;height:6px;padding:0;border-radius:50%%;background:rgba(29,35,43,.65);border:1px solid #fff;z-index:0}" +
    ".il-label.il-dot>span{display:none}" +
    ".il-label.il-dot:hover>span{display:block;position:absolute;left:9px;top:-6px;background:#fff;" +
    "border:1px solid rgba(29,35,43,.35);border-radius:3px;padding:0 3px;z-index:2}";
  function labelOverlay(viewer, el, labels) {
    if (!document.getElementById("il-label-css")) {
      var st = document.createElement("style"); st.id = "il-label-css"; st.textContent = LABEL_CSS;
      document.head.appendChild(st);
    }
    if (getComputedStyle(el).position === "static") el.style.position = "relative";
    var box = document.createElement("div"); box.className = "il-labels"; el.appendChild(box);
    var items = labels.map(function (l, i) {
      var d = document.createElement("div"); d.className = "il-label"; d.title = l[1];
      var t = document.createElement("span"); t.textContent = l[1]; d.appendChild(t); box.appendChild(d);
      return {path: l[0].split("/").filter(function (s) { return s.length; }), prio: l[2], order: i, el: d, w: 0, h: 0};
    });
    items.sort(function (a, b) { return (b.prio - a.prio) || (a.order - b.order); });
    var v = new viewer.camera.position.constructor();
    function overlaps(r, placed) {
      for (var k = 0; k < placed.length; k++) {
        var q = placed[k];
        if (r[0] < q[2] && q[0] < r[2] && r[1] < q[3] && q[1] < r[3]) return true;
      }
      return false;
    }
    function place() {
      var w = el.clientWidth, h = el.clientHeight, placed = [];
      viewer.scene.updateMatrixWorld();
      viewer.camera.updateMatrixWorld();
      for (var i = 0; i < items.length; i++) {
        var it = items[i], node = viewer.scene_tree.find(it.path).object;
        node.getWorldPosition(v); v.project(viewer.camera);
        if (!(v.z < 1) || Math.abs(v.x) > 1.02 || Math.abs(v.y) > 1.02) { it.el.style.display = "none"; continue; }
        it.el.style.display = "";
        var x = (v.x + 1) / 2 * w, y = (1 - v.y) / 2 * h;
        if (!it.w) { it.el.classList.remove("il-dot"); it.w = it.el.offsetWidth; it.h = it.el.offsetHeight; }
        var cands = [[x - it.w / 2, y - it.h - 3], [x - it.w / 2, y + 3], [x + 5, y - it.h / 2], [x - it.w - 5, y - it.h / 2]];
        var at = null;
        for (var c = 0; c < cands.length && !at; c++) {
          var r = [cands[c][0], cands[c][1], cands[c][0] + it.w, cands[c][1] + it.h];
          if (!overlaps(r, placed)) { at = cands[c]; placed.push(r); }
        }
        if (at) it.el.classList.remove("il-dot"); else { it.el.classList.add("il-dot"); at = [x - 4, y - 4]; }
        it.el.style.transform = "translate(" + at[0].toFixed(1) + "px," + at[1].toFixed(1) + "px)";
      }
    }
    function loop() { place(); requestAnimationFrame(loop); }
    loop();
  }
  // Mount when the element first becomes visible (limits live WebGL contexts).
  function mountLazy(el, cmds, opts) {
    if (typeof el === "string") el = document.getElementById(el);
    if (!("IntersectionObserver" in window)) return mount(el, cmds, opts);
    var io = new IntersectionObserver(function (entries) {
      for (var k = 0; k < entries.length; k++) {
        if (entries[k].isIntersecting) { io.disconnect(); mount(el, cmds, opts); return; }
      }
    }, {rootMargin: "200px"});
    io.observe(el);
  }
  window.InterlayerMeshcat = {mount: mount, mountLazy: mountLazy, setCamera: setCamera, decode: decode};
})();
""" % {"set_camera": _SET_CAMERA_JS.strip()}


def encode_commands(packed: list[bytes]) -> str:
    """JS array literal of base64 strings (safe inside <script>: alphabet has no '<')."""
    return "[" + ",\n".join('"' + base64.b64encode(p).decode("ascii") + '"' for p in packed) + "]"


BLOB_TYPE = "application/x-interlayer-blob"
_BLOB_RE = re.compile(r'<script type="' + re.escape(BLOB_TYPE) + r'" id="il-blob-([0-9a-f]+)">[^<]*</script>\n?')


def shared_commands(packed: list[bytes]) -> tuple[str, list[str]]:
    """(HTML elements holding each command, deflated, under its digest; the references "#digest"
    to mount: the page inflates them with the browser's DecompressionStream).
    :func:`unique_blobs` then keeps one element per digest in a page, so views drawing the same
    robot carry its meshes once."""
    refs, html = [], []
    for p in packed:
        h = hashlib.sha1(p).hexdigest()[:20]
        refs.append("#" + h)
        z = base64.b64encode(zlib.compress(p, 9)).decode("ascii")
        html.append(f'<script type="{BLOB_TYPE}" id="il-blob-{h}">{z}</script>\n')
    return "".join(html), refs


def unique_blobs(html: str) -> str:
    """``html`` with the second and later copies of every shared command removed."""
    seen = set()

    def once(m):
        if m.group(1) in seen:
            return ""
        seen.add(m.group(1))
        return m.group(0)

    return _BLOB_RE.sub(once, html)


def _opts_json(camera, controls: bool, fit: bool, labels=None) -> str:
    cam = None
    if camera is not None:
        cam = [[float(x) for x in camera[0]], [float(x) for x in camera[1]]]
    opts = {"camera": cam, "controls": bool(controls), "fit": bool(fit)}
    if labels:
        opts["labels"] = labels
    # "</" cannot close the script element from inside a label's text
    return json.dumps(opts).replace("</", "<\\/")


def mount_call(element_id: str, packed, camera=None, *, controls=False,
               fit=True, lazy=False, labels=None) -> str:
    """The JS call mounting a viewer; ``packed`` is the commands' bytes, or references
    from :func:`shared_commands`; ``labels`` is ``Scene.labels()``."""
    fn = "mountLazy" if lazy else "mount"
    cmds = json.dumps(packed) if packed and isinstance(packed[0], str) else encode_commands(packed)
    return (f"InterlayerMeshcat.{fn}({json.dumps(element_id)}, {cmds}, "
            f"{_opts_json(camera, controls, fit, labels)});")


def standalone_html(packed: list[bytes], *, title: str = "Interlayer scene", camera=None,
                    controls: bool = False, labels=None) -> str:
    """One self-contained page: inline viewer JS + boot script + commands."""
    return f"""<!DOCTYPE html>
<html>
<head>
<meta charset="utf-8">
<title>{escape(title)}</title>
<style>
html, body {{ margin: 0; padding: 0; overflow: hidden; }}
#meshcat-pane {{ position: relative; width: 100vw; height: 100vh; overflow: hidden; }}
</style>
</head>
<body>
<div id="meshcat-pane"></div>
<script>
{viewer_js()}
</script>
<script>
{BOOT_JS}
</script>
<script>
var viewer = {mount_call("meshcat-pane", packed, camera, controls=controls, fit=False, labels=labels)}
</script>
</body>
</html>
"""
