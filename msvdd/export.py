"""Export a fitted `MSVDD`'s scoring path to ONNX: `export_onnx(model, folder)`.

The graph is `msvdd.score_graph.ScoreGraph`: window arrays in (audio (N, 8820, 2), imu (N, 400) and, for a
model that reads all IMU axes, imu6 (N, 400, 6), float32), the final anomaly score out ((N,) float64). It
holds the audio front end (waveform normalisation and smoothing, or the log-mel spectrogram), the input
normaliser, the encoders, fusion and decoders, the Mahalanobis distance to mu with the fitted inverse
covariance, and the reconstruction term. It is exported with torch's dynamo exporter
(`torch.onnx.export(..., dynamo=True)`) from an example batch of `ExportOptions.example_windows` windows with
a dynamic batch dimension; each LSTM layer is one `msvdd.score_graph.lstm_layer` op, which becomes one ONNX
LSTM node (`_onnx_lstm_layer`).

What stays in numpy (in `msvdd.onnx_backend.OnnxScorer.score`): checking the `Windows` batch and casting its
arrays to contiguous float32. Decimation from 44.1 kHz is not part of scoring (`MSVDD.score` reads decimated
windows too). The decision `score > threshold_` is `OnnxScorer.predict`.

At export the graph is run on ONNX Runtime over check windows and compared with `MSVDD.score`; a difference
above `ExportOptions.rtol` relative to the largest score (`max_relative_difference`) is an `ExportError` and
nothing is written. The folder is written whole or not at all (built in a hidden temporary folder beside it,
then renamed into place).
"""

from __future__ import annotations

import contextlib
import dataclasses
import io
import json
import logging
import os
import shutil
import tempfile
import warnings
from collections.abc import Iterator
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path
from typing import Any, cast

import numpy as np
import onnx
import torch
from onnxscript import INT64
from onnxscript import opset18 as op

from msvdd.contract import Windows
from msvdd.model import MSVDD, NotFittedError
from msvdd.onnx_backend import (
    MANIFEST_FILE,
    ONNX_FILE,
    ExportManifest,
    OnnxScorer,
)
from msvdd.score_graph import ScoreGraph
from msvdd.synthetic import toy_windows

TOY_SOURCE = "msvdd.synthetic.toy_windows (no dataset given)"
"""`parity_source` when the check windows are the synthetic toy windows."""


class ExportError(RuntimeError):
    """The exported graph does not reproduce `MSVDD.score` (a bug, not bad input)."""


@dataclass(frozen=True)
class ExportOptions:
    """How `export_onnx` traces and checks the graph."""

    example_windows: int = 2
    """Windows in the example batch the exporter traces (>= 2: a batch of one would fix the batch size)."""
    opset: int = 20
    """ONNX opset version of the exported graph."""
    rtol: float = 1e-4
    """Largest difference between ONNX Runtime's and `MSVDD.score`'s scores accepted at export, relative to
    the largest score (`max_relative_difference`)."""
    check_windows: int = 16
    """Check windows scored both ways at export (the first of the windows given, or toy windows)."""

    def __post_init__(self) -> None:
        _check(self.example_windows >= 2, "example_windows", self.example_windows, ">= 2")
        _check(self.opset >= 18, "opset", self.opset, ">= 18")
        _check(0 < self.rtol < 1, "rtol", self.rtol, "0 < rtol < 1")
        _check(self.check_windows >= 1, "check_windows", self.check_windows, ">= 1")


def _check(ok: bool, name: str, value: object, allowed: str) -> None:
    if not ok:
        raise ValueError(f"ExportOptions.{name} = {value!r}; allowed: {allowed}")


def _versions() -> dict[str, str]:
    found: dict[str, str] = {}
    for dist in ("torch", "onnx", "onnxscript", "onnxruntime", "msvdd-bench"):
        with contextlib.suppress(metadata.PackageNotFoundError):
            found[dist] = metadata.version(dist)
    return found


@contextlib.contextmanager
def _quiet_exporter() -> Iterator[None]:
    """Silence the exporter's progress lines and its warnings about torch internals (not about our model)."""
    loggers = [
        logging.getLogger(name) for name in ("torch.onnx", "torch.export", "torch._dynamo", "onnxscript")
    ]
    levels = [lg.level for lg in loggers]
    try:
        for lg in loggers:
            lg.setLevel(logging.ERROR)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", category=FutureWarning)
            warnings.simplefilter("ignore", category=UserWarning)
            warnings.simplefilter("ignore", category=DeprecationWarning)
            with contextlib.redirect_stdout(io.StringIO()):
                yield
    finally:
        for lg, level in zip(loggers, levels, strict=True):
            lg.setLevel(level)


def _arrays(batch: Windows, names: tuple[str, ...]) -> tuple[torch.Tensor, ...]:
    values = {"audio": batch.audio, "imu": batch.imu, "imu6": batch.imu6}
    return tuple(torch.from_numpy(np.ascontiguousarray(values[n], dtype=np.float32)) for n in names)


