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
Plain Python types of numpy values: the one home of what JSON and ``yaml.safe_dump`` accept.

Model files, model ids, discovery results and scenarios all hold numpy arrays and scalars
that the serialisers refuse; :func:`plain` turns them (recursively, through mappings, lists
and tuples) into lists, floats, ints and bools.
"""

from __future__ import annotations

import math
from typing import Any, Mapping

import numpy as np

__all__ = ['plain']


def plain(value: Any, *, nan_to_none: bool = False, str_keys: bool = True) -> Any:
    """
    Return ``value`` with numpy values and tuples turned into plain Python types.

    Arrays become (nested) lists, numpy scalars their Python value, tuples lists, mappings
    dicts; anything else is returned as it is. ``nan_to_none`` writes a NaN or infinite
    float as None (JSON has no NaN); ``str_keys`` turns mapping keys into str.
    """
    def go(v: Any) -> Any:
        if isinstance(v, np.ndarray):
            return go(v.tolist())
        if isinstance(v, Mapping):
            return {(str(k) if str_keys else k): go(x) for k, x in v.items()}
        if isinstance(v, (list, tuple)):
            return [go(x) for x in v]
        if nan_to_none and isinstance(v, (float, np.floating)):
            return float(v) if math.isfinite(v) else None
        return v.item() if isinstance(v, np.generic) else v
    return go(value)
