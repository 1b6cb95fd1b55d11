"""A scheduler's words, every message of them, read by fabkit within bounds before dask sees them.

dask.distributed bounds the TCP connection by ``timeout`` but not the messages that follow:
its client reads every message with no time limit once it has begun, and allocates whatever
size the message announces (8 bytes, then that many). A peer that accepts and never speaks
keeps a sweep waiting for ever; one that announces 2⁶³−1 bytes, in its handshake or in any
later message, ends it in a MemoryError.

Two guards stand between dask and a ``tcp://`` scheduler. A dask scheduler speaks first on
every connection it accepts (its handshake, a few hundred bytes), so :func:`probe_scheduler`
connects on its own, reads that message under one deadline and one bound on its size, and
only then is dask let in. dask then connects through a :class:`PeerGuard`: a relay on this
machine's loopback that reads each message the scheduler sends whole, its announced sizes
checked (:data:`MAX_MESSAGE_BYTES`) before anything is allocated, and the rest of a message
begun (and the first message of a connection) within the connect timeout, before passing it
on. A peer past a bound is cut off, the guard refuses every later connection, and the sweep
ends with the guard's one line.

Examples
--------
>>> frame_size(b"\\x10\\x00\\x00\\x00\\x00\\x00\\x00\\x00")
16
"""

from __future__ import annotations

import socket
import struct
import threading
import time

from ..errors import FabkitError

__all__ = ["MAX_HANDSHAKE_BYTES", "MAX_MESSAGE_BYTES", "probe_scheduler", "frame_size",
           "PeerGuard", "guard_scheduler"]

#: Largest first message accepted from a scheduler: a dask handshake (versions, compression,
#: pickle protocol) is under 1 kB.
MAX_HANDSHAKE_BYTES = 1 << 20
#: Largest message accepted from a scheduler after its handshake, all its frames together: a
#: sweep's chunk of results is about 1 kB a point, 32 points at most (tens of kB); the
#: scheduler's own replies (its workers, a task's state) are smaller still.
MAX_MESSAGE_BYTES = 1 << 20
#: dask's frame header: the size of what follows, an unsigned 8-byte integer (native order).
_HEADER = struct.Struct("Q")


def frame_size(header: bytes) -> int:
    """The size a dask frame header announces."""
    return _HEADER.unpack(header)[0]


def _address(scheduler: str) -> tuple[str, int] | None:
    """``(host, port)`` of a ``tcp://`` address (or a bare ``host:port``); None for another
    scheme (TLS, UCX, in-process: dask's own connection is used as it is)."""
    scheme, sep, rest = scheduler.partition("://")
    if not sep:
        scheme, rest = "tcp", scheduler
    if scheme != "tcp":
        return None
    host, _, port = rest.rstrip("/").rpartition(":")
    host = host.strip("[]")
    try:
        return host or "127.0.0.1", int(port)
    except ValueError:
        raise FabkitError(f"the scheduler address {scheduler!r} has no port (e.g. "
                          "tcp://10.0.0.5:8786)") from None


def _receive(conn: socket.socket, n: int, deadline: float, scheduler: str, timeout: float):
    got = bytearray()
    while len(got) < n:
        left = deadline - time.monotonic()
        if left <= 0:
            raise socket.timeout
        conn.settimeout(left)
        part = conn.recv(min(n - len(got), 1 << 16))
        if not part:
            raise FabkitError(f"the scheduler at {scheduler} closed the connection before it "
                              "said who it is: not a dask scheduler, or one that refuses us")
        got += part
    return bytes(got)


def probe_scheduler(scheduler: str, timeout: float) -> None:
    """Connect to ``scheduler`` and read its first message, all within ``timeout`` seconds,
    its announced size within :data:`MAX_HANDSHAKE_BYTES`; the connection is then closed.

    Raises
    ------
    FabkitError
        No connection, no message within the timeout (a peer that accepts and never speaks),
        a message announced larger than the bound (checked before anything is allocated), or
        the connection closed early.
    """
    where = _address(scheduler)
    if where is None:
        return
    deadline = time.monotonic() + timeout
    try:
        with socket.create_connection(where, timeout=timeout) as conn:
            size = frame_size(_receive(conn, _HEADER.size, deadline, scheduler, timeout))
            if size > MAX_HANDSHAKE_BYTES:
                raise FabkitError(f"the scheduler at {scheduler} announces a first message of "
                                  f"{size:,} bytes, over the limit of {MAX_HANDSHAKE_BYTES:,} "
                                  "for a dask handshake: not a dask scheduler; refused before "
                                  "reading it")
            _receive(conn, size, deadline, scheduler, timeout)
    except socket.timeout:
        raise FabkitError(f"the scheduler at {scheduler} did not answer within the connect "
                          f"timeout of {timeout:g} s (it accepted the connection but sent no "
                          "handshake); check the address, or raise --connect-timeout") from None
    except OSError as exc:
        raise FabkitError(f"cannot reach the dask scheduler at {scheduler}: "
                          f"{exc.strerror or type(exc).__name__}") from None


def guard_scheduler(scheduler: str, timeout: float) -> "PeerGuard | None":
    """A started :class:`PeerGuard` in front of a ``tcp://`` scheduler; None for another scheme
    (its own transport is used as it is)."""
    where = _address(scheduler)
    return None if where is None else PeerGuard(scheduler, where, timeout)


