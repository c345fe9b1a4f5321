"""The campaign's Parquet dataset: a directory of part files, one row per run.

``OUT/runs/part-NNNNNN.parquet`` files are written as rows arrive (every
:data:`FLUSH_ROWS` rows or :data:`FLUSH_SECONDS` seconds, and on close), each one
atomically (written aside, then renamed), so an interruption at any point leaves only
whole files: every run in them is finished. ``pyarrow.parquet.read_table('OUT/runs')``
(or pandas, polars, DuckDB) reads the dataset. The campaign's config and the software
versions are in ``OUT/campaign.json`` and in every part's schema metadata
(key ``rigid_body_sim.campaign``).
"""
import glob
import json
import os
import platform
import time
from typing import List, Optional, Sequence, Set

META_KEY = b'rigid_body_sim.campaign'
FLUSH_ROWS = 256
FLUSH_SECONDS = 2.0

HEAD = (('run_id', 'int64'), ('seed', 'int64'), ('status', 'string'), ('error', 'string'),
        ('redraws', 'int32'), ('noise_seed', 'int64'))
TAIL = (('final_pointing_error', 'float64'), ('settling_time', 'float64'),
        ('detumble_time', 'float64'), ('peak_torque', 'float64'), ('saturated', 'bool'),
        ('energy_dissipated', 'float64'), ('flip_count', 'int64'),
        ('flip_times', 'list<float64>'), ('final_angular_momentum', 'float64'),
        ('angular_momentum_drift', 'float64'), ('kinetic_energy_drift', 'float64'),
        ('integrator', 'string'), ('cpu_time', 'float64'))


def versions() -> dict:
    from importlib import metadata
    out = {'python': platform.python_version()}
    for dist in ('rigid_body_sim', 'numpy', 'scipy', 'numba', 'dask', 'distributed',
                 'pyarrow'):
        try:
            out[dist] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            out[dist] = None
    return out


def schema(columns: Sequence[str], meta: Optional[dict] = None):
    """The dataset's schema: fixed head, a float64 column per dispersed value, metrics."""
    import pyarrow as pa
    types = {'int64': pa.int64(), 'int32': pa.int32(), 'string': pa.string(),
             'float64': pa.float64(), 'bool': pa.bool_(),
             'list<float64>': pa.list_(pa.float64())}
    fields = [pa.field(n, types[t]) for n, t in HEAD]
    fields += [pa.field(c, pa.float64()) for c in columns]
    fields += [pa.field(n, types[t]) for n, t in TAIL]
    s = pa.schema(fields)
    return s.with_metadata({META_KEY: json.dumps(meta)}) if meta else s


def runs_dir(out: str) -> str:
    return os.path.join(out, 'runs')


def part_files(out: str) -> List[str]:
    return sorted(glob.glob(os.path.join(runs_dir(out), 'part-*.parquet')))


def read_config(out: str) -> Optional[dict]:
    path = os.path.join(out, 'campaign.json')
    if not os.path.isfile(path):
        return None
    with open(path, encoding='utf-8') as f:
        return json.load(f)


def read(out: str, columns=None):
    """The whole dataset as a pyarrow Table (None if no run is stored)."""
    import pyarrow.parquet as pq
    files = part_files(out)
    if not files:
        return None
    import pyarrow as pa
    return pa.concat_tables([pq.read_table(f, columns=columns) for f in files])


def existing_ids(out: str) -> Set[int]:
    table = read(out, columns=['run_id'])
    return set() if table is None else set(table.column('run_id').to_pylist())


def _atomic_json(path: str, doc: dict):
    tmp = path + '.tmp'
    with open(tmp, 'w', encoding='utf-8') as f:
        json.dump(doc, f, indent=1, default=str)
    os.replace(tmp, path)


class RunStore:
    """Appends rows to the dataset in ``out``; see the module docstring."""

    def __init__(self, out: str, columns: Sequence[str], meta: dict):
        os.makedirs(runs_dir(out), exist_ok=True)
        _atomic_json(os.path.join(out, 'campaign.json'), meta)
        self.out, self.schema = out, schema(columns, meta)
        self.buffer: List[dict] = []
        self.last = time.monotonic()
        files = part_files(out)
        self.seq = int(os.path.basename(files[-1])[5:11]) + 1 if files else 0
        self.written = 0

    def add(self, rows: List[dict]):
        self.buffer.extend(rows)
        if len(self.buffer) >= FLUSH_ROWS or time.monotonic() - self.last >= FLUSH_SECONDS:
            self.flush()

    def flush(self):
        self.last = time.monotonic()
        if not self.buffer:
            return
        import pyarrow as pa
        import pyarrow.parquet as pq
        table = pa.Table.from_pylist(self.buffer, schema=self.schema)
        name = f'part-{self.seq:06d}.parquet'
        tmp = os.path.join(runs_dir(self.out), '.' + name + '.tmp')
        pq.write_table(table, tmp)
        os.replace(tmp, os.path.join(runs_dir(self.out), name))
        self.seq += 1
        self.written += len(self.buffer)
        self.buffer = []

    def close(self):
        self.flush()


def remove(out: str):
    """Delete a previous campaign's dataset in ``out`` (``--overwrite``)."""
    for f in part_files(out) + glob.glob(os.path.join(runs_dir(out), '.part-*.tmp')):
        os.remove(f)
    for f in ('campaign.json',):
        p = os.path.join(out, f)
        if os.path.exists(p):
            os.remove(p)
