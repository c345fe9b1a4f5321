"""The end of a campaign: a summary table, the worst runs by id, and PNG plots.

Statistics are over the runs with status ``ok``; NaN values (a metric that does not apply
to the scene, or a run that never settled) are left out and counted. Plots: one PNG of
histograms (one per metric with data), and per dispersed value one PNG of scatter plots
of each metric against it. A metric equal in every run gets no panel; the histograms'
title names it with its value.
"""
import math
import os
from typing import Dict, List

import numpy as np

from .metrics import NUMERIC

# metric -> (worse is larger?, a never-reached value counts as worst)
WORST = {'final_pointing_error': True, 'settling_time': True, 'detumble_time': True,
         'peak_torque': True, 'angular_momentum_drift': True, 'kinetic_energy_drift': True}
WORST_COUNT = 5
UNITS = {'final_pointing_error': 'rad', 'settling_time': 's', 'detumble_time': 's',
         'peak_torque': 'N·m', 'energy_dissipated': 'J', 'final_angular_momentum': 'kg·m²/s',
         'cpu_time': 's'}


def _label(name) -> str:
    return f'{name} [{UNITS[name]}]' if name in UNITS else name


def _column(table, name) -> np.ndarray:
    return np.asarray(table.column(name).to_numpy(zero_copy_only=False), dtype=float)


def _param_label(col) -> str:
    """A dispersed column with its parameter's unit (from the nodes' specs)."""
    from ..engine import specs
    key = col.split('[')[0]
    unit = next((p.unit for p in specs.SIMULATOR + specs.CONTROLLER
                 if p.name == key and p.unit), '')
    return f'{col} [{unit}]' if unit else col


def _constant(v) -> bool:
    """All finite values equal to 1e-9 relative (or none finite)."""
    v = v[np.isfinite(v)]
    return not v.size or float(np.ptp(v)) <= 1e-9 * max(1e-300, float(np.max(np.abs(v))))


def summary(table, columns) -> Dict:
    """Counts, per-metric statistics over ok runs, worst run ids, failures by status."""
    status = np.asarray(table.column('status').to_pylist())
    ids = np.asarray(table.column('run_id').to_pylist())
    ok = status == 'ok'
    stats = {}
    for name in NUMERIC:
        v = _column(table, name)[ok]
        good = v[np.isfinite(v)]
        if not good.size:
            continue
        stats[name] = {'n': int(good.size), 'nan': int(v.size - good.size),
                       'mean': float(good.mean()), 'std': float(good.std()),
                       'min': float(good.min()), 'p50': float(np.percentile(good, 50)),
                       'p95': float(np.percentile(good, 95)), 'max': float(good.max())}
    worst = {}
    for name in WORST:
        v = _column(table, name)[ok]
        if not np.any(np.isfinite(v)):
            continue
        if _constant(v):
            continue  # no run is worse than another
        key = np.where(np.isfinite(v), np.abs(v), np.inf)  # never reached = worst
        order = np.argsort(-key, kind='stable')[:WORST_COUNT]
        worst[name] = [int(i) for i in ids[ok][order]]
    failed = {}
    for s in sorted(set(status) - {'ok'}):
        failed[s] = [int(i) for i in ids[status == s]]
    saturated = int(np.sum(np.asarray(table.column('saturated').to_pylist())[ok]))
    redraws = int(np.sum(np.asarray(table.column('redraws').to_pylist())))
    return {'runs': int(len(ids)), 'ok': int(ok.sum()), 'failed': failed, 'stats': stats,
            'worst': worst, 'saturated': saturated, 'redraws': redraws}


