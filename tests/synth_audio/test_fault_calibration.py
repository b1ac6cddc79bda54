"""The calibration criterion of the wheel faults, measured on a simulated drive and its rendered stems.

See `fault_calibration_kit` for the criterion; it is physical (stem levels), not a detector's score.
"""

from __future__ import annotations

import numpy as np
import pytest
from fault_calibration_kit import audio_level_db, trace

from sim.trace import FaultRecord
from sim.vocab import FAULT_KINDS
from synth_audio.faults import DETECTOR_NYQUIST_HZ, REFERENCE_LEVEL_DB, fault_band, severity_gain


@pytest.mark.parametrize("kind", FAULT_KINDS)
def test_severity_one_is_clearly_audible_over_the_drive_sound_in_its_band(kind: str) -> None:
    assert REFERENCE_LEVEL_DB == 16.0
    assert audio_level_db(kind, 1.0) == pytest.approx(REFERENCE_LEVEL_DB, abs=1.5)


@pytest.mark.parametrize("kind", FAULT_KINDS)
def test_severity_0_3_sits_level_with_the_drive_sound(kind: str) -> None:
    expected = REFERENCE_LEVEL_DB + 20.0 * np.log10(severity_gain(0.3))
    assert expected == pytest.approx(0.3, abs=0.05)
    assert audio_level_db(kind, 0.3) == pytest.approx(expected, abs=2.0)
    assert audio_level_db(kind, 0.3) < audio_level_db(kind, 0.6) < audio_level_db(kind, 1.0)


@pytest.mark.parametrize("kind", FAULT_KINDS)
def test_every_fault_band_lies_below_the_detectors_nyquist(kind: str) -> None:
    record = trace(kind, 1.0).faults[0]
    low, high = fault_band(record, 1.6, 44100)
    assert 20.0 <= low < high <= DETECTOR_NYQUIST_HZ
    assert record.resonance_hz < DETECTOR_NYQUIST_HZ


def test_fault_band_centres_on_the_resonance_or_the_mesh_tone() -> None:
    bearing = FaultRecord("bearing", 0, 1.0, 0.0, 1.0, 3.5, 1000.0, 0.03)
    low, high = fault_band(bearing, 2.0, 44100)
    assert np.sqrt(low * high) == pytest.approx(1000.0) and high / low == pytest.approx(2.0)
    gears = FaultRecord("motor_degradation", 0, 1.0, 0.0, 1.0, 200.0, 1150.0, 0.04)
    low, high = fault_band(gears, 2.0, 44100)
    assert (low, high) == pytest.approx((400.0 / 1.2, 480.0))
    with pytest.raises(ValueError, match="empty"):
        fault_band(FaultRecord("bearing", 0, 1.0, 0.0, 1.0, 3.5, 4000.0, 0.03), 2.0, 44100)
