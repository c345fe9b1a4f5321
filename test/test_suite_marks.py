"""Every test of the run has a timeout, and `make check`'s ``fast`` mark is written on the
tests themselves (issue 32): the checks read the session's own collected items, so they
cover whatever `make test` or `make check` collected."""
import configparser
import os

import pytest

pytestmark = pytest.mark.fast

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _names(marks):
    marks = marks if isinstance(marks, (list, tuple)) else [marks]
    return {m.mark.name if hasattr(m, 'mark') else m.name for m in marks}


def _written(item):
    """The marks written in the test file: the module's, the class's, the function's and
    its parameter set's (not those a hook added at collection)."""
    names = set()
    for owner in (getattr(item, 'module', None), getattr(item, 'cls', None),
                  getattr(item, 'function', None)):
        names |= _names(getattr(owner, 'pytestmark', []))
    callspec = getattr(item, 'callspec', None)
    return names | _names(callspec.marks if callspec else [])


def test_every_test_of_the_run_has_a_timeout(request):
    """pytest-timeout is loaded, setup.cfg gives every test a bound, and no test's own
    mark lifts it (0 would mean none): a hang fails by name."""
    assert request.config.pluginmanager.hasplugin('timeout')
    cfg = configparser.ConfigParser()
    cfg.read(os.path.join(REPO, 'setup.cfg'))
    assert 0 < float(cfg['tool:pytest']['timeout']) <= 900
    assert float(request.config.getini('timeout')) > 0
    unbounded = []
    for item in request.session.items:
        marker = item.get_closest_marker('timeout')
        value = (marker.kwargs.get('timeout', marker.args[0] if marker.args else None)
                 if marker else request.config.getini('timeout'))
        if not value or float(value) <= 0:
            unbounded.append(item.nodeid)
    assert not unbounded, unbounded


def test_the_fast_mark_is_written_on_the_tests(request):
    """Each test `make check` selects carries ``fast`` in its own file (a module's
    ``pytestmark`` or the test's decorator), none from a list in a conftest; and the
    Makefile's file filter (`grep -l 'mark\\.fast'`) finds every such file."""
    items = request.session.items
    fast = [item for item in items if item.get_closest_marker('fast')]
    assert request.node in fast
    added = [item.nodeid for item in fast if 'fast' not in _written(item)]
    assert not added, f'fast marks not written in the test files: {added}'
    for path in {str(item.path) for item in fast}:
        with open(path, encoding='utf-8') as f:
            assert 'mark.fast' in f.read(), path
