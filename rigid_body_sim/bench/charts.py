"""PNG charts (matplotlib, Agg backend)."""
import os

import numpy as np


def _plt():
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    return plt


def reference_method(label):
    """The method a reference label names ('exact', 'dop853 rtol 1e-13' → 'dop853')."""
    return label.split()[0] if label else ''


def plotted_methods(rows, scene_name, reference_label=''):
    """The methods a work-precision chart draws: never the reference against itself (its
    error against itself is round-off, not an accuracy)."""
    methods = dict.fromkeys(r['method'] for r in rows if r['scene'] == scene_name)
    ref = reference_label.strip()
    # the closed form is its own reference outright; dop853 is drawn at its looser rtols
    return [m for m in methods if not (ref == 'exact' and m == 'exact')]


def work_precision(rows, scene, path, machine='', reference_label=''):
    """CPU against attitude error per method; ``reference_label`` names the reference the
    errors are measured against (subtitle), and that method is not plotted against itself."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(7.5, 5.2))
    methods = plotted_methods(rows, scene.name, reference_label)
    for i, method in enumerate(methods):
        rs = [r for r in rows
              if r['scene'] == scene.name and r['method'] == method and r['status'] == 'ok'
              and not (method == reference_method(reference_label)
                       and not r['attitude_error'] > 0)]  # the reference run itself
        if not rs:
            continue
        rs.sort(key=lambda r: r['cpu_s'])
        peer = rs[0]['family'] == 'peer'
        err = np.maximum([r['attitude_error'] for r in rs], 1e-17)
        ax.loglog([r['cpu_s'] for r in rs], err, ('--' if peer else '-') + ('s' if peer else 'o'),
                  ms=3.5, lw=1.3, label=method + (' (peer)' if peer else ''), color=f'C{i % 10}')
    ref = [r['cpu_s'] for r in rows if r['scene'] == scene.name and r['status'] == 'ok'
           and r['method'] == 'exact' and reference_label == 'exact']
    if ref:  # where it sits on the CPU axis, without an error against itself
        ax.axvline(min(ref), color='k', lw=0.8, ls=':',
                   label=f'exact: the reference ({min(ref):.2g} s; no error against itself)')
    ax.set_xlabel('CPU seconds (process time, includes Python overhead)')
    ax.set_ylabel('final attitude error (rad)')
    ref_note = ''
    if reference_label:
        ref_note = (f'\nerrors against the reference: {reference_label}'
                    + (' (the closed form: not plotted against itself)'
                       if reference_label == 'exact' else ''))
    ax.set_title(f'Work-precision: {scene.title}\n{scene.description}{ref_note}', fontsize=9)
    ax.grid(True, which='major', alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    if machine:
        fig.text(0.01, 0.005, machine, fontsize=6, color='0.4')
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def stability(rows, path):
    plt = _plt()
    scenes = list(dict.fromkeys(r['scene'] for r in rows))
    fig, axes = plt.subplots(len(scenes), 2, figsize=(11, 4.2 * len(scenes)), squeeze=False)
    for row_axes, scene in zip(axes, scenes):
        rs_scene = [r for r in rows if r['scene'] == scene]
        x_name = rs_scene[0]['x_name']
        for col, (key, label) in enumerate((('max_momentum_drift', 'max |L| drift (relative)'),
                                            ('max_energy_drift', 'max T error (relative)'))):
            ax = row_axes[col]
            for i, method in enumerate(dict.fromkeys(r['method'] for r in rs_scene)):
                rs = [r for r in rs_scene if r['method'] == method]
                ok = [r for r in rs if r['status'] == 'ok']
                ax.loglog([r['x'] for r in ok], [max(r[key], 1e-17) for r in ok], 'o-', ms=3,
                          lw=1.2, color=f'C{i % 10}', label=method)
                bad = [r for r in rs if r['status'] != 'ok']
                if bad:
                    ax.loglog([r['x'] for r in bad], [1e3] * len(bad), 'x', ms=8, mew=2,
                              color=f'C{i % 10}')
            ax.axhline(0.01, color='k', lw=0.8, ls=':')
            if 'alpha' in x_name:
                ax.axvline(2.785, color='r', lw=0.8, ls='--')
            ax.set_xlabel(x_name)
            ax.set_ylabel(label)
            ax.set_ylim(1e-17, 1e4)
            ax.set_title(f'{scene}: {label} (x at 1e3 = blown up; dotted = 1 %)', fontsize=8)
            ax.grid(True, alpha=0.3)
        row_axes[0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def long_horizon(rows, path):
    plt = _plt()
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    for i, method in enumerate(dict.fromkeys(r['method'] for r in rows)):
        rs = [r for r in rows if r['method'] == method and np.isfinite(r['energy_drift'])]
        for ax, key in zip(axes, ('energy_drift', 'momentum_drift')):
            ax.loglog([r['periods'] for r in rs], [max(r[key], 1e-17) for r in rs], '-',
                      color=f'C{i % 10}', label=method)
    for ax, key in zip(axes, ('T drift (relative)', '|L| drift (relative)')):
        ax.set_xlabel('rotation periods')
        ax.set_ylabel(key)
        ax.grid(True, alpha=0.3)
    axes[0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def ensure_dir(path):
    os.makedirs(path, exist_ok=True)
    return path


def redraw_work_precision(directory):
    """Redraw the work-precision charts of a finished bench run from its CSV (no rerun):
    ``python -m rigid_body_sim.bench.charts docs/bench``. The reference follows
    bench.common.reference: the closed form for torque-free scenes, else dop853 rtol 1e-13."""
    import csv

    from .scenes import SCENE_BY_NAME
    with open(os.path.join(directory, 'work_precision.csv'), newline='') as f:
        rows = [dict(r, cpu_s=float(r['cpu_s']), attitude_error=float(r['attitude_error']))
                for r in csv.DictReader(f)]
    machine = ''
    targets = os.path.join(directory, 'targets.md')
    if os.path.exists(targets):
        with open(targets) as f:
            first = f.readline().strip()
        machine = first.partition('Measured on: ')[2]
    written = []
    for name in dict.fromkeys(r['scene'] for r in rows):
        scene = SCENE_BY_NAME[name]
        label = 'exact' if scene.torque_free else 'dop853 rtol 1e-13'
        path = os.path.join(directory, f'work_precision_{name}.png')
        work_precision(rows, scene, path, machine, label)
        written.append(path)
    return written


if __name__ == "__main__":
    import argparse
    parser = argparse.ArgumentParser(prog='python -m rigid_body_sim.bench.charts',
                                     description='Redraw the work-precision charts from a '
                                     'bench directory\'s results.')
    parser.add_argument('directory', nargs='?', default='docs/bench',
                        help='the bench output (default: %(default)s)')
    for p in redraw_work_precision(parser.parse_args().directory):
        print(p)
