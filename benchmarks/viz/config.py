"""Display settings of a recording: rates, envelope, spectrogram and marker sizes."""

from __future__ import annotations

from dataclasses import dataclass

TIMELINE = "time"
"""The one timeline every temporal entity is logged on, in seconds from the episode start."""


@dataclass(frozen=True)
class VizConfig:
    """How an episode is turned into a recording (display only: nothing here changes a score)."""

    pose_rate_hz: float = 60.0
    """Rate the robot pose, wheel spin, wheel speeds and moving obstacles are logged at, Hz."""
    envelope_rate_hz: float = 1000.0
    """Rate of the audio min/max display envelope, Hz (each row holds one block's min and max)."""
    spectrogram_nfft: int = 1024
    """FFT length of the display spectrogram, samples at the audio rate."""
    spectrogram_hop_s: float = 0.02
    """Hop between spectrogram frames, s (one image column per hop)."""
    spectrogram_bands: int = 96
    """Log-spaced frequency bands (image rows) of the spectrogram."""
    spectrogram_fmin_hz: float = 40.0
    """Lowest band edge, Hz."""
    spectrogram_fmax_hz: float = 16000.0
    """Highest band edge, Hz (clipped to the Nyquist frequency)."""
    spectrogram_range_db: float = 80.0
    """Dynamic range shown: bands more than this far below the loudest are black, dB."""
    cursor_rate_hz: float = 20.0
    """Rate of the time cursor drawn over the whole-episode spectrogram, Hz."""
    contact_radius_m: float = 0.03
    """Radius of a contact marker with zero impulse, m."""
    contact_radius_per_sqrt_ns: float = 0.04
    """Marker radius added per square root of the contact impulse (N s), m."""
    max_markers: int = 64
    """Most recent collision (and transient) markers kept visible at once."""
    body_height_m: float = 0.12
    """Height of the drawn robot body box, m (the trace does not carry body dimensions)."""
    wheel_width_m: float = 0.05
    """Width of the drawn wheels, m."""
    follow_radius_m: float = 1.75
    """Radius of the ring around the robot that the 3D view follows; the camera stays about 2.1 times this
    away from the robot, m."""

    def __post_init__(self) -> None:
        for name in ("pose_rate_hz", "envelope_rate_hz", "spectrogram_hop_s", "cursor_rate_hz"):
            value = getattr(self, name)
            if not value > 0:
                raise ValueError(f"VizConfig.{name} must be > 0, got {value}")
        if self.max_markers < 1:
            raise ValueError(f"VizConfig.max_markers must be >= 1, got {self.max_markers}")
        if self.spectrogram_nfft < 16:
            raise ValueError(f"VizConfig.spectrogram_nfft must be >= 16, got {self.spectrogram_nfft}")
        if self.spectrogram_bands < 2:
            raise ValueError(f"VizConfig.spectrogram_bands must be >= 2, got {self.spectrogram_bands}")
        if not 0 < self.spectrogram_fmin_hz < self.spectrogram_fmax_hz:
            raise ValueError(
                f"VizConfig.spectrogram_fmin_hz {self.spectrogram_fmin_hz} must be in "
                f"(0, spectrogram_fmax_hz {self.spectrogram_fmax_hz})"
            )
        if not self.spectrogram_range_db > 0:
            raise ValueError(f"VizConfig.spectrogram_range_db must be > 0, got {self.spectrogram_range_db}")
