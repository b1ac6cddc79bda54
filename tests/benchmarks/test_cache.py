"""The dataset cache: an entry is reused while it verifies, regenerated when corrupt, keyed by its recipe."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

import benchmarks.cache as cache_mod
from benchmarks.cache import cache_entry, cache_key, cached_dataset
from benchmarks.cli import main
from benchmarks.dataset import open_dataset


@pytest.fixture()
def fake_generate(tiny_dataset: Path, monkeypatch: pytest.MonkeyPatch) -> list[Path]:
    """`generate` replaced by a copy of the session's tiny dataset; the list records each call's target."""
    calls: list[Path] = []

    def generate(
        preset: str,
        seed: int,
        out: Path,
        workers: int | None = None,
        progress: bool = True,
        executor: object = None,
    ) -> Path:
        assert (preset, seed) == ("tiny", 0)
        calls.append(Path(out))
        shutil.copytree(tiny_dataset, out)
        return Path(out)

    monkeypatch.setattr(cache_mod, "generate", generate)
    return calls


def test_the_key_follows_preset_seed_and_the_generating_code(monkeypatch: pytest.MonkeyPatch) -> None:
    key = cache_key("tiny", 0)
    assert key == cache_key("tiny", 0) and len(key) == cache_mod.KEY_LENGTH
    assert key != cache_key("tiny", 1) and key != cache_key("ci", 0)
    monkeypatch.setattr(cache_mod, "generator_digest", lambda: "other code")
    assert cache_key("tiny", 0) != key
    assert cache_entry(Path("c"), "tiny", 0).name.startswith("tiny-seed0-")


def test_an_entry_is_generated_once_then_reused(fake_generate: list[Path], tmp_path: Path) -> None:
    path, reused = cached_dataset(tmp_path / "cache", "tiny", 0, progress=False)
    assert not reused and fake_generate == [path] and path == cache_entry(tmp_path / "cache", "tiny", 0)
    again, reused = cached_dataset(tmp_path / "cache", "tiny", 0, progress=False)
    assert reused and again == path and len(fake_generate) == 1


def test_a_corrupt_entry_is_generated_again(
    fake_generate: list[Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path, _ = cached_dataset(tmp_path, "tiny", 0, progress=False)
    (path / "windows.csv").write_text("window_id\n")  # a truncated restore
    again, reused = cached_dataset(tmp_path, "tiny", 0, progress=False)
    assert not reused and again == path and len(fake_generate) == 2
    assert "does not verify" in capsys.readouterr().out
    open_dataset(path)  # verifies again
    assert [p.name for p in tmp_path.iterdir()] == [path.name]  # the corrupt copy is gone


def test_run_with_a_cache_reuses_the_entry(
    fake_generate: list[Path], tmp_path: Path, tiny_dataset: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    cache = tmp_path / "cache"
    for name in ("one", "two"):
        code = main(["run", "--preset", "tiny", "--cache", str(cache), "--out", str(tmp_path / name),
                     "--methods", "audio-rms", "--no-progress"])  # fmt: skip
        assert code == 0
    assert len(fake_generate) == 1
    assert "reusing cached dataset" in capsys.readouterr().out
    doc = json.loads((tmp_path / "two" / "results.json").read_text())
    assert doc["dataset"] == str(cache_entry(cache, "tiny", 0))
    assert doc["dataset_sha256"] == open_dataset(tiny_dataset, verify=False).fingerprint
    code = main(["run", "--data", str(tiny_dataset), "--cache", str(cache), "--out", str(tmp_path / "x"),
                 "--methods", "audio-rms", "--no-progress"])  # fmt: skip
    assert code == 2


def test_generate_with_a_cache_prints_the_entry_last(
    fake_generate: list[Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    for _ in range(2):
        assert main(["generate", "--preset", "tiny", "--cache", str(tmp_path), "--no-progress"]) == 0
        last = capsys.readouterr().out.strip().splitlines()[-1]
        assert last == str(cache_entry(tmp_path, "tiny", 0).absolute())
    assert len(fake_generate) == 1
