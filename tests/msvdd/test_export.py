"""The ONNX export of M-SVDD's scoring path: parity with torch on real windows at two batch sizes, the CLI
round trip, the ONNX Runtime backend of the streaming scorer, the graph without export for every variant,
its rewritten pieces against the modules and functions they stand for, the LSTM simplification, and what the
export refuses."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import onnx
import pytest
import torch
import torch.nn.functional as F

from benchmarks.cli import main
from benchmarks.dataset import open_dataset
from benchmarks.episode import read_episode
from benchmarks.methods import load_detector
from msvdd.config import MSVDDConfig
from msvdd.contract import AUDIO_RATE, WindowError, Windows
from msvdd.export import ExportOptions, export_onnx, max_relative_difference
from msvdd.frontend import LOGMEL_F_MIN, LOGMEL_HOP, LOGMEL_N_FFT, LOGMEL_N_MELS
from msvdd.logmel import log_mel_frames
from msvdd.model import MSVDD, NotFittedError
from msvdd.network import AudioDecoder, AudioEncoder
from msvdd.onnx_backend import MANIFEST_FILE, ONNX_FILE, OnnxFormatError, OnnxScorer
from msvdd.score_graph import (
    AudioDecoder2d,
    AudioEncoder2d,
    ExportLSTM,
    LogMel,
    PolyphaseUpsample,
    ScoreGraph,
    huber,
)
from msvdd.stream import StreamingScorer
from msvdd.synthetic import toy_windows

RTOL = 1e-4


pytestmark = pytest.mark.xdist_group("export")  # with `pytest -n`: one worker

# Session scope: a worker may run other modules' tests between this module's, which would tear a
# module-scoped fixture down and export again (20 s each time).


@pytest.fixture(scope="session")
def exported(tiny_model: Path, tiny_dataset: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The tiny M-SVDD model exported through the CLI, checked on the dataset's test windows."""
    out = tmp_path_factory.mktemp("onnx") / "msvdd"
    argv = ["export", str(tiny_model), "--out", str(out), "--data", str(tiny_dataset), "--check-windows", "8"]
    assert main(argv) == 0
    return out


@pytest.fixture(scope="session")
def torch_model(tiny_model: Path) -> MSVDD:
    _, detector = load_detector(tiny_model)
    assert isinstance(detector, MSVDD)
    return detector


@pytest.fixture(scope="module")
def real_windows(tiny_dataset: Path) -> Windows:
    """The tiny dataset's test windows (nominal and anomalous, decimated from simulated recordings)."""
    return open_dataset(tiny_dataset).load_windows("test")[0]


def test_cli_writes_the_graph_and_its_description(exported: Path, torch_model: MSVDD) -> None:
    assert sorted(p.name for p in exported.iterdir()) == [ONNX_FILE, MANIFEST_FILE]
    assert [p.name for p in exported.parent.iterdir()] == [exported.name]  # no temporary folder left
    info = json.loads((exported / MANIFEST_FILE).read_text())
    assert info["format"] == "msvdd-onnx" and info["method"] == "msvdd"
    assert info["threshold"] == torch_model.threshold_
    assert [i["name"] for i in info["inputs"]] == ["audio", "imu", "imu6"]  # "msvdd" reads all IMU axes
    assert info["window"] == {
        "seconds": 2.0,
        "audio_rate_hz": 4410.0,
        "audio_samples": 8820,
        "audio_channels": 2,
        "imu_rate_hz": 200.0,
        "imu_samples": 400,
    }
    assert info["parity"]["max_rel_diff"] <= RTOL and info["parity"]["windows"] == 8
    assert "test" in info["parity"]["source"]
    graph = onnx.load(str(exported / ONNX_FILE)).graph
    for value in graph.input:
        batch = value.type.tensor_type.shape.dim[0]
        assert batch.dim_param and not batch.HasField("dim_value")  # a dynamic batch dimension
    assert graph.output[0].type.tensor_type.elem_type == onnx.TensorProto.DOUBLE


def test_onnx_scores_match_torch_on_real_windows_at_two_batch_sizes(
    exported: Path, torch_model: MSVDD, real_windows: Windows
) -> None:
    scorer = OnnxScorer.load(exported)
    assert scorer.threshold_ == torch_model.threshold_
    spread = np.linspace(0, len(real_windows) - 1, 7).round().astype(int)
    for index in (spread[3:4], spread):  # batch sizes 1 and 7
        batch = real_windows.subset(index)
        assert max_relative_difference(scorer.score(batch), torch_model.score(batch)) <= RTOL
    every = scorer.score(real_windows)
    reference = torch_model.score(real_windows)
    assert max_relative_difference(every, reference) <= RTOL
    assert every.dtype == np.float64 and np.ptp(every) > 0  # not a constant score
    clear = np.abs(reference - torch_model.threshold_) > 1e-3 * abs(torch_model.threshold_)
    assert np.array_equal(scorer.predict(real_windows)[clear], torch_model.predict(real_windows)[clear])