class PeerGuard:
    """A relay on 127.0.0.1 between dask's client and a scheduler: what the client sends goes
    on as it is; what the scheduler sends is read one whole message at a time, bounded, and
    only then passed on (see the module's text).

    Parameters
    ----------
    scheduler : str
        The scheduler's address, for messages.
    where : (str, int)
        Its host and port.
    timeout : float
        Seconds for a connection's first message from its opening, and for the rest of any
        message from its first byte.
    limit : int
        Most bytes of one message, all its frames together.

    Attributes
    ----------
    failure : str or None
        Why the scheduler was cut off (one line), None while it keeps to the bounds.
    """

    def __init__(self, scheduler: str, where, timeout: float, limit: int = MAX_MESSAGE_BYTES):
        self.scheduler, self.where, self.timeout, self.limit = scheduler, where, timeout, limit
        self.failure: str | None = None
        self._lock = threading.Lock()
        self._open: list[socket.socket] = []
        self._server = socket.create_server(("127.0.0.1", 0))
        self._open.append(self._server)
        threading.Thread(target=self._accept, name="fabkit-peer-guard", daemon=True).start()

    @property
    def address(self) -> str:
        """The address dask connects to instead of the scheduler's."""
        return f"tcp://127.0.0.1:{self._server.getsockname()[1]}"

    def close(self) -> None:
        """Close the relay and every connection through it."""
        with self._lock:
            socks, self._open = self._open, []
        for sock in socks:
            _shut(sock)

    def __enter__(self) -> "PeerGuard":
        return self

    def __exit__(self, *exc) -> bool:
        self.close()
        return False

    def _fail(self, reason: str) -> None:
        with self._lock:
            if self.failure is None:
                self.failure = f"the scheduler at {self.scheduler} {reason}"
        self.close()  # and no connection after it: dask's retries meet a closed port

    def _accept(self) -> None:
        while True:
            try:
                local, _ = self._server.accept()
            except OSError:
                return  # closed
            try:
                remote = socket.create_connection(self.where, timeout=self.timeout)
            except OSError:
                _shut(local)
                continue
            with self._lock:
                if not self._open:  # closed meanwhile
                    _shut(local)
                    _shut(remote)
                    return
                self._open += [local, remote]
            threading.Thread(target=self._forward, args=(local, remote), daemon=True).start()
            threading.Thread(target=self._relay, args=(remote, local), daemon=True).start()

    @staticmethod
    def _forward(local: socket.socket, remote: socket.socket) -> None:
        """What the client sends, to the scheduler as it is."""
        try:
            while data := local.recv(1 << 16):
                remote.sendall(data)
        except OSError:
            pass
        _shut(remote)
        _shut(local)

    def _relay(self, remote: socket.socket, local: socket.socket) -> None:
        """What the scheduler sends, one bounded message at a time, to the client."""
        try:
            deadline = time.monotonic() + self.timeout  # the first message: from the connection
            while True:
                message = self._message(remote, deadline)
                if message is None:
                    break
                local.sendall(message)
                deadline = None  # later ones: from their first byte
        except _Refused as exc:
            self._fail(str(exc))
        except OSError:
            pass
        _shut(local)
        _shut(remote)

    def _message(self, remote: socket.socket, deadline) -> bytes | None:
        """One whole dask message (its 8-byte size, the frames read with it, the frames after),
        its sizes checked before they are read; None when the scheduler closed between two
        messages."""
        first = _read(remote, 1, deadline, idle=True)
        if not first:
            return None
        deadline = deadline or time.monotonic() + self.timeout
        header = first + self._read(remote, _HEADER.size - 1, deadline)
        size = frame_size(header)
        self._bound(size)
        body = self._read(remote, size, deadline)
        # the frames sent with the size: their count and lengths, then as many as fit
        count = _HEADER.unpack_from(body)[0] if size >= _HEADER.size else -1
        if count < 0 or _HEADER.size * (1 + count) > size:
            raise _Refused("sent a message that is not dask's (its frame count does not fit "
                           "its size): not a dask scheduler; cut off")
        lengths = struct.unpack_from(f"{count}Q", body, _HEADER.size)
        rest = sum(lengths) - (size - _HEADER.size * (1 + count))
        if rest < 0:
            raise _Refused("sent a message whose frames do not add up: not a dask scheduler; "
                           "cut off")
        self._bound(size + rest)
        return header + body + (self._read(remote, rest, deadline) if rest else b"")

    def _bound(self, size: int) -> None:
        if size > self.limit:
            raise _Refused(f"announces a message of {size:,} bytes, over the limit of "
                           f"{self.limit:,}: not a dask scheduler's; cut off before reading it")

    def _read(self, remote: socket.socket, n: int, deadline: float) -> bytes:
        got = _read(remote, n, deadline)
        if len(got) < n:
            raise _Refused("closed the connection in the middle of a message")
        return got


class _Refused(Exception):
    """A peer past a bound (the reason, to be said once)."""


def _read(conn: socket.socket, n: int, deadline: float | None, idle: bool = False) -> bytes:
    """Up to ``n`` bytes, fewer only when the peer closes; by ``deadline`` (None with ``idle``:
    waiting as long as it takes for the first byte of a message)."""
    got = bytearray()
    while len(got) < n:
        if deadline is None:
            conn.settimeout(None)
        else:
            left = deadline - time.monotonic()
            if left <= 0:
                raise _Refused("did not send the rest of a message within the connect timeout"
                               if not idle or got else "sent no message within the connect "
                               "timeout")
            conn.settimeout(left)
        try:
            part = conn.recv(min(n - len(got), 1 << 16))
        except socket.timeout:
            continue  # the deadline is said above
        if not part:
            break
        got += part
    return bytes(got)


def _shut(sock: socket.socket) -> None:
    try:
        sock.shutdown(socket.SHUT_RDWR)
    except OSError:
        pass
    sock.close()
