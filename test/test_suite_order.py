"""`make test` starts with the files that took longest last time (test/conftest.py), so that
xdist's loadfile does not leave a minutes-long file for the end (issue 32)."""
from pathlib import Path
from types import SimpleNamespace

import pytest

import conftest

pytestmark = pytest.mark.fast


class Cache(dict):
    def get(self, key, default):
        return dict.get(self, key, default)

    def set(self, key, value):
        self[key] = value


def _items(*nodeids):
    return [SimpleNamespace(nodeid=n) for n in nodeids]


def _config(cache, markexpr='', keyword=''):
    return SimpleNamespace(cache=cache, option=SimpleNamespace(markexpr=markexpr,
                                                               keyword=keyword))


def test_the_longest_file_goes_first_and_each_file_keeps_its_order():
    cache = Cache({conftest._FILE_SECONDS: {'test/test_b.py': 300.0, 'test/test_c.py': 5.0}})
    items = _items('test/test_a.py::one', 'test/test_a.py::two', 'test/test_b.py::one',
                   'test/test_c.py::one', 'test/test_b.py::two')
    conftest.pytest_collection_modifyitems(_config(cache), items)
    assert [i.nodeid for i in items] == [
        'test/test_b.py::one', 'test/test_b.py::two', 'test/test_c.py::one',
        'test/test_a.py::one', 'test/test_a.py::two']


def test_without_a_cache_the_committed_table_orders_and_unlisted_files_come_last(
        monkeypatch):
    """A fresh clone has no .pytest_cache: the committed table puts the long files first
    (by name, the viewer's files came last); files it does not list keep their order."""
    monkeypatch.setattr(conftest, 'committed_seconds',
                        lambda: {'test/test_z.py': 200, 'test/test_b.py': 20})
    items = _items('test/test_a.py::one', 'test/test_b.py::one', 'test/test_c.py::one',
                   'test/test_z.py::one')
    conftest.pytest_collection_modifyitems(_config(Cache()), items)
    assert [i.nodeid for i in items] == ['test/test_z.py::one', 'test/test_b.py::one',
                                         'test/test_a.py::one', 'test/test_c.py::one']


def test_the_committed_table_names_existing_files_and_the_longest_ones():
    """Each file of test/file_seconds.json exists (a renamed file would silently lose its
    place), and the files that took minutes (a module fixture each) are in it."""
    table = conftest.committed_seconds()
    root = Path(conftest.__file__).resolve().parent.parent
    assert table and all((root / name).is_file() for name in table), \
        [n for n in table if not (root / n).is_file()]
    assert all(isinstance(v, (int, float)) and v > 0 for v in table.values()), table
    assert {'test/test_bench.py', 'test/test_demo.py', 'test/test_campaign_dask.py',
            'test/test_viewer.py'} <= set(table)


def test_a_whole_run_keeps_each_files_time_and_a_selection_does_not(monkeypatch):
    monkeypatch.setattr(conftest, '_SPENT', {})
    for nodeid, seconds in (('test/test_b.py::one', 2.0), ('test/test_b.py::two', 3.0),
                            ('test/test_a.py::one', 1.0)):
        conftest.pytest_runtest_logreport(SimpleNamespace(nodeid=nodeid, duration=seconds))
    cache = Cache({conftest._FILE_SECONDS: {'test/test_c.py': 7.0, 'test/test_a.py': 9.0}})
    conftest.pytest_sessionfinish(SimpleNamespace(config=_config(cache, markexpr='fast')))
    assert cache[conftest._FILE_SECONDS]['test/test_a.py'] == 9.0  # `make check` kept none
    conftest.pytest_sessionfinish(SimpleNamespace(config=_config(cache)))
    assert cache[conftest._FILE_SECONDS] == {'test/test_a.py': 1.0, 'test/test_b.py': 5.0,
                                             'test/test_c.py': 7.0}
