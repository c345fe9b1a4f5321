"""rcl's C calls for lockstep's exchange, from a compiled loop that holds no GIL.

rclpy wraps each rcl call in Python (a bound method, its arguments checked and converted,
the GIL taken and released); a lockstep exchange makes three or four of them. Here the same
C functions (``rcl_publish_serialized_message``, ``rcl_take_serialized_message``,
``rcl_wait_set_clear`` / ``_add_subscription``, ``rcl_wait``) are called through ctypes
function pointers from a numba loop (``nogil``), on the handles rclpy made
(``Publisher.handle.pointer``: the ``rcl_publisher_t *``, likewise the subscription's and
the context's). The library is the one rclpy loaded into this process (its path read from
``/proc/self/maps``): a second copy of librcl would hold its own globals. :func:`load`
raises :class:`Unavailable` with the reason where it cannot be had (no librcl mapped, a
symbol missing, numba uncompiled); the callers then take rclpy's way.

The structures are rcl's (jazzy, ``rcl/wait.h`` and ``rcutils/types/uint8_array.h``): a
wait set is 13 pointers or sizes, zero before ``rcl_wait_set_init``; a serialized message
is ``rcutils_uint8_array_t`` (buffer, length, capacity, allocator: 5 pointers).
"""
import ctypes
import functools

import numpy as np

RET_OK, RET_TIMEOUT, RET_TAKE_FAILED = 0, 2, 401  # rcl/types.h
# how the simulator's compiled exchanges (rcl_loop.loop) ended: at the wall time given,
# with a command left to Python, rcl's context gone, an rcl error, no room left before an
# acknowledgement wait, a publish refused
UNTIL, OTHER, SHUTDOWN, ERROR, ROOM, REFUSED = 0, 1, 2, 3, 4, 5
WAIT_SET_WORDS = 13  # rcl_wait_set_t: six (array, size) pairs and impl
ARRAY_BYTES = 64  # rcutils_uint8_array_t: buffer, length, capacity, an allocator


class Unavailable(RuntimeError):
    """rcl's calls cannot be made from compiled code here (the reason)."""


class Allocator(ctypes.Structure):
    _fields_ = [('allocate', ctypes.c_void_p), ('deallocate', ctypes.c_void_p),
                ('reallocate', ctypes.c_void_p), ('zero_allocate', ctypes.c_void_p),
                ('state', ctypes.c_void_p)]


class Uint8Array(ctypes.Structure):
    _fields_ = [('buffer', ctypes.c_void_p), ('buffer_length', ctypes.c_size_t),
                ('buffer_capacity', ctypes.c_size_t), ('allocator', Allocator)]


assert ctypes.sizeof(Uint8Array) == ARRAY_BYTES


class _ErrorString(ctypes.Structure):
    _fields_ = [('text', ctypes.c_char * 1024)]  # rcutils_error_string_t


def _mapped(name: str) -> str:
    """The path of the shared library ``name`` (e.g. 'librcl.so') this process mapped."""
    try:
        with open('/proc/self/maps') as f:
            for line in f:
                path = line.rsplit(None, 1)[-1] if line.count(' ') >= 5 else ''
                if path.rsplit('/', 1)[-1] == name:
                    return path
    except OSError as exc:
        raise Unavailable(f'{name}: /proc/self/maps cannot be read ({exc})') from None
    raise Unavailable(f'{name} is not loaded in this process (import rclpy first)')


I64 = ctypes.c_int64  # every pointer passed as an int64 (the same register on x86-64)


def as_pointer(function, restype, n: int):
    """The C function ``function`` (a ctypes one) as a function pointer of ``n`` int64
    arguments returning ``restype``: what numba calls from compiled code."""
    return ctypes.CFUNCTYPE(restype, *[I64] * n)(ctypes.cast(function, ctypes.c_void_p).value)


def _typed(function, restype, *argtypes):
    """``function`` (ctypes) with its argument and result types set, for calls from Python."""
    function.argtypes, function.restype = list(argtypes), restype
    return function


@functools.lru_cache(maxsize=None)
def load():
    """(the ctypes functions, the compiled loops) of this process: see the module
    docstring. Raises Unavailable with the reason."""
    import rclpy  # noqa: F401 - maps librcl and librcutils
    from ..physics.jit import COMPILED
    if not COMPILED:
        raise Unavailable('numba is not compiling (NUMBA_DISABLE_JIT or no numba)')
    try:
        rcl = ctypes.CDLL(_mapped('librcl.so'))
        rcutils = ctypes.CDLL(_mapped('librcutils.so'))
        c = {k: as_pointer(f, ctypes.c_int32, n) for k, (f, n) in {
            'publish': (rcl.rcl_publish_serialized_message, 3),
            'take': (rcl.rcl_take_serialized_message, 4),
            'clear': (rcl.rcl_wait_set_clear, 1),
            'add': (rcl.rcl_wait_set_add_subscription, 3),
            'wait': (rcl.rcl_wait, 2)}.items()}
        c['valid'] = as_pointer(rcl.rcl_context_is_valid, ctypes.c_bool, 1)
        V, S, R = ctypes.c_void_p, ctypes.c_size_t, ctypes.c_int32
        lib = dict(c, init=_typed(rcl.rcl_wait_set_init, R, V, *[S] * 6, V, Allocator),
                   fini=_typed(rcl.rcl_wait_set_fini, R, V),
                   allocator=_typed(rcutils.rcutils_get_default_allocator, Allocator),
                   array_init=_typed(rcutils.rcutils_uint8_array_init, R, V, S, V),
                   array_fini=_typed(rcutils.rcutils_uint8_array_fini, R, V),
                   error=_typed(rcutils.rcutils_get_error_string, _ErrorString),
                   reset=_typed(rcutils.rcutils_reset_error, None))
    except (OSError, AttributeError) as exc:
        raise Unavailable(f'librcl: {exc}') from None
    return lib, _loops(c)


