"""Pictures of what was measured: the arm's motion plot and a self-contained report page for `run`.

Pure: results and traces in, files out. Plots use matplotlib (the ``plots`` extra), drawn headless
(Agg). The report page embeds its images (base64) and refers to the video beside it, so it opens
from the directory with no network and no server.
"""

from __future__ import annotations

import base64
import html
import textwrap
from pathlib import Path

import numpy as np

from pickdemo.apps.bench import ScenarioSummary
from pickdemo.apps.files import write_atomic, write_figure
from pickdemo.core.result import (
    EpisodeRecord,
    EpisodeResult,
    EpisodeTrace,
    LimitExceedance,
    joint_derivatives,
    limit_exceedances,
    summary_name,
)
from pickdemo.robot import robot_named
from pickdemo.robot.description import RobotDescription


class PlotsUnavailable(RuntimeError):
    """matplotlib is not installed."""


def _pyplot():
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError as exc:
        raise PlotsUnavailable("plots need matplotlib, a dependency of pickdemo: pip install matplotlib") from exc
    return plt


def joint_motion(trace: EpisodeTrace) -> dict[str, np.ndarray]:
    """The commanded joints' position, velocity, acceleration and jerk per tick (finite differences)."""
    return joint_derivatives(trace.time_s, trace.q)


def phase_changes(trace: EpisodeTrace) -> list[tuple[float, str]]:
    """(time, state) at the first tick of each run of ticks in one state of the pick."""
    out: list[tuple[float, str]] = []
    for t, st in zip(trace.time_s, trace.state, strict=True):
        if not out or out[-1][1] != st:
            out.append((float(t), st))
    return out


def _pretty(unit: str) -> str:
    return unit.replace("^2", "²").replace("^3", "³")


def write_motion_plot(trace: EpisodeTrace, path: Path, title: str = "", robot: RobotDescription | None = None) -> Path:
    """Per arm joint: position, velocity, acceleration and jerk over time, with the datasheet limits
    (dashed, each joint's colour), every tick over a limit (red rings, named in the panel; the same
    :func:`pickdemo.core.result.limit_exceedances` as ``result.json``'s), the states of the pick (dark
    dashed lines, named along the top) and the moments Ruckig was re-targeted (grey lines). ``robot``:
    whose limits (default: the default robot's)."""
    plt = _pyplot()
    m = joint_motion(trace)
    limits = (robot or robot_named()).limits.rates()
    over = limit_exceedances(trace.time_s, trace.q, limits)
    units = {"position": "rad", **{k: _pretty(u) for k, (_, u) in limits.items()}}
    fig, axes = plt.subplots(4, 1, figsize=(11, 10.5), sharex=True)
    colours = plt.get_cmap("tab10").colors
    retargets = m["time_s"][trace.retarget]
    phases = phase_changes(trace)
    for ax, key in zip(axes, ("position", "velocity", "acceleration", "jerk"), strict=True):
        for j in range(m[key].shape[1]):
            ax.plot(m["time_s"], m[key][:, j], color=colours[j], lw=1.0, label=f"joint {j + 1}")
        if key in limits:
            lims = limits[key][0]
            peak = float(np.max(np.abs(m[key])))
            mine = [e for e in over if e.quantity == key]
            for j in range(m[key].shape[1]):
                lim = lims[j]
                if lim < 4.0 * peak:  # a limit far off the scale would flatten the curves
                    ax.axhline(lim, color=colours[j], ls="--", lw=0.7)
                    ax.axhline(-lim, color=colours[j], ls="--", lw=0.7)
            head = f"peak |{key}| {peak:.3g} {units[key]}; datasheet limits dashed (off the scale if not shown)"
            ax.set_title(head + ("" if mine else "; no tick over a limit"), fontsize=8, loc="left")
            if mine:
                rings = [
                    ax.scatter(e.times_s, e.values, s=70, facecolors="none", edgecolors="red", linewidths=1.5, zorder=5)
                    for e in mine
                ]
                note = "OVER THE LIMIT: " + "; ".join(_pretty(e.note()) for e in mine)
                ax.set_title(note, fontsize=8, loc="right", color="red", fontweight="bold")
                ax.legend(handles=rings[:1], labels=["tick over its datasheet limit"], loc="lower right", fontsize=7,
                          framealpha=0.9)  # fmt: skip
        for tr in retargets:
            ax.axvline(tr, color="0.75", lw=0.5, zorder=0)
        for tp, _ in phases[1:]:
            ax.axvline(tp, color="0.2", lw=0.8, ls=(0, (4, 3)), zorder=1)
        ax.set_ylabel(f"{key}\n[{units[key]}]")
        ax.grid(alpha=0.3)
    if phases:  # the states' names along the top, at the time each was entered
        top = axes[0].secondary_xaxis("top")
        top.set_xticks([tp for tp, _ in phases], [st for _, st in phases], rotation=55, ha="left", fontsize=7.5)
        top.tick_params(length=3, pad=1)
    axes[0].legend(ncol=7, fontsize=7, loc="upper right")
    axes[-1].set_xlabel("simulated time [s] (dark dashed lines: the states of the pick, named along the top; "
                        "grey lines: Ruckig re-targeted or new limits)", fontsize=9)  # fmt: skip
    fig.suptitle(title or "commanded arm motion", fontsize=11)
    fig.tight_layout()
    write_figure(fig, path, dpi=90)
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
table.bench { font-size: 0.9em; } table.bench td:first-child { white-space: nowrap; font-weight: bold; }
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
    write_atomic(path, _page(title, body))
    return path


