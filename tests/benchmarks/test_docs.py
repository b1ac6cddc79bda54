"""The generated documentation (`msvdd-bench docs`): every figure comes from a results file, a results file
reads back into its own report, and the hand-written pages restate no measured figure."""

from __future__ import annotations

import json
import re
import sys
import types
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from benchmarks import methods
from benchmarks.cli import main
from benchmarks.dataset import open_dataset
from benchmarks.docs_pages import DocsTargets, read_perf, render, replace_block
from benchmarks.errors import UserError
from benchmarks.methods.external import external_spec
from benchmarks.pipeline import train_method
from benchmarks.report import markdown
from benchmarks.results_file import ResultsFileError, read_results
from msvdd.synthetic import toy_windows

ROOT = Path(__file__).resolve().parents[2]
DECIMAL = re.compile(r"(?<![\w.])[+-]?\d+\.\d+(?![\w.])")
"""A figure written with a decimal point (versions such as 0.1.0 and names such as msvdd-s64 do not match)."""
DATE = re.compile(r"20[0-9]{2}-[0-9]{2}-[0-9]{2}")
PERF = {
    "machine": {"platform": "Linux-test", "processor": "x86_64", "cpus": 2},
    "quick": True,
    "command": "msvdd-bench perf --stage sim --quick --json perf.json",
    "code_version": "msvdd-bench 0.1.0",
    "descriptions": {"sim_rtf": "simulated s per CPU s", "sim_overhead_vs_bare": "simulate() / bare loop"},
    "sim_rtf": 181.234567,
    "sim_overhead_vs_bare": 1.1875,
}