def format_summary(s: Dict) -> str:
    lines = [f'{s["runs"]} runs: {s["ok"]} ok, '
             f'{sum(len(v) for v in s["failed"].values())} failed; '
             f'{s["saturated"]} saturated; {s["redraws"]} refused draws redrawn']
    for status, ids in s['failed'].items():
        shown = ', '.join(map(str, ids[:20])) + (' ...' if len(ids) > 20 else '')
        lines.append(f'  {status}: {len(ids)} (runs {shown})')
    head = f'  {"metric":24s} {"n":>6s} {"mean":>11s} {"std":>11s} {"min":>11s} ' \
           f'{"p50":>11s} {"p95":>11s} {"max":>11s}'
    lines.append(head)
    for name, st in s['stats'].items():
        lines.append(f'  {name:24s} {st["n"]:6d} ' + ' '.join(
            f'{st[k]:11.4g}' for k in ('mean', 'std', 'min', 'p50', 'p95', 'max'))
            + (f'  ({st["nan"]} NaN)' if st['nan'] else ''))
    for name, ids in s['worst'].items():
        lines.append(f'  worst {name}: runs {", ".join(map(str, ids))}')
    return '\n'.join(lines)


MAX_BINS = 30


def bins_for(n: int) -> int:
    """Histogram bins for n values: √n (8 runs: 3 bins, not 30 mostly empty ones), at most
    MAX_BINS."""
    return int(min(MAX_BINS, max(1, math.ceil(math.sqrt(n)))))


def histogram_panels(data: Dict[str, np.ndarray]):
    """(panels, constant): (metric, finite values, bins) per metric that varies across the
    runs, and {metric: value} for those equal in every run (drawn as a one-bar histogram
    they said nothing; they are named in the figure's title instead)."""
    panels, constant = [], {}
    for name, v in data.items():
        finite = v[np.isfinite(v)]
        if _constant(finite):
            constant[name] = float(finite[0])
        else:
            panels.append((name, finite, bins_for(finite.size)))
    return panels, constant


def write_plots(table, columns, out_dir) -> List[str]:
    """histograms.png and scatter_<value>.png per dispersed column; returns the paths.
    Metrics equal in every run get no panel: the histograms' title names them."""
    import matplotlib
    matplotlib.use('Agg')  # files only; no display needed
    import matplotlib.pyplot as plt
    os.makedirs(out_dir, exist_ok=True)
    ok = np.asarray(table.column('status').to_pylist()) == 'ok'
    data = {n: _column(table, n)[ok] for n in NUMERIC}
    data = {n: v for n, v in data.items() if np.any(np.isfinite(v))}
    panels, constant = histogram_panels(data)
    paths = []
    if not panels:
        return paths
    cols = min(3, len(panels))
    rows = math.ceil(len(panels) / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(4 * cols, 3 * rows), squeeze=False)
    for ax, (name, finite, bins) in zip(axes.flat, panels):
        ax.hist(finite, bins=bins)
        ax.set_title(_label(name), fontsize=9)
        ax.set_ylabel('runs')
        ax.grid(alpha=0.3)
    for ax in list(axes.flat)[len(panels):]:
        ax.set_visible(False)
    title = f'{int(ok.sum())} ok runs'
    if constant:
        title += '\nthe same in every run: ' + ', '.join(
            f'{n} = {v:.4g}' + (f' {UNITS[n]}' if n in UNITS else '')
            for n, v in constant.items())
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    paths.append(os.path.join(out_dir, 'histograms.png'))
    fig.savefig(paths[-1], dpi=90)
    plt.close(fig)
    for col in columns:
        x = _column(table, col)[ok]
        fig, axes = plt.subplots(rows, cols, figsize=(4 * cols, 3 * rows), squeeze=False)
        for ax, (name, _, _) in zip(axes.flat, panels):
            ax.scatter(x, data[name], s=4)
            ax.set(xlabel=_param_label(col), title=_label(name))
            ax.title.set_fontsize(9)
            ax.grid(alpha=0.3)
        for ax in list(axes.flat)[len(panels):]:
            ax.set_visible(False)
        fig.tight_layout()
        safe = col.replace('[', '_').replace(']', '').replace('.', '_')
        paths.append(os.path.join(out_dir, f'scatter_{safe}.png'))
        fig.savefig(paths[-1], dpi=90)
        plt.close(fig)
    return paths
