"""The room's reverberation against the full-length FFTs it regroups (scipy's, the definition)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.fft as sfft

from synth_audio.reverb import DECIMATION, Room


@pytest.mark.parametrize("n", [44100, 44103, 200_001])
def test_send_spectrum_is_the_low_band_of_the_full_length_fft(n: int) -> None:
    room = Room(0.4, 44100, n, np.random.default_rng(1))
    send = np.random.default_rng(2).standard_normal(n).astype(np.float32)
    expected = sfft.rfft(send.astype(np.float64), room.nfft)[: room.bins]
    got = room.send_spectrum(send)
    assert got.dtype == np.complex64 and got.shape == (room.bins,)
    assert np.max(np.abs(got - expected)) < 2e-6 * np.max(np.abs(expected))


@pytest.mark.parametrize("n", [44100, 44103, 200_001])
def test_wet_is_the_full_length_inverse_fft_of_the_low_band(n: int) -> None:
    room = Room(0.4, 44100, n, np.random.default_rng(1))
    send = np.random.default_rng(3).standard_normal(n).astype(np.float32)
    spectrum = room.send_spectrum(send)
    full = np.zeros((2, room.nfft // 2 + 1), dtype=np.complex128)
    full[:, : room.bins] = room.spectrum.astype(np.complex128) * spectrum.astype(np.complex128)
    expected = sfft.irfft(full, room.nfft, axis=-1)[:, :n]
    got = room.wet(spectrum)
    assert got.dtype == np.float32 and got.shape == (2, n)
    assert np.max(np.abs(got - expected)) < 2e-6 * np.max(np.abs(expected))


def test_an_impulse_rings_with_the_room_response_band_limited_and_delayed() -> None:
    """A unit impulse at sample p: the wet signal is the room's response starting at p (nothing before it
    beyond the band limit's ringing), band-limited below a quarter of the Nyquist frequency, with the unit
    energy per channel of `room_ir`'s responses; `wet_energy` equals its sum of squares."""
    n, p = 88200, 30000
    room = Room(0.3, 44100, n, np.random.default_rng(4))
    send = np.zeros(n, dtype=np.float32)
    send[p] = 1.0
    spectrum = room.send_spectrum(send)
    wet = room.wet(spectrum).astype(np.float64)
    energy = np.sum(wet**2, axis=1)
    np.testing.assert_allclose(energy, 1.0, rtol=0.02)  # unit-energy responses (`room_ir`)
    assert np.sum(wet[:, : p - 2000] ** 2) < 1e-4 * np.sum(wet**2)
    low = np.abs(sfft.rfft(wet, axis=1)) ** 2
    edge = round(low.shape[1] / DECIMATION) + 50
    assert np.sum(low[:, edge:]) < 1e-6 * np.sum(low)
    assert room.wet_energy(spectrum) == pytest.approx(float(np.sum(wet**2)), rel=0.01)
