"""The staging of a recording: each episode written whole into ``DIR/.staging/`` (into a temporary name,
renamed when it is complete: a killed run leaves no half episode there), with its record
(``seed-N.json``) last; and what the formats share (a frame's ticks, the errors). The datasets are
made from the staging (:mod:`pickdemo.apps.datasets`, :mod:`pickdemo.apps.lerobot_dataset`).
"""

from __future__ import annotations

import json
from dataclasses import asdict
from pathlib import Path

import numpy as np

from pickdemo.apps.files import write_atomic
from pickdemo.envs.record import Recorded

STAGING = ".staging"


class DatasetError(Exception):
    """A dataset directory that cannot be used; the message is one line naming the file."""


def staged(out: Path) -> dict[int, dict]:
    """The episodes staged in ``out``: seed -> its record (``seed-N.json``, written last)."""
    stage = out / STAGING
    records = {}
    for path in sorted(stage.glob("seed-*.json")) if stage.is_dir() else ():
        record = json.loads(path.read_text())
        records[int(record["seed"])] = record
    return records


def write_record(out: Path, recorded: Recorded, extra: dict) -> None:
    write_atomic(out / STAGING / f"seed-{recorded.seed}.json", json.dumps({**asdict(recorded), **extra}) + "\n")


def hold_ticks(ticks: list[np.ndarray], stride: int) -> np.ndarray:
    """A frame's ticks' actions as (stride, A): a short last frame's missing ticks hold its last action
    (no NaN: LeRobot's tools turn a NaN into a null that no frame then loads); its count says how many
    were acted."""
    out = np.repeat(np.asarray(ticks[-1], dtype=np.float64)[None, :], stride, axis=0)
    out[: len(ticks)] = ticks
    return out


def acted_ticks(ticks: np.ndarray, counts: np.ndarray | None, width: int) -> list[np.ndarray]:
    """Every acted tick's action of an episode, in order, from its frames' ``ticks`` (T, stride x A) and
    how many each acted (None: a dataset written before the counts, its missing ticks NaN)."""
    rows = np.asarray(ticks, dtype=np.float64).reshape(len(ticks), -1, width)
    if counts is None:
        return [row for frame in rows for row in frame if not np.isnan(row).any()]
    return [row for frame, n in zip(rows, counts, strict=True) for row in frame[: int(n)]]


# ===================================================================================== HDF5


def remove_tree(path: Path) -> None:
    for p in sorted(path.rglob("*"), reverse=True):
        p.rmdir() if p.is_dir() else p.unlink()
    path.rmdir()
