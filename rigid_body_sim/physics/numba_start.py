"""numba imported without two of its start-up costs that no process of ours uses (issue 32).

Every process that runs a kernel (each live simulator, each CLI run, each campaign
worker) pays numba's start-up: its import, then the registry refresh before the first
kernel is compiled or loaded from the disk cache. Two parts of it do nothing for us:

* ``import coverage`` (0.04 CPU-s): numba imports it, if installed, only to report lines
  to a coverage run *of this process*. Where none is running (coverage not yet imported,
  and no ``COVERAGE_PROCESS_START`` to start one in a subprocess) it is kept out.
* ``import scipy.linalg`` (0.17 CPU-s of the 0.33 s refresh): ``numba.np.arraymath``
  asks at its import whether BLAS is there by importing ``scipy.linalg.cython_blas``, whose
  package imports the whole of ``scipy.linalg`` (and numpy.f2py). The answer only chooses
  how ``np.convolve``/``np.correlate`` are compiled, which no kernel here calls; numba's
  C helpers import ``cython_blas`` themselves at a BLAS routine's first call. The check
  here finds the same module file and runs numba's own integer-width check, without
  importing it.

And one cost of loading a kernel from the disk cache: numba's ``Cache.load_overload``
refreshes the target context first ("to ensure it is initialized"), whose first call
imports the rest of numba's implementations (typed containers, polynomials, jitclass...)
and installs every typing and lowering registry: 0.12-0.23 CPU-s of a fresh simulator or
CLI run (measured A/B). A cached kernel is object code: loading it needs only
the runtime (NRT) its code calls, initialised here; numba's compiler refreshes both
contexts itself before it compiles anything (``CompilerBase.__init__``), so a kernel
compiled later (a cache miss, a user's own njit) still sees every registry.
"""
import importlib.util
import os
import sys


def import_numba():
    """``import numba``, with the two costs above left out; returns the module."""
    if 'coverage' in sys.modules or os.environ.get('COVERAGE_PROCESS_START'):
        import numba
    else:
        sys.modules['coverage'] = None  # an ImportError for numba's `import coverage`
        try:
            import numba
        finally:
            del sys.modules['coverage']
    _blas_check_without_import()
    _load_without_refresh(numba)
    return numba


# the numba whose Cache.load_overload is `refresh(); return _load_overload(...)`
# (requirements.txt's pin); with another, its own load, as it is
_LOAD_AS_READ = '0.68.1'


def _load_without_refresh(numba):
    from numba.core import caching
    if numba.__version__ != _LOAD_AS_READ or getattr(
            caching.Cache.load_overload, 'rigid_body_sim', False):
        return

    def load_overload(self, sig, target_context):
        """numba's, with the runtime initialised instead of the whole refresh."""
        start_runtime(target_context)
        with self._guard_against_spurious_io_errors():
            return self._load_overload(sig, target_context)
    load_overload.rigid_body_sim = True
    caching.Cache.load_overload = load_overload


def start_runtime(target_context=None):
    """numba's runtime (NRT) initialised for ``target_context`` (the CPU target's by
    default): what a kernel loaded from the cache needs before it runs. Idempotent."""
    from numba.core.runtime import nrt
    if target_context is None:
        from numba.core.registry import cpu_target
        target_context = cpu_target.target_context
    nrt.rtsys.initialize(target_context)


def _blas_check_without_import():
    import numba.np.linalg as linalg
    if getattr(linalg.ensure_blas, 'rigid_body_sim', False) or 'numba.np.arraymath' in \
            sys.modules:  # done, or too late to matter
        return
    if not hasattr(linalg, '_check_lapack_int_width'):  # another numba than the pinned one:
        return  # its own check, as it is

    def ensure_blas():
        scipy = importlib.util.find_spec('scipy')
        folder = os.path.join(os.path.dirname(scipy.origin), 'linalg') if scipy else ''
        if not (os.path.isdir(folder) and any(
                name.startswith('cython_blas.') for name in os.listdir(folder))):
            raise ImportError('scipy 0.16+ is required for linear algebra')
        linalg._check_lapack_int_width()
    ensure_blas.rigid_body_sim = True
    linalg.ensure_blas = ensure_blas
