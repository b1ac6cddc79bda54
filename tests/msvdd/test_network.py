"""Network shapes, ablation switches, and that cross-attention really mixes the modalities."""

from __future__ import annotations

import pytest
import torch

from msvdd.config import MSVDDConfig
from msvdd.frontend import IMU_ALL_CHANNELS, LOGMEL_FRAMES, LOGMEL_N_MELS
from msvdd.network import (
    AUDIO_TOKENS,
    IMU_TOKENS,
    MODULATION_EDGES,
    ORDERS,
    CrossAttentionBlock,
    Fusion,
    FusionNet,
    interpolation_matrix,
    modulation_bands,
    order_amplitudes,
    pool,
    token_angles,
    token_times,
)


def _inputs(n: int = 3, seed: int = 0) -> tuple[torch.Tensor, torch.Tensor]:
    g = torch.Generator().manual_seed(seed)
    return torch.randn(n, 8820, 2, generator=g), torch.randn(n, 400, generator=g)


def test_shapes_and_token_sequences() -> None:
    torch.manual_seed(0)
    cfg = MSVDDConfig.smoke(d=8, s=6)
    out = FusionNet(cfg)(*_inputs())
    assert out.z.shape == (3, 6)
    assert out.audio_tokens is not None and out.audio_tokens.shape == (3, AUDIO_TOKENS, 8)
    assert out.imu_tokens is not None and out.imu_tokens.shape == (3, IMU_TOKENS, 8)
    assert AUDIO_TOKENS > 1 and IMU_TOKENS > 1
    assert out.z_a is not None and out.z_a.shape == (3, 8)
    assert out.audio_rec is not None and out.audio_rec.shape == (3, 8820, 2)
    assert out.imu_rec is not None and out.imu_rec.shape == (3, 400)


def test_cross_attention_mixes_modalities() -> None:
    torch.manual_seed(0)
    net = FusionNet(MSVDDConfig.smoke()).eval()
    audio, imu = _inputs()
    _, imu2 = _inputs(seed=1)
    with torch.no_grad():
        a = net(audio, imu)
        b = net(audio, imu2)
    assert a.fused_a is not None and b.fused_a is not None
    # Same audio, different IMU: the audio branch (audio queries IMU) changes...
    assert float((a.fused_a - b.fused_a).abs().max()) > 1e-4
    # ...while the audio encoder's own tokens do not.
    assert a.audio_tokens is not None and b.audio_tokens is not None
    assert torch.equal(a.audio_tokens, b.audio_tokens)


def test_attention_weights_are_not_trivial() -> None:
    torch.manual_seed(0)
    block = CrossAttentionBlock(8)
    q, k = torch.randn(2, 5, 8), torch.randn(2, 7, 8)
    w = block.attention(q, k)
    assert w.shape == (2, 5, 7)
    torch.testing.assert_close(w.sum(-1), torch.ones(2, 5))
    assert float(w.detach().max()) < 1.0  # a softmax over one key would always be exactly 1


@pytest.mark.parametrize("fusion", ["concat", "sum", "product"])
def test_fusion_variants(fusion: str) -> None:
    torch.manual_seed(0)
    out = FusionNet(MSVDDConfig.smoke(fusion=fusion))(*_inputs())
    assert out.z.shape == (3, 8)
    assert out.fused_a is None


@pytest.mark.parametrize(
    ("kw", "has_audio", "has_imu"),
    [({"use_audio": False}, False, True), ({"use_imu": False}, True, False), ({}, True, True)],
)
def test_modality_ablations(kw: dict[str, bool], has_audio: bool, has_imu: bool) -> None:
    torch.manual_seed(0)
    out = FusionNet(MSVDDConfig.smoke(**kw))(*_inputs())
    assert (out.audio_rec is not None) == has_audio
    assert (out.imu_rec is not None) == has_imu
    assert out.z.shape == (3, 8)


def test_without_reconstruction_has_no_decoders() -> None:
    net = FusionNet(MSVDDConfig.smoke(use_reconstruction=False))
    assert net.audio_decoder is None and net.imu_decoder is None


def test_bad_fusion() -> None:
    with pytest.raises(ValueError, match="fusion"):
        Fusion(8, 8, "attention")


