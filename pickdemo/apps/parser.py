"""The command line's arguments: every command's parser, its options and their help
(:func:`build_parser`); :mod:`pickdemo.apps.cli` runs what they ask for."""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from pickdemo import __version__
from pickdemo.apps.bench import DEFAULT_MIN_SUCCESS

#: What ``pickdemo --help`` says pickdemo is (the same words as pyproject.toml's description).
DESCRIPTION = (
    "A simulated robot arm (Panda, SO-101, UR5 with a hand or a suction cup ship) picks an object it has only "
    "seen: RGB-D perception to Ruckig control, headless and reproducible."
)

PERCEPTION_HELP = (
    "perception in the loop: paper (default), icp, centroid, pixel, or module:function for your own "
    "estimator (frame, target model) -> PoseEstimate"
)


class UsageError(Exception):
    """Bad command-line input; the message is one line."""


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # one line, exit 2, instead of argparse's usage dump
        raise UsageError(message)


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="pickdemo", description=DESCRIPTION)
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    run = sub.add_parser("run", help="run one episode of a scenario")
    run.add_argument("scenario", help="a scenario name (see `pickdemo list`) or a path to a .toml file")
    run.add_argument("--seed", type=int, default=0, help="episode seed (default 0)")
    run.add_argument(
        "--out",
        type=Path,
        metavar="DIR",
        help="directory to write result.json, motion.png and report.html into (and episode.mp4 with --video)",
    )
    run.add_argument("--gui", action="store_true", help="open the PyBullet window (needs a display)")
    run.add_argument("--quiet", action="store_true", help="print only the summary line")
    run.add_argument("--open-loop", action="store_true", help="look once and play the plan (for comparison)")
    run.add_argument("--perception", default="paper", metavar="METHOD", help=PERCEPTION_HELP)
    run.add_argument(
        "--video",
        action="store_true",
        help="with --out: write DIR/episode.mp4 (needs pip install -c .ci/constraints.txt '.[video]' in the checkout)",
    )
    run.add_argument(
        "--rerun",
        type=Path,
        metavar="FILE.rrd",
        help="write a rerun recording of the episode (open it with `rerun FILE.rrd`; needs the rerun extra: "
        "pip install -c .ci/constraints.txt '.[rerun]')",
    )
    bench = sub.add_parser(
        "bench",
        help="run many seeded episodes in parallel and gate on the success rate",
        description="Runs every scenario x seed as an episode in parallel workers, streams each result to "
        "DIR/episodes.jsonl, prints a summary and writes it to DIR/summary.json, DIR/bench.png and DIR/report.html "
        f"(and JUnit XML with --junit). Exit 1 when a scenario's success rate is below --min-success (default "
        f"{DEFAULT_MIN_SUCCESS:g}; --min-success 0 turns the gate off).",
    )
    bench.add_argument("scenarios", nargs="*", metavar="SCENARIO", help="names or paths (default: the suite)")
    bench.add_argument("--seeds", default="0-19", help="seeds, e.g. 0-199 or 0-9,20 (default 0-19)")
    bench.add_argument("--workers", type=int, default=os.cpu_count() or 1, help="worker processes (default: all cores)")
    bench.add_argument(
        "--min-success",
        type=float,
        default=DEFAULT_MIN_SUCCESS,
        metavar="RATE",
        help=f"exit 1 if a scenario's success rate is below RATE (default {DEFAULT_MIN_SUCCESS:g}; 0: no gate)",
    )
    bench.add_argument(
        "--out",
        type=Path,
        metavar="DIR",
        help="directory for episodes.jsonl, summary.json, bench.png and report.html",
    )
    bench.add_argument("--junit", type=Path, help="write JUnit XML (one test case per episode) to this file")
    bench.add_argument(
        "--resume",
        action="store_true",
        help="skip the episodes already in DIR/episodes.jsonl (it may hold only episodes this run asks for)",
    )
    bench.add_argument("--executor", choices=("local", "ray"), default="local", help="worker processes or Ray tasks")
    bench.add_argument("--address", help="Ray cluster address (default: RAY_ADDRESS, else a local Ray instance)")
    bench.add_argument(
        "--episode-timeout", type=float, default=300.0, help="wall-clock guard per episode, s (default 300)"
    )
    bench.add_argument("--no-progress", action="store_true", help="no progress bar")
    bench.add_argument(
        "--fail-fast",
        action="store_true",
        help="stop a scenario once its failures exceed what --min-success allows over the seeds asked, and the "
        "whole run once every scenario's answer is fixed (the same decision as the full run)",
    )
    bench.add_argument("--open-loop", action="store_true", help="look once and play the plan (for comparison)")
    bench.add_argument("--perception", default="paper", metavar="METHOD", help=PERCEPTION_HELP)
    perceive = sub.add_parser(
        "perceive",
        help="perception only: every method on the same frames, errors against the truth",
        description="Renders each seed's scene (no arm motion), runs each perception method on that frame and "
        "prints position, yaw, pitch and roll errors per method, the covariance's calibration (NEES) and the "
        "time per frame. --out DIR writes perception.json, perception.png and report.html. A file without a "
        "`task` key is read as a perception task.",
    )
    perceive.add_argument("scenario", help="a scenario name or path")
    perceive.add_argument("--seeds", default="0-19", help="seeds, e.g. 0-99 (default 0-19)")
    perceive.add_argument(
        "--methods", default=None, help="comma-separated (default: all that apply to the scenario's targets)"
    )
    perceive.add_argument(
        "--out", type=Path, metavar="DIR", help="directory for perception.json, perception.png and report.html"
    )
    perceive.add_argument("--repeat", type=int, default=1, help="time each method N times per frame (median)")
    prof = sub.add_parser(
        "profile",
        help="where an episode's wall time goes, stage by stage, beside its own physics replayed",
        description="Runs the seeds' episodes one after another in this process, each stage of the loop timed "
        "(physics, robot I/O, render, perception, tracker, skill, motion, kinematics, observers), and replays each "
        "one's physics right after it (the same scene, the commands sent at the same steps, nothing else) as the "
        "reference: the loop's real-time factor is printed as a share of the replay's, measured in the same run; "
        "the bare physics of the cell (its robot and table, no objects) as a second line.",
    )
    prof.add_argument("scenario", help="a scenario name or path")
    prof.add_argument("--seeds", default="0-2", help="seeds, e.g. 0-9 (default 0-2)")
    prof.add_argument("--json", action="store_true", help="print the figures as JSON instead")
    prof.add_argument(
        "--open-loop", action="store_true", help="look once and play the plan: the loop without its closed-loop frames"
    )
    validate = sub.add_parser(
        "validate",
        help="check scenarios without running them",
        description="Loads each scenario and checks everything that can be checked without running it: the "
        "schema, the geometry (objects on the table, apart, out of the robot), reach of the pick and place "
        "regions, the camera's view of the target. Prints `ok NAME` or the error; exit 0 if all are ok, else 2.",
    )
    validate.add_argument("scenarios", nargs="+", metavar="SCENARIO", help="names or paths")
    demos = sub.add_parser(
        "demos",
        help="record the expert's episodes as a dataset (LeRobot v3 or HDF5)",
        description="Runs pickdemo's closed-loop skill as the expert policy of the Gymnasium environment, seed "
        "after seed, and records each episode: per frame the state observation, the action, every control "
        "tick's action and the simulator's state (for an exact replay), and each camera's images. Needs the "
        "demos extra (pip install -c .ci/constraints.txt '.[demos]').",
    )
    demos.add_argument("scenario", help="a scenario name or path (its task: pick or clear)")
    demos.add_argument("--seeds", default="0-9", help="seeds, e.g. 0-99 (default 0-9)")
    demos.add_argument("--out", type=Path, metavar="DIR", required=True, help="the dataset's directory")
    demos.add_argument("--format", choices=("lerobot", "hdf5"), default="lerobot", help="default: lerobot")
    demos.add_argument(
        "--fps", type=float, default=30.0,
        help="dataset frames per second (default 30: LeRobot's own recordings', whose datasets a merge must match)",
    )  # fmt: skip
    demos.add_argument(
        "--image-width", type=int,
        help="the cameras' images' width in pixels (default 224, or a LeRobot follower's own, whose aspect it keeps)",
    )  # fmt: skip
    demos.add_argument(
        "--features", choices=("follower", "pickdemo"),
        help="LeRobot's format: a robot with a [lerobot] table in its file records its follower's features, as a real "
        "recording of that arm has them (default); pickdemo: the environment's own state and action",
    )  # fmt: skip
    demos.add_argument("--robot", help="another robot than the scenario's (a shipped robot's name or a robot file)")
    demos.add_argument(
        "--task", help="the episodes' task string (default: the scenario's instruction, or one made from its target)"
    )
    demos.add_argument("--only-success", action="store_true", help="keep only the episodes that succeed")
    demos.add_argument("--resume", action="store_true", help="go on with a recording in DIR that was stopped")
    demos.add_argument("--no-progress", action="store_true", help="no progress bar")
    replay = sub.add_parser(
        "replay",
        help="replay a recorded episode from its states and from its actions",
        description="Plays an episode of a `pickdemo demos` dataset again: set to its simulator states frame by "
        "frame, and from its actions alone; says whether each succeeds again and whether the replay from actions "
        "went through the recorded states bit for bit (it does on the machine that recorded it). Exit 0 when every "
        "replay of a successful episode succeeds, 1 otherwise.",
    )
    replay.add_argument("dir", type=Path, metavar="DIR", help="a dataset written by `pickdemo demos`")
    replay.add_argument(
        "--episode", default="0", help="the episode's number in the dataset (default 0), several (0-9,20) or all"
    )
    comp = sub.add_parser(
        "compare",
        help="two bench runs paired by seed: which scenarios a change made worse",
        description="Pairs two `bench --out` folders by scenario and seed (the same seeds, one machine and lock): "
        "per scenario the seeds that flipped, McNemar's exact test on them (one-sided for worse and for better, "
        "Holm-adjusted over the scenarios), and the pose error, place error, attempts and wall time as paired "
        "differences with a bootstrap 95 % interval. Exit 0: nothing significantly worse; 1: something is; "
        "2: the folders do not pair.",
    )
    comp.add_argument("base", type=Path, metavar="BASE", help="the bench folder of the base (before the change)")
    comp.add_argument("new", type=Path, metavar="NEW", help="the bench folder of the change")
    comp.add_argument("--alpha", type=float, default=0.05, help="the family-wise error rate (default 0.05)")
    comp.add_argument("--markdown", type=Path, metavar="FILE", help="write the report as Markdown (a CI summary)")
    comp.add_argument("--json", type=Path, metavar="FILE", help="write the report as JSON")
    listing = sub.add_parser("list", help="list the shipped scenarios with their descriptions")
    listing.add_argument("--names", action="store_true", help="only the names, one a line (for scripts)")
    return parser
