"""What the viewer shows of an episode imported from recordings (`msvdd-bench import`): there is no
simulator trace, so no 3D scene, wheel speeds or contact events; the labelled anomaly spans are the events."""

from __future__ import annotations

from benchmarks.episode import Episode
from benchmarks.viz.events import TextEvent


def span_events(episode: Episode) -> list[TextEvent]:
    """An ERROR at each labelled anomaly's onset and an INFO at its end (from events.json `anomalies`)."""
    out: list[TextEvent] = []
    for span in episode.events().anomalies or ():
        what = f"{span.kind}: {span.sub_kind}"
        out.append(TextEvent(float(span.onset), "ERROR", f"labelled anomaly starts ({what})"))
        out.append(TextEvent(float(span.end), "INFO", f"labelled anomaly ends ({what})"))
    return out
