"""`OnnxScorer`: M-SVDD scoring on ONNX Runtime from a folder written by `msvdd.export.export_onnx`.

The folder holds `model.onnx` (windows in, anomaly scores out: the whole of `MSVDD.score`, see
`msvdd.score_graph`) and `scorer.json` (`ExportManifest`: threshold, window contract, the graph's inputs).
`OnnxScorer.load(folder).score(windows)` gives `MSVDD.score`'s scores (within 1e-4 relative, checked at
export); the only work left in numpy is checking the `Windows` batch and handing its arrays over as
float32. The session runs on the CPU with one thread by default (`intra_op_num_threads=1`, sequential
execution), the setting of a detector that shares a robot's computer; `threads` raises it for batch scoring.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Self

import numpy as np

from msvdd.contract import (
    AUDIO_LEN,
    AUDIO_RATE,
    IMU_LEN,
    IMU_RATE,
    WINDOW_S,
    ModelFormatError,
    WindowError,
    Windows,
)

MANIFEST_FILE = "scorer.json"
"""Name of the export's JSON description inside the folder."""
ONNX_FILE = "model.onnx"
"""Name of the ONNX graph inside the folder."""
EXPORT_FORMAT = "msvdd-onnx"
"""`format` field of `scorer.json`."""
EXPORT_FORMAT_VERSION = 1
"""`format_version` of `scorer.json` that this code writes and reads."""
SCORE_BATCH = 256
"""Windows per ONNX Runtime call (bounds the memory of scoring a large batch)."""
INPUT_SHAPES: dict[str, list[int | str]] = {
    "audio": ["batch", AUDIO_LEN, 2],
    "imu": ["batch", IMU_LEN],
    "imu6": ["batch", IMU_LEN, 6],
}
"""Shape of each graph input ("batch" is the dynamic dimension); every input is float32."""
INPUT_MEANING: dict[str, str] = {
    "audio": f"binaural audio at {AUDIO_RATE:g} Hz (44.1 kHz anti-alias decimated), Windows.audio",
    "imu": f"IMU z-axis velocity at {IMU_RATE:g} Hz, Windows.imu",
    "imu6": f"accelerometer xyz and gyroscope xyz at {IMU_RATE:g} Hz, Windows.imu6",
}
"""What each graph input holds."""
GRAPH_COVERS = (
    "audio front end: waveform z-score and Savitzky-Golay smoothing, or log-mel (Hann frames, DFT, power, "
    "mel filterbank, log) and its z-score",
    "IMU input: z-velocity (and the six accelerometer/gyroscope axes for imu_input 'all'), z-score, "
    "smoothing",
    "network: encoders, fusion, decoders",
    "Mahalanobis distance D = ||L^-1 (z - mu)|| with the fitted Sigma = L L^T (float64)",
    "reconstruction term Rec (per-modality error over rec_scale, summed) and "
    "score = D + w (mean_D / mean_Rec) Rec",
)
"""The steps of `MSVDD.score` inside the graph."""
OUTSIDE_GRAPH = (
    "checking the Windows batch (shapes, rates, finite values) and casting it to contiguous float32 (numpy)",
    "decimating 44.1 kHz audio to the windows' 4410 Hz (msvdd.preprocess / msvdd.stream), as for MSVDD.score",
    "the decision score > threshold (OnnxScorer.predict)",
)
"""What stays outside the graph."""


class OnnxFormatError(ModelFormatError):
    """A folder is not an M-SVDD ONNX export of the supported format version; the message names the file."""


