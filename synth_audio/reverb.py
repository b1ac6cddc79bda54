"""Room reverberation by FFT convolution with a synthetic impulse response run at a quarter of the rate.

The reverberant tail carries little above a few kHz (highs decay fastest), so the impulse response is
generated at sample_rate / 4 and its spectrum multiplies only the lowest quarter of the full-rate spectrum
of the send; the inverse FFT at the full length, with zeros above, returns the wet signal at the full rate.
This is exact band-limited convolution (no resampling filters), at about half the cost of full-rate
convolution.

Both full-length transforms are computed from quarter-length ones (the same sums, regrouped): the send's low
band from the FFTs of its four polyphase components (x[4j + r], r < 4) combined with twiddle factors, and each
channel's wet signal as four interleaved polyphase components, each the inverse FFT of the low band times
its twiddles (`synth_audio.kernels`). scipy's FFT runs several transforms of one length together in its
vector lanes, on a quarter of the memory each, which is faster than one full-length transform; the sums are
the same within float32 rounding (tests/synth_audio/test_reverb.py checks them against it).
"""

from __future__ import annotations

import functools

import numpy as np
import scipy.fft as sfft

from synth_audio import kernels
from synth_audio.dsp import one_pole_lowpass, white

DECIMATION = 4
"""The impulse response runs at sample_rate / DECIMATION."""


def room_ir(rt60: float, rate: float, rng: np.random.Generator) -> np.ndarray:
    """(2, L) decorrelated room impulse responses at `rate` Hz with the given RT60, unit energy each.

    Exponentially decaying noise (highs decay twice as fast as lows), a 4 ms pre-delay and a few early
    reflections.
    """
    length = int(min(1.1 * rt60, 2.5) * rate) + 1
    t = np.arange(length) / rate
    pre = int(0.004 * rate)
    irs = []
    for _ in range(2):
        noise = white(rng, length)
        low = one_pole_lowpass(noise, 1200.0, rate)
        high = noise - low
        ir = low * np.exp(-6.9078 * t / rt60) + high * np.exp(-13.8155 * t / rt60)
        ir[:pre] = 0.0
        early = rng.integers(pre, max(pre + 1, int(0.03 * rate)), 6)
        ir[early] += rng.uniform(-1.0, 1.0, 6) * (0.8 * np.sqrt(np.sum(ir**2) / 50.0))
        ir /= max(float(np.sqrt(np.sum(np.square(ir, dtype=np.float64)))), 1e-12)
        irs.append(ir.astype(np.float32))
    return np.stack(irs)


class Room:
    """A room of given RT60 that convolves mono sends of n samples into (2, n) reverberation."""

    def __init__(self, rt60: float, sample_rate: int, n: int, rng: np.random.Generator) -> None:
        self.n = n
        ir = room_ir(rt60, sample_rate / DECIMATION, rng)
        full = n + ir.shape[1] * DECIMATION
        self.nfft = DECIMATION * sfft.next_fast_len(-(-full // DECIMATION) + 1, real=True)
        low = self.nfft // DECIMATION
        self.bins = low // 2
        spec = sfft.rfft(ir, low, axis=-1)[:, : self.bins]
        self.spectrum = (spec * np.float32(np.sqrt(DECIMATION))).astype(np.complex64)
        self.twiddles = _twiddles(self.nfft, self.bins)

    def send_spectrum(self, send: np.ndarray) -> np.ndarray:
        """Low band of the spectrum of a mono full-rate send (what the room responds to): `rfft(send,
        nfft)[:bins]`, from the FFTs of its polyphase components."""
        padded = np.zeros(self.nfft, dtype=np.float32)
        padded[: send.size] = send
        phases = sfft.rfft(padded.reshape(-1, DECIMATION), axis=0)
        out = np.empty(self.bins, dtype=np.complex64)
        kernels.polyphase_combine(phases, self.twiddles, out)
        return out

    def send_spectrum_low(self, send: np.ndarray) -> np.ndarray:
        """The same for a mono send sampled at sample_rate / DECIMATION."""
        s = sfft.rfft(send.astype(np.float32, copy=False), self.nfft // DECIMATION)[: self.bins]
        s *= np.float32(DECIMATION)
        return s

    def wet(self, send_spectrum: np.ndarray) -> np.ndarray:
        """(2, n) full-rate reverberation of a send spectrum (sums of send spectra are allowed): `irfft` at
        length nfft of the room's spectrum times the send's (zero above the low band), as its interleaved
        polyphase components."""
        low = self.nfft // DECIMATION
        spectra = np.empty((2, DECIMATION, low // 2 + 1), dtype=np.complex64)
        kernels.polyphase_spectra(self.spectrum, send_spectrum, self.twiddles, spectra)
        parts = sfft.irfft(spectra, low, axis=-1)
        out = np.empty((2, self.n), dtype=np.float32)
        kernels.interleave_phases(parts, out)
        return out

    def wet_energy(self, send_spectrum: np.ndarray) -> float:
        """Sum of squares of the reverberation of a send spectrum over both channels, by Parseval.

        The sum of squares of `irfft(X, L)` is (|X_0|^2 + 2 sum_k>0 |X_k|^2) / L when X_(L/2) = 0, as here
        (the low band stops below it): the room's power spectrum times the send's, summed, with no inverse
        FFT. It counts the whole response, the reverberant tail past the n samples of `wet` included (the
        last IR length's worth: a fraction of a percent of the energy in an episode-long send).
        """
        low = self.nfft // DECIMATION
        h = self.spectrum.astype(np.complex128)
        room_power = (h.real**2 + h.imag**2).sum(axis=0)
        s = send_spectrum.astype(np.complex128)
        send_power = s.real**2 + s.imag**2
        total = 2.0 * kernels.sum_products(room_power, send_power) - float(room_power[0] * send_power[0])
        # the full-rate samples are DECIMATION times as many, each band-limited: / DECIMATION (as `wet`)
        return total / low / DECIMATION

    def apply(self, send: np.ndarray) -> np.ndarray:
        """(2, n) reverberation of a mono full-rate send."""
        return self.wet(self.send_spectrum(send))


@functools.lru_cache(maxsize=4)
def _twiddles(nfft: int, bins: int) -> np.ndarray:
    """The (DECIMATION, bins) read-only `kernels.twiddles_into` factors of a length; kept for the next rooms
    of episodes as long (a dataset's episodes come in a few lengths)."""
    out = np.empty((DECIMATION, bins), dtype=np.complex64)
    kernels.twiddles_into(nfft, out)
    out.flags.writeable = False
    return out
