"""Results files are written whole or not at all (``pickdemo.apps.files``)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from pickdemo.apps import files
from pickdemo.apps.files import write_atomic


def test_a_file_is_replaced_whole_with_a_new_files_permissions(tmp_path: Path) -> None:
    path = tmp_path / "summary.json"
    path.write_text("old")
    old_umask = os.umask(0o027)
    try:
        assert write_atomic(path, "new ü\n") == path
    finally:
        os.umask(old_umask)
    assert path.read_bytes() == "new ü\n".encode() and list(tmp_path.iterdir()) == [path]
    assert path.stat().st_mode & 0o777 == 0o640  # as a new file gets (not mkstemp's 0600)
    write_atomic(path, b"\x89PNG")
    assert path.read_bytes() == b"\x89PNG"


def test_a_write_that_fails_leaves_the_old_file_and_no_temporary_one(tmp_path: Path, monkeypatch) -> None:
    path = tmp_path / "episodes.jsonl"
    path.write_text('{"seed": 0}\n')

    def disk_full(fd: int) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(files.os, "fsync", disk_full)
    with pytest.raises(OSError, match="No space"):
        write_atomic(path, "")
    assert path.read_text() == '{"seed": 0}\n' and list(tmp_path.iterdir()) == [path]
