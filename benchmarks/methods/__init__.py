"""Every detector the benchmark runs, by name: M-SVDD, its ablations and the paper's baselines.

from benchmarks.methods import make, names
det = make("iforest-early", seed=0, scale="short").fit(train)
save_detector(det, "iforest-early", "runs/x/model"); name, det = load_detector("runs/x/model")
"""

from benchmarks.methods import dcase_ae as _dcase_ae
from benchmarks.methods import deep as _deep
from benchmarks.methods import deep_if as _deep_if
from benchmarks.methods import frames as _frames
from benchmarks.methods import gaussian as _gaussian
from benchmarks.methods import msvdd_family as _msvdd
from benchmarks.methods import naive as _naive
from benchmarks.methods import orders as _orders
from benchmarks.methods import shallow as _shallow
from benchmarks.methods.base import SCALES
from benchmarks.methods.registry import (
    FAMILIES,
    MODALITIES,
    MethodSpec,
    load_detector,
    make,
    names,
    register,
    save_detector,
    spec,
)

_msvdd.register_methods()
_naive.register_methods()
_shallow.register_methods()
_deep.register_methods()
_deep_if.register_methods()
_dcase_ae.register_methods()
_gaussian.register_methods()
_orders.register_methods()
_frames.register_methods()

__all__ = [
    "FAMILIES",
    "MODALITIES",
    "SCALES",
    "MethodSpec",
    "load_detector",
    "make",
    "names",
    "register",
    "save_detector",
    "spec",
]
