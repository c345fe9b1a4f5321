"""What samples and the CLI add to a run, measured the way users run.

Sampling overhead: ``offline.simulate`` on a built-in scene keeping every sample (what an
in-process user gets), at 1 and at 100 samples/s, kernels warm, the engine built before
the clock (as the CLI does); the ratio of the two CPU times. CLI overhead: ``rigid-body-sim
run SCENE --json`` in a fresh process (bag written; its ``cpu_seconds`` is the run, the
bag's cost is ``output_cpu_seconds``) against the same run in-process with the kernels
warm. Both are minima of a few runs: the machine may be shared.

    python -m rigid_body_sim.bench.sampling [--quick]
"""
import json
import subprocess
import sys
import tempfile

from .common import cpu

FIELDS = ('what', 'scene', 'duration', 'rate_a', 'cpu_a_s', 'rate_b', 'cpu_b_s', 'ratio', 'note')
# (scene, duration s, overrides); explorer1 at rk4 1 ms, the case
SAMPLING_SCENES = (('slew', 15.0, {}), ('detumble', 15.0, {}),
                   ('explorer1', 690.0, {'integrator': 'rk4', 'step': 1e-3}),
                   ('tennis_racket', 20.0, {}))
CLI_SCENES = (('explorer1', 50.0), ('slew', 15.0))
SAMPLING_MAX, CLI_MAX = 1.5, 1.2  # the targets


def _simulate_cpu(name, duration, rate, overrides, repeats):
    """Least CPU (s) of ``repeats`` in-process runs, samples kept, engine built outside."""
    from ..offline import engine_for, simulate
    from ..scene import load
    scene = load(name, [f'publish_rate={rate:g}'])
    best = float('inf')
    for _ in range(repeats):
        engine = engine_for(scene, duration=duration, **overrides)
        t0 = cpu()
        result = simulate(scene, engine=engine, keep='all')
        best = min(best, cpu() - t0 - (engine.selection_cpu - result.selection_cpu_seconds))
    return best


def _cli_cpu(name, duration, repeats):
    """Least ``cpu_seconds`` (and that run's output_cpu_seconds) of the CLI's runs."""
    runs = []
    for _ in range(repeats):
        with tempfile.TemporaryDirectory() as out:
            proc = subprocess.run(
                [sys.executable, '-c', 'import sys; from rigid_body_sim import cli; '
                 'sys.exit(cli.main(sys.argv[1:]))', 'run', name, '--duration', f'{duration:g}',
                 '--no-plots', '--json', '--out', out], capture_output=True, text=True,
                timeout=600)
        if proc.returncode != 0:
            raise RuntimeError(f'rigid-body-sim run {name} failed: {proc.stderr[-500:]}')
        s = json.loads(proc.stdout.strip().splitlines()[-1])
        runs.append((s['cpu_seconds'], s['output_cpu_seconds'], s['kernels_loaded_during_run']))
    return min(runs)


def run(quick, log=print):
    """Rows, and the target rows (``targets.simple``)."""
    from .. import compiled
    from . import targets
    compiled.warm()
    repeats = 3 if quick else 5
    rows, out = [], []
    for name, duration, overrides in SAMPLING_SCENES:
        if quick:
            duration = duration / 10
        slow = _simulate_cpu(name, duration, 1.0, overrides, repeats)
        fast = _simulate_cpu(name, duration, 100.0, overrides, repeats)
        ratio = fast / slow
        rows.append({'what': 'sampling overhead', 'scene': name, 'duration': duration,
                     'rate_a': 1.0, 'cpu_a_s': slow, 'rate_b': 100.0, 'cpu_b_s': fast,
                     'ratio': ratio, 'note': ', '.join(f'{k} {v}' for k, v in overrides.items())})
        log(f'  sampling {name:14s} {duration:6g} s: 1/s {slow * 1e3:8.3f} ms, 100/s '
            f'{fast * 1e3:8.3f} ms CPU: x{ratio:.3g}')
        out.append(targets.simple('sampling overhead: 100 samples/s / 1 sample/s (CPU)', ratio,
                                  SAMPLING_MAX, ratio <= SAMPLING_MAX,
                                  f'{duration:g} s, samples kept in-process', scene=name))
    for name, duration in CLI_SCENES:
        inproc = _simulate_cpu(name, duration, _scene_rate(name), {}, repeats)
        cli_cpu, output, loaded = _cli_cpu(name, duration, repeats)
        ratio = cli_cpu / inproc
        rows.append({'what': 'CLI overhead', 'scene': name, 'duration': duration,
                     'rate_a': _scene_rate(name), 'cpu_a_s': inproc,
                     'rate_b': _scene_rate(name), 'cpu_b_s': cli_cpu, 'ratio': ratio,
                     'note': f'bag written: output_cpu_seconds {output:.3g}; kernels loaded in '
                             f'the clock {loaded}'})
        log(f'  CLI {name:14s} {duration:6g} s: in-process {inproc * 1e3:8.3f} ms, CLI '
            f'cpu_seconds {cli_cpu * 1e3:8.3f} ms: x{ratio:.3g} (bag {output * 1e3:.3g} ms '
            f'on its own; {loaded} kernels loaded in the clock)')
        out.append(targets.simple('CLI overhead: rigid-body-sim run cpu_seconds / in-process',
                                  ratio, CLI_MAX, ratio <= CLI_MAX,
                                  f'{duration:g} s; the bag on its own: {output:.3g} s',
                                  scene=name))
    return rows, out


def _scene_rate(name):
    from ..scene import load
    return float(load(name).simulator['publish_rate'])


if __name__ == '__main__':
    import argparse
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--quick', action='store_true')
    args = parser.parse_args()
    for r in run(args.quick)[1]:
        print(json.dumps(r))
