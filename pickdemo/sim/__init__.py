"""The simulator side: the only modules of pickdemo that import pybullet."""

from __future__ import annotations

import contextlib
import ctypes
import os
import sys
from collections.abc import Iterator

try:
    _LIBC = ctypes.CDLL(None)
except OSError:  # pragma: no cover - platforms without a loadable C library handle
    _LIBC = None


def _flush_c_stdio() -> None:
    if _LIBC is not None:
        _LIBC.fflush(None)


@contextlib.contextmanager
def quiet_c_stdout() -> Iterator[None]:
    """Silence what PyBullet's C code prints (its build time, ``argv[0]=``) on stdout and stderr.

    Those lines would interleave with pickdemo's own output and break machine-readable stdout.
    """
    streams = []
    for stream in (sys.stdout, sys.stderr):
        try:
            streams.append((stream, stream.fileno()))
        except (AttributeError, OSError, ValueError):  # replaced by something without a file
            pass
    saved = []
    with open(os.devnull, "w") as devnull:
        for stream, fd in streams:
            stream.flush()
            saved.append((stream, fd, os.dup(fd)))
            os.dup2(devnull.fileno(), fd)
        try:
            yield
        finally:
            _flush_c_stdio()  # C's buffers hold what was printed while redirected
            for stream, fd, old in saved:
                stream.flush()
                os.dup2(old, fd)
                os.close(old)


with quiet_c_stdout():
    import pybullet  # noqa: F401  (prints its build time on import)
