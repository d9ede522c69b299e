"""Calling a numba kernel's compiled variant directly, past the dispatcher.

numba's dispatcher types every argument of every call to pick the compiled variant. A
loose array is typed in C from a cached fingerprint (~0.1 us); an array inside a
NamedTuple is typed in Python (~0.1 us more per array), and the collision kernels take
their tables as NamedTuples of some 25-35 arrays: ~3-5 us per call, several percent of
a plan (a state check is ~20 us; a sweep and the certifier's walk resume many times).

A call site whose argument types never change (the world's and the certifier's own
buffers and frozen tables) types them once, at its first call, and calls the variant's
entry point from then on. The entry point still unboxes each argument, it only skips
the typing: so it must never see other types than the first call's (an array of
another dtype, rank or layout would be misread), which is why :class:`Direct` is held
by the object that owns those arguments, never shared across call sites.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any


class Direct:
    """``kernel`` (a numba dispatcher) called through the compiled variant for the
    argument types of its first call through this object.

    Args:
        kernel: the ``numba.njit`` function.
    """

    __slots__ = ("kernel", "call")

    def __init__(self, kernel: Any) -> None:
        self.kernel = kernel
        #: the entry point once bound; the first call binds it
        self.call: Callable[..., Any] = self._bind

    def _bind(self, *args: Any) -> Any:
        # typed as the dispatcher types a call (so an on-disk cached variant is reused)
        sig = tuple(self.kernel.typeof_pyval(a) for a in args)
        self.call = self.kernel.compile(sig)
        return self.call(*args)
