"""The benchmark: presets, datasets, methods, metrics, reports, performance runs, CLI and Rerun views."""