@pytest.fixture(scope="module")
def fixture_run(tiny_dataset: Path, tiny_model: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A run folder of `evaluate` on the tiny dataset: M-SVDD, the reference and both naive baselines."""
    root = tmp_path_factory.mktemp("docs-run")
    data = open_dataset(tiny_dataset)
    models = [str(tiny_model)]
    for name in ("gaussian-early", "audio-rms", "imu-kurtosis"):
        models.append(str(train_method(data, name, 0, "smoke", root / name).path))
    run = root / "run"
    args = ["evaluate", "--data", str(tiny_dataset), "--model", *models, "--out", str(run), "--no-progress"]
    assert main(args) == 0
    return run


def _allowed(doc: Any) -> set[str]:
    """Every way the report and the docs write a number of a parsed JSON document, and every decimal figure
    inside its strings (a command line, a machine)."""
    out: set[str] = set()
    if isinstance(doc, bool) or doc is None:
        return out
    if isinstance(doc, int | float):
        v = float(doc)
        for x in (v, 100.0 * v):
            out |= {f"{x:.1f}", f"{x:+.1f}", f"{x:.2f}", f"{x:.3f}", f"{x:.4g}"}
        return out
    if isinstance(doc, str):
        return set(DECIMAL.findall(doc))
    values = doc.values() if isinstance(doc, dict) else doc
    for value in values:
        out |= _allowed(value)
    return out


def _pages(run: Path, tmp: Path) -> dict[Path, str]:
    """The pages `msvdd-bench docs` writes for the fixture run and PERF, into a README and a detectors page
    made for the test."""
    perf = tmp / "perf.json"
    perf.write_text(json.dumps(PERF))
    readme, detectors = tmp / "README.md", tmp / "detectors.md"
    readme.write_text("intro\n<!-- results:begin -->\nold\n<!-- results:end -->\noutro\n")
    detectors.write_text("# Detectors\n<!-- methods:begin -->\n<!-- methods:end -->\nmore\n")
    targets = DocsTargets(results=tmp / "docs" / "results.md", readme=readme, detectors=detectors)
    return render([read_results(run)], read_perf(perf), targets)


def test_a_results_file_reads_back_into_its_own_report(fixture_run: Path) -> None:
    back = read_results(fixture_run)
    assert set(back.per_method) == {"msvdd", "gaussian-early", "audio-rms", "imu-kurtosis"}
    assert back.intervals is not None and back.intervals.naive_vs_best is not None
    assert back.info.code_version.startswith("msvdd-bench ")
    again = markdown(back.info, back.per_method, back.intervals)
    assert again == (fixture_run / "results.md").read_text()


def test_every_figure_of_the_generated_pages_comes_from_the_results_files(
    fixture_run: Path, tmp_path: Path
) -> None:
    pages = _pages(fixture_run, tmp_path)
    allowed = _allowed(json.loads((fixture_run / "results.json").read_text())) | _allowed(PERF)
    # the method list's figures are settings, from the descriptors; the other pages' come from results
    specs = [methods.spec(n) for n in methods.names()]
    settings = {f for spec in specs for f in DECIMAL.findall(f"{spec.config} {spec.description}")}
    assert len(pages) == 3
    for path, text in pages.items():
        figures = DECIMAL.findall(text)
        known = settings if path.name == "detectors.md" else allowed
        assert figures, path
        stray = sorted({f for f in figures if f not in known and f.lstrip("+") not in known})
        assert stray == [], (path.name, stray)
    results = pages[tmp_path / "docs" / "results.md"]
    doc = json.loads((fixture_run / "results.json").read_text())
    assert doc["dataset_sha256"] in results and doc["code_version"] in results and doc["machine"] in results
    assert doc["command"] in results and "181.2" in results  # the perf figure, as `perf` prints it
    readme = pages[tmp_path / "README.md"]
    assert readme.startswith("intro\n<!-- results:begin -->\n")
    assert readme.endswith("<!-- results:end -->\noutro\n")
    block = readme.split("<!-- results:begin -->\n")[1].split("\n<!-- results:end -->")[0]
    lines = block.splitlines()
    assert lines[1].startswith("Preset `tiny`, dataset seed 0, one training seed per method, written by")
    assert f"written by `{' '.join(doc['command'].split()[:2])}`;" in lines[1]
    assert doc["command"] not in lines[1] and "runs/" not in block  # the whole command: docs/results.md
    assert lines[3].startswith("**This test set cannot rank") or lines[3].startswith("**Ranking**")
    assert doc["naive_verdict"] == lines[-1]
    assert DATE.search(block) is None
    methods_page = pages[tmp_path / "detectors.md"]
    assert all(f"| `{name}` |" in methods_page for name in methods.names())


def test_docs_command_writes_then_checks(
    fixture_run: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    Path("README.md").write_text("<!-- results:begin -->\n<!-- results:end -->\n")
    assert main(["docs", str(fixture_run)]) == 0
    assert Path("docs/results.md").is_file() and "| **M-SVDD (ours)** |" in Path("README.md").read_text()
    assert main(["docs", str(fixture_run), "--check"]) == 0
    Path("docs/results.md").write_text("edited by hand\n")
    assert main(["docs", str(fixture_run), "--check"]) == 1
    assert main(["docs", str(tmp_path / "nowhere")]) == 2
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "results.json").write_text('{"methods": {}}')
    with pytest.raises(ResultsFileError, match="holds no method"):
        read_results(bad)
    (bad / "results.json").write_text('{"methods": {"x": {}}}')
    with pytest.raises(ResultsFileError, match="is not a results file of this code"):
        read_results(bad)


def test_a_block_needs_its_two_markers() -> None:
    assert replace_block("a\n<!-- x:begin -->\nold\n<!-- x:end -->\nb", "x", "new", "f") == (
        "a\n<!-- x:begin -->\nnew\n<!-- x:end -->\nb"
    )
    for text in ("no markers", "<!-- x:end -->\n<!-- x:begin -->", "<!-- x:begin -->" * 2 + "<!-- x:end -->"):
        with pytest.raises(UserError, match="needs one <!-- x:begin --> line"):
            replace_block(text, "x", "new", "f")


def _outside_blocks(text: str) -> str:
    """`text` without its generated blocks."""
    return re.sub(r"<!-- (\w+):begin -->.*?<!-- \1:end -->", "", text, flags=re.S)


def test_the_hand_written_pages_restate_no_measured_figure() -> None:
    pages = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
    interval = re.compile(r"\d+\.\d+ \[[-+]?\d+\.\d+, [-+]?\d+\.\d+\]")
    auc = re.compile(r"\bAUC (of )?[-+]?\d+\.\d")
    for page in pages:
        if page.name == "results.md":
            continue  # written whole by the generator
        text = _outside_blocks(page.read_text(encoding="utf-8"))
        assert interval.search(text) is None, page
        assert auc.search(text) is None, page
        assert DATE.search(text) is None, page
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert len(readme.splitlines()) <= 300
    assert re.search(r"runs/(?!demo\b)", _outside_blocks(readme)) is None  # no run folder but the demo's
    commit = re.compile(r"\b(?=[0-9a-f]*\d)(?=[0-9a-f]*[a-f])[0-9a-f]{7,40}\b")
    assert commit.search(_outside_blocks(readme)) is None
    headings = [line for line in readme.splitlines() if line.startswith("## ")]
    assert headings[:4] == ["## Two commands", "## Results", "## Bring your own detector", "## Quick start"]
    assert "make demo" in readme and "make test" in readme


def test_the_readme_detector_follows_the_contract(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    code = readme.split("```python\n# mydetectors.py\n", 1)[1].split("```", 1)[0]
    module = types.ModuleType("mydetectors")
    exec(compile(code, "mydetectors.py", "exec"), module.__dict__)
    monkeypatch.setitem(sys.modules, "mydetectors", module)
    spec = external_spec("mydetectors:Energy")
    assert spec.family == "external" and spec.modality == "audio"
    train, _ = toy_windows(30, 0, seed=1)
    val, _ = toy_windows(25, 0, seed=2)
    det = spec.factory(0, "smoke", "cpu").fit(train, val)
    assert np.isfinite(det.threshold_) and det.threshold_source_ == "val"  # type: ignore[attr-defined]
    det.save(tmp_path / "m.json")
    again = spec.cls.load(tmp_path / "m.json")
    test, _ = toy_windows(3, 3, seed=3)
    np.testing.assert_array_equal(again.predict(test), det.predict(test))
