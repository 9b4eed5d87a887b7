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

"""The one field checker: each failure names the field, what it must be and what it holds."""

import math

from gyro_tdc.base import FieldChecker, is_number, shown
import numpy as np
import pytest


class Bad(ValueError):
    """The error a document raises."""


CHK = FieldChecker(lambda path, expected, got: Bad(f'`{path}` must be {expected}, '
                                                   f'got {shown(got)}'))


def test_numbers():
    assert is_number(3) and is_number(np.float32(2.5)) and is_number(np.int64(7))
    assert not any(is_number(x) for x in (True, 'x', None, math.nan, math.inf, 10 ** 400))
    assert CHK.number(2, 'a', 0.0, 5.0) == 2.0
    with pytest.raises(Bad, match=r'`a` must be a number \(finite, 0 .. 5\), got 6'):
        CHK.number(6, 'a', 0.0, 5.0)
    with pytest.raises(Bad, match=r"`b` must be a number > 0, got str 'x'"):
        CHK.above('x', 'b', 0.0, strict=True)
    assert CHK.above(0.0, 'b', 0.0) == 0.0


def test_counts_lists_and_mappings():
    assert CHK.count(3.0, 'n') == 3
    with pytest.raises(Bad, match='`n` must be a whole count'):
        CHK.count(2.5, 'n')
    with pytest.raises(Bad, match='`n` must be a count'):
        CHK.count(-1, 'n')
    assert CHK.numbers([1, 2, 3], 'v', 3) == [1.0, 2.0, 3.0]
    with pytest.raises(Bad, match=r'`v\[1\]` must be a number'):
        CHK.numbers([1, math.nan, 3], 'v', 3)
    with pytest.raises(Bad, match='`v` must be a list of 3 items'):
        CHK.items([1, 2], 'v', 3)
    assert CHK.keys({'a': 1}, 'm', ('a',), ('b',)) == {'a': 1}
    with pytest.raises(Bad, match='`m` must be a mapping of a, c; missing c; unknown z'):
        CHK.keys({'a': 1, 'z': 2}, 'm', ('a', 'c'))
    with pytest.raises(Bad, match='`m` must be a mapping of a; unknown z'):
        CHK.keys({'z': 2}, 'm', ('a',), exact=False)
    with pytest.raises(Bad, match='`f` must be true or false, got 1'):
        CHK.boolean(1, 'f')


def test_an_unknown_key_that_is_not_printable_keeps_the_message_one_line():
    with pytest.raises(Bad) as err:
        CHK.keys({'a\nb': None}, 'm', ('a',))
    assert '\n' not in str(err.value)
    assert "unknown 'a\\nb'" in str(err.value)


def test_a_mapping_of_any_keys():
    assert CHK.mapping({'x': 1}, 'm') == {'x': 1}
    with pytest.raises(Bad, match="`m` must be a mapping, got str 'imu'"):
        CHK.mapping('imu', 'm')
