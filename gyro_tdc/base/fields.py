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
One field checker for the documents the package reads: scenarios, model files, learn files.

:class:`FieldChecker` checks that a value is what a field must hold and raises one error
naming the field, what it must be and what it holds; each document gives the error class
and the wording (``fail``).
"""

from __future__ import annotations

import math
from typing import Any, Callable, Mapping, Sequence

import numpy as np

__all__ = ['FieldChecker', 'is_number', 'MAX_COUNT', 'shown']

#: Largest count a field holds: a float holds every whole number up to it exactly.
MAX_COUNT = 2 ** 53


def is_number(x: Any) -> bool:
    """Return whether ``x`` is a finite real number (a bool is not one)."""
    if isinstance(x, bool) or not isinstance(x, (int, float, np.integer, np.floating)):
        return False
    try:
        return math.isfinite(float(x))
    except OverflowError:                 # an int beyond float range
        return False


def shown(v: Any, width: int = 40) -> str:
    """Return a short description of a value for a message (its type too, but for a number)."""
    if isinstance(v, (int, float)) and not isinstance(v, bool):
        return f'{v!r:.{width}}'
    return f'{type(v).__name__} {v!r:.{width}}'


def _bounds(lo: float, hi: float) -> str:
    """Return the words of a range: ``' (finite, lo .. hi)'``, or '' when unbounded."""
    return '' if lo == -math.inf and hi == math.inf else f' (finite, {lo:g} .. {hi:g})'


class FieldChecker:
    """
    Checks of one document's fields; each failure raises ``fail(path, expected, got)``.

    Parameters
    ----------
    fail : callable
        Makes the error for the field at ``path`` that must be ``expected`` and holds ``got``.

    """

    def __init__(self, fail: Callable[[str, str, Any], Exception]) -> None:
        self.fail = fail

    def number(self, v: Any, path: str, lo: float = -math.inf, hi: float = math.inf,
               what: str = 'a number') -> float:
        """Return ``v`` as a finite float within ``lo .. hi``."""
        if not is_number(v) or not lo <= float(v) <= hi:
            raise self.fail(path, what + _bounds(lo, hi), v)
        return float(v)

    def above(self, v: Any, path: str, low: float, strict: bool = False,
              what: str = 'a number') -> float:
        """Return ``v`` as a finite float above ``low`` (``strict``) or at least it."""
        if is_number(v) and (float(v) > low if strict else float(v) >= low):
            return float(v)
        raise self.fail(path, f'{what} {">" if strict else ">="} {low:g}', v)

    def count(self, v: Any, path: str, lo: int = 0, hi: int = MAX_COUNT) -> int:
        """Return ``v`` as a whole count within ``lo .. hi`` (an integral float is one)."""
        f = self.number(v, path, lo, hi, 'a count')
        if f != math.floor(f):
            raise self.fail(path, 'a whole count', v)
        return int(f)

    def boolean(self, v: Any, path: str) -> bool:
        """Return ``v``, true or false."""
        if not isinstance(v, bool):
            raise self.fail(path, 'true or false', v)
        return v

    def items(self, v: Any, path: str, n: int | None = None, most: int | None = None,
              kinds: tuple = (list,)) -> list:
        """Return ``v`` as a list of ``n`` items, or of at most ``most``."""
        if not isinstance(v, kinds):
            raise self.fail(path, 'a list', v)
        if n is not None and len(v) != n:
            raise self.fail(path, f'a list of {n} items', v)
        if most is not None and len(v) > most:
            raise self.fail(path, f'a list of at most {most} items', v)
        return list(v)

    def numbers(self, v: Any, path: str, n: int, lo: float = -math.inf, hi: float = math.inf,
                what: str = 'a number') -> list[float]:
        """Return ``v`` as ``n`` numbers within ``lo .. hi`` (each named ``path[i]``)."""
        return [self.number(x, f'{path}[{i}]', lo, hi, what)
                for i, x in enumerate(self.items(v, path, n))]

    def mapping(self, v: Any, path: str) -> dict:
        """Return ``v`` as a dict (any keys)."""
        if not isinstance(v, Mapping):
            raise self.fail(path, 'a mapping', v)
        return dict(v)

    def keys(self, v: Any, path: str, keys: Sequence[str], optional: Sequence[str] = (),
             exact: bool = True) -> dict:
        """
        Return ``v`` as a dict holding ``keys`` (and maybe ``optional`` ones).

        ``exact``: every key must be one of them, and all of ``keys`` must be there; else
        only unknown keys are refused (a document merged over defaults).
        """
        self.mapping(v, path)
        missing = [k for k in keys if k not in v] if exact else []
        # A key that is not printable is shown quoted: the message stays one line.
        extra = sorted(str(k) if str(k).isprintable() else repr(str(k))
                       for k in v if k not in keys and k not in optional)
        if missing or extra:
            raise self.fail(path, 'a mapping of ' + ', '.join(keys)
                            + (f'; missing {", ".join(missing)}' if missing else '')
                            + (f'; unknown {", ".join(extra)}' if extra else ''), v)
        return dict(v)
