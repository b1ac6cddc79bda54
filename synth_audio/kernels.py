"""Compiled loops (numba) for the audio's per-sample work, where numpy needs a pass and a temporary per
product, or an index per product: a wheel's motor (`motor_mix`) and rolling (`rolling_mix`), each reading its
wavetables at the ramped phase in the same pass, envelopes ramped within control blocks (`add_ramped`),
scattering copies of a kernel (`overlap_add_into`), a fixed fractional delay (`fractional_delay_into`),
reading a wavetable at a ramped phase (`wavetable_read`), reading a signal at moving fractional positions
(a Doppler path, `lagrange_read`), steady tones (`sinusoid_into`), banks of damped modes
(`damped_modes_into`), weaving noise beds (`weave`), the limiter, which also interleaves the channels
(`limit_interleave`), one- and two-pole filters (`two_pole_into`), int16 noise to float32 (`scale_int16`),
a scan for silence (`any_nonzero`), sums of squares (`sum_squares`), the room's long FFTs regrouped into
quarter-length ones (`twiddles_into`, `polyphase_combine`, `polyphase_spectra`, `interleave_phases`; see
`synth_audio.reverb`), and the dithered quantisation of a file's samples (`tpdf_quantise`). Each touches every
output sample once. Loops index array slices from 0: an index that might be negative costs a
wraparound test per sample, which stops LLVM vectorising the loop.

Compiled without fast-math, so the same inputs give the same samples on the same machine; `cache=True`
keeps the machine code beside the module (`__pycache__`), so a worker process loads it instead of
compiling it again.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

_LANES = 8
"""Independent phasors of `sinusoid_into` (consecutive samples)."""
_ANCHOR = 4096
"""Samples between `sinusoid_into`'s restarts from the exact phase (a multiple of `_LANES`)."""
_TWIDDLE_ANCHOR = 64
"""Bins between `twiddles_into`'s restarts of its phasor from the exact angle."""


@njit(cache=True, nogil=True)
def overlap_add_into(
    out: np.ndarray, positions: np.ndarray, amps: np.ndarray, kernel: np.ndarray
) -> None:  # pragma: no cover - compiled
    """out[p_i + k] += amps[i] kernel[k] for every event i and tap k inside out (float32, in place), the
    events in their order."""
    n = out.shape[0]
    size = kernel.shape[0]
    for e in range(positions.shape[0]):
        p = positions[e]
        a = np.float32(amps[e])
        lo = max(0, -p)
        hi = min(size, n - p)
        if hi <= lo:
            continue
        o = out[p + lo : p + hi]
        taps = kernel[lo:hi]
        for k in range(o.shape[0]):  # indices from 0: no wraparound test, so the loop vectorises
            o[k] += a * taps[k]


@njit(cache=True, nogil=True)
def sinusoid_into(
    out: np.ndarray, start: float, step: float, amp: float, cosine: bool
) -> None:  # pragma: no cover - compiled
    """out[j] += amp sin(2 pi (start + step j)) (amp cos with `cosine`): a steady tone of `step` cycles per
    sample. Eight phasors, one per lane of eight consecutive samples, each turned by eight samples' rotation
    (no transcendental per sample, and eight independent multiply chains); every `_ANCHOR` samples they
    restart from the exact phase, so rounding never accumulates over more than that many steps."""
    n = out.shape[0]
    zr = np.empty(_LANES)
    zi = np.empty(_LANES)
    turn = 2.0 * math.pi * step * _LANES
    qr, qi = math.cos(turn), math.sin(turn)
    offset = 0.5 * math.pi if cosine else 0.0
    for a in range(0, n, _ANCHOR):
        for lane in range(_LANES):
            c = start + step * (a + lane)
            angle = 2.0 * math.pi * (c - math.floor(c)) + offset
            zr[lane] = amp * math.cos(angle)
            zi[lane] = amp * math.sin(angle)
        o = out[a : a + _ANCHOR]
        whole = o.shape[0] - o.shape[0] % _LANES
        for i in range(0, whole, _LANES):
            for lane in range(_LANES):
                o[i + lane] += np.float32(zi[lane])
                r = zr[lane]
                zr[lane] = r * qr - zi[lane] * qi
                zi[lane] = r * qi + zi[lane] * qr
        for lane in range(o.shape[0] - whole):
            o[whole + lane] += np.float32(zi[lane])


