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
the last block holds the remainder and is kept or dropped. :class:`BlockGrid` is the one
block grid of the fits, discovery and the accelerometer part (segments, short tails merged,
rows that count, rows taken). See ``doc/internals/signal.md``.
"""

from __future__ import annotations

import math
from typing import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ['block_counts', 'block_length', 'block_mean', 'block_sum', 'block_sumsq', 'BlockGrid',
           'PASS_ROWS']

#: Rows a :class:`BlockGrid` takes, masks or centres per pass (rounded down to whole blocks):
#: its temporaries stay this small however long the stream.
PASS_ROWS = 1 << 17


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
    return max(1, math.ceil(n / points) if at_most else n // points)


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
    Sum ``a`` (N, ...) over consecutive blocks of ``block`` (>= 1) rows of its first axis.

    Returns the block sums (B, ...), ``B = ceil(N / block)``: the last block, when shorter
    than ``block``, is kept unless ``partial`` is False (then ``B = N // block``).
    """
    block, a = _check_block(block), np.asarray(a, dtype=np.float64)
    n = a.shape[0]
    full = n // block * block
    if not full:      # no whole block (e.g. a block longer than the data): no ones(block)
        head = np.zeros((0,) + a.shape[1:])
    elif a.ndim == 1:
        head = a[:full].reshape(full // block, block) @ np.ones(block)
    else:
        # Rows flattened to (N, M) so one product per block sums every column at once.
        m = math.prod(a.shape[1:])
        flat = a.reshape(n, m)[:full].reshape(full // block, block, m)
        head = (np.ones(block) @ flat).reshape((full // block,) + a.shape[1:])
    if full == n or not partial:
        return head
    return np.concatenate([head, a[full:].sum(axis=0, keepdims=True)])


def block_mean(a: ArrayLike, block: int, *, partial: bool = True) -> NDArray[np.float64]:
    """
    Average ``a`` (N, ...) over consecutive blocks of ``block`` (>= 1) rows of its first axis.

    ``block`` 1 returns ``a`` as float64 (no copy when it is one). A shorter last block keeps
    its mean unless ``partial`` is False; ``B`` blocks as in :func:`block_sum`.
    """
    block, a = _check_block(block), np.asarray(a, dtype=np.float64)
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
    block, a = _check_block(block), np.asarray(a, dtype=np.float64)
    n = a.shape[0]
    full = n // block * block
    stacked = a[:full].reshape((full // block, block) + a.shape[1:])
    head = np.einsum('ij...,ij...->i...', stacked, stacked)
    if full == n:
        return head
    tail = a[full:]
    return np.concatenate([head, np.einsum('j...,j...->...', tail, tail)[None, ...]])


class BlockGrid:
    """
    Consecutive rows cut into blocks: the one block grid of fits, discovery, accelerometer part.

    Each segment (``bounds``) is cut into blocks of ``per`` rows, the last one shorter; with
    ``merge_tail`` a tail shorter than half a block joins the block before it. With ``rows``
    only those rows count: blocks without any are dropped. With ``take`` the grid's rows are
    those rows of every array given (the still samples of a stream), gathered a pass at a time.

    Parameters
    ----------
    n : int
        Number of rows.
    per : int
        Rows per block, >= 1.
    bounds : NDArray[np.int64], optional
        Segment edges ``[0, ..., n]`` (default one segment).
    merge_tail : bool
        Join a short segment tail to the block before it.
    rows : NDArray[np.bool_], shape (n,), optional
        The rows that count.
    take : NDArray[np.int64], shape (n,), optional
        Increasing row indices of the arrays given: the grid's rows.

    """

    def __init__(self, n: int, per: int, *, bounds: NDArray[np.int64] | None = None,
                 merge_tail: bool = False, rows: NDArray[np.bool_] | None = None,
                 take: NDArray[np.int64] | None = None) -> None:
        self.n, self.per, self.merge_tail = int(n), _check_block(per), merge_tail
        self.bounds = np.array([0, n]) if bounds is None else np.asarray(bounds)
        self.rows = None if rows is None else np.asarray(rows, dtype=bool)
        self.take, self.offset = None if take is None else np.asarray(take), 0
        if self.take is not None and self.take.size and self.take[-1] - self.take[0] + 1 == n:
            self.take, self.offset = None, int(self.take[0])     # a contiguous run: views
        self.keep = None
        if self.rows is None:
            self.counts = self._segments(lambda a, b: block_counts(b - a, self.per))
        else:
            c = self._passes(self.rows.astype(np.float64), block_sum, masked=False)
            self.keep = c > 0
            self.counts = c[self.keep]

    def _segments(self, blocks: Callable[[int, int], NDArray[np.float64]]) -> NDArray[np.float64]:
        """Return ``blocks(a, b)`` of every segment, short tails merged, concatenated."""
        out, per = [], self.per
        for a, b in zip(self.bounds[:-1].tolist(), self.bounds[1:].tolist()):
            s, m = blocks(a, b), b - a
            if self.merge_tail and m > per and 0 < (m % per) * 2 < per:
                s = np.concatenate([s[:-2], s[-2:-1] + s[-1:]])
            out.append(s)
        return np.concatenate(out)

    def _passes(self, x: ArrayLike, f: Callable[..., NDArray[np.float64]], *,
                masked: bool = True, origin: NDArray[np.float64] | None = None
                ) -> NDArray[np.float64]:
        """
        Return ``f(rows - origin, per)`` of every segment, of the blocks kept when ``masked``.

        Rows taken, masked or centred are new arrays: they are made in passes of whole blocks.
        """
        x = np.asarray(x, dtype=np.float64)
        mask = self.rows if masked else None
        copied = self.take is not None or origin is not None or mask is not None
        step = self.per * max(1, PASS_ROWS // self.per) if copied else max(self.n, 1)
        buf = np.empty((min(step, self.n),) + x.shape[1:]) if copied else None   # reused

        def blocks(a: int, b: int) -> NDArray[np.float64]:
            parts = []
            for c in range(a, max(b, a + 1), step):
                d = min(c + step, b)
                r = (x[self.offset + c:self.offset + d] if self.take is None else
                     np.take(x, self.take[c:d], axis=0, out=buf[:d - c]))
                if origin is not None:
                    r = np.subtract(r, origin, out=buf[:d - c])
                if mask is not None:
                    r = np.where(mask[c:d].reshape((-1,) + (1,) * (x.ndim - 1)), r, 0.0)
                parts.append(f(r, self.per))
            return np.concatenate(parts)

        return self.sel(self._segments(blocks)) if masked else self._segments(blocks)

    def sel(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """Return the rows of a per-block array (one per block) of the blocks kept."""
        return x if self.keep is None else x[self.keep]

    def mean(self, x: ArrayLike) -> NDArray[np.float64]:
        """Return the block means of ``x`` (N, ...) over the rows that count."""
        s = self._passes(x, block_sum)
        return s / self.counts.reshape((-1,) + (1,) * (s.ndim - 1))

    def moments(self, x: ArrayLike, *, centred: bool = False
                ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """
        Return the block means of ``x`` (N, M) and each block's squared deviations from its mean.

        The deviations are summed as ``sum(x^2) - n mean^2`` (at least 0); ``centred`` sums
        ``x`` less the grid's first row, so no cancellation where the mean dwarfs the scatter
        (gravity in a specific force).
        """
        x = np.asarray(x, dtype=np.float64)
        origin = None
        if centred and self.n:
            origin = x[self.offset if self.take is None else self.take[0]]
        mean = self._passes(x, block_sum, origin=origin) / self.counts[:, None]
        ss = self._passes(x, block_sumsq, origin=origin) - self.counts[:, None] * mean ** 2
        return (mean if origin is None else mean + origin), np.maximum(ss, 0.0)
