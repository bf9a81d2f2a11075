"""The worker process of :class:`physics.parallel.CheckPool`: ``python -m physics._worker IN_FD OUT_FD``.

Once its imports are done it sends ``"ready"``; then it reads ``(task, vertices, edges, config)`` messages from one
inherited pipe and answers ``(task, report)`` on the other until it reads ``None`` or the pipe closes. Started as a
fresh interpreter (not forked, not through multiprocessing's spawn), so it never re-runs the caller's main script and
never inherits the caller's threads.
"""

from __future__ import annotations

import os
import sys
from multiprocessing.connection import Connection

from physics._quiet import import_pybullet
from physics.stability import check_or_fail


def serve(reader: Connection, writer: Connection) -> None:
    """Receive (task, vertices, edges, config), send back (task, report); stop on None or a closed pipe."""
    while True:
        try:
            message = reader.recv()
        except EOFError:
            return
        if message is None:
            return
        task, vertices, edges, config = message
        writer.send((task, check_or_fail(vertices, edges, config)))


def main(argv: list[str]) -> None:
    reader = Connection(int(argv[0]), writable=False)
    writer = Connection(int(argv[1]), readable=False)
    # Our results travel on the pipe; anything the simulator prints to stdout would only be noise.
    null = os.open(os.devnull, os.O_WRONLY)
    os.dup2(null, 1)
    import_pybullet()
    writer.send("ready")  # start-up done: the pool starts this worker's clock now, not at launch
    serve(reader, writer)


if __name__ == "__main__":
    main(sys.argv[1:])