def test_streaming_scorer_takes_the_onnx_backend(
    exported: Path, torch_model: MSVDD, tiny_dataset: Path
) -> None:
    episode_id = open_dataset(tiny_dataset).rows("test")[0].episode
    episode = read_episode(tiny_dataset / episode_id)
    seconds = 5.0
    audio = episode.audio[: int(44100 * seconds)]
    imu, imu6 = episode.imu_vel_z[: int(200 * seconds)], episode.imu6[: int(200 * seconds)]
    results = []
    for backend in (torch_model, OnnxScorer.load(exported)):
        scorer = StreamingScorer(backend, hop_s=0.5)
        emitted = scorer.push(audio[:50_000], imu[:200], imu6[:200])
        emitted += scorer.push(audio[50_000:], imu[200:], imu6[200:])
        results.append(emitted)
    (torch_out, onnx_out) = results
    assert [s for s, _ in onnx_out] == [s for s, _ in torch_out] and len(onnx_out) >= 5
    got, want = np.array([v for _, v in onnx_out]), np.array([v for _, v in torch_out])
    assert max_relative_difference(got, want) <= RTOL


def test_export_api_for_the_papers_waveform_configuration(tmp_path: Path) -> None:
    train, _ = toy_windows(48, 0, seed=0)
    model = MSVDD(MSVDDConfig.smoke(epochs=1, val_fraction=0.0)).fit(train)  # waveform, z-velocity, mean Rec
    manifest = export_onnx(model, tmp_path / "paper", ExportOptions(example_windows=3, check_windows=4))
    assert manifest.inputs == ("audio", "imu") and manifest.parity_max_rel <= RTOL
    scorer = OnnxScorer.load(tmp_path / "paper")
    windows, _ = toy_windows(4, 4, seed=5)
    no_imu6 = Windows(audio=windows.audio, imu=windows.imu)
    for n in (1, 7):
        batch = no_imu6.subset(slice(0, n))
        assert max_relative_difference(scorer.score(batch), model.score(batch)) <= RTOL
    assert scorer.score(no_imu6.subset(slice(0, 0))).shape == (0,)


@pytest.mark.parametrize(
    "overrides",
    [
        {"use_mahalanobis": False},
        {"use_reconstruction": False},
        {"use_imu": False},
        {"use_audio": False},
        {"fusion": "concat"},
        {"audio_frontend": "logmel"},
        {"imu_input": "all", "smooth_window": 0},
        {"audio_frontend": "logmel", "imu_input": "all", "frame_density": True},
        {"frame_density": True},
        {"use_audio": False, "frame_density": True},
        {"svdd_fit": "frozen", "bias_free": True},
        {"svdd_fit": "frozen", "bias_free": True, "use_mahalanobis": False},
        {"svdd_fit": "frozen", "bias_free": True, "pooling": "modulation"},
    ],
    ids=lambda o: "-".join(f"{k}={v}" for k, v in o.items()),
)
def test_score_graph_reproduces_msvdd_score_for_every_variant(overrides: dict[str, object]) -> None:
    """The graph that is exported, run in torch: every ablation and front end gives MSVDD.score."""
    train, _ = toy_windows(48, 0, seed=0)
    model = MSVDD(MSVDDConfig.smoke(epochs=1, val_fraction=0.0, **overrides)).fit(train)
    batch, _ = toy_windows(3, 3, seed=2)
    graph = ScoreGraph(model).eval()
    with torch.inference_mode():
        got = graph(*(torch.from_numpy(x) for x in (batch.audio, batch.imu, batch.imu6))).numpy()
    assert max_relative_difference(got, model.score(batch)) <= RTOL


def test_score_graph_refuses_a_model_that_reads_odometry() -> None:
    train, _ = toy_windows(48, 0, seed=0)
    cfg = MSVDDConfig.smoke(epochs=1, val_fraction=0.0, svdd_fit="frozen", bias_free=True, order_view=True)
    model = MSVDD(cfg).fit(train)
    with pytest.raises(ValueError, match=r"order_view=True.*odometry"):
        ScoreGraph(model)