def pre(text: str) -> str:
    return f"<pre>{html.escape(text)}</pre>"


def image(path: Path) -> str:
    return _img(path)


def plain_number(v: float) -> str:
    """A tick label without exponents: 0.01, 0.1, 1, 10, 250."""
    return np.format_float_positional(float(v), precision=6, trim="-")


def _plain_log_axis(axis, values: list[float]) -> None:
    """A log axis labelled in plain numbers: the decades, and 2 and 5 between them if it spans few."""
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

    v = np.asarray([x for x in values if np.isfinite(x) and x > 0], dtype=float)
    decades = float(np.log10(v.max() / v.min())) if len(v) else 0.0
    axis.set_major_locator(LogLocator(base=10.0, subs=(1.0,) if decades > 2.5 else (1.0, 2.0, 5.0)))
    axis.set_major_formatter(FuncFormatter(lambda x, _: plain_number(x)))
    axis.set_minor_formatter(NullFormatter())


def _boxplot_h(ax, data: list[list[float]], y: np.ndarray) -> None:
    kw = {"positions": y, "widths": 0.55, "showfliers": True, "manage_ticks": False}
    try:
        ax.boxplot(data, orientation="horizontal", **kw)
    except TypeError:  # matplotlib < 3.10
        ax.boxplot(data, vert=False, **kw)