@njit(cache=True, nogil=True)
def damped_modes_into(
    out: np.ndarray,
    omega: np.ndarray,
    decay: np.ndarray,
    amps: np.ndarray,
    phases: np.ndarray,
    lengths: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """out[j] += sum over modes m of amps[m] exp(-decay[m] j) sin(omega[m] j + phases[m]) for j < lengths[m]
    (per sample: rad and 1/sample), each mode by the exact rotation-and-decay of a complex phasor, z <- z q
    with q = exp(-decay + i omega), in float64 (the recurrence's rounding grows like j x 1e-16)."""
    for m in range(omega.shape[0]):
        qr = math.exp(-decay[m]) * math.cos(omega[m])
        qi = math.exp(-decay[m]) * math.sin(omega[m])
        zr = amps[m] * math.cos(phases[m])
        zi = amps[m] * math.sin(phases[m])
        o = out[: min(lengths[m], out.shape[0])]
        for j in range(o.shape[0]):
            o[j] += np.float32(zi)
            zr, zi = zr * qr - zi * qi, zr * qi + zi * qr


@njit(cache=True, nogil=True)
def lagrange_read(
    padded: np.ndarray,
    pad: int,
    position: np.ndarray,
    gain: np.ndarray,
    control: int,
    out: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """out[j] += g(j) x(p(j)) for j < out.size: x read at fractional sample p(j) by third-order Lagrange
    interpolation over x[i - 1 .. i + 2] (i = floor p, f = p - i), p and g ramped linearly between their
    values every `control` samples (`position`, `gain`: one more than out.size / control).

    `padded` is x with `pad` zeros on either side; reads beyond them are those zeros.
    """
    last = padded.shape[0] - 1
    n = out.shape[0]
    ramp = np.arange(control) / control  # r at each sample of a block (computed once: no division per sample)
    base = np.empty(control, dtype=np.int64)  # x[i - 1]'s index in `padded`, per sample of a block
    weights = np.empty((4, control), dtype=np.float64)  # the four Lagrange weights, per sample
    g = np.empty(control, dtype=np.float64)
    for k in range((n + control - 1) // control):
        p0 = position[k]
        dp = position[k + 1] - p0
        g0 = gain[k]
        dg = gain[k + 1] - g0
        o = out[k * control : (k + 1) * control]
        m = o.shape[0]
        # p is linear within the block: when both its ends (and a sample more) read inside `padded`, every
        # sample does, and the loop needs no bounds test
        inside = (
            math.floor(min(p0, p0 + dp)) + pad - 2 >= 0 and math.floor(max(p0, p0 + dp)) + pad + 3 <= last
        )
        for i in range(m):  # positions and weights first, in a loop without reads (it vectorises)
            r = ramp[i]
            p = p0 + dp * r
            g[i] = g0 + dg * r
            f = math.floor(p)
            base[i] = int(f) + pad - 1
            f = p - f
            low = (f - 1.0) * (f - 2.0)
            high = (f + 1.0) * f
            weights[0, i] = -f * low / 6.0
            weights[1, i] = (f + 1.0) * low * 0.5
            weights[2, i] = -high * (f - 2.0) * 0.5
            weights[3, i] = high * (f - 1.0) / 6.0
        w0, w1, w2, w3 = weights[0], weights[1], weights[2], weights[3]
        if inside:
            for i in range(m):
                j = base[i]
                y = w0[i] * padded[j] + w1[i] * padded[j + 1] + w2[i] * padded[j + 2] + w3[i] * padded[j + 3]
                o[i] += np.float32(g[i] * y)
        else:
            for i in range(m):
                j = base[i]
                x0 = padded[j] if 0 <= j <= last else np.float32(0.0)
                x1 = padded[j + 1] if 0 <= j + 1 <= last else np.float32(0.0)
                x2 = padded[j + 2] if 0 <= j + 2 <= last else np.float32(0.0)
                x3 = padded[j + 3] if 0 <= j + 3 <= last else np.float32(0.0)
                o[i] += np.float32(g[i] * (w0[i] * x0 + w1[i] * x1 + w2[i] * x2 + w3[i] * x3))


@njit(cache=True, nogil=True)
def fractional_delay_into(
    out: np.ndarray, x: np.ndarray, shift: int, taps: np.ndarray, start: int
) -> None:  # pragma: no cover - compiled
    """out[start + j] += sum_k taps[k] x[j - shift - k] over the samples of out that x reaches (float32, in
    place; x is zero outside itself): a four-tap fractional delay in one pass."""
    n = out.shape[0]
    m = x.shape[0]
    t0, t1, t2, t3 = taps[0], taps[1], taps[2], taps[3]
    origin = start + shift  # out index of x[0] through tap 0
    lo = max(origin, 0)
    hi = min(origin + m + 3, n)
    inner_lo = min(max(origin + 3, lo), hi)  # from here on every tap reads inside x ...
    inner_hi = max(min(origin + m, hi), inner_lo)  # ... up to here
    o = out[inner_lo:inner_hi]  # the interior, in one loop that vectorises
    x0 = x[inner_lo - origin : inner_hi - origin]
    x1 = x[inner_lo - origin - 1 : inner_hi - origin - 1]
    x2 = x[inner_lo - origin - 2 : inner_hi - origin - 2]
    x3 = x[inner_lo - origin - 3 : inner_hi - origin - 3]
    for j in range(o.shape[0]):
        o[j] += t0 * x0[j] + t1 * x1[j] + t2 * x2[j] + t3 * x3[j]
    for edge in range(2):  # the first three and last three samples, where some taps read outside x
        for q in range(lo, inner_lo) if edge == 0 else range(inner_hi, hi):
            i = q - origin  # x index of tap 0
            acc = np.float32(0.0)
            if 0 <= i < m:
                acc += t0 * x[i]
            if 0 <= i - 1 < m:
                acc += t1 * x[i - 1]
            if 0 <= i - 2 < m:
                acc += t2 * x[i - 2]
            if 0 <= i - 3 < m:
                acc += t3 * x[i - 3]
            out[q] += acc


@njit(cache=True, nogil=True)
def add_ramped(out: np.ndarray, signal: np.ndarray, env: np.ndarray, block: int) -> None:  # pragma: no cover
    """out[j] += signal[j] e(j) (float32, in place), e linear within each block between its values at the
    block boundaries `env` (len(out) / block + 1 of them)."""
    n = out.shape[0]
    for b in range((n + block - 1) // block):
        start = b * block
        e0 = np.float32(env[b])
        de = (np.float32(env[b + 1]) - e0) / np.float32(block)
        o = out[start : start + block]
        x = signal[start : start + block]
        for i in range(o.shape[0]):  # indices from 0: no wraparound test, so the loop vectorises
            o[i] += x[i] * (e0 + de * np.float32(i))


@njit(cache=True, nogil=True)
def wavetable_read(
    cycles: np.ndarray, block: int, table: np.ndarray, out: np.ndarray
) -> None:  # pragma: no cover - compiled
    """out[j] = table[k(j)], k the nearest point of a power-of-two table (one cycle) of the phase ramped in
    float32 within each block from the cycle counts at the block boundaries, `cycles` (float64): the samples
    of `dsp.wavetable(dsp.frac_phase(cycles, block, n), table)`, by the same float32 operations, in one pass
    (no phase and index arrays)."""
    n = out.shape[0]
    size = np.float32(table.shape[0])
    mask = table.shape[0] - 1
    ramp = np.arange(block, dtype=np.float32) / np.float32(block)
    for b in range((n + block - 1) // block):
        base = np.float32(cycles[b] - np.floor(cycles[b]))
        inc = np.float32(cycles[b + 1] - cycles[b])
        o = out[b * block : (b + 1) * block]
        for i in range(o.shape[0]):
            o[i] = table[np.int32((base + inc * ramp[i]) * size) & mask]


@njit(cache=True, nogil=True)
def table_indices(
    c_start: float, c_end: float, block: int, size: int, out: np.ndarray
) -> None:  # pragma: no cover - compiled
    """out[i] = the nearest point (of `size`, a power of two, per cycle) of the phase
    c_start + (c_end - c_start) i / block cycles (float64): one block of a phase linear within it, in a loop
    that vectorises, so that the table reads that follow need no conversion."""
    c0 = c_start - np.floor(c_start)
    dc = (c_end - c_start) / block
    mask = size - 1
    for i in range(out.shape[0]):
        out[i] = int((c0 + dc * i) * size) & mask


@njit(cache=True, nogil=True)
def rolling_mix(
    out: np.ndarray,
    noise: np.ndarray,
    noise_env: np.ndarray,
    cycles: np.ndarray,
    table: np.ndarray,
    tone_env: np.ndarray,
    block: int,
) -> None:  # pragma: no cover - compiled
    """out[j] += noise[j] n(j), then += table[k] t(j), k the nearest point (`table_indices`) of the phase
    whose cycle counts at the block boundaries are `cycles`, the envelopes n and t linear within each block
    between their block-boundary values (as `add_ramped`); the tone only when `table` is not empty. Float32,
    in place."""
    add_ramped(out, noise, noise_env, block)  # the noise first, in a loop that vectorises
    size = table.shape[0]
    if size == 0:
        return
    k = np.empty(block, dtype=np.int64)
    for b in range((out.shape[0] + block - 1) // block):
        o = out[b * block : (b + 1) * block]
        table_indices(cycles[b], cycles[b + 1], block, size, k[: o.shape[0]])
        t0 = np.float32(tone_env[b])
        dt = (np.float32(tone_env[b + 1]) - t0) / np.float32(block)
        for i in range(o.shape[0]):
            o[i] += table[k[i]] * (t0 + dt * np.float32(i))


@njit(cache=True, nogil=True)
def weave(
    out: np.ndarray, pool: np.ndarray, segments: np.ndarray, offsets: np.ndarray, window: np.ndarray, hop: int
) -> None:  # pragma: no cover - compiled
    """out[s hop + j] += pool[segments[s]][(offsets[s] + j) mod size] window[j] for every snippet s and
    j < size (float32, in place; `out` must hold len(segments) x hop + size samples)."""
    size = window.shape[0]
    for s in range(segments.shape[0]):
        seg = pool[segments[s]]
        offset = offsets[s]
        head = size - offset  # the segment from `offset` to its end, then from its start
        o = out[s * hop : s * hop + head]
        x = seg[offset:]
        w = window[:head]
        for j in range(head):
            o[j] += x[j] * w[j]
        o = out[s * hop + head : s * hop + size]
        x = seg[:offset]
        w = window[head:]
        for j in range(offset):
            o[j] += x[j] * w[j]


@njit(cache=True, nogil=True)
def scale_int16(raw: np.ndarray, scale: np.float32, out: np.ndarray) -> None:  # pragma: no cover - compiled
    """out[i] = float32(raw[i]) x scale (float32): int16 samples to float32 in one pass."""
    for i in range(raw.shape[0]):
        out[i] = np.float32(raw[i]) * scale


@njit(cache=True, nogil=True)
def any_nonzero(x: np.ndarray) -> bool:  # pragma: no cover - compiled
    """Whether a 1-D array holds a non-zero (or NaN) element, `numpy.any`'s answer, stopping at the first."""
    for i in range(x.shape[0]):  # noqa: SIM110 - a loop compiles to this; numba takes no generator to `any`
        if x[i] != 0:
            return True
    return False


@njit(cache=True, nogil=True)
def limit_interleave(x: np.ndarray, knee: float, out: np.ndarray) -> None:  # pragma: no cover - compiled
    """out[j, c] = the soft limit of x[c, j] (x (C, n) float32 -> out (n, C) float32): identity up to |x| =
    knee, then sign(x) (knee + (1 - knee) tanh((|x| - knee) / (1 - knee))) towards full scale; an infinite
    knee only interleaves.

    The channels are interleaved first, in a loop without branches that notes whether any sample passes the
    knee; only then are those samples limited, in a second pass (a limiter rarely acts: most blocks take
    the first pass alone)."""
    over = False
    if x.shape[0] == 2:
        left, right = x[0], x[1]
        for j in range(left.shape[0]):
            a, b = left[j], right[j]
            out[j, 0] = a
            out[j, 1] = b
            over |= (abs(a) > knee) | (abs(b) > knee)
    else:
        for c in range(x.shape[0]):
            row = x[c]
            for j in range(row.shape[0]):
                out[j, c] = row[j]
                over |= abs(row[j]) > knee
    if not over:
        return
    span = 1.0 - knee
    for c in range(x.shape[0]):
        row = x[c]
        for j in range(row.shape[0]):  # (one branch per sign: a select between +y and -y ran 20x slower)
            v = row[j]
            if v > knee:
                out[j, c] = np.float32(knee + span * np.tanh((v - knee) / span))
            elif v < -knee:
                out[j, c] = np.float32(-(knee + span * np.tanh((-v - knee) / span)))


@njit(cache=True, nogil=True)
def motor_mix(
    out: np.ndarray,
    cycles: np.ndarray,
    table: np.ndarray,
    modulations: np.ndarray,
    tone_env: np.ndarray,
    brush_noise: np.ndarray,
    brush_env: np.ndarray,
    carrier: np.ndarray,
    pwm_env: np.ndarray,
    block: int,
) -> None:  # pragma: no cover - compiled
    """out[j] += table[k] tone(j) + brush[k] brush_noise[j] brush(j) + side[k] carrier[j] pwm(j), k the
    nearest point (`table_indices`) of the shaft phase whose cycle counts at the block boundaries are
    `cycles`, every envelope linear within each block between its values at the block boundaries (float32,
    in place); the last term only when `carrier` is not empty. brush[k] and side[k] are the columns of
    `modulations` (P, 2) at row k mod P: one period of both modulations, P a power of two dividing the
    table's size, so that one small table stays in cache where two tables of the tone's size did not."""
    n = out.shape[0]
    whine = carrier.shape[0] > 0
    mask = modulations.shape[0] - 1
    k = np.empty(block, dtype=np.int64)
    for b in range((n + block - 1) // block):
        start = b * block
        o = out[start : start + block]
        table_indices(cycles[b], cycles[b + 1], block, table.shape[0], k[: o.shape[0]])
        t0 = np.float32(tone_env[b])
        dt = (np.float32(tone_env[b + 1]) - t0) / np.float32(block)
        n0 = np.float32(brush_env[b])
        dn = (np.float32(brush_env[b + 1]) - n0) / np.float32(block)
        noise = brush_noise[start : start + block]
        if whine:
            p0 = np.float32(pwm_env[b])
            dp = (np.float32(pwm_env[b + 1]) - p0) / np.float32(block)
            c = carrier[start : start + block]
            for i in range(o.shape[0]):
                f = np.float32(i)
                row = modulations[k[i] & mask]
                tone_brush = table[k[i]] * (t0 + dt * f) + row[0] * noise[i] * (n0 + dn * f)
                o[i] = (o[i] + tone_brush) + row[1] * c[i] * (p0 + dp * f)
        else:
            for i in range(o.shape[0]):
                f = np.float32(i)
                o[i] += table[k[i]] * (t0 + dt * f) + modulations[k[i] & mask, 0] * noise[i] * (n0 + dn * f)


@njit(cache=True, nogil=True)
def twiddles_into(length: int, out: np.ndarray) -> None:  # pragma: no cover - compiled
    """out[r, k] = exp(-2 pi i k r / length) (out (D, m) complex64): the factors that join the spectra of a
    signal's D polyphase components into its spectrum. Each row is a float64 phasor restarted from the exact
    angle every `_TWIDDLE_ANCHOR` bins (its drift stays far under float32's resolution)."""
    for r in range(out.shape[0]):
        angle = -2.0 * math.pi * r / length
        rot = complex(math.cos(angle), math.sin(angle))
        row = out[r]
        w = complex(1.0, 0.0)
        for k in range(row.shape[0]):
            if k % _TWIDDLE_ANCHOR == 0:
                w = complex(math.cos(angle * k), math.sin(angle * k))
            row[k] = w
            w *= rot


@njit(cache=True, nogil=True)
def polyphase_combine(phases: np.ndarray, twiddles: np.ndarray, out: np.ndarray) -> None:  # pragma: no cover
    """out[k] = sum_r phases[k, r] twiddles[r, k] for k < len(out) (complex64): the low band of a signal's
    spectrum from the spectra `phases` (m, D) of its D polyphase components (x[D j + r], r < D), given its
    `twiddles_into`. Row 0 of the twiddles is 1 and is not multiplied."""
    d = phases.shape[1]
    for k in range(out.shape[0]):
        acc = phases[k, 0]
        for r in range(1, d):
            acc += phases[k, r] * twiddles[r, k]
        out[k] = acc


@njit(cache=True, nogil=True)
def polyphase_spectra(
    responses: np.ndarray, send: np.ndarray, twiddles: np.ndarray, out: np.ndarray
) -> None:  # pragma: no cover - compiled
    """out[c, r, k] = responses[c, k] send[k] conj(twiddles[r, k]) / D for k < len(send), 0 above (out (C, D,
    h) complex64, h > len(send)): the spectra whose inverse FFTs are the D polyphase components of the
    inverse FFT of the low band responses[c] send (zero above it), given the signal's `twiddles_into`."""
    d = out.shape[1]
    bins = send.shape[0]
    scale = np.float32(1.0 / d)
    for c in range(out.shape[0]):
        for r in range(d):
            row = out[c, r]
            for k in range(bins):
                row[k] = responses[c, k] * send[k] * np.conj(twiddles[r, k]) * scale
            for k in range(bins, row.shape[0]):
                row[k] = 0


@njit(cache=True, nogil=True)
def interleave_phases(parts: np.ndarray, out: np.ndarray) -> None:  # pragma: no cover - compiled
    """out[c, D j + r] = parts[c, r, j] while D j + r < out.shape[1] (parts (C, D, m), out (C, n) float32):
    D polyphase components back into one signal per channel."""
    d = parts.shape[1]
    n = out.shape[1]
    for c in range(out.shape[0]):
        row = out[c]
        whole = n // d
        for j in range(whole):
            for r in range(d):
                row[d * j + r] = parts[c, r, j]
        for i in range(whole * d, n):
            row[i] = parts[c, i - whole * d, whole]


@njit(cache=True, nogil=True)
def sum_squares(x: np.ndarray) -> float:  # pragma: no cover - compiled
    """Sum of x[i]^2 over a 1-D array, in float64 (eight running sums, added pairwise at the end), without
    numpy's float64 temporary of the squares."""
    acc = np.zeros(8)
    whole = x.shape[0] // 8 * 8
    for i in range(0, whole, 8):
        for j in range(8):
            v = np.float64(x[i + j])
            acc[j] += v * v
    rest = 0.0
    for i in range(whole, x.shape[0]):
        v = np.float64(x[i])
        rest += v * v
    return ((acc[0] + acc[1]) + (acc[2] + acc[3])) + ((acc[4] + acc[5]) + (acc[6] + acc[7])) + rest


@njit(cache=True, nogil=True)
def sum_products(x: np.ndarray, y: np.ndarray) -> float:  # pragma: no cover - compiled
    """Sum of x[i] y[i] over two 1-D arrays of one length, in float64 (eight running sums, added pairwise at
    the end): a dot product on this thread alone, the same bits whatever the machine's BLAS threads (whose
    `np.dot` splits a long sum by thread count, and whose idle threads then spin on the other cores)."""
    acc = np.zeros(8)
    whole = x.shape[0] // 8 * 8
    for i in range(0, whole, 8):
        for j in range(8):
            acc[j] += np.float64(x[i + j]) * np.float64(y[i + j])
    rest = 0.0
    for i in range(whole, x.shape[0]):
        rest += np.float64(x[i]) * np.float64(y[i])
    return ((acc[0] + acc[1]) + (acc[2] + acc[3])) + ((acc[4] + acc[5]) + (acc[6] + acc[7])) + rest


@njit(cache=True, nogil=True)
def two_pole_into(
    x: np.ndarray, b0: float, a1: float, a2: float, out: np.ndarray
) -> None:  # pragma: no cover - compiled
    """out = the recursive filter y[n] = b0 x[n] - a1 y[n-1] - a2 y[n-2] of x from rest (1-D), in float64,
    stored as out's dtype: `scipy.signal.lfilter([b0], [1, a1, a2], x)` in its own order of operations (its
    transposed direct form II), without its per-call cost; a2 = 0 is a one-pole filter."""
    z1 = 0.0
    z2 = 0.0
    for i in range(x.shape[0]):
        v = np.float64(x[i])
        y = z1 + v * b0
        z1 = z2 - y * a1
        z2 = -(y * a2)
        out[i] = y


@njit(cache=True, nogil=True, inline="always")
def _lowbias32(h: np.uint64) -> np.uint64:  # pragma: no cover - compiled
    """A 32-bit integer hash, `lowbias32` (C. Wellons' integer hash prospector): each input bit flips each
    output bit with probability close to 1/2; h < 2^32, held in 64 bits (the products stay exact)."""
    h ^= h >> np.uint64(16)
    h = (h * np.uint64(0x7FEB352D)) & np.uint64(0xFFFFFFFF)
    h ^= h >> np.uint64(15)
    h = (h * np.uint64(0x846CA68B)) & np.uint64(0xFFFFFFFF)
    h ^= h >> np.uint64(16)
    return h


@njit(cache=True, nogil=True)
def tpdf_quantise(
    x: np.ndarray, key: int, scale: float, out: np.ndarray
) -> None:  # pragma: no cover - compiled
    """out[i] = floor(x[i] scale + d + 1/2) clipped to [-scale, scale - 1], d = (hi - lo) / 2^16 where hi and
    lo are the high and low 16 bits of r = lowbias32(i xor k): the difference of two uniform draws, a
    triangular dither over +-1 step (in steps of 2^-16), from a hash of the sample's index, so no random
    numbers are drawn or stored. k = lowbias32(key + i // 2^32) (key < 2^32), one per 2^32 samples. x and out
    are 1-D (a file's interleaved samples, flattened: one loop); x float32 or float64, out integers; the
    arithmetic in float64."""
    lowest = -scale
    highest = scale - 1.0
    n = x.shape[0]
    span = np.int64(1) << np.int64(32)
    for block in range(0, n, span):
        k = _lowbias32((np.uint64(key) + np.uint64(block >> 32)) & np.uint64(0xFFFFFFFF))
        xs = x[block : min(n, block + span)]
        os = out[block : min(n, block + span)]
        for i in range(xs.shape[0]):
            r = _lowbias32(np.uint64(i) ^ k)
            d = np.float64(np.int64(r >> np.uint64(16)) - np.int64(r & np.uint64(0xFFFF))) * (1.0 / 65536.0)
            y = math.floor(np.float64(xs[i]) * scale + d + 0.5)
            os[i] = min(max(y, lowest), highest)
