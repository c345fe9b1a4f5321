"""``rigid-body-sim bag``: inspect (``info``) or repair (``recover``) MCAP bags."""
from __future__ import annotations

import argparse
import datetime
import json
import sys

from rigid_body_sim.bag.errors import BagError


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest='bag_command', metavar='ACTION', required=True)
    info = sub.add_parser('info', help='topics, types, counts, duration and run configuration')
    info.add_argument('path', help='bag directory or .mcap file')
    rec = sub.add_parser('recover', help='rebuild a valid, indexed bag from an unfinished one '
                                         '(recorder killed)')
    rec.add_argument('input', help='unfinished .mcap file or bag directory')
    rec.add_argument('output', help='new .mcap file, or new bag directory for a directory')


def _time(ns: int) -> str:
    stamp = datetime.datetime.fromtimestamp(ns / 1e9, tz=datetime.timezone.utc)
    return f'{stamp:%b %d %Y %H:%M:%S.%f}'[:-3] + f' UTC ({ns / 1e9:.9f})'


def _size(n: float) -> str:
    for unit in ('B', 'KiB', 'MiB', 'GiB'):
        if n < 1024 or unit == 'GiB':
            return f'{n:.1f} {unit}' if unit != 'B' else f'{int(n)} B'
        n /= 1024
    return ''


def _text(value: object) -> str:
    return value if isinstance(value, str) else json.dumps(value, sort_keys=True)


def info(path: str) -> int:
    from rigid_body_sim.bag.reader import read_info
    bag = read_info(path)
    print(f'Files:             {", ".join(f.path for f in bag.files)}')
    print(f'Bag size:          {_size(sum(f.size for f in bag.files))}')
    print('Storage id:        mcap')
    print(f'Duration:          {bag.duration_s:.3f}s')
    if bag.message_count:
        print(f'Start:             {_time(bag.start_ns)}')
        print(f'End:               {_time(bag.end_ns)}')
    print(f'Messages:          {bag.message_count}')
    print('Topic information:', end='' if bag.topics else ' (none)\n')
    for i, t in enumerate(sorted(bag.topics.values(), key=lambda t: t.name)):
        pad = ' ' if i == 0 else ' ' * 19
        print(f'{pad}Topic: {t.name} | Type: {t.type} | Count: {t.count} | '
              'Serialization Format: cdr')
    if bag.run_configuration is None:
        print('Run configuration: (none stored)')
    else:
        print('Run configuration:')
        for key, value in bag.run_configuration.items():
            if isinstance(value, dict):  # parameter sets: one per line
                print(f'  {key}:')
                for sub, item in sorted(value.items()):
                    print(f'    {sub}: {_text(item)}')
            else:
                print(f'  {key}: {_text(value)}')
    return 0


def recover(source: str, output: str) -> int:
    from rigid_body_sim.bag.recover import recover as do_recover
    for r in do_recover(source, output):
        state = 'complete' if r.complete else f'truncated input, stopped at: {r.stopped_at}' \
            if r.stopped_at else 'truncated input'
        print(f'{r.source} -> {r.output}: {r.messages} messages ({state})')
    return 0


def run(args: argparse.Namespace) -> int:
    try:
        if args.bag_command == 'info':
            return info(args.path)
        return recover(args.input, args.output)
    except BagError as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 1
    except OSError as exc:
        print(f'error: {exc.filename or ""}: {exc.strerror}', file=sys.stderr)
        return 1
    except BrokenPipeError:
        return 0
