"""The issue's targets as measured ratios with PASS/MISS (never asserted, never weakened)."""
import math

import numpy as np

LEVELS = tuple(10.0 ** -k for k in range(2, 11))
FIELDS = ('target', 'scene', 'level', 'ours_method', 'ours_cpu_s', 'peer_method', 'peer_cpu_s',
          'measured', 'required', 'verdict', 'note')


def cpu_to_reach(points, level):
    """CPU seconds for one method to reach attitude error ≤ level: log–log interpolation
    along its cost-ordered curve (running best error); None if it never gets there. No
    extrapolation: below its cheapest run the cheapest run's cost is used."""
    pts = sorted((c, e) for c, e in points if c > 0 and np.isfinite(c) and np.isfinite(e))
    best = math.inf
    prev = None
    for c, e in pts:
        e = min(e, best)
        if e <= level:
            if prev is None or prev[1] <= level:
                return c
            c0, e0 = prev
            if e0 == e or e <= 0:
                return c
            frac = (math.log(level) - math.log(e0)) / (math.log(e) - math.log(e0))
            return math.exp(math.log(c0) + frac * (math.log(c) - math.log(c0)))
        best = e
        prev = (c, e)
    return None


def _best(rows, family, level):
    best = None
    for method in dict.fromkeys(r['method'] for r in rows if r['family'] == family):
        pts = [(r['cpu_s'], r['attitude_error']) for r in rows
               if r['method'] == method and r['family'] == family and r['status'] == 'ok']
        c = cpu_to_reach(pts, level)
        if c is not None and (best is None or c < best[1]):
            best = (method, c)
    return best


def work_precision(rows, scenes):
    out = []
    for scene in scenes:
        rs = [r for r in rows if r['scene'] == scene.name]
        required = 10.0
        for level in LEVELS:
            ours = _best(rs, 'ours', level)
            peer = _best(rs, 'peer', level)
            row = {'target': 'cpu ratio best peer / best ours', 'scene': scene.name,
                   'level': level,
                   'ours_method': ours[0] if ours else '',
                   'ours_cpu_s': ours[1] if ours else math.nan,
                   'peer_method': peer[0] if peer else '',
                   'peer_cpu_s': peer[1] if peer else math.nan,
                   'required': required}
            if peer is None and ours is None:
                row.update(measured=math.nan, verdict='n/a',
                           note='neither ours nor any peer reaches this error')
            elif peer is None:
                row.update(measured=math.nan, verdict='n/a',
                           note='no peer reaches this error (ours does)')
            elif ours is None:
                row.update(measured=0.0, verdict='MISS',
                           note='ours does not reach this error; a peer does')
            else:
                ratio = peer[1] / ours[1]
                row.update(measured=ratio, verdict='PASS' if ratio >= required else 'MISS',
                           note='' if ratio >= required else f'short by {required / ratio:.3g}x')
            out.append(row)
    return out


def simple(target, measured, required, passed, note='', scene=''):
    return {'target': target, 'scene': scene, 'level': '', 'ours_method': '',
            'ours_cpu_s': math.nan, 'peer_method': '', 'peer_cpu_s': math.nan,
            'measured': measured, 'required': required,
            'verdict': ('PASS' if passed else 'MISS') if passed is not None else 'n/a',
            'note': note}