def _loops(c):
    """The compiled loops over the functions ``c`` (made per process: numba embeds the
    functions' addresses, so these are not cached on disk)."""
    from ..physics.numba_start import import_numba
    njit = import_numba().njit
    publish, take, clear, add, wait = c['publish'], c['take'], c['clear'], c['add'], c['wait']

    @njit(nogil=True)
    def take_or_wait(wait_set, sub, into, timeout_ns):
        """The next message of ``sub`` into the array at ``into``, waited for at most
        ``timeout_ns`` per wait: rcl's return (RET_OK, RET_TIMEOUT, or an error)."""
        while True:
            ret = take(sub, into, 0, 0)
            if ret != RET_TAKE_FAILED:
                return ret
            ret = clear(wait_set)
            if ret == RET_OK:
                ret = add(wait_set, sub, 0)
            if ret == RET_OK:
                ret = wait(wait_set, timeout_ns)
            if ret != RET_OK:
                return ret

    @njit(nogil=True)
    def floor_loop(wait_set, sub, pub, frames, k0, k1, into, timeout_ns, out):
        """``tools.lockstep_floor``'s exchanges k0 .. k1-1: publish the array at
        ``frames + ARRAY_BYTES * k``, take the answer into ``into``. ``out``: the
        exchange reached and rcl's return (RET_OK: all done)."""
        for k in range(k0, k1):
            out[0] = k
            ret = publish(pub, frames + ARRAY_BYTES * k, 0)
            if ret == RET_OK:
                ret = take_or_wait(wait_set, sub, into, timeout_ns)
            if ret != RET_OK:
                out[1] = ret
                return
        out[0] = k1
        out[1] = RET_OK

    return {'take_or_wait': take_or_wait, 'floor_loop': floor_loop}


def error(lib, ret: int, what: str) -> str:
    """rcl's error message for ``ret`` from ``what``, and its error state reset."""
    text = lib['error']().text.decode(errors='replace')
    lib['reset']()
    return f'{what}: rcl returned {ret}' + (f' ({text})' if text else '')


class Exchange:
    """A wait set of one subscription and a serialized message to take into, made with
    rcl for the handles of ``pub`` and ``sub`` (rclpy's Publisher and Subscription) in
    ``context`` (rclpy's Context): what the compiled loops take as int64 addresses
    (``wait_set``, ``sub``, ``pub``, ``into``). :meth:`close` before the node goes."""

    def __init__(self, context, sub, pub=None, capacity=256):
        self.lib, self.loops = load()
        lib = self.lib
        self._words = np.zeros(WAIT_SET_WORDS, dtype=np.int64)  # zero-initialized
        self.wait_set = self._words.ctypes.data
        self._allocator = lib['allocator']()
        ret = lib['init'](self.wait_set, 1, 0, 0, 0, 0, 0, context.handle.pointer,
                          self._allocator)
        if ret != RET_OK:
            raise Unavailable(error(lib, ret, 'rcl_wait_set_init'))
        self._into = Uint8Array()
        ret = lib['array_init'](ctypes.addressof(self._into), capacity,
                                ctypes.addressof(self._allocator))
        if ret != RET_OK:
            lib['fini'](self.wait_set)
            raise Unavailable(error(lib, ret, 'rcutils_uint8_array_init'))
        self.into = ctypes.addressof(self._into)
        self._handles = (sub, pub)  # kept alive with this
        self.sub = sub.handle.pointer
        self.pub = 0 if pub is None else pub.handle.pointer
        self.allocator = self._allocator

    def taken(self) -> bytes:
        """The bytes of the message taken last."""
        return ctypes.string_at(self._into.buffer, self._into.buffer_length)

    def close(self):
        if self.wait_set:
            self.lib['fini'](self.wait_set)
            self.lib['array_fini'](self.into)
            self.wait_set = 0


def frames_array(frames, allocator):
    """Serialized messages ``frames`` (bytes) as rcutils_uint8_array_t structures, one
    after the other: (the structures' ctypes array, whose address ``ctypes.addressof``
    the loops take, and the bytes' array; both kept while in use)."""
    size = max(len(b) for b in frames)
    data = np.zeros((len(frames), size), dtype=np.uint8)
    arrays = (Uint8Array * len(frames))()
    for i, b in enumerate(frames):
        data[i, :len(b)] = np.frombuffer(b, dtype=np.uint8)
        arrays[i].buffer = data[i].ctypes.data
        arrays[i].buffer_length = arrays[i].buffer_capacity = len(b)
        arrays[i].allocator = allocator
    return arrays, data
