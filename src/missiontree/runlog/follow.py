"""``view --follow``: serve the viewer on 127.0.0.1 and keep it current as the tick log grows.

A stdlib :class:`http.server.ThreadingHTTPServer` serves ``/`` (the page, with the data as it is
now) and ``/data.json`` (the data again, which the page polls once a second). The tick log is read
incrementally: each request reads only the bytes written since the last one, and the data is
rebuilt only when new lines arrived. A line still being written (no newline yet) waits for the
next read.
"""

from __future__ import annotations

import json
import threading
import time
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any

from missiontree.runlog.html import page_data, render_page
from missiontree.runlog.replay import (
    POSES_FILE,
    RUNVIEW_FILE,
    Replay,
    load_tree,
    read_pose_trail,
    read_records,
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


def make_server(run_dir: Path, port: int = 0, mission: Path | None = None) -> ThreadingHTTPServer:
    """A server for ``run_dir`` on 127.0.0.1 (``port`` 0 picks a free one: see ``server.server_address``)."""
    live = LiveRun(run_dir, mission)

    class Handler(BaseHTTPRequestHandler):
        def do_GET(self) -> None:  # noqa: N802 - http.server's naming
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
            self.end_headers()
            self.wfile.write(body)

        def log_message(self, format: str, *args: Any) -> None:  # noqa: A002 - http.server's signature
            """Keep polls off the terminal."""

    server = ThreadingHTTPServer(("127.0.0.1", port), Handler)
    server.daemon_threads = True
    return server


def serve_in_background(run_dir: Path, port: int = 0, mission: Path | None = None) -> ThreadingHTTPServer:
    """Start a server on a daemon thread (for ``run --view``); call ``shutdown()`` to stop it."""
    server = make_server(run_dir, port, mission)
    thread = threading.Thread(target=server.serve_forever, name="missiontree-view", daemon=True)
    thread.start()
    return server
