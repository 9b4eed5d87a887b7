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
    if isinstance(value, np.ndarray):
        return plain(value.tolist(), nan_to_none=nan_to_none, str_keys=str_keys)
    if isinstance(value, Mapping):
        return {(str(k) if str_keys else k): plain(v, nan_to_none=nan_to_none,
                                                   str_keys=str_keys)
                for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(v, nan_to_none=nan_to_none, str_keys=str_keys) for v in value]
    if nan_to_none and isinstance(value, (float, np.floating)):
        v = float(value)
        return v if math.isfinite(v) else None
    if isinstance(value, np.generic):
        return value.item()
    return value
