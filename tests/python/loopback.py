"""A TCP server on loopback, in a thread of the test's own process: what
tests point a client at (a Dask address, a storage endpoint) to see what
it sends or how it gives up, without any network."""

from __future__ import annotations

import socket
import threading


class Server:
    """Listens on 127.0.0.1 at a free port (``port``); ``answer(conn)``
    handles each connection in a thread of its own. ``conns`` are the
    connections accepted, in order."""

    def __init__(self, answer):
        self.sock = socket.socket()
        self.sock.bind(("127.0.0.1", 0))
        self.sock.listen(16)
        self.port = self.sock.getsockname()[1]
        self.conns: list[socket.socket] = []
        self.answer = answer
        threading.Thread(target=self._loop, daemon=True).start()

    def _loop(self):
        while True:
            try:
                conn, _ = self.sock.accept()
            except OSError:
                return
            self.conns.append(conn)
            threading.Thread(target=self.answer, args=(conn,), daemon=True).start()

    def close(self):
        for c in self.conns:
            c.close()
        self.sock.close()
