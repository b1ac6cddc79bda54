"""The `msvdd` package: its public names, and that reading the window contract does not import torch."""

from __future__ import annotations

import subprocess
import sys

import pytest

import msvdd


def test_every_public_name_resolves_to_its_module() -> None:
    assert sorted(msvdd.__all__) == sorted(msvdd._MODULE_OF)
    for name in msvdd.__all__:
        value = getattr(msvdd, name)
        assert value.__module__ == msvdd._MODULE_OF[name], name
    assert set(msvdd.__all__) <= set(dir(msvdd))
    with pytest.raises(AttributeError, match="no_such_name"):
        msvdd.no_such_name  # noqa: B018


def test_dataset_generation_does_not_import_torch() -> None:
    # Every worker process `generate` spawns imports this; torch alone took about 2 of its 5 s.
    code = "import sys, benchmarks.dataset, msvdd.preprocess; print('torch' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
