"""Silencing PyBullet, which prints from C (its import banner to stderr, engine warnings to stdout).

Python-level redirection (``contextlib.redirect_stdout``) cannot catch C ``printf``, so the process's file
descriptors are pointed at /dev/null for the duration, and C's stdio buffers are flushed before they are restored:
otherwise text printed while silenced would still come out later, when the buffer fills.
"""

from __future__ import annotations

import ctypes
import os
import sys
from collections.abc import Iterator
from contextlib import contextmanager

_libc = ctypes.CDLL(None)


def _flush_everything() -> None:
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (AttributeError, ValueError):  # replaced or closed streams
            pass
    _libc.fflush(None)


@contextmanager
def silenced(*descriptors: int) -> Iterator[None]:
    """Discard everything written to the given file descriptors (default: stdout) inside the block."""
    descriptors = descriptors or (1,)
    _flush_everything()
    saved = [os.dup(fd) for fd in descriptors]
    null = os.open(os.devnull, os.O_WRONLY)
    try:
        for fd in descriptors:
            os.dup2(null, fd)
        yield
    finally:
        _flush_everything()
        for fd, copy in zip(descriptors, saved):
            os.dup2(copy, fd)
            os.close(copy)
        os.close(null)


def import_pybullet():
    """Import pybullet without its build-time banner on stderr."""
    if "pybullet" in sys.modules:
        return sys.modules["pybullet"]
    with silenced(1, 2):
        import pybullet
    return pybullet
