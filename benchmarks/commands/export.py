"""`msvdd-bench export`: an M-SVDD model folder's scoring path as an ONNX graph plus its description.

The folder written holds `model.onnx` (window arrays in, the anomaly score out: front end, normaliser,
network, Mahalanobis distance and reconstruction term; `msvdd.score_graph`) and `scorer.json` (threshold,
window contract, inputs, parity at export). `msvdd.onnx_backend.OnnxScorer.load(DIR)` scores with it on ONNX
Runtime; `msvdd.stream.StreamingScorer` takes either backend.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from benchmarks.command import Command
from benchmarks.errors import OutputExistsError, UserError

SPLITS = ("train", "val", "test")
"""Dataset splits `--split` may name."""


def _add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("model", type=Path, metavar="MODEL", help="M-SVDD model folder (from `train` or `run`)")
    p.add_argument(
        "--out", type=Path, required=True, help="export folder to write (must not exist, or empty)"
    )
    p.add_argument(
        "--data",
        type=Path,
        default=None,
        help="dataset folder whose windows check the graph against torch (default: synthetic toy windows)",
    )
    p.add_argument("--split", choices=SPLITS, default="test", help="split of --data to check on")
    p.add_argument("--check-windows", type=int, default=16, help="windows scored both ways at export")


def _run(args: argparse.Namespace) -> int:
    import numpy as np

    from benchmarks import methods
    from benchmarks.dataset import load_window_rows, open_dataset
    from msvdd.export import ExportOptions, export_onnx
    from msvdd.model import MSVDD

    if args.check_windows < 1:
        raise UserError(f"--check-windows = {args.check_windows}; allowed: an integer >= 1")
    out: Path = args.out
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise OutputExistsError(f"export folder exists and is not empty: {out}")
    name, detector = methods.load_detector(args.model)
    if not isinstance(detector, MSVDD):
        raise UserError(
            f"{args.model} holds method {name!r} (family {methods.spec(name).family!r}); export reads the "
            f"msvdd family only: {', '.join(methods.names('msvdd'))}"
        )
    check = None
    source = "msvdd.synthetic.toy_windows (no --data)"
    if args.data is not None:
        dataset = open_dataset(args.data)
        rows = dataset.rows(args.split)
        if not rows:
            raise UserError(f"{args.data} has no {args.split!r} windows; choose another --split")
        pick = np.unique(
            np.linspace(0, len(rows) - 1, min(args.check_windows, len(rows))).round().astype(int)
        )
        check, _ = load_window_rows(dataset.path, [rows[i] for i in pick])
        source = f"{args.data} split {args.split} ({len(pick)} windows spread over the split)"
    options = ExportOptions(check_windows=args.check_windows)
    manifest = export_onnx(detector, out, options, check=check, check_source=source, method=name)
    print(
        f"exported {name} to {out / manifest.onnx_file} (opset {manifest.opset}, inputs "
        f"{', '.join(manifest.inputs)}); threshold {manifest.threshold:.6g}; ONNX Runtime vs torch: max "
        f"relative difference {manifest.parity_max_rel:.2g} on {manifest.parity_windows} windows"
    )
    return 0


COMMAND = Command(
    name="export",
    help="export an M-SVDD model's scoring path (front end to anomaly score) to ONNX",
    add_arguments=_add_arguments,
    run=_run,
    description=(
        "Export an M-SVDD model folder's scoring path to ONNX with torch's dynamo exporter: the graph reads "
        "window arrays (audio at 4410 Hz, IMU at 200 Hz) and outputs the final anomaly score. The folder "
        "holds model.onnx and scorer.json (threshold, window contract, inputs). At export, ONNX Runtime's "
        "scores are checked against torch's (relative difference <= 1e-4)."
    ),
    example=(
        "msvdd-bench export runs/models/msvdd-seed1 --out runs/onnx/msvdd-seed1\n"
        "msvdd-bench export runs/models/msvdd-seed1 --out runs/onnx/msvdd-seed1 --data runs/demo/dataset"
    ),
)
