"""Names of a package imported on first use (PEP 562), so that light commands (``torquesim
--help``, reading the technique registry) do not load Numba, SciPy or Matplotlib."""

from __future__ import annotations

from importlib import import_module


def lazy_exports(package: str, namespace: dict, exports: dict[str, str]):
    """The module ``__getattr__`` and ``__dir__`` of ``package`` (its ``globals()`` is
    ``namespace``) serving each name of ``exports`` from its submodule on first use."""
    def __getattr__(name: str):
        if name in exports:
            value = getattr(import_module(f".{exports[name]}", package), name)
            namespace[name] = value
            return value
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    def __dir__():
        return sorted([*namespace, *exports])

    return __getattr__, __dir__
