"""Display signal processing of the Rerun viewer against analytic answers."""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks.viz.config import VizConfig
from benchmarks.viz.scene import _recent, contact_radii
from benchmarks.viz.signals import (
    band_edges,
    band_spectrogram,
    colorize_db,
    display_indices,
    minmax_envelope,
    run_starts,
)


def test_envelope_is_blockwise_min_max_with_short_tail() -> None:
    x = np.array([3.0, -1.0, 2.0, 5.0, -4.0, 0.5, 7.0])
    mins, maxs = minmax_envelope(x, 3)
    np.testing.assert_array_equal(mins, [-1.0, -4.0, 7.0])
    np.testing.assert_array_equal(maxs, [3.0, 5.0, 7.0])
    with pytest.raises(ValueError, match="block"):
        minmax_envelope(x, 0)


def test_envelope_of_a_sine_reaches_its_amplitude() -> None:
    rate, f, amp = 44100, 50.0, 0.7
    t = np.arange(rate) / rate
    mins, maxs = minmax_envelope(amp * np.sin(2 * np.pi * f * t), 441 * 2)  # one period per block
    # the crest falls half-way between two samples: the nearest sample is pi f / rate rad from it
    crest = amp * np.cos(np.pi * f / rate)
    np.testing.assert_allclose(maxs, crest, rtol=1e-9)
    np.testing.assert_allclose(mins, -crest, rtol=1e-9)


def test_display_indices_keep_ends_and_rate() -> None:
    t = np.arange(1001) * 0.001  # 1 kHz for 1 s
    idx = display_indices(t, 100.0)
    assert idx[0] == 0 and idx[-1] == 1000
    np.testing.assert_allclose(np.diff(t[idx])[:-1], 0.01, atol=1e-9)
    sparse = np.array([0.0, 1.0, 2.0])
    np.testing.assert_array_equal(display_indices(sparse, 100.0), [0, 1, 2])
    assert display_indices(np.zeros(0), 10.0).size == 0