def write_bench_plots(
    summary: dict[str, ScenarioSummary], results: list[EpisodeRecord], path: Path, title: str = ""
) -> Path:
    """What a bench measured, one row per scenario across the panels: success rate with its Wilson
    95 % interval, failures by stage (only if any failed), the distributions of the pose, tracking
    and place errors (log mm axes in plain numbers), wall time per episode."""
    plt = _pyplot()
    names = list(summary)
    by_name: dict[str, list[EpisodeRecord]] = {n: [] for n in names}
    for r in results:
        by_name.setdefault(summary_name(r), []).append(r)
    stages = sorted({s for n in names for s in summary[n]["failures_by_stage"]})
    pose = [[(r.get("perception") or {}).get("position_error_mm") for r in by_name[n]] for n in names]
    panels: list[tuple[str, str, list | None]] = [("pose", "pose error of the first estimate [mm]", pose),
              ("tracking_error_mm", "tracking error at the grasp [mm]", None),
              ("place_error_mm", "place error [mm]", None),
              ("wall_time_s", "wall time per episode [s]", None)]  # fmt: skip
    n_axes = 1 + bool(stages) + len(panels)
    fig, axes = plt.subplots(
        1, n_axes, figsize=(2.9 * n_axes + 2.0, max(3.4, 1.7 + 0.42 * len(names))), sharey=True, squeeze=False
    )
    axes = list(axes[0])
    y = np.arange(len(names))
    ax = axes.pop(0)
    n_ep = sum(summary[n]["episodes"] for n in names)
    failed = sum(summary[n]["episodes"] - summary[n]["successes"] for n in names)
    rate = np.array([summary[n]["success_rate"] for n in names]) * 100
    lo = np.array([summary[n]["success_rate_wilson95"][0] for n in names]) * 100
    hi = np.array([summary[n]["success_rate_wilson95"][1] for n in names]) * 100
    ax.errorbar(rate, y, xerr=[np.maximum(rate - lo, 0.0), np.maximum(hi - rate, 0.0)], fmt="o", ms=7, capsize=4,
                clip_on=False, zorder=3)  # fmt: skip
    left = float(np.floor(min(50.0, float(lo.min()) - 5.0) / 10.0) * 10.0)
    ax.set_xlim(left, 104.0)  # beyond 100: a dot at 100 % is drawn whole
    ax.set_xticks([t for t in np.arange(left, 100.1, 10.0 if left >= 50 else 20.0)])
    ax.set_yticks(y, names, fontsize=10)
    ax.set_ylim(len(names) - 0.5, -0.5)  # the first scenario on top
    ax.set_xlabel("success % (Wilson 95 % interval)")
    ax.set_title("no failed episodes" if not failed else f"{failed} of {n_ep} episodes failed", fontsize=9,
                 loc="left", color="#176617" if not failed else "#a31515")  # fmt: skip
    if stages:
        ax = axes.pop(0)
        start = np.zeros(len(names))
        for st in stages:
            counts = np.array([summary[n]["failures_by_stage"].get(st, 0) for n in names], dtype=float)
            ax.barh(y, counts, left=start, label=st, height=0.6)
            start += counts
        ax.set_xlabel("failed episodes by stage")
        ax.xaxis.get_major_locator().set_params(integer=True)
        ax.legend(fontsize=8, loc="lower right")
    for ax, (key, label, given) in zip(axes, panels, strict=True):
        values = given or [[r.get(key) for r in by_name[n]] for n in names]
        data = [[v for v in vs if v is not None] or [np.nan] for vs in values]
        _boxplot_h(ax, data, y)
        ax.set_xlabel(label)
        flat = [v for vs in data for v in vs if np.isfinite(v)]
        positive = [v for v in flat if v > 0]
        # Log where there is something to scale: errors spread over decades (at least 0.7 of one).
        if key != "wall_time_s" and positive and max(positive) / min(positive) >= 5.0:
            ax.set_xscale("log")
            _plain_log_axis(ax.xaxis, positive)
        else:
            ax.ticklabel_format(axis="x", style="plain", useOffset=False)
        if not flat:
            ax.set_title("none measured", fontsize=9, loc="left", color="0.4")
    for a in fig.axes:
        a.grid(alpha=0.3)
        a.tick_params(axis="x", labelsize=9)
    # a long list of scenarios wraps within the figure's width (about 8 characters an inch at this size)
    fig.suptitle(textwrap.fill(title or "bench", width=int(fig.get_figwidth() * 8)))
    fig.tight_layout()
    write_figure(fig, path, dpi=90)
    plt.close(fig)
    return path


def _cell(st: dict | None, fmt: str = ".2f") -> str:
    """``median (p95)`` of a :func:`pickdemo.core.stats.describe`, or a dash."""
    if not st:
        return "-"
    return f"{st['median']:{fmt}} ({st['p95']:{fmt}})"


def _cleared_cell(c: dict | None) -> str:
    """A clear scenario's percent cleared (Wilson 95 %), grasp success rate and picks per hour."""
    if not c or not c["objects"]:
        return "-"
    lo, hi = c["percent_cleared_wilson95"]
    text = f"{c['cleared']}/{c['objects']} ({c['percent_cleared']:.1f} %, {lo:.1f} - {hi:.1f} %)"
    if c["grasp_success_rate"] is not None:
        text += f"; grasps {100 * c['grasp_success_rate']:.1f} %; {c['picks_per_hour']:.0f} picks/h"
    return html.escape(text)


