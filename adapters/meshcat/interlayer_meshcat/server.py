"""meshcat's server (``meshcat.servers.zmqserver``) bound to one address and stopped with its parent.

``python -m interlayer_meshcat.server HOST PARENT_PID``: meshcat's own ``meshcat-server`` binds its
ZeroMQ socket to 127.0.0.1 but its web server (tornado's ``listen(port)``) to every network interface,
and it has no authentication; here both listen on HOST only. It prints meshcat's two lines
(``zmq_url=...``, ``web_url=...``) and exits when PARENT_PID does (a killed run leaves no server behind).
"""
from __future__ import annotations

import os
import subprocess
import sys
import threading
import time

PARENT_POLL = 0.5  # s between checks that the run is still there


def start(host: str = "127.0.0.1") -> tuple[subprocess.Popen, str, str]:
    """The server as a child process in its own session: (process, zmq_url, web_url)."""
    from meshcat.servers.zmqserver import match_web_url, match_zmq_url

    proc = subprocess.Popen([sys.executable, "-u", "-m", "interlayer_meshcat.server", host, str(os.getpid())],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, start_new_session=True,
                            env={**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)})
    lines = []
    while len(lines) < 2:
        line = proc.stdout.readline().decode().strip()
        if not line and proc.poll() is not None:
            why = proc.stderr.read().decode().strip().splitlines()[-1:] or [f"exit code {proc.returncode}"]
            raise RuntimeError(f"the meshcat server did not start on {host}: {why[0]}")
        if line:
            lines.append(line)
    return proc, match_zmq_url(lines[0]), match_web_url(lines[1])


def _bridge(host: str):
    from meshcat.servers.zmqserver import ZMQWebSocketBridge

    class Bridge(ZMQWebSocketBridge):
        def make_app(self):
            app = super().make_app()
            listen = app.listen
            app.listen = lambda port, **kw: listen(port, address=host, **kw)  # not every interface
            return app

    return Bridge(host=host)


def _die_with(parent: int) -> None:
    def watch():
        while os.getppid() == parent:
            time.sleep(PARENT_POLL)
        os._exit(0)

    threading.Thread(target=watch, daemon=True).start()


def main(argv=None) -> None:
    host, parent = (argv or sys.argv[1:])[:2]
    _die_with(int(parent))
    bridge = _bridge(host)
    print(f"zmq_url={bridge.zmq_url}", flush=True)
    print(f"web_url={bridge.web_url}", flush=True)
    try:
        bridge.run()
    except KeyboardInterrupt:
        pass


if __name__ == "__main__":
    main()
