"""Compiled kernels: where the numba code lives and the one way to load it.

Layout. Every algorithm that runs compiled has one implementation, a numba kernel in a
``_<name>_jit.py`` module next to the module that uses it (``filters/_two_stage_jit.py`` for
``filters/two_stage.py``). The public module wraps the kernel (allocates outputs, builds the
state dataclasses); it does not carry a second, numpy copy of the equations. The numpy
references that the equivalence tests compare a kernel with live beside the tests
(``tests/reference/``). Where a numpy path still runs (the iterated first steps of the
two-stage filter), its module docstring says which equations it shares with the kernel and why
the others cannot be shared. Small linear algebra for the filter kernels (Cholesky, its solves,
loop products) is written once, in ``filters/_linalg.py``.

Loading. A kernel module is imported only through :func:`load_kernels`, by its full name::

    from gcs_monitor.core.kernels import load_kernels

    kern = load_kernels("gcs_monitor.filters._two_stage_jit")
    kern.predict(...)

It is imported on first use (importing numba and loading the compiled code from numba's disk
cache takes a while; ``import gcs_monitor.filters`` stays light) and then cached. numba is a
core dependency: a kernel that cannot be imported is an error, not a reason to fall back to
numpy.

Dependencies between files. numba's disk cache (``cache=True``) is invalidated only by a
change of the file that defines the cached function: it does not notice that a function
called from another file, or a module-level constant read from another file, has changed,
and would keep running the old compiled code (numba issue #1833). A kernel module that calls
jitted functions of, or reads constants from, another file therefore names that file and the
SHA-256 of its source in ``KERNEL_DEPENDENCIES``::

    KERNEL_DEPENDENCIES = {"gcs_monitor.filters._linalg": "<first 16 hex digits>"}

:func:`load_kernels` checks the digests and raises :class:`StaleKernelError` when one no
longer matches. Updating the digest changes the kernel's own file, which is exactly what makes
numba recompile it. :func:`source_digest` gives the current value.
"""

from __future__ import annotations

import functools
import hashlib
import importlib
import importlib.util
from pathlib import Path
from types import ModuleType

DIGEST_HEX = 16  # hex digits of SHA-256 kept in KERNEL_DEPENDENCIES


class StaleKernelError(RuntimeError):
    """A kernel module was written against another version of a file it depends on."""


@functools.cache
def source_digest(module: str) -> str:
    """First :data:`DIGEST_HEX` hex digits of the SHA-256 of ``module``'s source file."""
    spec = importlib.util.find_spec(module)
    if spec is None or spec.origin is None:
        raise ModuleNotFoundError(f"no source file for {module!r}")
    return hashlib.sha256(Path(spec.origin).read_bytes()).hexdigest()[:DIGEST_HEX]


@functools.cache
def load_kernels(name: str) -> ModuleType:
    """The kernel module ``name`` (a ``_*_jit`` module), imported once and dependency-checked.

    Raises
    ------
    ImportError
        if the module (or numba) cannot be imported
    StaleKernelError
        if a digest in the module's ``KERNEL_DEPENDENCIES`` does not match that file any more
    """
    mod = importlib.import_module(name)
    deps: dict[str, str] = getattr(mod, "KERNEL_DEPENDENCIES", {})
    for dep, digest in deps.items():
        now = source_digest(dep)
        if now != digest:
            raise StaleKernelError(
                f"{name} was compiled against another version of {dep}; numba's cache would "
                f"keep the old code. Check {name} against the change and set its "
                f'KERNEL_DEPENDENCIES["{dep}"] = "{now}"'
            )
    return mod
