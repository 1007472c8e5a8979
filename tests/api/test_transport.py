"""The light client's HTTP connection (``multion_client.transport``) against a scripted server:
keep-alive reuse, a connection the server closed while idle, failures before and after the
request was sent (which decide whether a step may be resent), path prefixes and proxies."""

from __future__ import annotations

import socket
import threading
import time
from collections.abc import Callable, Iterator
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

import pytest

from multion_client import Client
from multion_client.errors import ServerUnavailable
from multion_client.protocol import decode, encode
from multion_client.transport import Connection, TransportError


class Recorder(ThreadingHTTPServer):
    daemon_threads = True
    # what happened, for the tests to read
    connections = 0
    targets: list[str]
    behaviour: Callable[[BaseHTTPRequestHandler], None]


class Handler(BaseHTTPRequestHandler):
    protocol_version = "HTTP/1.1"  # keep-alive
    server: Recorder

    def setup(self) -> None:
        super().setup()
        self.server.connections += 1

    def do_GET(self) -> None:  # noqa: N802 - http.server's naming
        self._answer()

    def do_POST(self) -> None:  # noqa: N802
        self.rfile.read(int(self.headers.get("content-length", 0)))
        self._answer()

    def _answer(self) -> None:
        self.server.targets.append(self.path)
        self.server.behaviour(self)

    def log_message(self, format: str, *args: object) -> None:
        pass


def answer_msgpack(handler: BaseHTTPRequestHandler) -> None:
    body = encode({"ok": True, "path": handler.path})
    handler.send_response(200)
    handler.send_header("content-type", "application/msgpack")
    handler.send_header("content-length", str(len(body)))
    handler.end_headers()
    handler.wfile.write(body)


@pytest.fixture
def server() -> Iterator[Recorder]:
    recorder = Recorder(("127.0.0.1", 0), Handler)
    recorder.targets, recorder.behaviour = [], answer_msgpack
    thread = threading.Thread(target=recorder.serve_forever, daemon=True)
    thread.start()
    yield recorder
    recorder.shutdown()
    recorder.server_close()


def url_of(server: Recorder) -> str:
    host, port = server.server_address[:2]
    return f"http://{host!s}:{port}"


def connect(url: str) -> Connection:
    return Connection(url, timeout_s=10, connect_timeout_s=5, headers={})


def test_requests_share_one_connection(server: Recorder) -> None:
    conn = connect(url_of(server))
    for _ in range(3):
        answer = conn.request("POST", "/v1/x", b"abc", {"content-type": "application/msgpack"})
        assert answer.is_success and decode(answer.content)["ok"] is True
    assert server.connections == 1
    conn.close()


def test_a_connection_the_server_closed_while_idle_is_replaced(server: Recorder) -> None:
    def answer_then_close(handler: BaseHTTPRequestHandler) -> None:
        answer_msgpack(handler)
        handler.close_connection = True  # what uvicorn does after its keep-alive timeout

    server.behaviour = answer_then_close
    conn = connect(url_of(server))
    first = conn.request("GET", "/a", None, None)
    # without a "connection: close" header the client cannot know: it must notice the close
    assert not first.headers.get("connection")
    time.sleep(0.3)  # the close arrives (uvicorn's comes after 5 idle seconds)
    second = conn.request("POST", "/b", b"step", None)
    assert second.is_success and server.targets == ["/a", "/b"] and server.connections == 2
    conn.close()


def test_a_refused_connection_was_never_sent() -> None:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        port = sock.getsockname()[1]  # bound, not listening: connections are refused
        with pytest.raises(TransportError) as caught:
            connect(f"http://127.0.0.1:{port}").request("POST", "/v1/step", b"", None)
    assert caught.value.never_sent


def hang_up(handler: BaseHTTPRequestHandler) -> None:
    """Read the request, then close without an answer (a server that died mid-request)."""
    handler.close_connection = True
    handler.connection.shutdown(socket.SHUT_RDWR)


def test_a_step_whose_answer_was_lost_is_not_resent(server: Recorder) -> None:
    server.behaviour = hang_up
    client = Client(url_of(server), retries=3, backoff_s=0.01)
    with pytest.raises(ServerUnavailable, match="POST .*/step failed"):
        client.step("abc", [1])
    assert len(server.targets) == 1  # the server may have stepped: once only
    with pytest.raises(ServerUnavailable):
        client.observe("abc")  # idempotent: retried
    assert len(server.targets) == 1 + 4
    client.close()


def test_a_path_prefix_is_kept(server: Recorder) -> None:
    client = Client(url_of(server) + "/multion/", retries=0)
    assert client.health()["path"] == "/multion/v1/health"
    client.close()


def test_a_proxy_from_the_environment_gets_absolute_urls(
    server: Recorder, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("HTTP_PROXY", url_of(server))
    monkeypatch.delenv("NO_PROXY", raising=False)
    monkeypatch.delenv("no_proxy", raising=False)
    conn = connect("http://multion.example:8000/p")
    assert conn.request("GET", "/v1/health", None, None).is_success
    assert server.targets == ["http://multion.example:8000/p/v1/health"]
    monkeypatch.setenv("NO_PROXY", "multion.example")
    assert connect("http://multion.example:8000")._proxy is None


def test_a_url_that_is_not_http_is_refused() -> None:
    for url in ("ftp://host", "localhost:8000", "http://"):
        with pytest.raises(ValueError, match="http:// or https://"):
            connect(url)