def test_rewritten_graph_pieces_match_what_they_stand_for() -> None:
    """The 2-D audio encoder, the polyphase decoder, the matrix log-mel, Huber and the block peak: the
    modules and functions of `MSVDD.score` they replace give the same numbers."""
    torch.manual_seed(0)
    rng = np.random.default_rng(0)
    audio = rng.standard_normal((2, 8820, 2)).astype(np.float32)
    x = torch.from_numpy(audio)
    encoder, decoder = AudioEncoder(8).eval(), AudioDecoder(8).eval()
    with torch.inference_mode():
        tokens = encoder(x)
        assert torch.allclose(AudioEncoder2d(encoder)(x.transpose(1, 2).unsqueeze(2)), tokens, atol=1e-5)
        rebuilt = AudioDecoder2d(decoder)(tokens)[:, :, 0].transpose(1, 2)
        assert torch.allclose(rebuilt, decoder(tokens), atol=1e-5)
        for stride, pad in (
            (1, 1),
            (2, 2),
            (3, 2),
            (5, 3),
            (4, 1),
            (2, 0),
            (2, 5),
        ):  # kernel = stride + 2 pad
            deconv = torch.nn.ConvTranspose1d(3, 5, stride + 2 * pad, stride=stride, padding=pad).eval()
            signal = torch.randn(2, 3, 7)
            assert torch.allclose(
                PolyphaseUpsample(deconv)(signal.unsqueeze(2))[:, :, 0], deconv(signal), atol=1e-5
            )
        logmel = LogMel()(x).numpy()
    expected = log_mel_frames(
        audio, AUDIO_RATE, LOGMEL_N_FFT, LOGMEL_HOP, LOGMEL_N_MELS, LOGMEL_F_MIN, AUDIO_RATE / 2, False
    )
    assert logmel.shape == expected.shape and np.abs(logmel - expected).max() < 1e-4
    with pytest.raises(ValueError, match="unsupported"):
        PolyphaseUpsample(torch.nn.ConvTranspose1d(3, 5, 4, stride=2, padding=0))
    target, recon = torch.randn(3, 8820, 2) * 2, torch.randn(3, 8820, 2) * 2
    err = F.huber_loss(recon, target, reduction="none", delta=1.0)
    assert torch.allclose(huber(target, recon), err, atol=1e-6)


@pytest.mark.parametrize("layers", [1, 2])
def test_export_lstm_is_the_lstm_it_replaces(layers: int) -> None:
    torch.manual_seed(layers)
    lstm = torch.nn.LSTM(12, 5, num_layers=layers, batch_first=True).eval()
    x = torch.randn(3, 9, 12)
    with torch.inference_mode():
        out, state = ExportLSTM(lstm)(x)
        assert state is None
        assert torch.allclose(out, lstm(x)[0], rtol=0, atol=1e-6)  # the same arithmetic, gates reordered
    for bad in (
        torch.nn.LSTM(12, 5, bidirectional=True, batch_first=True),
        torch.nn.LSTM(12, 5),  # time first
        torch.nn.LSTM(12, 5, proj_size=2, batch_first=True),
    ):
        with pytest.raises(ValueError, match="unsupported LSTM"):
            ExportLSTM(bad)


def test_exported_lstms_start_from_zeros_and_are_squeezed(exported: Path) -> None:
    """Each LSTM layer is one ONNX LSTM node without initial states (ONNX Runtime starts from zeros), its
    output goes straight into a Squeeze, and no Shape node computes anything for them."""
    graph = onnx.load(str(exported / ONNX_FILE)).graph
    lstms = [node for node in graph.node if node.op_type == "LSTM"]
    # the log-mel encoder's, the IMU encoder's two layers and the IMU decoder's two (`msvdd` scores its
    # decoders' reconstruction error)
    assert len(lstms) == 5
    readers = {name: node.op_type for node in graph.node for name in node.input}
    assert all(len(node.input) == 4 and readers[node.output[0]] == "Squeeze" for node in lstms)
    assert not [node for node in graph.node if node.op_type == "Shape"]


def test_export_refusals(
    exported: Path,
    tiny_model: Path,
    real_windows: Windows,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert main(["export", str(tiny_model), "--out", str(exported)]) == 2
    assert "not empty" in capsys.readouterr().err
    assert main(["export", str(tmp_path / "nothing"), "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "nothing" in err
    with pytest.raises(WindowError, match="imu6"):
        OnnxScorer.load(exported).score(Windows(audio=real_windows.audio[:1], imu=real_windows.imu[:1]))
    broken = tmp_path / "broken"
    broken.mkdir()
    (broken / MANIFEST_FILE).write_text(json.dumps({"format": "msvdd-onnx", "format_version": 99}))
    with pytest.raises(OnnxFormatError, match="format_version 99"):
        OnnxScorer.load(broken)
    with pytest.raises(FileNotFoundError, match=MANIFEST_FILE):
        OnnxScorer.load(tmp_path)
    with pytest.raises(NotFittedError):
        export_onnx(MSVDD(MSVDDConfig.smoke()), tmp_path / "unfitted")
    with pytest.raises(ValueError, match="example_windows"):
        ExportOptions(example_windows=1)


def test_parity_is_measured_against_the_scale_of_the_scores() -> None:
    # A window scoring 1e-9 that comes out 2e-9 is no difference at the scale of scores near 1.
    assert max_relative_difference(np.array([1.0, 2e-9]), np.array([1.0, 1e-9])) == pytest.approx(1e-9)
    assert max_relative_difference(np.array([2.0, 4.0]), np.array([1.0, 2.0])) == pytest.approx(1.0)
    assert max_relative_difference(np.array([-3.0, 1.0]), np.array([-2.0, 1.0])) == pytest.approx(0.5)
    assert max_relative_difference(np.zeros(0), np.zeros(0)) == 0.0
