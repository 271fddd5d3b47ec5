"""Pictures of what was measured: the arm's motion plot and a self-contained report page for `run`.

Pure: results and traces in, files out. Plots use matplotlib (the ``plots`` extra), drawn headless
(Agg). The report page embeds its images (base64) and refers to the video beside it, so it opens
from the directory with no network and no server.
"""

from __future__ import annotations

import base64
import html
from pathlib import Path

import numpy as np

from pickdemo import robot_model as rm
from pickdemo.result import EpisodeResult, EpisodeTrace


class PlotsUnavailable(RuntimeError):
    """matplotlib is not installed."""


def _pyplot():
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError as exc:
        raise PlotsUnavailable('plots need matplotlib: pip install "pickdemo[plots]"') from exc
    return plt


def joint_motion(trace: EpisodeTrace) -> dict[str, np.ndarray]:
    """The commanded joints' position, velocity, acceleration and jerk per tick (finite differences)."""
    t = trace.time_s
    q = trace.q
    if len(t) < 4:
        raise ValueError("the trace is too short to differentiate")
    vel = np.gradient(q, t, axis=0)
    acc = np.gradient(vel, t, axis=0)
    jerk = np.gradient(acc, t, axis=0)
    return {"time_s": t, "position": q, "velocity": vel, "acceleration": acc, "jerk": jerk}


def write_motion_plot(trace: EpisodeTrace, path: Path, title: str = "") -> Path:
    """Per arm joint: position, velocity, acceleration and jerk over time, with the datasheet limits
    (dashed, each joint's colour) and the moments Ruckig was re-targeted (grey lines)."""
    plt = _pyplot()
    m = joint_motion(trace)
    limits = {
        "velocity": rm.MAX_VELOCITY_RAD_S,
        "acceleration": rm.MAX_ACCELERATION_RAD_S2,
        "jerk": rm.MAX_JERK_RAD_S3,
    }
    units = {"position": "rad", "velocity": "rad/s", "acceleration": "rad/s²", "jerk": "rad/s³"}
    fig, axes = plt.subplots(4, 1, figsize=(11, 10), sharex=True)
    colours = plt.get_cmap("tab10").colors
    retargets = m["time_s"][trace.retarget]
    for ax, key in zip(axes, ("position", "velocity", "acceleration", "jerk"), strict=True):
        for j in range(7):
            ax.plot(m["time_s"], m[key][:, j], color=colours[j], lw=1.0, label=f"joint {j + 1}")
        if key in limits:
            peak = float(np.max(np.abs(m[key])))
            for j in range(7):
                lim = limits[key][j]
                if lim < 4.0 * peak:  # a limit far off the scale would flatten the curves
                    ax.axhline(lim, color=colours[j], ls="--", lw=0.7)
                    ax.axhline(-lim, color=colours[j], ls="--", lw=0.7)
            ax.set_title(f"peak |{key}| {peak:.3g} {units[key]}; datasheet limits dashed (off the scale if not shown)",
                         fontsize=8, loc="left")  # fmt: skip
        for tr in retargets:
            ax.axvline(tr, color="0.6", lw=0.5, zorder=0)
        ax.set_ylabel(f"{key}\n[{units[key]}]")
        ax.grid(alpha=0.3)
    axes[0].legend(ncol=7, fontsize=7, loc="upper right")
    axes[-1].set_xlabel("simulated time [s] (grey lines: Ruckig re-targeted or new limits)")
    fig.suptitle(title or "commanded arm motion", fontsize=11)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def _img(path: Path) -> str:
    data = base64.b64encode(path.read_bytes()).decode("ascii")
    return f'<img alt="{html.escape(path.name)}" src="data:image/png;base64,{data}">'


_STYLE = """
body { font-family: system-ui, sans-serif; margin: 2em auto; max-width: 1100px; color: #222; }
table { border-collapse: collapse; margin: 1em 0; } td, th { border: 1px solid #ccc; padding: 3px 8px; }
th { background: #f2f2f2; text-align: left; } img, video { max-width: 100%; display: block; margin: 1em 0; }
.ok { color: #176617; font-weight: bold; } .failed { color: #a31515; font-weight: bold; }
"""


def _page(title: str, body: str) -> str:
    return (
        f'<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8"><title>{html.escape(title)}</title>'
        f"<style>{_STYLE}</style></head><body>\n<h1>{html.escape(title)}</h1>\n{body}\n</body></html>\n"
    )


def _rows(pairs: list[tuple[str, object]]) -> str:
    return "".join(f"<tr><th>{html.escape(k)}</th><td>{html.escape(str(v))}</td></tr>" for k, v in pairs)


def write_page(out_dir: Path, title: str, sections: list[tuple[str, str]]) -> Path:
    """``out_dir/report.html``: a self-contained page of (heading, HTML) sections."""
    body = "\n".join((f"<h2>{html.escape(h)}</h2>" if h else "") + content for h, content in sections)
    path = out_dir / "report.html"
    path.write_text(_page(title, body))
    return path


def pre(text: str) -> str:
    return f"<pre>{html.escape(text)}</pre>"


def image(path: Path) -> str:
    return _img(path)


