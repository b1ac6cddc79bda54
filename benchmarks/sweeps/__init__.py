"""Difficulty curves: `msvdd-bench sweep SPEC.toml --out DIR`.

A sweep spec (`spec`) names a base preset, dataset seeds, methods and one swept axis (fault severity, SNR,
driving or obstacle-approach speed, or an unseen test domain: robot units, floor surfaces, environments).
Each point is a preset derived from the base with `dataclasses.replace`, so it is reproducible on its own;
`run` generates, trains and scores every point (one task per point and dataset seed, on an executor), and
`report` writes the curves: Markdown and JSON tables and PNG plots, AUC with episode-cluster bootstrap
intervals, one line per method.
"""
