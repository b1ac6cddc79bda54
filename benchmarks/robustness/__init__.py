"""`msvdd-bench robustness`: how detectors' AUC holds up when the test streams are perturbed at scoring time.

`perturb` holds the perturbations (pure functions on arrays), `run` scores saved models on clean and
perturbed test windows with episode-cluster bootstrap intervals, `report` writes the table, JSON and plot.
"""