def write_bench_plots(summary: dict, results: list[dict], path: Path, title: str = "") -> Path:
    """What a bench measured, per scenario: success rate with its Wilson 95 % interval, failures by
    stage, the distributions of the pose, tracking and place errors, wall time per episode."""
    plt = _pyplot()
    names = list(summary)
    by_name: dict[str, list[dict]] = {n: [] for n in names}
    from pickdemo.bench import summary_name

    for r in results:
        by_name.setdefault(summary_name(r), []).append(r)
    fig, axes = plt.subplots(2, 3, figsize=(16, max(6.0, 2.5 + 0.5 * len(names) * 2)))
    y = np.arange(len(names))
    ax = axes[0, 0]
    rate = np.array([summary[n]["success_rate"] for n in names]) * 100
    lo = np.array([summary[n]["success_rate_wilson95"][0] for n in names]) * 100
    hi = np.array([summary[n]["success_rate_wilson95"][1] for n in names]) * 100
    ax.errorbar(rate, y, xerr=[np.maximum(rate - lo, 0.0), np.maximum(hi - rate, 0.0)], fmt="o", capsize=3)
    ax.set_yticks(y, names, fontsize=8)
    ax.set_xlim(min(50.0, float(lo.min()) - 5), 101)
    ax.set_xlabel("success % (Wilson 95 % interval)")
    ax.invert_yaxis()
    ax = axes[0, 1]
    stages = sorted({s for n in names for s in summary[n]["failures_by_stage"]})
    left = np.zeros(len(names))
    for st in stages:
        counts = np.array([summary[n]["failures_by_stage"].get(st, 0) for n in names], dtype=float)
        ax.barh(y, counts, left=left, label=st)
        left += counts
    ax.set_yticks(y, names, fontsize=8)
    ax.set_xlabel("failed episodes by stage" + ("" if stages else " (none)"))
    if stages:
        ax.legend(fontsize=7)
    ax.invert_yaxis()
    pose = [[(r.get("perception") or {}).get("position_error_mm") for r in by_name[n]] for n in names]
    panels = ((axes[1, 0], "place_error_mm", "place error (mm)", None),
              (axes[1, 1], "wall_time_s", "wall time per episode (s)", None),
              (axes[0, 2], "pose", "pose error of the first estimate (mm)", pose),
              (axes[1, 2], "tracking_error_mm", "tracking error at the grasp (mm)", None))  # fmt: skip
    for ax, key, label, given in panels:
        values = given or [[r.get(key) for r in by_name[n]] for n in names]
        data = [[v for v in vs if v is not None] or [np.nan] for vs in values]
        ax.boxplot(data, showfliers=True)
        ax.set_xticks(y + 1, names, fontsize=7, rotation=20, ha="right")
        ax.set_ylabel(label)
        positive = any(np.isfinite(v) and v > 0 for vs in data for v in vs)
        if key != "wall_time_s" and positive:  # log only where there is something to scale (all failed: none)
            ax.set_yscale("log")
    for a in axes.flat:
        a.grid(alpha=0.3)
    fig.suptitle(title or "bench")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def write_run_report(result: EpisodeResult, out_dir: Path, *, video: Path | None, images: list[Path]) -> Path:
    """``out_dir/report.html``: the outcome, the measurements, the phases, the attempts, the video
    (beside the page) and the plots (embedded)."""
    r = result
    status = (
        '<span class="ok">SUCCESS</span>'
        if r.success
        else f'<span class="failed">FAILED in {r.failure.stage.value}</span>'
    )
    summary = [
        ("scenario, seed", f"{r.scenario}, {r.seed}" + (" (open loop)" if r.open_loop else "")),
        ("failure", "-" if r.failure is None else f"{r.failure.stage.value}: {r.failure.reason}"),
        ("pose error (first estimate)", "-" if r.perception is None else f"{r.perception.position_error_mm:.3f} mm"),
        ("tracking error at the grasp", "-" if r.tracking_error_mm is None else f"{r.tracking_error_mm:.3f} mm"),
        ("place error", "-" if r.place_error_mm is None else f"{r.place_error_mm:.2f} mm"),
        ("attempts", len(r.attempts)),
        (
            "perception",
            f"{r.perception_frames} frames, {r.perception_rate_hz or 0:.1f} Hz while tracking, "
            f"{r.estimates_rejected} rejected, {r.target_moves_detected} target move(s)",
        ),  # fmt: skip
        ("time", f"{r.sim_time_s:.2f} s simulated in {r.wall_time_s:.2f} s"),
    ]
    body = [f"<p>{status}</p>", f"<table>{_rows(summary)}</table>"]
    if video is not None:
        body.append(f'<h2>Video</h2><video controls muted playsinline src="{html.escape(video.name)}"></video>')
    for img in images:
        body.append(f"<h2>{html.escape(img.stem.replace('_', ' '))}</h2>{_img(img)}")
    phases = "".join(
        f"<tr><td>{p.sim_time_s:.2f}</td><td>{html.escape(p.phase)}</td><td>{html.escape(p.message)}</td></tr>"
        for p in r.phases
    )
    body.append(f"<h2>Phases</h2><table><tr><th>t [s]</th><th>state</th><th>message</th></tr>{phases}</table>")
    attempts = "".join(
        f"<tr><td>{a.number}</td><td>{html.escape(a.outcome)}</td><td>{a.grip_force_n:.0f} N</td>"
        f"<td>{html.escape(a.reason)}</td></tr>"
        for a in r.attempts
    )
    body.append(
        f"<h2>Attempts</h2><table><tr><th>#</th><th>outcome</th><th>grip</th><th>reason</th></tr>{attempts}</table>"
    )
    path = out_dir / "report.html"
    path.write_text(_page(f"pickdemo: {r.scenario} seed {r.seed}", "\n".join(body)))
    return path
