"""A package's names imported on first use (PEP 562 module ``__getattr__``), one mechanism
for ``engine``, ``physics`` and ``bag``: a process that needs one light module of a package
(a scene's checks, ``--help``) then does not load the rest (numba, the kernels, mcap)."""
import importlib


def lazy_exports(package: str, namespace: dict, home: dict):
    """(``__getattr__``, ``__dir__``) for ``package`` whose ``namespace`` is its globals():
    ``home`` maps each exported name to the submodule defining it."""
    def __getattr__(name):
        where = home.get(name)
        if where is None:
            raise AttributeError(f'module {package!r} has no attribute {name!r}')
        value = getattr(importlib.import_module(f'.{where}', package), name)
        namespace[name] = value  # once: later look-ups are plain attribute reads
        return value

    def __dir__():
        return sorted(set(namespace) | set(home))
    return __getattr__, __dir__
