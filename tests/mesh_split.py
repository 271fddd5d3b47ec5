"""Objects nobody described, one by one (a benchmark that prints figures, not a test): every file of
a ``random_urdfs`` split picked by the full closed loop (camera, segmentation by geometry, the
paper's point model, grasps from the cloud) on a few seeds each, with the figures per object and
per failing stage.

For each file it writes a scenario (the template's, with ``urdf`` set to that file) into DIR and runs
``python -m pickdemo bench`` over them all, so the episodes are the bench's (workers, resume,
``episodes.jsonl``); then it prints the success rate with its Wilson interval, how many objects were
picked in at least 2 of their tries, and the failures by stage and by object.

    python tests/mesh_split.py                                   # the test split, 3 seeds, 2 workers
    python tests/mesh_split.py --glob "pybullet_data:random_urdfs/??5/*.urdf" --seeds 0-1
"""

from __future__ import annotations

import argparse
import collections
import json
import subprocess
import sys
from pathlib import Path

from pickdemo.apps.bench import wilson_interval
from pickdemo.core.meshes import usable

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib


def _toml(d: dict) -> str:
    """The few TOML shapes a scenario uses (tables, arrays of tables, scalars, lists)."""

    def value(v: object) -> str:
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, str):
            return json.dumps(v)
        if isinstance(v, list | tuple):
            return "[" + ", ".join(value(x) for x in v) + "]"
        return repr(v)

    lines, tables = [], []
    for k, v in d.items():
        if isinstance(v, dict):
            tables.append(f"\n[{k}]\n" + "".join(f"{kk} = {value(vv)}\n" for kk, vv in v.items()))
        elif isinstance(v, list) and v and isinstance(v[0], dict):
            for item in v:
                tables.append(f"\n[[{k}]]\n" + "".join(f"{kk} = {value(vv)}\n" for kk, vv in item.items()))
        else:
            lines.append(f"{k} = {value(v)}")
    return "\n".join(lines) + "\n" + "".join(tables)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--template", default=str(Path(__file__).parent.parent / "scenarios" / "pick_mesh_test.toml"))
    ap.add_argument("--glob", default=None, help="the files (default: the template's urdf_choice)")
    ap.add_argument("--seeds", default="0-2")
    ap.add_argument("--workers", default="2")
    ap.add_argument("--out", default="/tmp/pickdemo_mesh_split")
    ap.add_argument("--resume", action="store_true")
    args = ap.parse_args()
    template = tomllib.loads(Path(args.template).read_text())
    target = next(o for o in template["objects"] if o.get("target"))
    files = usable(args.glob or target["urdf_choice"])
    out = Path(args.out)
    (out / "scenarios").mkdir(parents=True, exist_ok=True)
    paths = []
    for f in files:
        name = f"obj_{Path(f).parent.name}"
        sc = dict(template, name=name, tags=[])
        obj = {k: v for k, v in target.items() if k != "urdf_choice"}
        obj["urdf"] = f
        sc["objects"] = [obj if o is target else o for o in template["objects"]]
        path = out / "scenarios" / f"{name}.toml"
        path.write_text(_toml(sc))
        paths.append(str(path))
    cmd = [sys.executable, "-m", "pickdemo", "bench", *paths, "--seeds", args.seeds, "--workers", args.workers,
           "--min-success", "0", "--out", str(out / "bench"), "--no-progress"]  # fmt: skip
    if args.resume:
        cmd.append("--resume")
    if subprocess.run(cmd, check=False, stdout=subprocess.DEVNULL).returncode != 0:  # (no old run's figures)
        raise SystemExit("mesh_split: the bench failed (see above)")
    rows = [json.loads(line) for line in (out / "bench" / "episodes.jsonl").read_text().splitlines() if line.strip()]
    by_obj: dict[str, list[dict]] = collections.defaultdict(list)
    for r in rows:
        by_obj[r["scenario"]].append(r)
    ok = sum(r["success"] for r in rows)
    lo, hi = wilson_interval(ok, len(rows))
    first = sum(r["success"] and len(r.get("attempts") or []) == 1 for r in rows)
    picked2 = sum(sum(r["success"] for r in rs) >= 2 for rs in by_obj.values())
    print(f"{len(files)} objects, {len(rows)} episodes: {ok} succeeded ({ok / len(rows):.1%}, Wilson 95 % "
          f"[{lo:.1%}, {hi:.1%}]); {first} on the first attempt")  # fmt: skip
    print(f"objects picked in at least 2 of their tries: {picked2} of {len(by_obj)}")
    stages = collections.Counter((r.get("failure") or {}).get("stage") for r in rows if not r["success"])
    print("failures by stage:", dict(stages.most_common()))
    for name, rs in sorted(by_obj.items()):
        bad = [r for r in rs if not r["success"]]
        if bad:
            why = "; ".join(f"seed {r['seed']} {r['failure']['stage']}: {r['failure']['reason'][:70]}" for r in bad)
            print(f"  {name}: {len(rs) - len(bad)}/{len(rs)}  {why}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
