"""``view --follow``: serve the viewer on 127.0.0.1 and keep it current as the tick log grows.

A stdlib :class:`http.server.ThreadingHTTPServer` serves ``/`` (the page, with the data as it is
now) and ``/data.json`` (the data again, which the page polls once a second). The tick log is read
incrementally: each request reads only the bytes written since the last one, and the data is
rebuilt only when new lines arrived. A line still being written (no newline yet) waits for the
next read.

The server answers only requests whose ``Host`` (and ``Origin``, when sent) name its own loopback
address, so a page on another site, a DNS-rebinding domain included, cannot read the run's data.
It serves at most :data:`MAX_CONNECTIONS` connections at once (others get 503 at once) and drops a
connection silent for :data:`READ_TIMEOUT_S` while its request is read.
"""

from __future__ import annotations

import json
import threading
import time
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any, cast

from missiontree.engine.tick_log import read_records
from missiontree.runlog.html import page_data, render_page
from missiontree.runlog.replay import (
    POSES_FILE,
    RUNVIEW_FILE,
    Replay,
    load_tree,
    read_pose_trail,
    read_runview,
)


class LiveRun:
    """A run directory whose tick log may still be growing.

    Args:
        run_dir: The run directory (``ticks.jsonl`` may not exist yet).
        mission: The mission file, when the run records no tree.
    """

    def __init__(self, run_dir: Path, mission: Path | None = None) -> None:
        self.run_dir = Path(run_dir)
        self.mission = mission
        self._lock = threading.Lock()
        self._offset = 0
        self._replay: Replay | None = None
        self._data: dict[str, Any] | None = None
        self._runview_stamp: tuple[int | None, ...] | None = None
        self._frames: dict[str, str | None] = {}
        self._declared = False
        self._tree_tried: int | None = None
        self._dirty = False
        self._built_at = 0.0
        self._build_s = 0.0
        self._encoded: tuple[dict[str, Any], bytes] | None = None

    def _tree_may_have_come(self) -> bool:
        """Whether the tree may be readable now that was not before (a new runview.json, once each)."""
        path = self.run_dir / RUNVIEW_FILE
        stamp = path.stat().st_mtime_ns if path.is_file() else None
        if stamp is None or stamp == self._tree_tried:
            return False
        self._tree_tried = stamp
        return True

    def data(self) -> dict[str, Any]:
        """The viewer data as of now (rebuilt only when the log or the run view changed)."""
        with self._lock:
            if self._replay is None or (not self._declared and self._tree_may_have_come()):
                # (re)start once the run has recorded its tree: nodes then carry types and parameters
                tree = load_tree(self.mission, self.run_dir)
                self._declared = tree is not None
                self._replay = Replay(tree)
                self._offset = 0
            log = self.run_dir / "ticks.jsonl"
            changed = False
            if log.is_file():
                if log.stat().st_size < self._offset:  # a new run replaced the log: start over
                    tree = load_tree(self.mission, self.run_dir)
                    self._declared = tree is not None
                    self._replay = Replay(tree)
                    self._offset = 0
                records, self._offset = read_records(log, self._offset)
                for record in records:
                    self._replay.feed(record)
                self._replay.flush_events()
                changed = bool(records)
            runview = self.run_dir / RUNVIEW_FILE
            trail = self.run_dir / POSES_FILE
            stamp = tuple(p.stat().st_mtime_ns if p.is_file() else None for p in (runview, trail))
            if stamp != self._runview_stamp:
                self._runview_stamp = stamp
                self._replay.set_poses(read_pose_trail(self.run_dir))
                poses = read_runview(self.run_dir).get("poses")
                if isinstance(poses, list) and poses:
                    self._replay.set_poses(
                        [tuple(p[:3]) for p in poses if isinstance(p, list) and len(p) >= 3]
                    )
                changed = True
            self._dirty = self._dirty or changed
            now = time.monotonic()
            # A long run's data takes a while to build: rebuild at most every 3 build times (>= 1 s),
            # so a page polling each second never keeps a core busy beside the running mission.
            if self._data is None or (self._dirty and now - self._built_at >= max(1.0, 3.0 * self._build_s)):
                start = time.perf_counter()
                self._data = page_data(self._replay, self.run_dir, follow=True, frame_cache=self._frames)
                self._encoded = None
                self._build_s = time.perf_counter() - start
                self._built_at = now
                self._dirty = False
            return self._data

    def data_json(self) -> bytes:
        """:meth:`data` as JSON bytes (encoded once per rebuild)."""
        data = self.data()
        with self._lock:
            if self._encoded is None or self._encoded[0] is not data:
                self._encoded = (data, json.dumps(data, separators=(",", ":")).encode("utf-8"))
            return self._encoded[1]


