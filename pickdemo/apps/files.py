"""Writing a results file whole or not at all: the one way the apps write what they measured.

:func:`write_atomic` writes a file beside its destination under a temporary name, flushes and fsyncs
it, then renames it over the destination (``os.replace``, atomic on one file system): a reader, or a
run killed mid-write, sees the old file or the new one, never a part of either. A kill leaves at most
the temporary file (``.NAME.XXXXXXXX.tmp``) beside the destination. :func:`write_figure` is the same
for a matplotlib figure. (Appending one whole, flushed line to ``episodes.jsonl`` as results stream in
is the one other write: :func:`pickdemo.apps.bench.append_episode`.)
"""

from __future__ import annotations

import io
import os
import secrets
from pathlib import Path
from typing import Any


def write_atomic(path: str | os.PathLike[str], data: str | bytes) -> Path:
    """Write ``data`` (text is written as UTF-8) to ``path`` atomically; return the path.

    The temporary file is created in the destination's directory (a rename across file systems is
    not atomic) with the permissions a new file gets (0666 less the umask), and removed if the
    write fails. The directory is fsynced after the rename where the platform allows it, so that
    the new name survives a power cut too.
    """
    path = Path(path)
    payload = data.encode("utf-8") if isinstance(data, str) else data
    fd, tmp = _create_beside(path)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(payload)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    _fsync_dir(path.parent)
    return path


def write_figure(fig: Any, path: str | os.PathLike[str], **savefig_kwargs: Any) -> Path:
    """A matplotlib figure as a PNG file, written with :func:`write_atomic`."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", **savefig_kwargs)
    return write_atomic(path, buf.getvalue())


def _create_beside(path: Path) -> tuple[int, Path]:
    """A new file beside ``path`` under a name nobody holds (``O_EXCL``), open for writing."""
    for _ in range(100):
        tmp = path.with_name(f".{path.name}.{secrets.token_hex(4)}.tmp")
        try:
            return os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0), 0o666), tmp
        except FileExistsError:
            continue
    raise FileExistsError(f"{path}: no free temporary name beside it")  # pragma: no cover - 100 random clashes


def _fsync_dir(directory: Path) -> None:
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError:  # pragma: no cover - a platform whose directories cannot be opened (Windows)
        return
    try:
        os.fsync(fd)
    except OSError:  # pragma: no cover - a file system that does not sync directories
        pass
    finally:
        os.close(fd)
