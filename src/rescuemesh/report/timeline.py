"""timeline.png: what each robot did and what crossed the radio, on one time axis.

Owns: the timeline figure. Top: each robot's speed, with its key events marked (commands sent,
Stop arrival, behaviours given up, links lost and resumed). Bottom: every frame each radio put on
the air, by message kind: heard by its destination or not, first send or resend, relayed, and
collisions. Must not know: how the run was scripted.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from rescuemesh.protocol import MessageType  # noqa: E402
import numpy as np  # noqa: E402

from rescuemesh.report.plots import SMALL_TEAM, legend_label, robot_colours  # noqa: E402
from rescuemesh.robot import robot_name  # noqa: E402
from rescuemesh.robot.events import BrainEventKind  # noqa: E402

#: Brain log entries worth a mark on the speed plot, and how to draw them.
EVENT_MARKS = {
    BrainEventKind.COMMAND_SENT: ("v", "command sent"),
    BrainEventKind.STOPPED: ("X", "Stop arrived"),
    BrainEventKind.COMMAND_GIVEN_UP: ("D", "command given up"),
    BrainEventKind.FOLLOW_GIVEN_UP: ("D", "command given up"),
    BrainEventKind.BEHAVIOUR_ENDED: ("|", "behaviour ended"),
    BrainEventKind.LINK_LOST: ("s", "link lost (paused)"),
    BrainEventKind.LINK_RESUMED: ("^", "link resumed"),
}
#: Rows of the radio panel: message kinds, bottom to top.
KINDS = ("Heartbeat", "Confirm", "PoseUpdate", "Command", "Bulk")
_KIND_OF_TYPE = {MessageType.HEARTBEAT: "Heartbeat", MessageType.CONFIRM: "Confirm",
                 MessageType.SEGMENT_ACK: "Confirm", MessageType.POSE_UPDATE: "PoseUpdate",
                 MessageType.DATA: "Bulk"}


def _kind(record) -> str:
    if record.segment is not None:
        return "Bulk"
    return _KIND_OF_TYPE.get(record.msg_type, "Command")


#: The speed axis reaches at least this, in m/s (a still team's markers sit on 0, in view).
MIN_SPEED_AXIS = 0.1


def plot_timeline(rt, path: Path, *, title: str = "", metrics: dict | None = None) -> Path:
    """Draw the timeline; a metrics `outage_start_s`/`outage_end_s` pair is shaded as a radio outage."""
    names = list(rt.trajectories)
    large = len(names) > SMALL_TEAM
    height = 6.5 if not large else 5.0 + 0.08 * len(names)
    fig, (ax_speed, ax_radio) = plt.subplots(2, 1, figsize=(11, height), dpi=110, sharex=True,
                                             gridspec_kw={"height_ratios": [1.0, 1.3]})
    if large:
        _speed_rows(fig, ax_speed, rt, names)
    else:
        _speed_lines(ax_speed, rt, names)
    metrics = metrics or {}
    if metrics.get("outage_start_s") is not None:
        end = metrics.get("outage_end_s") or rt.time
        for ax in (ax_speed, ax_radio):
            ax.axvspan(metrics["outage_start_s"], end, color="0.85", zorder=0,
                       label="robot_1's radio off" if ax is ax_speed else None)
    if not large:
        ax_speed.set_ylabel("speed [m/s]")
        # at least 0..MIN_SPEED_AXIS: a run where no robot moved (relay --no-relay) used to get an axis
        # from -0.02 to 0 with its markers cut in half
        top = max((s.speed for samples in rt.trajectories.values() for s in samples), default=0.0)
        ax_speed.set_ylim(-0.02, max(MIN_SPEED_AXIS, 1.08 * top))
    ax_speed.legend(loc="upper left", bbox_to_anchor=(1.09 if large else 1.01, 1.0), fontsize=8, frameon=False)
    ax_speed.grid(True, lw=0.3, alpha=0.5)
    ax_speed.set_title(title, fontsize=11)

    if large:
        _radio_rates(ax_radio, rt)
    else:
        _radio_marks(ax_radio, rt, names)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return path


def _speed_lines(ax, rt, names) -> None:
    """A small team: one speed curve per robot, its key events marked on it."""
    colours = robot_colours(names)
    seen_labels: set[str] = set()
    for index, name in enumerate(names):
        samples = rt.trajectories[name]
        colour = colours[name]
        ax.plot([s.time_s for s in samples], [s.speed for s in samples], color=colour, lw=1.4,
                label=legend_label(names, index))
        for event in rt.brains[name].log:
            if event.kind not in EVENT_MARKS:
                continue
            marker, label = EVENT_MARKS[event.kind]
            speed = min(samples, key=lambda s: abs(s.time_s - event.time_s)).speed
            ax.plot(event.time_s, speed, marker=marker, color=colour, ms=8, mec="k", mew=0.6, ls="none",
                    label=None if label in seen_labels else label, zorder=5)
            seen_labels.add(label)


def _speed_rows(fig, ax, rt, names) -> None:
    """A large team: speed as a heat map, one row per robot (robot_1 on top), key events marked on
    each robot's row (30 curves on one axis would be a tangle)."""
    times = np.array([s.time_s for s in rt.trajectories[names[0]]])
    speeds = np.array([[s.speed for s in rt.trajectories[n]][:len(times)] for n in names])
    t_end = times[-1] if len(times) > 1 else 1.0
    image = ax.imshow(speeds, aspect="auto", cmap="viridis", interpolation="nearest", origin="upper",
                      extent=(times[0], t_end, len(names) - 0.5, -0.5), vmin=0.0)
    fig.colorbar(image, ax=ax, pad=0.01, fraction=0.03, label="speed [m/s]")
    seen_labels: set[str] = set()
    for row, name in enumerate(names):
        for event in rt.brains[name].log:
            if event.kind not in EVENT_MARKS:
                continue
            marker, label = EVENT_MARKS[event.kind]
            ax.plot(event.time_s, row, marker=marker, color="white", ms=5, mec="k", mew=0.5, ls="none",
                    label=None if label in seen_labels else label, zorder=5)
            seen_labels.add(label)
    ticks = [i for i in range(len(names)) if legend_label(names, i)]
    ax.set_yticks(ticks, [names[i] for i in ticks], fontsize=7)
    ax.set_ylim(len(names) - 0.5, -0.5)
    ax.set_ylabel("robot")

