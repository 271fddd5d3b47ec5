"""Summary statistics of measurements, shared by the bench and the perception evaluation."""

from __future__ import annotations

import numpy as np


def describe(values: list[float | None]) -> dict[str, float] | None:
    """Median, 95th percentile, max, mean and count of the values that are not None (None if none)."""
    v = np.asarray([x for x in values if x is not None], dtype=float)
    if len(v) == 0:
        return None
    return {"median": float(np.median(v)), "p95": float(np.percentile(v, 95)), "max": float(v.max()),
            "mean": float(v.mean()), "n": int(len(v))}  # fmt: skip
