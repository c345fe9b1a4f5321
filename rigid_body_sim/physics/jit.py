"""numba's settings for every compiled kernel of the package: ``jit``, ``inline``, ``COMPILED``
and ``depends_on``.

Compilation: ``numba.njit(cache=True)``, IEEE division (see ``jit``) — compiled on first
use and cached on disk beside each source file (``make`` warms the cache). With
``NUMBA_DISABLE_JIT=1`` (or without numba) the same functions run as ordinary Python, which
the tests use to check both modes agree.

``signatures()`` counts the compiled versions the package's kernels hold in this process
(compiled now or loaded from the disk cache): the live simulator reports those that came
after its t = 0, each a stall of its real-time loop.
"""
import hashlib
import os
import sys

_DISPATCHERS = []  # every kernel made by jit or inline, for signatures()


def _kept(decorator):
    def make(function):
        dispatcher = decorator(function)
        _DISPATCHERS.append(dispatcher)
        return dispatcher
    return make


def signatures() -> int:
    """The compiled versions (argument types) the package's kernels hold in this process;
    0 uncompiled."""
    return sum(len(getattr(d, 'signatures', ())) for d in _DISPATCHERS)


try:
    from .numba_start import import_numba  # without what no process of ours uses
    njit = import_numba().njit
    # error_model='numpy': a division by zero gives inf/NaN (the loops' finiteness checks
    # report it) instead of raising. The python model's checks kept the small rate functions
    # from being optimised: rk4_run 610 → 120 ns per step, results bitwise unchanged.
    jit = _kept(njit(cache=True, nogil=True, error_model='numpy'))
    # small helpers taking several arrays: called out of line, each call pays a reference
    # count round trip per array (≈ 0.15 µs, 5× a body's whole step); inlined, none
    inline = _kept(njit(cache=True, nogil=True, error_model='numpy', inline='always'))
    COMPILED = not getattr(sys.modules['numba'].config, 'DISABLE_JIT', False)
except Exception as exc:  # noqa: BLE001 - numba missing, or broken (a numpy it refuses)
    def jit(function):
        return function
    inline = jit
    COMPILED = False
    # asked for (NUMBA_DISABLE_JIT=1, as the tests do) it is a mode; otherwise say so
    # once: a system Python without numba once ran a benchmark uncompiled for 10
    # CPU-minutes without a word
    if os.environ.get('NUMBA_DISABLE_JIT', '').strip() in ('', '0'):
        print(f'warning: rigid_body_sim: numba cannot be imported ({type(exc).__name__}: '
              f'{exc}); the kernels run uncompiled, 10-1000x slower. Install the pinned '
              'numba (make venv, or pip install -r requirements.txt), or set '
              'NUMBA_DISABLE_JIT=1 to run uncompiled on purpose.', file=sys.stderr)


def depends_on(kernel, *modules):
    """Key ``kernel``'s disk cache on the source of ``modules`` too, and return it.

    numba's cache checks only the file that defines a function; a kernel that calls
    compiled code from other files would otherwise keep running their old code after
    those files change. Without the cache (JIT disabled), nothing to do."""
    cache_file = getattr(getattr(kernel, '_cache', None), '_cache_file', None)
    if cache_file is None or not hasattr(cache_file, '_source_stamp'):
        return kernel
    digest = hashlib.sha256(repr(cache_file._source_stamp).encode())
    for module in modules:
        with open(module.__file__, 'rb') as f:
            digest.update(f.read())
    cache_file._source_stamp = digest.hexdigest()
    return kernel
