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
    Return the block length that reduces ``n`` rows to about ``points`` blocks.

    Parameters
    ----------
    n : int
        Number of rows.
    points : int
        Wanted number of blocks (values below 1 count as 1).
    at_most : bool
        False: ``n // points`` rows per block, so there are at least ``points`` full blocks
        when ``n >= points`` (plots). True: ``ceil(n / points)`` rows per block, so there are
        at most ``points`` blocks (bounded memory for a solve).

    Returns
    -------
    int
        Block length, >= 1.

    """
    points = max(int(points), 1)
    if at_most:
        return max(1, math.ceil(n / points))
    return max(1, n // points)


def block_counts(n: int, block: int) -> NDArray[np.float64]:
    """
    Return the number of rows in each block of ``block`` rows out of ``n``.

    Parameters
    ----------
    n : int
        Number of rows, >= 0.
    block : int
        Rows per block, >= 1.

    Returns
    -------
    NDArray[np.float64], shape (ceil(n / block),)
        ``block`` for every block, the remainder for a shorter last block.

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
    Average ``a`` over consecutive blocks of ``block`` rows.

    Parameters
    ----------
    a : ArrayLike, shape (N, ...)
        Rows to average (first axis).
    block : int
        Rows per block, >= 1; 1 returns ``a`` as a float64 array (no copy when it is one).
    partial : bool
        Keep the mean of a shorter last block (default); False drops it.

    Returns
    -------
    NDArray[np.float64], shape (B, ...)
        Block means, ``B`` as in :func:`block_sum`.

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

    Parameters
    ----------
    a : ArrayLike, shape (N, ...)
        Rows (first axis).
    block : int
        Rows per block, >= 1; the last block may be shorter.

    Returns
    -------
    NDArray[np.float64], shape (ceil(N / block), ...)
        Block sums of squares.

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