def test_spectrogram_front_end_and_all_imu_axes_shapes() -> None:
    torch.manual_seed(0)
    cfg = MSVDDConfig.smoke(d=8, s=6, audio_frontend="logmel", imu_input="all")
    logmel = torch.randn(3, 2, LOGMEL_FRAMES, LOGMEL_N_MELS)
    out = FusionNet(cfg)(logmel, torch.randn(3, 400, IMU_ALL_CHANNELS))
    assert out.z.shape == (3, 6)
    assert out.audio_tokens is not None and out.audio_tokens.shape == (3, LOGMEL_FRAMES, 8)
    assert out.imu_tokens is not None and out.imu_tokens.shape == (3, IMU_TOKENS, 8)
    assert out.audio_rec is not None and out.audio_rec.shape == logmel.shape
    assert out.imu_rec is not None and out.imu_rec.shape == (3, 400, IMU_ALL_CHANNELS)


def test_log_mel_tokens_are_causal_in_time_only_through_the_lstm() -> None:
    # A change in the last frame cannot change an earlier token (convolutions see +-1 frame, the LSTM runs
    # forward): the k-th token reads frames <= k + 3 only.
    torch.manual_seed(0)
    cfg = MSVDDConfig.smoke(d=8, s=6, audio_frontend="logmel")
    net = FusionNet(cfg)
    x = torch.randn(1, 2, LOGMEL_FRAMES, LOGMEL_N_MELS)
    y = x.clone()
    y[:, :, -1] += 5.0
    assert net.audio_encoder is not None
    a, b = net.audio_encoder(x), net.audio_encoder(y)
    torch.testing.assert_close(a[:, : LOGMEL_FRAMES - 4], b[:, : LOGMEL_FRAMES - 4])
    assert not torch.allclose(a[:, -1], b[:, -1])


def test_statistics_pooling_keeps_mean_spread_and_peak_apart() -> None:
    tokens = torch.tensor([[[1.0, -2.0], [3.0, -2.0], [5.0, -2.0]]])  # (1, 3 tokens, d = 2)
    stats = pool(tokens, "stats")
    assert torch.allclose(stats, torch.tensor([[3.0, -2.0, 2.0, 0.0, 5.0, -2.0]]))  # mean | std | max
    assert torch.allclose(pool(tokens), torch.tensor([[8.0, -4.0]]))  # mean + max
    # two sequences with the same mean and peak but another spread: only statistics pooling tells them apart
    other = torch.tensor([[[2.0, -2.0], [2.0, -2.0], [5.0, -2.0]]])
    assert torch.allclose(pool(other), pool(tokens))
    assert torch.allclose(pool(other, "stats")[0, 2], torch.tensor(3.0).sqrt())
    for fusion in ("cross_attention", "concat", "sum", "product"):
        out = FusionNet(MSVDDConfig.smoke(d=8, s=6, fusion=fusion, pooling="stats"))(*_inputs())
        assert out.z.shape == (3, 6) and out.z_a is not None and out.z_a.shape == (3, 24)
    with pytest.raises(ValueError, match="pooling"):
        MSVDDConfig.smoke(pooling="median")


@pytest.mark.parametrize("count", [50, 67])  # the IMU's tokens and the log-mel frames per window
def test_modulation_pooling_splits_the_spread_by_how_fast_a_feature_swings(count: int) -> None:
    steps = torch.arange(count, dtype=torch.float64)
    # feature 0 swings 3 times a window (band [2, 4)), feature 1 12 times (band [8, 16)), at amplitude 2:
    # an RMS of sqrt(2) in that band and none elsewhere; feature 2 is constant
    tokens = torch.stack(
        [
            2 * torch.cos(2 * torch.pi * 3 * steps / count),
            1.0 + 2 * torch.sin(2 * torch.pi * 12 * steps / count + 0.3),
            torch.full((count,), 4.0, dtype=torch.float64),
        ],
        dim=1,
    )[None]
    bands = modulation_bands(tokens)[0]  # (bands, d)
    assert bands.shape == (len(MODULATION_EDGES), 3)
    expected = torch.zeros(len(MODULATION_EDGES), 3, dtype=torch.float64)
    expected[MODULATION_EDGES.index(2), 0] = expected[MODULATION_EDGES.index(8), 1] = 2**0.5
    torch.testing.assert_close(bands, expected, atol=1e-5, rtol=1e-6)
    # Parseval: the bands' squares add up to the population variance of any sequence
    torch.manual_seed(count)
    noise = torch.randn(4, count, 5, dtype=torch.float64)
    torch.testing.assert_close(
        (modulation_bands(noise) ** 2).sum(dim=1), noise.var(dim=1, unbiased=False), atol=1e-9, rtol=1e-9
    )
    pooled = pool(tokens, "modulation")
    assert pooled.shape == (1, (2 + len(MODULATION_EDGES)) * 3)
    mean, peak = tokens.mean(dim=1)[0], tokens.amax(dim=1)[0]  # mean, max, then the bands (band-major)
    torch.testing.assert_close(pooled[0], torch.cat([mean, peak, bands.flatten()]))
    for fusion in ("cross_attention", "concat"):
        out = FusionNet(MSVDDConfig.smoke(d=8, s=6, fusion=fusion, pooling="modulation"))(*_inputs())
        assert out.z.shape == (3, 6) and out.z_a is not None and out.z_a.shape == (3, 56)