def _radio_marks(ax_radio, rt, names) -> None:
    """A small team: one mark per transmission, in a lane per radio and message kind."""
    kinds = KINDS
    lanes = {(name, kind): i for i, (name, kind) in enumerate((n, k) for n in names for k in kinds)}
    styles = {  # mark kind -> marker style
        "heard": dict(marker="|", color="0.35", ms=9, label="heard by its destination"),
        "resend": dict(marker="|", color="#ff7f0e", ms=11, mew=2, label="heard (resend)"),
        "relayed": dict(marker="o", mfc="none", color="#1f77b4", ms=5, mew=1.0, label="relayed (this radio relays)"),
        "lost": dict(marker="x", color="#d62728", ms=6, label="not heard by its destination"),
        "collision": dict(marker="*", color="k", mfc="#ffeb3b", ms=9, mew=0.6, label="collision at a receiver"),
    }
    points: dict[str, tuple[list[float], list[float]]] = {k: ([], []) for k in styles}
    for record in rt.medium.records or []:
        lane = lanes.get((robot_name(record.transmitter), _kind(record)))
        if lane is None:
            continue
        heard = record.dst_heard if record.dst_heard is not None else record.heard_by > 0
        resend = _is_resend(record)
        key = "relayed" if record.relayed else ("lost" if not heard else ("resend" if resend else "heard"))
        points[key][0].append(record.start_s)
        points[key][1].append(lane)
        if record.collided:
            points["collision"][0].append(record.start_s)
            points["collision"][1].append(lane + 0.3)
    for key, style in styles.items():
        xs, ys = points[key]
        if xs:
            ax_radio.plot(xs, ys, ls="none", **style)
    ax_radio.set_yticks(list(lanes.values()), [f"{name}  {kind}" for name, kind in lanes], fontsize=7)
    for boundary in range(len(kinds), len(lanes), len(kinds)):
        ax_radio.axhline(boundary - 0.5, color="0.6", lw=0.6)
    ax_radio.set_ylim(-0.6, len(lanes) - 0.4)
    ax_radio.set_xlabel("simulated time [s]")
    ax_radio.set_title("frames on the air, by radio and kind (one mark per transmission)", fontsize=9)
    ax_radio.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False)
    ax_radio.grid(True, axis="x", lw=0.3, alpha=0.5)


#: Width in s of the bins of a large team's radio panel.
RATE_BIN_S = 1.0


def _radio_rates(ax, rt) -> None:
    """A large team: what the air carried per second (marks per transmission would be a black
    band): frames originated, relayed, resent, and receptions lost to collisions."""
    records = rt.medium.records or []
    end = max(rt.time, RATE_BIN_S)
    bins = np.arange(0.0, end + RATE_BIN_S, RATE_BIN_S)
    series = {
        "originated (first sends)": [r.start_s for r in records if not r.relayed and not _is_resend(r)],
        "resent": [r.start_s for r in records if not r.relayed and _is_resend(r)],
        "relayed copies": [r.start_s for r in records if r.relayed],
        "with a collision at some receiver": [r.start_s for r in records if r.collided],
    }
    colours = ("0.25", "#ff7f0e", "#1f77b4", "#d62728")
    for (label, times), colour in zip(series.items(), colours):
        counts, _ = np.histogram(times, bins=bins)
        ax.step(bins[:-1], counts / RATE_BIN_S, where="post", color=colour, lw=1.2, label=f"{label}: {len(times)}")
    ax.set_ylabel("frames per second")
    ax.set_ylim(bottom=0)
    ax.set_xlabel("simulated time [s]")
    ax.set_title("the air, per second (all radios)", fontsize=9)
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False)
    ax.grid(True, lw=0.3, alpha=0.5)


def _is_resend(record) -> bool:
    return record.segment is None and record.frame[1] >> 6 > 0  # attempt bits (docs/protocol.md)
