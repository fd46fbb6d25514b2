"""Tests of the live viewer's server: only requests addressed to it, bounded connections, read timeouts."""

from __future__ import annotations

import http.client
import socket
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from missiontree.runlog import follow
from missiontree.runlog.follow import make_server
from missiontree.testing_runs import synthesize_run


@pytest.fixture
def served(tmp_path: Path) -> Iterator[int]:
    """A synthetic run served live; yields the port."""
    synthesize_run(tmp_path / "run", 20)
    server = make_server(tmp_path / "run", 0)
    thread = threading.Thread(target=server.serve_forever, args=(0.05,), daemon=True)
    thread.start()
    try:
        yield int(server.server_address[1])
    finally:
        server.shutdown()
        server.server_close()


def _get(port: int, path: str = "/data.json", **headers: str) -> int:
    connection = http.client.HTTPConnection("127.0.0.1", port, timeout=10)
    try:
        connection.putrequest("GET", path, skip_host=True)
        for name, value in headers.items():
            connection.putheader(name, value)
        connection.endheaders()
        response = connection.getresponse()
        response.read()
        return response.status
    finally:
        connection.close()


def test_requests_addressed_to_the_viewer_are_served(served: int) -> None:
    """Host 127.0.0.1:port or localhost:port (and a same-site Origin) get the data."""
    assert _get(served, Host=f"127.0.0.1:{served}") == 200
    assert _get(served, "/", Host=f"localhost:{served}", Origin=f"http://localhost:{served}") == 200


def test_a_foreign_host_header_is_refused(served: int) -> None:
    """A DNS-rebinding page sends its own domain as Host: the data is not served to it."""
    assert _get(served, Host=f"attacker.example:{served}") == 403
    assert _get(served) == 403  # no Host at all


def test_a_foreign_origin_is_refused(served: int) -> None:
    """A request from another site's page (its Origin) is refused even with a loopback Host."""
    assert _get(served, Host=f"127.0.0.1:{served}", Origin="http://attacker.example") == 403


def test_a_silent_connection_is_dropped_after_the_read_timeout(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A client that sends half a request and stays silent is disconnected after the read timeout."""
    monkeypatch.setattr(follow, "READ_TIMEOUT_S", 0.3)
    synthesize_run(tmp_path / "run", 5)
    server = make_server(tmp_path / "run", 0)
    threading.Thread(target=server.serve_forever, args=(0.05,), daemon=True).start()
    try:
        with socket.create_connection(("127.0.0.1", server.server_address[1]), timeout=10) as slow:
            slow.sendall(b"GET / HTTP/1.1\r\n")
            start = time.monotonic()
            assert slow.recv(1024) == b""  # the server closed it
            assert time.monotonic() - start < 9
    finally:
        server.shutdown()
        server.server_close()


def test_connections_beyond_the_limit_get_503_at_once(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """With every slot held by a silent client, the next connection is answered 503, not left hanging."""
    monkeypatch.setattr(follow, "MAX_CONNECTIONS", 2)
    synthesize_run(tmp_path / "run", 5)
    server = make_server(tmp_path / "run", 0)
    port = int(server.server_address[1])
    threading.Thread(target=server.serve_forever, args=(0.05,), daemon=True).start()
    holders = [socket.create_connection(("127.0.0.1", port), timeout=10) for _ in range(2)]
    try:
        time.sleep(0.3)  # both accepted and holding a slot
        assert _get(port, Host=f"127.0.0.1:{port}") == 503
    finally:
        for holder in holders:
            holder.close()
        server.shutdown()
        server.server_close()