def test_order_amplitudes_read_a_line_in_a_wheels_angle() -> None:
    """Analytic oracle: a feature that swings as A cos(k angle + phase) over whole revolutions of a steadily
    turning wheel reads A at order k and 0 at the other orders; a constant feature reads 0; a wheel that
    does not turn reads about 0; the wheel with the line wins."""
    t = 64
    angle = torch.linspace(0, 2 * torch.pi * 3, t + 1, dtype=torch.float64)[:-1]  # 3 revolutions
    angles = torch.stack([angle, torch.zeros(t, dtype=torch.float64)], dim=1)[None]  # wheel 1 stands still
    tokens = torch.stack(
        [
            1.5 * torch.cos(angle + 0.4),  # order 1, amplitude 1.5
            5.0 + 0.7 * torch.sin(2 * angle),  # order 2, amplitude 0.7, on a level
            torch.full((t,), 3.0, dtype=torch.float64),  # constant
        ],
        dim=1,
    )[None]
    amp = order_amplitudes(tokens, angles)[0]  # (orders, d)
    assert amp.shape == (len(ORDERS), 3)
    expected = torch.zeros(len(ORDERS), 3, dtype=torch.float64)
    expected[ORDERS.index(1), 0] = 1.5
    expected[ORDERS.index(2), 1] = 0.7
    torch.testing.assert_close(amp, expected, atol=1e-5, rtol=1e-6)
    # a wheel that does not turn reads (about) nothing, whatever the tokens do
    still = order_amplitudes(tokens, torch.zeros(1, t, 1, dtype=torch.float64))
    assert float(still.abs().max()) < 1e-5
    pooled = pool(tokens, "stats", angles)
    assert pooled.shape == (1, (3 + len(ORDERS)) * 3)
    torch.testing.assert_close(pooled[0, 9:], amp.flatten())


def test_token_angles_interpolate_the_encoders_at_the_token_centres() -> None:
    """A wheel turning at a steady rate reads rate x the token's centre time, for the log-mel frames, the
    waveform tokens and the IMU tokens."""
    rate = 7.3  # rad/s
    odometry = (rate * torch.arange(400, dtype=torch.float64) / 200.0)[None, :, None].repeat(2, 1, 3)
    for modality, frontend, count in (
        ("audio", "logmel", LOGMEL_FRAMES),
        ("audio", "waveform", AUDIO_TOKENS),
        ("imu", "logmel", IMU_TOKENS),
    ):
        times = token_times(modality, frontend)
        assert times.shape == (count,) and 0 < times[0] < times[-1] < 2.0
        matrix = torch.from_numpy(interpolation_matrix(times)).to(torch.float64)
        got = token_angles(odometry, matrix)
        assert got.shape == (2, count, 3)
        torch.testing.assert_close(got[0, :, 0], rate * torch.from_numpy(times), atol=1e-6, rtol=1e-6)


def test_order_view_network_needs_odometry_and_widens_the_pooled_features() -> None:
    torch.manual_seed(0)
    cfg = MSVDDConfig.smoke(d=8, s=6, pooling="stats", order_view=True)
    net = FusionNet(cfg).eval()
    audio, imu = _inputs()
    odometry = torch.cumsum(torch.rand(3, 400, 4), dim=1) * 0.05
    out = net(audio, imu, odometry)
    assert out.z.shape == (3, 6) and out.z_a is not None and out.z_a.shape == (3, (3 + len(ORDERS)) * 8)
    with pytest.raises(ValueError, match="odometry"):
        net(audio, imu)
    # the wheels' angles enter z: another rotation gives another embedding
    with torch.no_grad():
        other = net(audio, imu, odometry * 1.7).z
    assert not torch.allclose(out.z.detach(), other)
