"""Seeded scenes across the space users run, each with an oracle: the generalisation suite.

``python -m rigid_body_sim.bench.generated [--quick] [--seed N] [--count N]``

Seeded scenes (torque-free, double-bracket or viscous dissipation, detumble control; an
orbit family with the gravity gradient; a B-dot family), each drawn alone from its seed and
index: :mod:`.generated_scenes` (and :mod:`.generated_bdot`). Each is judged against its
oracle and the families summed up into target rows: :mod:`.generated_judge`. This module
is the command line, and keeps the names the suite's users import from it.

The oracle is the cheapest fixed choice of the registry proven to meet the budget, found by
a sweep of bounded CPU, and the reference carries a bound on its own error (the exact
solution checked against the 40-digit closed form torque-free; a Taylor series in long
double with dissipation or under the detumble law; else ``dop853`` down a ladder of
rtol): see :mod:`.oracle`. A row is judged when the bound decides it.
"""
from . import generated_judge, generated_scenes
from .generated_judge import (COUNTS, FAMILIES, FIELDS, INFEASIBLE, JUDGE, JUDGED, SEED,
                              TARGET_NAMES, _family_of, _snap, _spacing, _try, classify,
                              error, family_targets, judge, merge, oracle, read_rows,
                              reference, run, summary, targets_for, timed, update)
from .generated_scenes import (GEO, GG_ORBITS, GG_STREAM, KINDS, LOW_PERIGEE, WEIGHTS, Scene,
                               _log_uniform, _nested, _orbit_words, draw,
                               draw_gravity_gradient, scenes)

__all__ = ['COUNTS', 'FAMILIES', 'FIELDS', 'GEO', 'GG_ORBITS', 'GG_STREAM', 'INFEASIBLE',
           'JUDGE', 'JUDGED', 'KINDS', 'LOW_PERIGEE', 'SEED', 'TARGET_NAMES', 'WEIGHTS',
           'Scene', '_family_of', '_log_uniform', '_nested', '_orbit_words', '_snap',
           '_spacing', '_try', 'classify', 'draw', 'draw_gravity_gradient', 'error',
           'family_targets', 'generated_judge', 'generated_scenes', 'judge', 'main', 'merge',
           'oracle', 'read_rows', 'reference', 'run', 'scenes', 'summary', 'targets_for',
           'timed', 'update']


def main(argv=None):
    import argparse
    import json
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--quick', action='store_true', help=f'{COUNTS[True]} scenes, '
                        'rotations up to 1e4 rad')
    parser.add_argument('--seed', type=int, default=SEED, help=f'default {SEED}')
    parser.add_argument('--count', type=int, default=None, help='scenes of the body family, '
                        'or of --family (default: FAMILIES\' counts)')
    parser.add_argument('--family', choices=tuple(FAMILIES), default=None,
                        help='this family only (default: all)')
    parser.add_argument('--only', type=int, default=None, help='just scene INDEX of the seed '
                        '(of --family, default body)')
    parser.add_argument('--kind', choices=KINDS, default=None,
                        help='the body family\'s scenes of this kind only (e.g. detumble: '
                             'auto under a control law); with --update, in place of that '
                             'kind\'s rows (the other kinds\' kept); not with --out')
    parser.add_argument('--held-out', action='store_true',
                        help='with --kind and --update: a seed nothing was tuned on, its '
                             'rows and target rows apart (generated_held_out.csv)')
    parser.add_argument('--csv', default='', help='write the rows here')
    parser.add_argument('--out', default='', metavar='DIR', help='with --family: its rows '
                        'and targets into a full run\'s files in DIR (others kept)')
    parser.add_argument('--update', metavar='DIR', default='',
                        help='put the rows (or those of --from-csv) into a full run\'s DIR '
                             '(e.g. docs/bench): generated.csv, its targets, the summary')
    parser.add_argument('--from-csv', default='', help='with --update: rows a run wrote')
    args = parser.parse_args(argv)
    if args.only is not None:
        from .. import compiled
        compiled.setup()
        scene = FAMILIES[args.family or 'body'][0](args.seed, args.only, args.quick)
        print(scene.describe())
        row = judge(scene, log=print)
        print(json.dumps(row, indent=1, default=str))
        return 0
    if args.kind and args.out:
        parser.error('--kind runs a share of a family: with --update only (its rows in '
                     'place of that kind\'s), or --csv')
    if args.held_out and not (args.kind and args.update):
        parser.error('--held-out needs --kind and --update')
    if args.out and not args.family:
        parser.error('--out needs --family (a whole run: rigid-body-sim bench)')
    if args.update and args.from_csv:
        rows = read_rows(args.from_csv)
        print(generated_judge.update_kind(args.update, rows, args.seed, args.kind,
                                          args.held_out) if args.kind else
              update(args.update, rows, args.seed))
        return 0
    families = (args.family,) if args.family else tuple(FAMILIES)
    rows, t_rows, s = run(args.quick, seed=args.seed, count=args.count, families=families,
                          kind=args.kind)
    for r in t_rows:
        print(f'{r["verdict"]:5s} {r["target"]}: {r["measured"]:.3g} (required '
              f'{r["required"]:g}) {r["note"]}')
    if args.csv:
        from .common import write_csv
        write_csv(args.csv, FIELDS, rows)
    if args.out:
        print(merge(args.out, args.family, rows, t_rows, args.seed))
    print(json.dumps(s))
    if args.update and args.kind:
        print(generated_judge.update_kind(args.update, rows, args.seed, args.kind,
                                          args.held_out))
    elif args.update:
        print(update(args.update, rows, args.seed))
    return 0


if __name__ == '__main__':
    import sys
    sys.exit(main())
