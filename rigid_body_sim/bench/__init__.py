"""``rigid-body-sim bench``: work-precision, stability, long-horizon, batch and live benchmarks.

    rigid-body-sim bench [--quick] [--out DIR] [--peers]

One process run measures every section, prints tables and writes CSV + PNG files into DIR:
work_precision.csv, stability.csv, long_horizon.csv, batch.csv, sampling.csv, live.json,
exact_horizon.csv,
generated.csv (auto against each generated scene's oracle),
targets.csv, targets.md, summary.md (:mod:`.report`: the benchmarks page's figures from
these files), work_precision_<scene>.png, stability.png, long_horizon.png. Times
are process CPU seconds (``time.process_time``), so they include Python overhead — ours and
scipy's alike; MuJoCo and Basilisk step in C. ``sections.SECTIONS`` lists the sections in run
order; each is a module here: workprecision, stability, longhorizon, batch, perstep, sampling,
live, selection, generated, compile, exact_horizon (with reference40, the 40-digit reference;
mpmath); scenes (data), peers, targets and charts serve them. Standalone load, soak, fault
and host tools are in :mod:`rigid_body_sim.tools`.
"""
# The command lives in :mod:`.command` (its arguments, numba-free for --help) and
# :mod:`.suite` (the run), not here: a package that imports its modules makes
# ``python -m rigid_body_sim.bench.<module>`` warn (runpy: found in sys.modules before
# execution), and makes every tool importing ``bench.common`` load the whole suite.