def _onnx_lstm_layer(x: Any, w: Any, r: Any, b: Any) -> Any:
    """ONNX translation of `msvdd.score_graph.lstm_layer`: one LSTM node on the time-major input, its
    (T, 1, N, H) output squeezed and back to batch first."""
    y, _, _ = op.LSTM(op.Transpose(x, perm=[1, 0, 2]), w, r, b, hidden_size=r.shape[2])
    direction_axis = cast(INT64, op.Constant(value_ints=[1]))
    return op.Transpose(op.Squeeze(y, direction_axis), perm=[1, 0, 2])


def export_graph(model: MSVDD, path: Path, options: ExportOptions) -> tuple[str, ...]:
    """Write the ONNX graph of `model`'s scoring path to `path`; returns the graph's input names.

    Raises:
        NotFittedError: the model is not fitted.
    """
    graph = ScoreGraph(model).eval()
    names = ("audio", "imu", "imu6") if model.config.imu_input == "all" else ("audio", "imu")
    example, _ = toy_windows(options.example_windows, 0, seed=0)
    batch = torch.export.Dim("batch", min=1)
    with _quiet_exporter():
        program = torch.onnx.export(
            graph,
            _arrays(example, names),
            dynamo=True,
            input_names=list(names),
            output_names=["score"],
            dynamic_shapes=tuple({0: batch} for _ in names),
            opset_version=options.opset,
            verbose=False,
            custom_translation_table={torch.ops.msvdd.lstm_layer.default: _onnx_lstm_layer},
        )
    if program is None:
        raise ExportError("torch.onnx.export returned no ONNX program")
    proto = program.model_proto
    onnx.checker.check_model(proto)
    onnx.save_model(proto, str(path))
    return names


def max_relative_difference(scores: np.ndarray, reference: np.ndarray) -> float:
    """max |scores - reference| / max |reference|: the largest difference relative to the scale of the scores.

    Relative to each window's own score it would blow up on windows that score near 0, where a score is a
    small difference of larger float32 terms whose rounding depends on the CPU's kernels (a toy model's
    1.2e-4 on one AMD EPYC, 1e-6 elsewhere); a difference that could move a decision is one on the scale of
    the scores. The reference's largest magnitude is floored at 1e-12.
    """
    ref = np.asarray(reference, dtype=np.float64)
    if ref.size == 0:
        return 0.0
    diff = np.abs(np.asarray(scores, dtype=np.float64) - ref)
    return float(diff.max() / max(float(np.abs(ref).max()), 1e-12))


def export_onnx(
    model: MSVDD,
    folder: str | os.PathLike[str],
    options: ExportOptions | None = None,
    check: Windows | None = None,
    check_source: str = TOY_SOURCE,
    method: str | None = None,
) -> ExportManifest:
    """Export `model`'s scoring path to `folder` (`model.onnx` and `scorer.json`) and check it.

    Args:
        model: a fitted `MSVDD` (left as it is: the graph holds a CPU copy of its network).
        folder: the export folder to create; it must not exist or be empty.
        options: tracing and checking options (`ExportOptions()` by default).
        check: windows scored by ONNX Runtime and `MSVDD.score` (the first `options.check_windows`);
            None: synthetic toy windows.
        check_source: where `check` came from, recorded in `scorer.json`.
        method: registry name of the method, recorded in `scorer.json`.

    Raises:
        NotFittedError: the model is not fitted.
        FileExistsError: `folder` exists and is not an empty folder.
        ExportError: ONNX Runtime's scores differ from `MSVDD.score`'s by more than `options.rtol`.
    """
    opts = options or ExportOptions()
    if model.normalizer is None or model.mu_ is None or model.sigma_ is None:
        raise NotFittedError("MSVDD is not fitted: call fit() or MSVDD.load() before exporting")
    target = Path(folder)
    if target.exists() and (not target.is_dir() or any(target.iterdir())):
        raise FileExistsError(f"export folder {target} exists and is not empty")
    if check is None:
        check, check_source = toy_windows(opts.check_windows, 0, seed=1)[0], TOY_SOURCE
    check = check.subset(slice(0, opts.check_windows))
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent))
    try:
        names = export_graph(model, tmp / ONNX_FILE, opts)
        manifest = ExportManifest(
            threshold=float(model.threshold_),
            inputs=names,
            audio_frontend=model.config.audio_frontend,
            imu_input=model.config.imu_input,
            opset=opts.opset,
            parity_max_rel=float("nan"),
            parity_windows=len(check),
            parity_source=check_source,
            config=model.config.to_dict(),
            method=method,
            versions=_versions(),
        )
        scorer = OnnxScorer.load_graph(tmp / ONNX_FILE, manifest, tmp)
        gap = max_relative_difference(scorer.score(check), model.score(check))
        if not gap <= opts.rtol:
            raise ExportError(
                f"the exported graph's scores differ from MSVDD.score by {gap:.3g} relative "
                f"(allowed {opts.rtol:g}) on {len(check)} windows of {check_source}"
            )
        manifest = dataclasses.replace(manifest, parity_max_rel=gap)
        (tmp / MANIFEST_FILE).write_text(json.dumps(manifest.to_dict(), indent=2) + "\n", encoding="utf-8")
        os.chmod(tmp, 0o755)
        os.replace(tmp, target)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return manifest
