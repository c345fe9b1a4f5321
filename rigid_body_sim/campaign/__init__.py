"""Monte Carlo campaigns: many runs of a scene with dispersed parameters, on Dask.

* :mod:`.dispersions` — dispersions as data (``KEY=normal:SIGMA``), one draw per run.
* :mod:`.metrics` — per-run metrics from the sample stream (definitions in its docstring).
* :mod:`.runner` — the pure per-run function and the Dask driver.
* :mod:`.store` — the Parquet dataset, written incrementally.
* :mod:`.report` — summary table, worst runs, plots.
* :mod:`.cli` — ``rigid-body-sim campaign SCENE``.
"""
