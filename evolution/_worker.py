"""A worker of :class:`evolution.pool.WorkerPool`, started by the pool as ``python -c BOOT MODE PARENT IN OUT PATH...``
(``PATH...``: the module search path it is given).

It reads messages from the pipe ``IN`` and answers on ``OUT``: ``("job", bytes)`` loads a job (a pickled callable)
and answers ``"ready"``; ``("task", index, payload)`` answers ``("ok", index, job(payload))``, or ``("error", index,
traceback)`` if the job raised; ``None`` or a closed pipe ends it. It dies with its parent: a parent killed with
``kill -9`` leaves no worker behind.
"""

from __future__ import annotations

import os
import pickle
import signal
import sys
import threading
import time
import traceback
from multiprocessing.connection import Connection
from typing import Any


def die_with_parent(parent: int) -> None:
    """End this process as soon as ``parent`` is gone: at once on Linux (the kernel's parent-death signal), within
    half a second elsewhere (a thread that watches the parent process id)."""
    try:
        import ctypes

        prctl = ctypes.CDLL(None, use_errno=True).prctl
        prctl(1, signal.SIGKILL, 0, 0, 0)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):  # not Linux
        pass

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(0.5)
        os._exit(1)

    if os.getppid() != parent:  # the parent died before the signal was set up
        os._exit(1)
    threading.Thread(target=watch, daemon=True).start()


def serve(reader: Connection, writer: Connection) -> None:
    job: Any = None
    while True:
        try:
            message = reader.recv()
        except EOFError:
            return
        if message is None:
            return
        if message[0] == "job":
            job = pickle.loads(message[1])
            writer.send("ready")
            continue
        _, index, payload = message
        try:
            result = job(payload)
        except Exception:  # the job's own failure: the parent decides what it means
            writer.send(("error", index, traceback.format_exc()))
            continue
        writer.send(("ok", index, result))


def main(argv: list[str]) -> None:
    mode, parent, inbound, outbound = argv
    die_with_parent(int(parent))
    # Ctrl-C is the parent's: it finishes or abandons the batch and ends the pool.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    # Results travel on the pipes; standard output belongs to the parent's results.
    target = os.open(os.devnull, os.O_WRONLY) if mode == "quiet" else 2
    os.dup2(target, 1)
    serve(Connection(int(inbound), writable=False), Connection(int(outbound), readable=False))


if __name__ == "__main__":
    main(sys.argv[1:])
