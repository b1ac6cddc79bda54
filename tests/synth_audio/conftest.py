"""Shared settings for the audio tests."""

from __future__ import annotations

import pytest

from synth_audio import AudioConfig


@pytest.fixture
def quiet() -> AudioConfig:
    """Robot sound only: no ambience, no reverberation, no microphone noise, stems returned."""
    return AudioConfig(ambience=False, rt60_s=0.0, mic_noise_spl_db=float("-inf"), stems=True)
