"""Fits on one BLAS thread, so that their results do not depend on the machine's cores.

A multithreaded BLAS sums a matrix product in an order set by its thread count, so a fit's last
bits, and a choice that turns on them (two diagnosis candidates a hair apart, a least-squares
step at a trust-region boundary), would differ between a 2-core and a 16-core machine. The fits
of the diagnosis and the identification run their linear algebra on one thread whatever the
caller set (threadpoolctl), and give the same result bit for bit on any cores of one BLAS build
(not across builds: another build's kernels round differently). Their matrices are small; the
simulations, not the BLAS, take their time.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any

from threadpoolctl import threadpool_limits


def on_one_blas_thread(function: Callable[..., Any]) -> Callable[..., Any]:
    """``function`` run with the BLAS libraries limited to one thread; the caller's limit is back
    when it returns."""

    @functools.wraps(function)
    def limited(*args: Any, **kwargs: Any) -> Any:
        with threadpool_limits(limits=1, user_api="blas"):
            return function(*args, **kwargs)

    return limited
