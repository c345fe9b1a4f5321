"""The simulator's lockstep exchanges in one compiled call: no Python, no GIL between them.

As fast as possible, one exchange is: wait for the held instant's command and take it
(rcl), decode its CDR bytes by the layout the Python way kept (``sim_lockstep
.command_layout``), check its stamp against the held one, clip and apply it, step the
period (``engine.lockstep_direct.period_kernel``), pack the state topics from their
templates and publish them (rcl), hold the next instant. :func:`make` compiles that loop
over rcl's ctypes functions (``rcl_direct.load``). It commits an exchange only once the
period has been stepped: anything unusual (another stamp, frame or length, a value not
finite, a zero torque, the run's end or the command's expiry within the period, a method
that fails) leaves the command taken but not applied and returns to Python, which hands
its bytes to ``_on_torque_bytes``, the general way, exactly as if Python had taken it.
It also returns at the wall time ``until`` (diagnostics, the executor's slice, the held
instant's ``lockstep_timeout``), when rcl says the context is gone, on rcl's errors, after
``room`` exchanges (the acknowledgement window), and after a publish that failed (the
refusal is then reported by ``sim_acks`` as before). ``nodes/sim_rcl.py`` builds the
tables and writes the outcome back into the engine and the node.
"""
import ctypes

import numpy as np

from ..engine import lockstep_direct, sample_kernel
from ..engine.lockstep_direct import EVALS, FAILED, STEPS, T_NS, UNTIL_NS, VALUES, period_kernel
from ..physics import dynamics_kernel
from ..physics.jit import depends_on, jit
from . import rcl_direct
from .rcl_direct import (ARRAY_BYTES, ERROR, I64, OTHER, REFUSED, RET_OK, RET_TAKE_FAILED,
                         RET_TIMEOUT, ROOM, SHUTDOWN, UNTIL)

# ints: in: the engine's t_ns (the held instant), the control period, the run's end, the
# command's timeout, the held stamp's sec and nanosec, room, the round trips' count,
# CPU_EVERY; out: the code, exchanges done, steps, evaluations, saturated, the refused
# topic, rcl's return, the count's last CPU reading
(T, PERIOD, END, TIMEOUT, HELD_SEC, HELD_NSEC, ROOM_LEFT, COUNT, CPU_EVERY, CODE, DONE,
 STEPS_DONE, EVALS_DONE, SATURATED, REFUSED_TOPIC, RET, LAST_N, N_INTS) = range(18)
# floats: in: max torque x, y, z, until (wall), lockstep_timeout; in and out: held since,
# sent (round trips), wall total, wall max; out: the last command x, y, z, the CPU readings
(MAX_X, MAX_Y, MAX_Z, UNTIL_WALL, HOLD_TIMEOUT, HELD_SINCE, SENT, WALL_TOTAL, WALL_MAX,
 CMD_X, CMD_Y, CMD_Z, LAST_CPU, LAST_THREAD, N_FLOATS) = range(15)
# the command's layout (ints): its length, the frame id's size (with its nul), the
# doubles' offset
LENGTH, FRAME_SIZE, DOUBLES_AT = range(3)
CAPACITY = 256  # the command's bytes copied (a longer one goes the general way)
# field kinds of the templates (fields[:, 1]): a value, the stamp's sec, its nanosec
DOUBLE, INT32, UINT32 = 0, 1, 2


def functions(c) -> tuple:
    """The C functions :func:`loop` calls, in its order: rcl's ``c`` (``rcl_direct.load``)
    and libc's clock_gettime and memcpy. Passed as arguments, not read as globals, so that
    the loop is cached on disk like the other kernels (numba keys it on their types)."""
    try:
        libc = ctypes.CDLL(None)
        clock = rcl_direct.as_pointer(libc.clock_gettime, ctypes.c_int32, 2)
        memcpy = rcl_direct.as_pointer(libc.memcpy, I64, 3)
    except (OSError, AttributeError) as exc:
        raise rcl_direct.Unavailable(f'libc: {exc}') from None
    return (c['publish'], c['take'], c['clear'], c['add'], c['wait'], c['valid'], clock,
            memcpy)


@jit
def seconds(clock, clock_id, ts):
    """time.monotonic / process_time / thread_time's reading (clock 1, 2, 3)."""
    clock(clock_id, ts.ctypes.data)
    return (ts[0] * 1_000_000_000 + ts[1]) / 1e9


