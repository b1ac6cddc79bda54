"""The renderer on traces from the real simulator (`sim.simulate`), checked against the trace's own events."""

from __future__ import annotations

import numpy as np
import pytest

from sim import ScenarioOptions, draw_scenario, simulate
from synth_audio import AudioConfig, render

SR = 44100


@pytest.mark.parametrize(
    ("category", "kwargs"),
    [("collision", {"obstacle_kind": "box"}), ("fault", {"fault_kind": "bearing"}), ("nominal", {})],
)
def test_simulated_trace_renders_with_events_where_the_trace_puts_them(
    category: str, kwargs: dict[str, str]
) -> None:
    trace = simulate(draw_scenario(5, category, ScenarioOptions(duration=12.0, **kwargs)))  # type: ignore[arg-type]
    audio = render(trace, AudioConfig(stems=True), seed=1)
    assert audio.samples.shape == (round(trace.duration * SR), 2)
    assert np.all(np.isfinite(audio.samples)) and np.max(np.abs(audio.samples)) <= 1.0
    impacts = np.abs(audio.stems["impacts"][:, 0])
    if len(trace.contacts.time):
        assert not np.any(impacts[: int(np.min(trace.contacts.time) * SR)])  # nothing before the first hit
    for t in trace.contacts.time:
        start = int(t * SR)
        assert np.max(impacts[start : start + int(0.002 * SR)]) > 0  # sound within 2 ms of each contact
    faults = audio.stems["faults"][:, 0]
    for fault in trace.faults:
        before = faults[: max(int((fault.onset - 0.05) * SR), 0)]
        assert not np.any(before)
        assert np.any(faults[int(fault.onset * SR) :])
    if category == "nominal":
        assert not np.any(audio.stems["impacts"]) and not np.any(audio.stems["faults"])
