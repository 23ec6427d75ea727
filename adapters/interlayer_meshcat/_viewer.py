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
import importlib.util
import json
import os
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
  var setCamera = %(set_camera)s;
  // opts: {camera: [[x,y,z],[tx,ty,tz]] | null, controls: bool, fit: bool}
  function mount(el, cmds, opts) {
    opts = opts || {};
    if (typeof el === "string") el = document.getElementById(el);
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
      try { viewer.handle_command_bytearray(decode(cmds[i])); }
      catch (e) { console.error("interlayer_meshcat: command " + i + " failed", e); }
    }
    if (opts.camera) setCamera(viewer, opts.camera[0], opts.camera[1]);
    if (opts.controls) viewer.gui.open();
    el.meshcatViewer = viewer;
    return viewer;
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


def _opts_json(camera, controls: bool, fit: bool) -> str:
    cam = None
    if camera is not None:
        cam = [[float(x) for x in camera[0]], [float(x) for x in camera[1]]]
    return json.dumps({"camera": cam, "controls": bool(controls), "fit": bool(fit)})


def mount_call(element_id: str, packed: list[bytes], camera=None, *, controls=False,
               fit=True, lazy=False) -> str:
    fn = "mountLazy" if lazy else "mount"
    return (f"InterlayerMeshcat.{fn}({json.dumps(element_id)}, {encode_commands(packed)}, "
            f"{_opts_json(camera, controls, fit)});")


def standalone_html(packed: list[bytes], *, title: str = "Interlayer scene", camera=None,
                    controls: bool = False) -> str:
    """One self-contained page: inline viewer JS + boot script + commands."""
    return f"""<!DOCTYPE html>
<html>
<head>
<meta charset="utf-8">
<title>{escape(title)}</title>
<style>
html, body {{ margin: 0; padding: 0; overflow: hidden; }}
#meshcat-pane {{ width: 100vw; height: 100vh; overflow: hidden; }}
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
var viewer = {mount_call("meshcat-pane", packed, camera, controls=controls, fit=False)}
</script>
</body>
</html>
"""
