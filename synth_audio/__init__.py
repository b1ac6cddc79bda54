"""Procedural binaural audio rendered from a simulated Trace.

from synth_audio import AudioConfig, render, write
audio = render(trace, AudioConfig(snr_db=0.0), seed=1)
write("episode.flac", audio)
"""

from synth_audio.config import STEM_NAMES, Audio, AudioConfig, AudioError
from synth_audio.io import read, write
from synth_audio.render import reference_rms, render

__all__ = ["STEM_NAMES", "Audio", "AudioConfig", "AudioError", "read", "reference_rms", "render", "write"]