def bench_table(summary: dict[str, ScenarioSummary], results: list[EpisodeRecord] | None = None) -> str:
    """The bench's per-scenario table (HTML): episodes, success with its Wilson 95 % interval,
    failures by stage, the pose, yaw, tracking and place errors and the wall time (median and p95),
    and how many episodes commanded a joint beyond its datasheet limits."""
    over: dict[str, int] = {}
    for r in results or ():
        over[summary_name(r)] = over.get(summary_name(r), 0) + bool(r.get("limit_exceedances"))
    head = ["scenario", "episodes", "success", "Wilson 95 %", "failures by stage", "pose error [mm]",
            "yaw error [deg]", "tracking error at the grasp [mm]", "place error [mm]", "wall time per episode [s]",
            "over joint limits", "cleared (clear rounds)"]  # fmt: skip
    rows = []
    for name, s in summary.items():
        lo, hi = s["success_rate_wilson95"]
        fails = ", ".join(f"{k} {v}" for k, v in s["failures_by_stage"].items()) or "none"
        if s["failures_by_stage"]:
            fails += f" (seeds {', '.join(str(x) for x in s['failed_seeds'])})"
        cls = "ok" if s["successes"] == s["episodes"] else "failed"
        cells = [
            html.escape(name),
            str(s["episodes"]),
            f'<span class="{cls}">{s["successes"]}/{s["episodes"]} ({100 * s["success_rate"]:.1f} %)</span>',
            f"{100 * lo:.1f} - {100 * hi:.1f} %",
            html.escape(fails),
            _cell(s.get("position_error_mm"), ".3f"),
            _cell(s.get("yaw_error_deg"), ".3f"),
            _cell(s.get("tracking_error_mm")),
            _cell(s.get("place_error_mm")),
            _cell(s.get("wall_time_s")),
            "-" if results is None else str(over.get(name, 0)),
            _cleared_cell(s.get("clear")),
        ]
        rows.append("<tr>" + "".join(f"<td>{c}</td>" for c in cells) + "</tr>")
    heading = "<tr>" + "".join(f"<th>{html.escape(h)}</th>" for h in head) + "</tr>"
    note = "<p>Errors and times: median (p95). Over joint limits: episodes whose joint command went beyond a " \
        "datasheet limit (<code>limit_exceedances</code> in the episode's result).</p>"  # fmt: skip
    return f'<table class="bench">{heading}{"".join(rows)}</table>{note}'


def attempt_reason(attempt, phases) -> str:
    """What ended an attempt: its reason, or (a placed attempt has none) the message of the state
    entered as it ended (``released at (x, y)``)."""
    if attempt.reason:
        return attempt.reason
    said = [p.message for p in phases if abs(p.sim_time_s - attempt.end_s) < 1e-5 and p.message]
    return said[0] if said else attempt.outcome


def _clear_rows(c: dict | None) -> list[tuple[str, object]]:
    """A clear round's figures and each object's fate, as rows of the run report."""
    if c is None:
        return []
    rate = c["grasp_success_rate"]
    rows: list[tuple[str, object]] = [
        ("cleared", f"{c['cleared']}/{c['total']} ({c['percent_cleared']:.0f} %)"),
        (
            "grasps",
            f"{c['successful_grasps']}/{c['grasp_attempts']}" + ("" if rate is None else f" ({100 * rate:.0f} %)"),
        ),
        ("picks per hour (simulated)", f"{c['picks_per_hour']:.0f} ({c['round_time_s']:.1f} s in all)"),
    ]
    for o in c["objects"]:
        at = "" if o["cleared_at_s"] is None else f" at {o['cleared_at_s']:.1f} s"
        rows.append((o["name"], f"{o['urdf']} x {o['scale']:g}: {o['outcome']}{at}, {o['attempts']} attempt(s)"))
    return rows


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
        *_clear_rows(r.clear),
        (
            "perception",
            f"{r.perception_frames} frames, {r.perception_rate_hz or 0:.1f} Hz while tracking, "
            f"{r.estimates_rejected} turned away by the tracker's gate, {r.target_moves_detected} target move(s)",
        ),  # fmt: skip
        ("time", f"{r.sim_time_s:.2f} s simulated in {r.wall_time_s:.2f} s"),
        (
            "joint command beyond the datasheet limits",
            "; ".join(f"{e['quantity']} of {LimitExceedance(**e).note()}" for e in r.limit_exceedances) or "none",
        ),
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
        f"<tr><td>{a.number}</td><td>{html.escape(a.outcome)}</td><td>{a.start_s:.2f} - {a.end_s:.2f}</td>"
        f"<td>{a.grip_force_n:.0f} N</td><td>{html.escape(attempt_reason(a, r.phases))}</td></tr>"
        for a in r.attempts
    )
    body.append(
        "<h2>Attempts</h2><table><tr><th>#</th><th>outcome</th><th>t [s]</th><th>grip</th><th>reason</th></tr>"
        f"{attempts}</table>"
    )
    path = out_dir / "report.html"
    write_atomic(path, _page(f"pickdemo: {r.scenario} seed {r.seed}", "\n".join(body)))
    return path
