"""The ``rigid-body-sim`` command: one entry point, one subcommand per feature.

Each subcommand lives in its own module exposing ``add_arguments(parser)`` and
``run(args) -> int``; they are imported only when chosen, so ``--help`` stays fast.
"""
import argparse
import importlib
import importlib.util
import math
import os
import re
import sys

# what argparse takes for a negative number rather than an option, exponents included
# (its own pattern stops at -1.5: `--accuracy -1e-3` gave "expected one argument")
NEGATIVE_NUMBER = re.compile(r'^-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$|^-inf$|^-nan$',
                             re.IGNORECASE)


class ArgumentParser(argparse.ArgumentParser):
    """argparse's parser, for which ``-1e-3`` is a value, not an option: a number that may
    be negative parses, and its range check then says what is wrong with it. Subparsers
    are made of this class too (argparse makes them of the parent's type)."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = NEGATIVE_NUMBER


def number(low=-math.inf, high=math.inf, low_open=False, integer=False):
    """An argparse ``type`` for a finite number in a range; argparse names the option in
    its error ("argument --duration: must be a finite number > 0, got 'inf'")."""
    def parse(text):
        try:
            value = int(text) if integer else float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(
                f'must be {"an integer" if integer else "a number"}, got {text!r}') from None
        bounds = [f'{">" if low_open else ">="} {low:g}' if low > -math.inf else '',
                  f'<= {high:g}' if high < math.inf else '']
        wanted = ' and '.join(b for b in bounds if b)
        if not math.isfinite(value) or value < low or (low_open and value == low) \
                or value > high:
            raise argparse.ArgumentTypeError(
                f'must be a finite number{" " + wanted if wanted else ""}, got {text!r}')
        return value
    return parse

# name -> (module, one-line help)
SUBCOMMANDS = {
    'run': ('rigid_body_sim.run_cli', 'run a scene offline (no ROS graph): bag, plots, JSON'),
    'scenes': ('rigid_body_sim.scene', 'list the built-in scenes'),
    'demo': ('rigid_body_sim.demo', 'the live demo: simulator + controller + recorder'),
    'bag': ('rigid_body_sim.bag.cli', 'inspect or recover MCAP bags (info, recover)'),
    'bench': ('rigid_body_sim.bench.command', 'work-precision, stability and speed benchmarks'),
    'campaign': ('rigid_body_sim.campaign.cli', 'Monte Carlo campaign of a scene on Dask: '
                 'dispersions, Parquet rows, summary and plots'),
    'tour': ('rigid_body_sim.tour', 'the five classic phenomena of free rotation: one figure '
             'each (docs/tour)'),
}


def main(argv=None) -> int:
    from . import command
    nodes = ', '.join(command(n) for n in ('simulator', 'controller', 'recorder', 'replay',
                                            'viewer'))
    parser = ArgumentParser(
        prog='rigid-body-sim',
        description='Spacecraft attitude simulation (ROS 2 Jazzy). The live nodes, each '
                    f'with --help: {nodes}.')
    sub = parser.add_subparsers(dest='command', metavar='COMMAND')
    available = {}
    for name, (module, help_text) in SUBCOMMANDS.items():
        if importlib.util.find_spec(module) is None:  # feature not built yet
            continue
        available[name] = (module, sub.add_parser(name, help=help_text, description=help_text))
    argv = sys.argv[1:] if argv is None else argv
    # Import only the chosen subcommand's module to attach its arguments.
    chosen = next((a for a in argv if not a.startswith('-')), None)
    if chosen in available:
        mod = importlib.import_module(available[chosen][0])
        mod.add_arguments(available[chosen][1])
        available[chosen][1].set_defaults(_run=mod.run)
    args = parser.parse_args(argv)
    if not getattr(args, '_run', None):
        parser.print_help()
        return 0 if args.command is None else 2
    try:
        return int(args._run(args) or 0)
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:  # the reader went away (`| head`): stop quietly, as SIGPIPE would
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())  # no second error when Python flushes at exit
        return 141


if __name__ == '__main__':
    sys.exit(main())
