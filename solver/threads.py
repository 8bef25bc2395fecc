"""BLAS threads for hyperstat's small dense linear algebra (units: none).

The stages do thousands of small dense solves, SVDs and QRs (tens to a few thousand rows):
a multi-threaded OpenBLAS spends more time synchronising than computing, and on a loaded
machine its spinning threads cost far more (measured on 2 cores: lstsq + svd of a 450 x 41
matrix, 4.7 ms of CPU with one thread, 234 ms with two; the Tripteor diagnosis 4.4 s -> 2.1 s;
the Tripteor report 7.5-8.0 s -> 5.6-6.0 s).  The large batched work runs on the stages' own
thread pools.  ``HYPERSTAT_BLAS_THREADS`` sets the number (default 1; 0 leaves BLAS as it is);
the command line and every stage read the same variable.
"""

from __future__ import annotations

import functools
import os
from typing import Callable, TypeVar

__all__ = ["blas_threads", "limited_blas"]

F = TypeVar("F", bound=Callable)


def blas_threads() -> int | None:
    """BLAS threads to use: ``HYPERSTAT_BLAS_THREADS`` (default 1), ``None`` for 0 (BLAS left as it is).

    Examples
    --------
    >>> blas_threads() if "HYPERSTAT_BLAS_THREADS" not in os.environ else 1
    1
    """
    text = os.environ.get("HYPERSTAT_BLAS_THREADS", "1").strip()
    try:
        value = int(text)
    except ValueError:
        value = 1
    return None if value <= 0 else value


def limited_blas(func: F) -> F:
    """Decorator: run ``func`` with BLAS limited to :func:`blas_threads` threads.

    Examples
    --------
    >>> @limited_blas
    ... def square(x):
    ...     return x * x
    >>> square(3)
    9
    """

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        threads = blas_threads()
        if threads is None:
            return func(*args, **kwargs)
        from threadpoolctl import threadpool_limits

        with threadpool_limits(limits=threads, user_api="blas"):
            return func(*args, **kwargs)

    return wrapper  # type: ignore[return-value]
