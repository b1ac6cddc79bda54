"""Text events on `events`: collisions, benign transients, fault onset and end, detections."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import rerun as rr

from benchmarks.viz.config import TIMELINE
from benchmarks.viz.scoring import EpisodeScores
from sim.trace import Trace

EVENTS = "events"
"""Entity path of the text log."""


@dataclass(frozen=True)
class TextEvent:
    """One line of the event log."""

    time: float
    """When it happened, s."""
    level: str
    """Rerun text-log level (DEBUG, INFO, WARN, ERROR)."""
    text: str
    """What happened."""


def trace_events(trace: Trace) -> list[TextEvent]:
    """Collisions (WARN), benign transients (DEBUG), fault onsets (ERROR) and ends (INFO)."""
    out: list[TextEvent] = []
    c = trace.contacts
    for i in range(len(c.time)):
        out.append(
            TextEvent(
                float(c.time[i]),
                "WARN",
                f"collision: {c.obstacle_kind[i]} ({c.material[i]}), {c.impulse[i]:.3g} N s at "
                f"{c.normal_speed[i]:.2g} m/s, {c.duration[i]:.2g} s long",
            )
        )
    t = trace.transients
    for i in range(len(t.time)):
        wheel = trace.robot.wheel_names[int(t.wheel[i])] if 0 <= int(t.wheel[i]) < trace.n_wheels else "?"
        out.append(
            TextEvent(float(t.time[i]), "DEBUG", f"benign {t.kind[i]} under {wheel} ({t.impulse[i]:.3g} N s)")
        )
    for f in trace.faults:
        wheel = trace.robot.wheel_names[f.wheel] if 0 <= f.wheel < trace.n_wheels else str(f.wheel)
        out.append(
            TextEvent(
                float(f.onset), "ERROR", f"fault starts: {f.kind} on {wheel}, severity {f.severity:.2f}"
            )
        )
        out.append(TextEvent(float(f.onset + f.duration), "INFO", f"fault ends: {f.kind} on {wheel}"))
    return out


def detection_events(scores: EpisodeScores) -> list[TextEvent]:
    """A WARN when the detector starts firing (score rises above threshold), an INFO when it stops."""
    hit = scores.detected.astype(np.int8)
    change = np.diff(np.concatenate([[0], hit]))
    out: list[TextEvent] = []
    for i in np.flatnonzero(change):
        if change[i] > 0:
            text = (
                f"{scores.method} alarm: score {scores.score[i]:.4g} > threshold {scores.threshold:.4g} "
                f"(window {scores.start_s[i]:.2f}-{scores.end_s[i]:.2f} s)"
            )
            out.append(TextEvent(float(scores.end_s[i]), "WARN", text))
        else:
            out.append(TextEvent(float(scores.end_s[i]), "INFO", f"{scores.method} back below threshold"))
    return out


def event_line(event: TextEvent) -> str:
    """The text shown for an event: its time first (the table's own time column is hidden: too narrow to
    read), then what happened."""
    return f"{event.time:6.2f} s  {event.text}"


def log_events(rec: rr.RecordingStream, events: list[TextEvent]) -> None:
    """All events in one `send_columns` call, in time order."""
    if not events:
        return
    ordered = sorted(events, key=lambda e: e.time)
    rec.send_columns(
        EVENTS,
        indexes=[rr.TimeColumn(TIMELINE, duration=np.array([e.time for e in ordered]))],
        columns=rr.TextLog.columns(text=[event_line(e) for e in ordered], level=[e.level for e in ordered]),
    )
