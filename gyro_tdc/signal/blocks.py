# Copyright 2026 The gyro_tdc Authors
#
# Licensed under the Apache License, Version 2.0 (the "License");
# you may not use this file except in compliance with the License.
# You may obtain a copy of the License at
#
#     http://www.apache.org/licenses/LICENSE-2.0
#
# Unless required by applicable law or agreed to in writing, software
# distributed under the License is distributed on an "AS IS" BASIS,
# WITHOUT WARRANTIES OR CONDITIONS OF ANY KIND, either express or implied.
# See the License for the specific language governing permissions and
# limitations under the License.

"""
Block sums and means over consecutive rows: the one home of block averaging.

Long runs are reduced to means over blocks of consecutive samples before a fit or a plot;
the last block holds the remainder and is kept or dropped. See ``doc/internals/signal.md``.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ['block_counts', 'block_length', 'block_mean', 'block_sum', 'block_sumsq']


def _check_block(block: int) -> int:
    """Return ``block`` as an int, rejecting values below 1."""
    if int(block) != block or block < 1:
        raise ValueError(f'Expected `block` to be an integer >= 1, got {block!r}.')
    return int(block)


def block_length(n: int, points: int, *, at_most: bool = False) -> int:
    """
    Return the block length (>= 1) that reduces ``n`` rows to about ``points`` blocks.

    ``points`` below 1 counts as 1. By default ``n // points`` rows per block: at least
    ``points`` full blocks when ``n >= points`` (plots); ``at_most``: ``ceil(n / points)``
    rows, so at most ``points`` blocks (bounded memory for a solve).
    """
    points = max(int(points), 1)
    if at_most:
        return max(1, math.ceil(n / points))
    return max(1, n // points)


def block_counts(n: int, block: int) -> NDArray[np.float64]:
    """
    Return the number of rows in each block of ``block`` (>= 1) rows out of ``n`` (>= 0).

    ``block`` for every block, the remainder for a shorter last one; ``ceil(n / block)`` values.
    """
    block = _check_block(block)
    counts = np.full(-(-n // block), float(block))
    if n % block:
        counts[-1] = n % block
    return counts


def block_sum(a: ArrayLike, block: int, *, partial: bool = True) -> NDArray[np.float64]:
    """
    Sum ``a`` over consecutive blocks of ``block`` rows.

    Parameters
    ----------
    a : ArrayLike, shape (N, ...)
        Rows to sum (first axis).
    block : int
        Rows per block, >= 1.
    partial : bool
        Keep the last block when it is shorter than ``block`` (default); False drops it.

    Returns
    -------
    NDArray[np.float64], shape (B, ...)
        Block sums, ``B = ceil(N / block)`` (``N // block`` when ``partial`` is False).

    """
    block = _check_block(block)
    a = np.asarray(a, dtype=np.float64)
    n = a.shape[0]
    full = n // block * block
    if not full:      # no whole block (e.g. a block longer than the data): no ones(block)
        head = np.zeros((0,) + a.shape[1:])
        return head if not partial or n == 0 else a.sum(axis=0, keepdims=True)
    ones = np.ones(block)
    if a.ndim == 1:
        head = a[:full].reshape(full // block, block) @ ones
    else:
        # Rows flattened to (N, M) so one product per block sums every column at once.
        m = math.prod(a.shape[1:])
        flat = a.reshape(n, m)[:full].reshape(full // block, block, m)
        head = (ones @ flat).reshape((full // block,) + a.shape[1:])
    if full == n or not partial:
        return head
    return np.concatenate([head, a[full:].sum(axis=0, keepdims=True)])


def block_mean(a: ArrayLike, block: int, *, partial: bool = True) -> NDArray[np.float64]:
    """
    Average ``a`` (N, ...) over consecutive blocks of ``block`` (>= 1) rows of its first axis.

    ``block`` 1 returns ``a`` as float64 (no copy when it is one). A shorter last block keeps
    its mean unless ``partial`` is False; ``B`` blocks as in :func:`block_sum`.
    """
    block = _check_block(block)
    a = np.asarray(a, dtype=np.float64)
    if block == 1:
        return a
    counts = block_counts(a.shape[0], block)
    if not partial:
        counts = counts[:a.shape[0] // block]
    return block_sum(a, block, partial=partial) / counts.reshape((-1,) + (1,) * (a.ndim - 1))


def block_sumsq(a: ArrayLike, block: int) -> NDArray[np.float64]:
    """
    Sum ``a * a`` over consecutive blocks of ``block`` rows without a squared temporary.

    ``a`` (N, ...) is summed along its first axis; the last block may be shorter, so the
    result has ``ceil(N / block)`` rows.
    """
    block = _check_block(block)
    a = np.asarray(a, dtype=np.float64)
    n = a.shape[0]
    full = n // block * block
    stacked = a[:full].reshape((full // block, block) + a.shape[1:])
    head = np.einsum('ij...,ij...->i...', stacked, stacked)
    if full == n:
        return head
    tail = a[full:]
    return np.concatenate([head, np.einsum('j...,j...->...', tail, tail)[None, ...]])