@jit
def loop(publish, take, clear, add, wait, valid, clock, memcpy, h, into, pubs, msgs, out,
         fields, lay, frame, f, ticks, env, q, m, ints, fl):
    """The exchanges (module docstring). ``h``: the wait set, subscription and context
    addresses; ``into``: the taken message's rcutils array as 8 words; ``pubs`` and
    ``msgs``: each topic's publisher and its array's address (its bytes in ``out``);
    ``fields``: (offset in ``out``, kind, the row's index) of each number; ``q``, ``m``:
    the engine's state, in and out; ``ints``, ``fl``: above."""
    ws, sub, ctx = h[0], h[1], h[2]
    ts = np.zeros(2, dtype=np.int64)
    cmd = np.zeros(CAPACITY, dtype=np.uint8)
    d = np.zeros(1)
    db = d.view(np.uint8)
    i4 = np.zeros(1, dtype=np.int32)
    i4b = i4.view(np.uint8)
    u4 = np.zeros(1, dtype=np.uint32)
    u4b = u4.view(np.uint8)
    qb, mb = np.empty(4), np.empty(3)
    tau = np.empty(3)
    t, period, end = ints[T], ints[PERIOD], ints[END]
    held_sec, held_nsec = ints[HELD_SEC], ints[HELD_NSEC]
    count = ints[COUNT]
    done, steps, evals, saturated = 0, 0, 0, 0
    ints[REFUSED_TOPIC] = -1
    ints[LAST_N] = 0
    n_topics = len(pubs)
    code = UNTIL
    while True:
        if done >= ints[ROOM_LEFT]:
            code = ROOM
            break
        if not valid(ctx):
            code = SHUTDOWN
            break
        now = seconds(clock, 1, ts)
        limit = min(fl[UNTIL_WALL], fl[HELD_SINCE] + fl[HOLD_TIMEOUT])
        if now >= limit:
            code = UNTIL
            break
        ret = clear(ws)
        if ret == RET_OK:
            ret = add(ws, sub, 0)
        if ret == RET_OK:
            ret = wait(ws, np.int64(1e9 * (limit - now)))
        if ret == RET_TIMEOUT:
            continue
        if ret == RET_OK:
            if not valid(ctx):
                code = SHUTDOWN
                break
            ret = take(sub, into.ctypes.data, 0, 0)
            if ret == RET_TAKE_FAILED:
                continue
        if ret != RET_OK:  # (rcl's context shut down meanwhile: Ctrl-C, not an error)
            ints[RET] = ret
            code = ERROR if valid(ctx) else SHUTDOWN
            break
        code = OTHER  # until the command is known to be the held instant's
        length = into[1]
        if length != lay[LENGTH] or length > CAPACITY:
            break
        memcpy(cmd.ctypes.data, into[0], length)
        if cmd[0] != 0 or cmd[1] != 1:
            break
        size = lay[FRAME_SIZE]
        for i in range(4):
            u4b[i] = cmd[12 + i]
        same = u4[0] == size
        for i in range(size):
            same = same and cmd[16 + i] == frame[i]
        if not same:
            break
        for i in range(4):
            i4b[i] = cmd[4 + i]
            u4b[i] = cmd[8 + i]
        if i4[0] != held_sec or u4[0] != held_nsec:
            break
        at = lay[DOUBLES_AT]
        for k in range(3):
            for i in range(8):
                db[i] = cmd[at + 8 * k + i]
            tau[k] = d[0]
        x, y, z = tau[0], tau[1], tau[2]
        if not (np.isfinite(x) and np.isfinite(y) and np.isfinite(z)):
            break
        mx, my, mz = fl[MAX_X], fl[MAX_Y], fl[MAX_Z]
        clipped = abs(x) > mx or abs(y) > my or abs(z) > mz  # CommandHold.set's
        if clipped:
            x, y, z = min(max(x, -mx), mx), min(max(y, -my), my), min(max(z, -mz), mz)
        if x == 0.0 and y == 0.0 and z == 0.0:
            break
        until_ns = t + period
        if until_ns >= end or ints[TIMEOUT] <= period:
            break
        tau[0], tau[1], tau[2] = x, y, z
        applied_at = seconds(clock, 1, ts)
        ticks[T_NS], ticks[UNTIL_NS] = t, until_ns
        period_kernel(f, ticks, env, q, m, tau, tau, qb, mb)
        if ticks[FAILED] != -1:
            break
        # committed: the command applied, the instant released and stepped to
        code = UNTIL
        saturated += clipped
        fl[CMD_X], fl[CMD_Y], fl[CMD_Z] = x, y, z
        rt = applied_at - fl[SENT]
        count += 1
        fl[WALL_TOTAL] += rt
        if rt > fl[WALL_MAX]:
            fl[WALL_MAX] = rt
        if count % ints[CPU_EVERY] == 0:
            ints[LAST_N] = count
            fl[LAST_CPU], fl[LAST_THREAD] = seconds(clock, 2, ts), seconds(clock, 3, ts)
        for i in range(4):
            q[i] = qb[i]
        for i in range(3):
            m[i] = mb[i]
        t = until_ns
        steps += ticks[STEPS]
        evals += ticks[EVALS]
        held_sec, held_nsec = t // 1_000_000_000, t % 1_000_000_000
        for j in range(len(fields)):
            at, kind, src = fields[j, 0], fields[j, 1], fields[j, 2]
            if kind == DOUBLE:
                d[0] = f[VALUES + src - 2]
                for i in range(8):
                    out[at + i] = db[i]
            elif kind == INT32:  # the stamp's sec
                i4[0] = held_sec
                for i in range(4):
                    out[at + i] = i4b[i]
            else:  # its nanosec
                u4[0] = held_nsec
                for i in range(4):
                    out[at + i] = u4b[i]
        for j in range(n_topics):
            ret = publish(pubs[j], msgs[j], 0)
            if ret != RET_OK and ints[REFUSED_TOPIC] < 0:
                ints[REFUSED_TOPIC], ints[RET] = j, ret
        done += 1
        fl[HELD_SINCE] = fl[SENT] = seconds(clock, 1, ts)
        if ints[REFUSED_TOPIC] >= 0:
            code = REFUSED
            break
    ints[CODE], ints[DONE], ints[STEPS_DONE], ints[EVALS_DONE] = code, done, steps, evals
    ints[SATURATED], ints[COUNT], ints[T] = saturated, count, t
    ints[HELD_SEC], ints[HELD_NSEC] = held_sec, held_nsec


# it inlines period_kernel and its step loops (see jit.depends_on)
loop = depends_on(loop, lockstep_direct, sample_kernel, dynamics_kernel, rcl_direct)


def array_words(array) -> np.ndarray:
    """An rcutils_uint8_array_t as the 8 int64 words the loop reads (buffer, length)."""
    return np.frombuffer((ctypes.c_char * ARRAY_BYTES).from_address(ctypes.addressof(array)),
                         dtype=np.int64)
