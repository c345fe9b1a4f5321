"""DOP853's tableau: scipy's own coefficients (``scipy.integrate._ivp.dop853_coefficients``),
read from its file without importing ``scipy.integrate``.

Importing ``scipy.integrate`` (with the sparse, optimize and linalg packages it loads)
cost every node and CLI process ~0.1 CPU-s of its start-up, for a table of constants; the
file itself needs only numpy. The compiled loop and its dense output read the same arrays
solve_ivp's DOP853 uses (test_dop853 compares the two).
"""
import importlib.util
import os


def _load():
    scipy_dir = importlib.util.find_spec('scipy').submodule_search_locations[0]
    path = os.path.join(scipy_dir, 'integrate', '_ivp', 'dop853_coefficients.py')
    spec = importlib.util.spec_from_file_location('rigid_body_sim._dop853_coefficients', path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


coefficients = _load()
