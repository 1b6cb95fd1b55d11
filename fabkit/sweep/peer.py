"""A scheduler's first words, read by fabkit within the connect timeout, before dask is let in.

dask.distributed bounds the TCP connection by ``timeout`` but not the handshake that follows:
its client reads the peer's first message with no time limit, and allocates whatever size the
message announces (8 bytes, then that many). A peer that accepts and never speaks keeps a sweep
waiting for ever; one that announces 2⁶³−1 bytes ends it in a MemoryError. A dask scheduler
speaks first on every connection it accepts (its handshake, a few hundred bytes), so
:func:`probe_scheduler` connects on its own, reads that message under one deadline and one
bound on its size, and only then hands the address to dask.

Examples
--------
>>> frame_size(b"\\x10\\x00\\x00\\x00\\x00\\x00\\x00\\x00")
16
"""

from __future__ import annotations

import socket
import struct
import time

from ..errors import FabkitError

__all__ = ["MAX_HANDSHAKE_BYTES", "probe_scheduler", "frame_size"]

#: Largest first message accepted from a scheduler: a dask handshake (versions, compression,
#: pickle protocol) is under 1 kB.
MAX_HANDSHAKE_BYTES = 1 << 20
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