@pytest.mark.parametrize("freq", [250.0, 1000.0, 6000.0])
def test_spectrogram_peak_band_holds_the_tone(freq: float) -> None:
    rate, amp = 44100.0, 0.5
    t = np.arange(int(rate)) / rate
    times, centres, db = band_spectrogram(
        amp * np.sin(2 * np.pi * freq * t), rate, 1024, 0.02, 96, 40.0, 16000.0
    )
    edges = band_edges(rate, 1024, 96, 40.0, 16000.0)
    lo, hi = edges[:-1] * rate / 1024, edges[1:] * rate / 1024
    peak = int(np.argmax(db[:, db.shape[1] // 2]))
    assert lo[peak] - rate / 1024 <= freq <= hi[peak] + rate / 1024
    assert db.shape == (centres.size, times.size)
    np.testing.assert_allclose(np.diff(times), 882 / rate)
    # Parseval: the band powers (mean per bin x bins) of a pure tone add up to A**2 / 2.
    total = (10 ** (db[:, db.shape[1] // 2] / 10) * np.diff(edges)).sum()
    assert total == pytest.approx(amp**2 / 2, rel=0.02)


def test_colorize_maps_the_loudest_cell_to_the_top_of_the_table() -> None:
    lut = np.stack([np.arange(256)] * 3, axis=1).astype(np.uint8)
    db = np.array([[0.0, -40.0], [-100.0, -80.0]])  # band 0 (low) loud
    img = colorize_db(db, 80.0, lut)
    assert img.shape == (2, 2, 3) and img.dtype == np.uint8
    # low band is the bottom row
    np.testing.assert_array_equal(img[1, :, 0], [255, 128])
    np.testing.assert_array_equal(img[0, :, 0], [0, 0])


def test_frequency_ticks_point_at_the_nearest_band() -> None:
    from benchmarks.viz.series import frequency_ticks

    centres = np.geomspace(50.0, 5000.0, 5)  # 50, 158, 500, 1581, 5000 Hz; row 0 is the top (5000 Hz)
    rows, labels = frequency_ticks(centres)
    assert labels == ["100 Hz", "300 Hz", "1 kHz", "3 kHz"]
    np.testing.assert_allclose(rows, [3.5, 2.5, 1.5, 0.5])  # 3 kHz is nearer 5 kHz in log frequency


def test_run_starts() -> None:
    np.testing.assert_array_equal(run_starts(np.array([0, 0, 1, 1, 1, 0, 2])), [0, 2, 5, 6])
    assert run_starts(np.zeros(0)).size == 0


def test_recent_markers_keep_the_last_cap_events() -> None:
    take, lengths = _recent(np.array([2, 0, 1]), 2)
    np.testing.assert_array_equal(lengths, [1, 2, 2])
    np.testing.assert_array_equal(take, [2, 2, 0, 0, 1])


def test_contact_radius_grows_with_sqrt_impulse() -> None:
    cfg = VizConfig(contact_radius_m=0.02, contact_radius_per_sqrt_ns=0.05)
    np.testing.assert_allclose(contact_radii(np.array([0.0, 4.0, -1.0]), cfg), [0.02, 0.12, 0.02])


def test_config_refuses_bad_values() -> None:
    with pytest.raises(ValueError, match="pose_rate_hz"):
        VizConfig(pose_rate_hz=0.0)
    with pytest.raises(ValueError, match="spectrogram_fmin_hz"):
        VizConfig(spectrogram_fmin_hz=20000.0)


def test_anomaly_spans_are_the_runs_of_non_normal_labels() -> None:
    from benchmarks.viz.focus import AnomalySpan, anomaly_spans

    t = np.arange(8) * 0.5
    spans = anomaly_spans(t, np.array([0, 1, 1, 0, 2, 2, 2, 2]))
    assert spans == [AnomalySpan(0.5, 1.5, "collision"), AnomalySpan(2.0, 4.0, "mechanical")]
    assert anomaly_spans(t, np.zeros(8)) == []
    two = anomaly_spans(t, np.array([1, 1, 2, 0, 0, 0, 0, 0]), end_s=5.0)
    assert two == [AnomalySpan(0.0, 1.0, "collision"), AnomalySpan(1.0, 1.5, "mechanical")]
    last = anomaly_spans(t, np.array([0, 0, 0, 0, 0, 0, 2, 2]), end_s=5.0)
    assert last == [AnomalySpan(3.0, 5.0, "mechanical")]  # runs to the episode's end
    with pytest.raises(ValueError, match="samples"):
        anomaly_spans(t, np.zeros(3))


def test_truth_steps_rise_inside_spans_and_cover_the_episode() -> None:
    from benchmarks.viz.focus import AnomalySpan
    from benchmarks.viz.series import truth_steps

    spans = [AnomalySpan(0.0, 1.0, "collision"), AnomalySpan(2.0, 3.0, "mechanical")]
    t, v = truth_steps(spans, 4.0, -1.0, 1.0)
    np.testing.assert_allclose(t, [0.0, 1.0, 2.0, 3.0, 4.0])
    np.testing.assert_allclose(v, [1.0, -1.0, 1.0, -1.0, -1.0])
    t, v = truth_steps([], 4.0, 0.0, 1.0)
    np.testing.assert_allclose(t, [0.0, 4.0])
    np.testing.assert_allclose(v, [0.0, 0.0])


def test_score_axis_holds_scores_and_threshold_above_the_truth_strip() -> None:
    from benchmarks.viz.focus import score_axis

    axis = score_axis(np.array([1.0, 2.0, 3.0]), threshold=5.0)  # threshold above every score
    assert axis.bottom < axis.truth_low < axis.truth_high < 1.0
    assert axis.top > 5.0
    axis = score_axis(np.array([np.nan, 2.0]), threshold=2.0)  # flat and one NaN: still a range
    assert axis.bottom < axis.truth_high < 2.0 < axis.top


def test_spectrogram_axis_labels() -> None:
    from benchmarks.viz.series import Spectrogram, spaced_ticks, spectrogram_layout, time_ticks

    np.testing.assert_allclose(time_ticks(14.0), [0, 2, 4, 6, 8, 10, 12, 14])
    np.testing.assert_allclose(time_ticks(60.0), np.arange(0, 61, 10))
    names = ["100 Hz", "300 Hz", "1 kHz", "3 kHz"]
    rows, labels = spaced_ticks(np.array([90.5, 88.0, 60.0, 30.0]), names, 10.0)
    np.testing.assert_allclose(rows, [30.0, 60.0, 88.0])  # 100 Hz is 2.5 rows under 300 Hz: dropped
    assert labels == ["3 kHz", "1 kHz", "300 Hz"]
    spec = Spectrogram(np.arange(700) * 0.02, np.zeros((96, 700, 3), np.uint8), np.geomspace(40, 16000, 96))
    layout = spectrogram_layout(spec)
    assert layout.height == pytest.approx(700 / 4)  # rows stretched to a 4:1 strip
    assert layout.x_range[0] < 0 and layout.y_range[1] > layout.height  # room for the labels


def test_events_show_their_time_first() -> None:
    from benchmarks.viz.events import TextEvent, event_line

    assert event_line(TextEvent(7.8, "WARN", "collision: wall")) == "  7.80 s  collision: wall"


def test_shot_sizes_and_small_pngs() -> None:
    import io

    from PIL import Image

    from benchmarks.errors import UserError
    from benchmarks.viz.shots import parse_size, shrink_png

    assert parse_size("1440x900") == (1440, 900)
    for bad in ("1440", "axb", "10x10"):
        with pytest.raises(UserError, match="--size"):
            parse_size(bad)
    raw = io.BytesIO()
    Image.new("RGB", (64, 32), (10, 20, 30)).save(raw, format="PNG")
    small = Image.open(io.BytesIO(shrink_png(raw.getvalue())))
    assert small.size == (64, 32) and small.mode == "P"
    assert small.convert("RGB").getpixel((5, 5)) == (10, 20, 30)
