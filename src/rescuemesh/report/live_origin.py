"""The live Foxglove server's front door: a TCP listener that reads each WebSocket upgrade request,
admits it only when its Origin is local (or allowed), and then relays the bytes both ways to the
Foxglove SDK's server on a private port. Owns the Origin rule; must not know the Foxglove protocol.
"""

# Why. A web page open in the operator's browser may open a WebSocket to ws://127.0.0.1:8765 (the
# same-origin policy does not apply to WebSockets); the server must check the Origin header the
# browser adds (RFC 6455, 10.2). The Foxglove SDK (foxglove-sdk 0.30) offers no such check, so this
# front does it: a request without Origin (a native client: the Foxglove desktop app, a script) or
# with an Origin whose host is localhost, 127.0.0.1 or [::1] is relayed; any other Origin gets
# `403 Forbidden` and is closed before a byte reaches the SDK. `allowed_origins` (or the environment
# variable RESCUEMESH_LIVE_ORIGINS, comma-separated, e.g. https://app.foxglove.dev) admits more.

from __future__ import annotations

import os
import socket
import threading
from collections.abc import Iterable
from urllib.parse import urlsplit

#: Hosts whose pages may watch a run.
LOCAL_HOSTS = frozenset({"localhost", "127.0.0.1", "::1"})
#: Extra origins the operator allows, comma-separated (exact scheme://host[:port]).
ORIGINS_ENV = "RESCUEMESH_LIVE_ORIGINS"
#: An upgrade request longer than this, or slower than HEAD_TIMEOUT_S, is dropped.
MAX_HEAD_BYTES = 16 * 1024
HEAD_TIMEOUT_S = 5.0
#: Clients served at once (a run has an operator or two watching).
MAX_CLIENTS = 16
_FORBIDDEN = b"HTTP/1.1 403 Forbidden\r\nContent-Length: 0\r\nConnection: close\r\n\r\n"


def origin_allowed(origin: str | None, allowed: Iterable[str] = ()) -> bool:
    """Whether an upgrade with this Origin header (None: the header is absent) may watch."""
    if origin is None:
        return True
    origin = origin.strip()
    if origin in {a.strip().rstrip("/") for a in allowed if a.strip()}:
        return True
    try:
        parts = urlsplit(origin)
        host = parts.hostname
    except ValueError:
        return False
    return parts.scheme in ("http", "https") and host in LOCAL_HOSTS


def origins_from_env(environ: dict[str, str] | None = None) -> tuple[str, ...]:
    environ = os.environ if environ is None else environ
    return tuple(o.strip().rstrip("/") for o in environ.get(ORIGINS_ENV, "").split(",") if o.strip())


def _origin_of(head: bytes) -> tuple[bool, str | None]:
    """(well formed, the Origin header's value or None) of a request head; two Origins: malformed."""
    origins = []
    for line in head.split(b"\r\n")[1:]:
        name, sep, value = line.partition(b":")
        if sep and name.strip().lower() == b"origin":
            origins.append(value.strip().decode("latin-1"))
    if len(origins) > 1:
        return False, None
    return True, origins[0] if origins else None


class OriginGuard:
    """Listen on host:port; relay the admitted WebSocket clients to 127.0.0.1:`backend_port`.
    `close()` stops listening and ends every relay."""

    def __init__(self, host: str, port: int, backend_port: int, allowed_origins: Iterable[str] = ()) -> None:
        self.allowed = tuple(allowed_origins)
        self.backend_port = backend_port
        self.refused = 0  # upgrades refused for their Origin (or a malformed head)
        self._listener = socket.create_server((host, port))
        self.port = self._listener.getsockname()[1]
        self._closed = threading.Event()
        self._sockets: set[socket.socket] = set()
        self._lock = threading.Lock()
        self._slots = threading.BoundedSemaphore(MAX_CLIENTS)
        threading.Thread(target=self._accept, name="live-origin-guard", daemon=True).start()

    def close(self) -> None:
        self._closed.set()
        try:
            self._listener.shutdown(socket.SHUT_RDWR)
        except OSError:
            pass
        self._listener.close()
        with self._lock:
            for sock in list(self._sockets):
                _shut(sock)
            self._sockets.clear()

    # internals

    def _accept(self) -> None:
        while not self._closed.is_set():
            try:
                client, _ = self._listener.accept()
            except OSError:
                return
            if not self._slots.acquire(blocking=False):
                client.close()
                continue
            threading.Thread(target=self._serve, args=(client,), daemon=True).start()

    def _serve(self, client: socket.socket) -> None:
        backend = None
        try:
            self._track(client)
            head = self._read_head(client)
            ok, origin = _origin_of(head) if head is not None else (False, None)
            if not ok or not origin_allowed(origin, self.allowed):
                self.refused += 1
                client.sendall(_FORBIDDEN)
                return
            backend = socket.create_connection(("127.0.0.1", self.backend_port), timeout=HEAD_TIMEOUT_S)
            backend.settimeout(None)
            client.settimeout(None)
            self._track(backend)
            backend.sendall(head)
            pump = threading.Thread(target=_relay, args=(backend, client), daemon=True)
            pump.start()
            _relay(client, backend)
            pump.join()
        except OSError:
            pass
        finally:
            for sock in (client, backend):
                if sock is not None:
                    self._untrack(sock)
                    _shut(sock)
                    sock.close()
            self._slots.release()

    def _read_head(self, client: socket.socket) -> bytes | None:
        """The request up to and including its blank line (and whatever came with it), or None."""
        client.settimeout(HEAD_TIMEOUT_S)
        data = b""
        while b"\r\n\r\n" not in data:
            if len(data) > MAX_HEAD_BYTES:
                return None
            chunk = client.recv(4096)
            if not chunk:
                return None
            data += chunk
        return data

    def _track(self, sock: socket.socket) -> None:
        with self._lock:
            self._sockets.add(sock)
        if self._closed.is_set():
            _shut(sock)

    def _untrack(self, sock: socket.socket) -> None:
        with self._lock:
            self._sockets.discard(sock)


def _relay(source: socket.socket, sink: socket.socket) -> None:
    """Copy source -> sink until either side ends; then end both directions."""
    try:
        while True:
            data = source.recv(65536)
            if not data:
                break
            sink.sendall(data)
    except OSError:
        pass
    _shut(sink)
    _shut(source)


def _shut(sock: socket.socket) -> None:
    try:
        sock.shutdown(socket.SHUT_RDWR)
    except OSError:
        pass
