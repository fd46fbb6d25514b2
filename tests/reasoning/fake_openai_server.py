"""An OpenAI-compatible HTTP server on loopback, written for the tests: scripted answers and faults.

It serves ``POST /v1/chat/completions`` and ``GET /v1/models`` on 127.0.0.1 (port 0: the OS
picks a free one) from a thread. Each request takes the next scripted :class:`Reply` (or the
default one when the script is empty): an answer text, an HTTP error (429, 500, 401 ...), a body
that is not JSON, a delay. Every request is recorded (path, headers, JSON body) for assertions.
"""

from __future__ import annotations

import json
import threading
import time
from collections import deque
from dataclasses import dataclass, field
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any


@dataclass
class Reply:
    """One scripted answer.

    Attributes:
        status: HTTP status.
        content: The assistant's text, wrapped into a chat completion (status 200).
        body: A raw body sent instead (dict → JSON, str → as is).
        delay: Seconds to wait before answering.
        headers: Extra response headers (e.g. Retry-After).
    """

    status: int = 200
    content: str | None = None
    body: dict[str, Any] | str | None = None
    delay: float = 0.0
    headers: dict[str, str] = field(default_factory=dict)

    @classmethod
    def text(cls, content: str, delay: float = 0.0) -> Reply:
        """An answer with ``content`` as the assistant's message."""
        return cls(content=content, delay=delay)

    @classmethod
    def error(cls, status: int, message: str = "scripted failure", **headers: str) -> Reply:
        """An OpenAI-style error answer."""
        error = {"message": message, "type": "server_error", "code": status}
        return cls(status=status, body={"error": error}, headers=dict(headers))

    @classmethod
    def not_json(cls) -> Reply:
        """A 200 answer whose body is not JSON at all."""
        return cls(status=200, body="<html>upstream proxy error</html>",
                   headers={"Content-Type": "text/html"})


class FakeOpenAIServer:
    """The server; use as a context manager (``with FakeOpenAIServer() as server: server.url``).

    Args:
        api_key: When set, requests must carry ``Authorization: Bearer <api_key>`` or get 401
            (with a message that echoes a masked key, as OpenAI's does).
        models: Model ids ``/v1/models`` lists.
        default: The reply used when the script is empty.
    """

    def __init__(self, api_key: str | None = None, models: tuple[str, ...] = ("test-model",),
                 default: Reply | None = None) -> None:
        self.api_key = api_key
        self.models = models
        self.default = default or Reply.text("SAFE: nothing to see.")
        self.requests: list[dict[str, Any]] = []
        self._script: deque[Reply] = deque()
        self._lock = threading.Lock()
        self._server = ThreadingHTTPServer(("127.0.0.1", 0), self._handler())
        self._server.daemon_threads = True
        self._thread = threading.Thread(target=self._server.serve_forever, args=(0.02,), daemon=True)

    @property
    def url(self) -> str:
        """The base URL to give the client (``http://127.0.0.1:<port>/v1``)."""
        return f"http://127.0.0.1:{self._server.server_address[1]}/v1"

    def script(self, *replies: Reply) -> None:
        """Queue replies for the next requests, in order."""
        with self._lock:
            self._script.extend(replies)

    def chat_requests(self) -> list[dict[str, Any]]:
        """The JSON bodies of the chat requests received."""
        return [r["json"] for r in self.requests if r["path"].endswith("/chat/completions")]

    def __enter__(self) -> FakeOpenAIServer:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._server.shutdown()
        self._server.server_close()

    def _next(self) -> Reply:
        with self._lock:
            return self._script.popleft() if self._script else self.default

    def _handler(self) -> type[BaseHTTPRequestHandler]:
        server = self

        class Handler(BaseHTTPRequestHandler):
            def log_message(self, format: str, *args: Any) -> None:  # noqa: A002 - BaseHTTPRequestHandler's name
                pass

            def _record(self) -> dict[str, Any] | None:
                length = int(self.headers.get("Content-Length") or 0)
                raw = self.rfile.read(length) if length else b""
                try:
                    body = json.loads(raw) if raw else None
                except json.JSONDecodeError:
                    body = None
                server.requests.append({"path": self.path, "json": body,
                                        "headers": {k.lower(): v for k, v in self.headers.items()}})
                return body

            def _authorised(self) -> bool:
                if server.api_key is None:
                    return True
                sent = self.headers.get("Authorization", "")
                if sent == f"Bearer {server.api_key}":
                    return True
                key = sent.removeprefix("Bearer ")
                masked = f"{key[:3]}***{key[-4:]}" if len(key) > 8 else "***"
                self._send(Reply.error(401, f"Incorrect API key provided: {masked}. You can find your "
                                       f"API key at the dashboard. (full: {key})"))
                return False

            def _send(self, reply: Reply, model: str = "test-model") -> None:
                if reply.delay:
                    time.sleep(reply.delay)
                if reply.body is not None:
                    payload = reply.body if isinstance(reply.body, str) else json.dumps(reply.body)
                else:
                    payload = json.dumps({
                        "id": "chatcmpl-fake", "object": "chat.completion", "created": 0, "model": model,
                        "choices": [{"index": 0, "finish_reason": "stop",
                                     "message": {"role": "assistant", "content": reply.content}}],
                        "usage": {"prompt_tokens": 1, "completion_tokens": 1, "total_tokens": 2},
                    })
                data = payload.encode()
                try:
                    self.send_response(reply.status)
                    headers = {"Content-Type": "application/json", **reply.headers}
                    for name, value in headers.items():
                        self.send_header(name, value)
                    self.send_header("Content-Length", str(len(data)))
                    self.end_headers()
                    self.wfile.write(data)
                except (BrokenPipeError, ConnectionResetError):
                    pass  # the client gave up (timeout test)

            def do_GET(self) -> None:  # noqa: N802 - http.server's name
                self._record()
                if not self._authorised():
                    return
                if self.path.rstrip("/").endswith("/models"):
                    listed = [{"id": m, "object": "model", "created": 0, "owned_by": "test"}
                              for m in server.models]
                    self._send(Reply(body={"object": "list", "data": listed}))
                else:
                    self._send(Reply.error(404, f"no route {self.path}"))

            def do_POST(self) -> None:  # noqa: N802 - http.server's name
                body = self._record()
                if not self._authorised():
                    return
                if not self.path.rstrip("/").endswith("/chat/completions"):
                    self._send(Reply.error(404, f"no route {self.path}"))
                    return
                model = body.get("model", "test-model") if isinstance(body, dict) else "test-model"
                self._send(server._next(), model)

        return Handler