#: Requests served at once; a connection beyond this is answered 503 at once (no thread held).
MAX_CONNECTIONS = 32
#: Seconds a connection may stay silent while its request is read (a partial request then ends).
READ_TIMEOUT_S = 10.0
#: Connections the operating system queues before the server accepts them.
LISTEN_BACKLOG = 128


class ViewerServer(ThreadingHTTPServer):
    """The viewer's HTTP server: loopback only, a bounded number of connections served at once."""

    daemon_threads = True
    request_queue_size = LISTEN_BACKLOG

    def __init__(self, address: tuple[str, int], handler: type[BaseHTTPRequestHandler]) -> None:
        super().__init__(address, handler)
        self._slots = threading.BoundedSemaphore(MAX_CONNECTIONS)

    def allowed_hosts(self) -> set[str]:
        """The Host header values a request may carry: the bound address by IP or as localhost."""
        port = self.server_address[1]
        hosts = {f"127.0.0.1:{port}", f"localhost:{port}"}
        if port == 80:
            hosts |= {"127.0.0.1", "localhost"}
        return hosts

    def process_request(self, request: Any, client_address: Any) -> None:
        """Serve the connection on a thread of its own, or answer 503 when all slots are taken."""
        if not self._slots.acquire(blocking=False):
            try:
                request.sendall(b"HTTP/1.1 503 Service Unavailable\r\nContent-Length: 0\r\n"
                                b"Connection: close\r\nRetry-After: 1\r\n\r\n")
            except OSError:
                pass
            self.shutdown_request(request)
            return
        super().process_request(request, client_address)

    def process_request_thread(self, request: Any, client_address: Any) -> None:
        """Serve one connection, then free its slot."""
        try:
            super().process_request_thread(request, client_address)
        finally:
            self._slots.release()


def make_server(run_dir: Path, port: int = 0, mission: Path | None = None) -> ThreadingHTTPServer:
    """A server for ``run_dir`` on 127.0.0.1 (``port`` 0 picks a free one: see ``server.server_address``).

    It answers only requests addressed to it: the ``Host`` header must name the bound address
    (127.0.0.1 or localhost with its port) and an ``Origin``, when sent, must be that address too,
    so a web page on another site (a DNS-rebinding domain included) cannot read the run's data.
    """
    live = LiveRun(run_dir, mission)

    class Handler(BaseHTTPRequestHandler):
        timeout = READ_TIMEOUT_S  # socket timeout while the request is read: a stalled client ends

        def do_GET(self) -> None:  # noqa: N802 - http.server's naming
            refusal = self._refusal()
            if refusal:
                self.send_error(403, refusal)
                return
            route = self.path.split("?", 1)[0]
            if route in ("/", "/index.html"):
                body = render_page(live.data()).encode("utf-8")
                kind = "text/html; charset=utf-8"
            elif route == "/data.json":
                body = live.data_json()
                kind = "application/json"
            else:
                self.send_error(404, "the viewer serves / and /data.json")
                return
            self.send_response(200)
            self.send_header("Content-Type", kind)
            self.send_header("Content-Length", str(len(body)))
            self.send_header("Cache-Control", "no-store")
            self.send_header("X-Content-Type-Options", "nosniff")
            self.end_headers()
            self.wfile.write(body)

        def _refusal(self) -> str:
            """Why this request is not served ("" to serve it): a foreign Host or Origin."""
            allowed = cast(ViewerServer, self.server).allowed_hosts()
            host = (self.headers.get("Host") or "").strip().lower()
            if host not in allowed:
                return "the viewer answers only requests addressed to 127.0.0.1 or localhost"
            origin = self.headers.get("Origin")
            if origin is not None and origin.strip().lower() not in {f"http://{h}" for h in allowed}:
                return "the viewer answers no other site's pages"
            return ""

        def log_message(self, format: str, *args: Any) -> None:  # noqa: A002 - http.server's signature
            """Keep polls off the terminal."""

    return ViewerServer(("127.0.0.1", port), Handler)


def serve_in_background(run_dir: Path, port: int = 0, mission: Path | None = None) -> ThreadingHTTPServer:
    """Start a server on a daemon thread (for ``run --view``); call ``shutdown()`` to stop it."""
    server = make_server(run_dir, port, mission)
    thread = threading.Thread(target=server.serve_forever, name="missiontree-view", daemon=True)
    thread.start()
    return server
