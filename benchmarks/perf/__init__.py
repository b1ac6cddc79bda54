"""One module per performance stage; each exposes `STAGE: benchmarks.perf.base.PerfStage`."""
