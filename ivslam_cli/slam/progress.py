"""Progress heard from inside a run: a per-thread listener the long loops tell how far they got.

A pipeline's ``run(log, params, progress)`` receives ``progress(fraction, label)`` (or None).
Python loops call it directly; a jitted kernel cannot, so it calls :func:`tell` from an
``objmode`` block once per sweep or per pair, and the pipeline wraps the kernel call in
:func:`listening`, which routes those calls to ``progress`` with a label. Nothing here changes
a result: with no listener :func:`tell` returns at once.
"""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Callable, Iterator

_local = threading.local()


def tell(done: int, total: int) -> None:
    """``done`` of ``total`` units of the current kernel are finished (called from kernels)."""
    hook = getattr(_local, "hook", None)
    if hook is not None:
        hook(int(done), int(total))


@contextlib.contextmanager
def listening(progress: Callable | None, unit: str, share: tuple[float, float] = (0.0, 1.0)) -> Iterator[None]:
    """Route :func:`tell` to ``progress(fraction, "unit done/total")`` while inside, the fraction
    mapped into ``share`` of the run. A no-op when ``progress`` is None."""
    if progress is None:
        yield
        return
    a, b = share

    def hook(done: int, total: int) -> None:
        progress(a + (b - a) * (done / total if total > 0 else 1.0), f"{unit} {done}/{total}")

    previous = getattr(_local, "hook", None)
    _local.hook = hook
    try:
        yield
    finally:
        _local.hook = previous
