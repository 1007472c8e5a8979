"""One keep-alive HTTP/1.1 connection to a server, on the standard library's ``http.client``.

A step's answer carries images (about 460 kB at 256² RGB-D): httpx parses it in Python in
64 kB chunks and cost the client 2.0-2.3 ms of CPU per step at 256², against 0.7 ms for
``http.client``, which reads a sized body in one call (``multion bench --only http``). The
client makes one request at a time, so one connection is all it needs.

Proxies are honoured as by httpx and urllib (``HTTP_PROXY``, ``HTTPS_PROXY``, ``NO_PROXY``).
"""

from __future__ import annotations

import http.client
import select
import socket
import ssl
import urllib.request
from dataclasses import dataclass
from urllib.parse import urlsplit


class TransportError(Exception):
    """The request did not get an answer. ``never_sent``: the connection was never made, so
    the server cannot have acted on the request."""

    def __init__(self, message: str, never_sent: bool) -> None:
        super().__init__(message)
        self.never_sent = never_sent


@dataclass(frozen=True)
class Response:
    status: int
    reason: str
    headers: http.client.HTTPMessage
    content: bytes

    @property
    def is_success(self) -> bool:
        return 200 <= self.status < 300

    @property
    def text(self) -> str:
        return self.content.decode("utf-8", errors="replace")


class Connection:
    """Requests to ``base_url`` (``http://`` or ``https://``, with an optional path prefix)
    over one reused connection; a connection the server has closed while idle (its keep-alive
    timeout) is replaced before it is used."""

    def __init__(
        self, base_url: str, timeout_s: float, connect_timeout_s: float, headers: dict[str, str]
    ) -> None:
        url = urlsplit(base_url)
        if url.scheme not in ("http", "https") or not url.hostname:
            raise ValueError(f"the server's URL must be http:// or https://HOST, got {base_url!r}")
        self.scheme, self.host = url.scheme, url.hostname
        self.port = url.port or (443 if url.scheme == "https" else 80)
        self.prefix = url.path.rstrip("/")
        self.timeout_s, self.connect_timeout_s = timeout_s, connect_timeout_s
        self.headers = {"host": url.netloc, "connection": "keep-alive", **headers}
        self._proxy = _proxy_for(url.scheme, url.netloc)
        self._conn: http.client.HTTPConnection | None = None

    def request(
        self, method: str, path: str, body: bytes | None, headers: dict[str, str] | None
    ) -> Response:
        """The server's answer, whatever its status; raises :class:`TransportError`."""
        conn, fresh = self._connection()
        target = self.prefix + path
        if self._proxy is not None and self.scheme == "http":
            target = f"http://{self.headers['host']}{target}"  # a plain proxy takes full URLs
        try:
            if fresh:
                conn.connect()
                conn.sock.settimeout(self.timeout_s)
                # http.client sends a request's headers and body in two writes: without this
                # the body could wait for the server's delayed ACK of the headers (as httpx)
                conn.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        except OSError as error:
            self.close()
            raise TransportError(f"cannot connect: {_describe(error)}", never_sent=True) from None
        try:
            conn.request(method, target, body=body, headers={**self.headers, **(headers or {})})
            answer = conn.getresponse()
            content = answer.read()
        except (OSError, http.client.HTTPException) as error:
            self.close()
            raise TransportError(_describe(error), never_sent=False) from None
        if answer.will_close:
            self.close()
        return Response(answer.status, answer.reason, answer.headers, content)

    def close(self) -> None:
        if self._conn is not None:
            self._conn.close()
            self._conn = None

    def _connection(self) -> tuple[http.client.HTTPConnection, bool]:
        """The open connection, or a new (not yet connected) one: ``(connection, fresh)``."""
        if self._conn is not None and self._conn.sock is not None and not _closed(self._conn.sock):
            return self._conn, False
        self.close()
        host, port = (self.host, self.port) if self._proxy is None else self._proxy
        conn: http.client.HTTPConnection
        if self.scheme == "https":
            conn = http.client.HTTPSConnection(
                host, port, timeout=self.connect_timeout_s, context=ssl.create_default_context()
            )
        else:
            conn = http.client.HTTPConnection(host, port, timeout=self.connect_timeout_s)
        if self._proxy is not None and self.scheme == "https":
            conn.set_tunnel(self.host, self.port)
        self._conn = conn
        return conn, True


def _closed(sock: socket.socket) -> bool:
    """True if the server closed this idle connection (or sent something unasked): either
    way it cannot carry the next request."""
    try:
        readable, _, _ = select.select([sock], [], [], 0)
    except (OSError, ValueError):
        return True
    return bool(readable)


def _proxy_for(scheme: str, netloc: str) -> tuple[str, int] | None:
    """The proxy the environment names for this server (``HTTP(S)_PROXY``, not in
    ``NO_PROXY``), as (host, port)."""
    proxy = urllib.request.getproxies().get(scheme)
    if not proxy or urllib.request.proxy_bypass(netloc.rsplit(":", 1)[0]):
        return None
    parsed = urlsplit(proxy if "://" in proxy else f"http://{proxy}")
    if not parsed.hostname:
        return None
    return parsed.hostname, parsed.port or 80


def _describe(error: BaseException) -> str:
    return f"{type(error).__name__}: {error}" if str(error) else type(error).__name__