@dataclass(frozen=True)
class ExportManifest:
    """What `scorer.json` says about an exported graph."""

    threshold: float
    """The model's `threshold_` (score > threshold = anomalous), from training data only."""
    inputs: tuple[str, ...]
    """Graph input names in order: ("audio", "imu") or ("audio", "imu", "imu6")."""
    audio_frontend: str
    """The model's audio front end ("waveform" or "logmel"), computed inside the graph."""
    imu_input: str
    """The model's IMU input ("z" or "all": "all" needs Windows.imu6)."""
    opset: int
    """ONNX opset version of the graph."""
    parity_max_rel: float
    """max |onnx - torch| / max |torch| over the check windows at export (torch = MSVDD.score)."""
    parity_windows: int
    """Number of check windows."""
    parity_source: str
    """Where the check windows came from (a dataset folder and split, or the synthetic toy windows)."""
    config: dict[str, Any] = field(default_factory=dict)
    """The model's `MSVDDConfig.to_dict()`, for reference."""
    method: str | None = None
    """Registry name of the exported method, when known."""
    output: str = "score"
    """Graph output name: (batch,) float64 anomaly scores."""
    onnx_file: str = ONNX_FILE
    """The graph's file name inside the folder."""
    versions: dict[str, str] = field(default_factory=dict)
    """Versions of the software that exported the graph (torch, onnx, onnxscript, onnxruntime)."""

    def to_dict(self) -> dict[str, Any]:
        """The JSON object written to `scorer.json` (with the window contract and coverage notes)."""
        return {
            "format": EXPORT_FORMAT,
            "format_version": EXPORT_FORMAT_VERSION,
            "onnx_file": self.onnx_file,
            "method": self.method,
            "threshold": self.threshold,
            "window": {
                "seconds": WINDOW_S,
                "audio_rate_hz": AUDIO_RATE,
                "audio_samples": AUDIO_LEN,
                "audio_channels": 2,
                "imu_rate_hz": IMU_RATE,
                "imu_samples": IMU_LEN,
            },
            "inputs": [
                {"name": n, "shape": INPUT_SHAPES[n], "dtype": "float32", "holds": INPUT_MEANING[n]}
                for n in self.inputs
            ],
            "output": {"name": self.output, "shape": ["batch"], "dtype": "float64", "holds": "anomaly score"},
            "audio_frontend": self.audio_frontend,
            "imu_input": self.imu_input,
            "opset": self.opset,
            "graph_covers": list(GRAPH_COVERS),
            "outside_graph": list(OUTSIDE_GRAPH),
            "parity": {
                "max_rel_diff": self.parity_max_rel,
                "windows": self.parity_windows,
                "source": self.parity_source,
                "reference": "MSVDD.score (torch eager)",
            },
            "config": self.config,
            "versions": self.versions,
        }

    @classmethod
    def from_dict(cls, data: object, source: Path) -> Self:
        """Inverse of `to_dict`; a wrong format, version or field is an `OnnxFormatError` naming `source`."""
        if not isinstance(data, dict) or data.get("format") != EXPORT_FORMAT:
            raise OnnxFormatError(
                f"{source} is not an M-SVDD ONNX export description (format {EXPORT_FORMAT!r})"
            )
        version = data.get("format_version")
        if version != EXPORT_FORMAT_VERSION:
            raise OnnxFormatError(
                f"{source} has format_version {version}; this code reads {EXPORT_FORMAT_VERSION}"
            )
        try:
            inputs = tuple(str(item["name"]) for item in data["inputs"])
            parity = data["parity"]
            manifest = cls(
                threshold=float(data["threshold"]),
                inputs=inputs,
                audio_frontend=str(data["audio_frontend"]),
                imu_input=str(data["imu_input"]),
                opset=int(data["opset"]),
                parity_max_rel=float(parity["max_rel_diff"]),
                parity_windows=int(parity["windows"]),
                parity_source=str(parity["source"]),
                config=dict(data.get("config") or {}),
                method=None if data.get("method") is None else str(data["method"]),
                output=str(data["output"]["name"]),
                onnx_file=str(data["onnx_file"]),
                versions={str(k): str(v) for k, v in (data.get("versions") or {}).items()},
            )
        except (KeyError, TypeError, ValueError) as err:
            raise OnnxFormatError(f"{source}: field {err} is missing or malformed") from err
        unknown = sorted(set(inputs) - set(INPUT_SHAPES))
        if unknown or inputs[:2] != ("audio", "imu"):
            raise OnnxFormatError(f"{source}: inputs {list(inputs)}; expected audio, imu[, imu6]")
        if Path(manifest.onnx_file).name != manifest.onnx_file:
            raise OnnxFormatError(
                f"{source}: onnx_file {manifest.onnx_file!r} must be a file name in the folder"
            )
        return manifest


def session_options(threads: int = 1) -> Any:
    """ONNX Runtime session options: `threads` intra-op threads, one inter-op thread, sequential execution."""
    import onnxruntime as ort

    if threads < 1:
        raise ValueError(f"threads {threads}; allowed: >= 1")
    options = ort.SessionOptions()
    options.intra_op_num_threads = threads
    options.inter_op_num_threads = 1
    options.execution_mode = ort.ExecutionMode.ORT_SEQUENTIAL
    options.graph_optimization_level = ort.GraphOptimizationLevel.ORT_ENABLE_ALL
    return options


