"""The worker process of :class:`evolution.evaluators.PoolEvaluator`: ``python -m evolution._worker IN OUT PARENT``.

It first receives the problem (pickled once by the parent), says ``"ready"``, then answers every ``(task, genomes,
seeds)`` with ``(task, "ok", evaluation)`` or ``(task, "error", traceback)`` until it reads ``None`` or the pipe
closes. It is a fresh interpreter (not forked, not multiprocessing's spawn), so it never re-runs the caller's script,
and it dies with its parent: a parent killed with ``kill -9`` leaves no worker behind.
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
    problem = pickle.loads(reader.recv_bytes())
    writer.send("ready")
    while True:
        try:
            message = reader.recv()
        except EOFError:
            return
        if message is None:
            return
        task, genomes, seeds = message
        try:
            writer.send((task, "ok", problem.evaluate(genomes, seeds)))
        except Exception:  # the problem's own failure: the parent decides what it means
            writer.send((task, "error", traceback.format_exc()))


def main(argv: list[str]) -> None:
    die_with_parent(int(argv[2]))
    # Ctrl-C is for the parent, which finishes the generation and checkpoints.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    serve(Connection(int(argv[0]), writable=False), Connection(int(argv[1]), readable=False))


if __name__ == "__main__":
    main(sys.argv[1:])
