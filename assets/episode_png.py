"""Make docs/img/episode.png (the README's picture): two frames of a real episode's video, stacked.

    python assets/episode_png.py            # pick_pushed seed 1: just after the push, and the descent

Needs the video extra (PyAV). The frames are taken at simulated times, from the video that
`python -m pickdemo run pick_pushed --seed 1 --out DIR --video` writes.
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

import av
import cv2
import numpy as np

from pickdemo.apps.cli import main as pickdemo


def frames_at(video: Path, times_s: list[float]) -> list[np.ndarray]:
    with av.open(str(video)) as container:
        stream = container.streams.video[0]
        frames = [(float(f.pts * stream.time_base), f.to_ndarray(format="bgr24")) for f in container.decode(video=0)]
    return [min(frames, key=lambda tf: abs(tf[0] - t))[1] for t in times_s]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", default="pick_pushed")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--push-after-s", type=float, default=0.4, help="the first frame: this long after the push")
    parser.add_argument("--out", type=Path, default=Path(__file__).resolve().parents[1] / "docs/img/episode.png")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        pickdemo(["run", args.scenario, "--seed", str(args.seed), "--out", tmp, "--video", "--quiet"])
        result = json.loads((Path(tmp) / "result.json").read_text())
        phases = {p["phase"]: p["sim_time_s"] for p in reversed(result["phases"])}  # each state's first entry
        push = result["disturbances"][0]["start_s"] if result["disturbances"] else phases["approach"]
        descent = 0.5 * (phases["descend"] + phases["close"])
        times = [push + args.push_after_s, descent]
        top, bottom = frames_at(Path(tmp) / "episode.mp4", times)
    cv2.imwrite(str(args.out), np.vstack([top, bottom]))
    print(f"wrote {args.out}: frames at {times[0]:.2f} s and {times[1]:.2f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
