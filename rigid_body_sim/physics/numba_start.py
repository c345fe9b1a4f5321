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
    return numba


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