def read_manifest(folder: str | os.PathLike[str]) -> ExportManifest:
    """The `ExportManifest` of an export folder.

    Raises:
        FileNotFoundError: the folder or its `scorer.json` does not exist.
        OnnxFormatError: `scorer.json` is not an export description of the supported version.
    """
    path = Path(folder) / MANIFEST_FILE
    if not path.is_file():
        raise FileNotFoundError(f"{path} does not exist (expected a folder written by `msvdd-bench export`)")
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except ValueError as err:
        raise OnnxFormatError(f"{path} is not JSON (expected the file `msvdd-bench export` writes)") from err
    return ExportManifest.from_dict(data, path)


class OnnxScorer:
    """Scores `Windows` with an exported M-SVDD graph on ONNX Runtime: `OnnxScorer.load(folder)`."""

    threshold_: float

    def __init__(self, session: Any, manifest: ExportManifest, folder: Path) -> None:
        self.session = session
        """The `onnxruntime.InferenceSession`."""
        self.manifest = manifest
        """What `scorer.json` says."""
        self.folder = folder
        """The export folder."""
        self.threshold_ = manifest.threshold

    @classmethod
    def load(cls, folder: str | os.PathLike[str], threads: int = 1) -> Self:
        """Open an export folder with an ONNX Runtime CPU session of `threads` intra-op threads.

        Raises:
            FileNotFoundError: the folder, `scorer.json` or the graph file does not exist.
            OnnxFormatError: not an M-SVDD export of the supported version, or a graph that does not
                load or whose inputs differ from what `scorer.json` says.
        """
        root = Path(folder)
        manifest = read_manifest(root)
        graph = root / manifest.onnx_file
        if not graph.is_file():
            raise FileNotFoundError(f"{graph} does not exist (named by {root / MANIFEST_FILE})")
        return cls.load_graph(graph, manifest, root, threads)

    @classmethod
    def load_graph(cls, graph: Path, manifest: ExportManifest, folder: Path, threads: int = 1) -> Self:
        """A scorer of the ONNX file `graph` described by `manifest` (`load` reads both from a folder).

        Raises:
            OnnxFormatError: a graph that does not load, or whose inputs differ from `manifest.inputs`.
        """
        import onnxruntime as ort

        try:
            session = ort.InferenceSession(
                str(graph), sess_options=session_options(threads), providers=["CPUExecutionProvider"]
            )
        except Exception as err:  # onnxruntime raises its own exception types for unreadable graphs
            raise OnnxFormatError(
                f"{graph} is not a loadable ONNX graph: {str(err).splitlines()[0]}"
            ) from err
        names = tuple(i.name for i in session.get_inputs())
        if names != manifest.inputs:
            raise OnnxFormatError(
                f"{graph} has inputs {list(names)} but its description says {list(manifest.inputs)}"
            )
        return cls(session, manifest, folder)

    @property
    def imu_input(self) -> str:
        """The exported model's IMU input: "z", or "all" (the windows must carry `imu6`)."""
        return self.manifest.imu_input

    def _feeds(self, batch: Windows) -> dict[str, np.ndarray]:
        arrays = {"audio": batch.audio, "imu": batch.imu, "imu6": batch.imu6}
        if "imu6" in self.manifest.inputs and batch.imu6 is None:
            raise WindowError(
                'the exported model reads all IMU axes (imu_input "all"): the windows need imu6'
            )
        return {n: np.ascontiguousarray(arrays[n], dtype=np.float32) for n in self.manifest.inputs}

    def score(self, batch: Windows) -> np.ndarray:
        """(N,) float64 anomaly scores, higher = more anomalous (`MSVDD.score`'s, computed by the graph).

        Raises:
            WindowError: not a `Windows` batch, or windows without the `imu6` the model reads.
        """
        if not isinstance(batch, Windows):
            raise WindowError(f"batch must be a msvdd.Windows batch, got {type(batch).__name__}")
        feeds = self._feeds(batch)
        n = len(batch)
        if n == 0:
            return np.zeros(0, dtype=np.float64)
        out = [
            self.session.run([self.manifest.output], {k: v[i : i + SCORE_BATCH] for k, v in feeds.items()})[0]
            for i in range(0, n, SCORE_BATCH)
        ]
        return np.concatenate(out).astype(np.float64, copy=False)

    def predict(self, batch: Windows) -> np.ndarray:
        """(N,) bool: score > threshold_."""
        return self.score(batch) > self.threshold_
