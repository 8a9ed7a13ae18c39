"""BLAS threads inside softrod's own fits.

The fits (``calibrate``, ``identify_stiffness``, ``fit_stiffness_map``, the axial and PCC
identifications) work on small matrices: a 3-45-50-1 network, P x P normal equations, 3 x 3
systems per sample. BLAS threads cannot speed these up; they only add synchronisation, and
on a busy machine a lot of it: ``fit_stiffness_map`` on 216 samples took 87.5 s with the
default BLAS threads and 2.3 s with one, on 2 cores. With one thread every product is also
summed in one fixed order, so a fit gives the same numbers whatever the caller's BLAS
settings (``OMP_NUM_THREADS``, ``threadpoolctl``): results depend on the data and the seed
only. The Rust core's own parallelism (rayon, ``threads=``) is not affected.
"""

from __future__ import annotations

import contextlib
import functools
from collections.abc import Callable, Iterator
from typing import TypeVar

__all__ = ["FIT_BLAS_THREADS", "fit_blas_threads", "one_blas_thread"]

#: BLAS threads inside softrod's fits (see the module docstring).
FIT_BLAS_THREADS = 1

F = TypeVar("F", bound=Callable)


@contextlib.contextmanager
def fit_blas_threads() -> Iterator[None]:
    """Limit BLAS (OpenBLAS, MKL, BLIS, ...) to :data:`FIT_BLAS_THREADS` while the block
    runs; the previous limits come back afterwards."""
    # threadpoolctl limits the BLAS libraries loaded when the block starts: load numpy's and
    # scipy's (scikit-learn uses scipy's) first, or a fit that imports scipy lazily would
    # run its BLAS with the default threads.
    import numpy  # noqa: F401
    import scipy.linalg  # noqa: F401
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=FIT_BLAS_THREADS, user_api="blas"):
        yield


def one_blas_thread(func: F) -> F:
    """Run ``func`` under :func:`fit_blas_threads`."""

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        with fit_blas_threads():
            return func(*args, **kwargs)

    return wrapper  # type: ignore[return-value]
