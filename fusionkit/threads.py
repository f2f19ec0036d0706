"""One BLAS thread for fusionkit's work.

fusionkit makes many small numpy calls (Monte-Carlo particle batches, per-factor residuals, small
solves). BLAS threads give them nothing on 2-4 cores and, when another process keeps a core busy,
each call waits for that core: the Monte-Carlo initializer went from 0.9 s to 24 s on a loaded
2-core laptop, and to 0.55 s with one thread (benchmarks/bench_busy_core.py measures it).
"""

from __future__ import annotations

from threadpoolctl import threadpool_limits


def one_blas_thread() -> threadpool_limits:
    """A context manager (or a call that lasts until `.restore_original_limits()`) limiting numpy's
    BLAS (OpenBLAS, MKL, BLIS) to one thread; the caller's own setting comes back afterwards."""
    return threadpool_limits(limits=1, user_api="blas")
