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

"""Parameter tables as plain data: the spec rows and the dataclasses built from them."""

from __future__ import annotations

from dataclasses import fields, FrozenInstanceError
import math

from gyro_tdc.base.paramspec import ParamSpec, spec_dataclass
import pytest

TABLE = (
    ParamSpec('mode', 'a', 'Which way.', choices=('a', 'b')),
    ParamSpec('timeout', 2.0, 'How long to wait [s].', 0.001, 60.0),
    ParamSpec('gain', 0.5, 'How much [rad/s].', 0.0, 10.0),
    ParamSpec('depth', 10, 'How many [messages].', 1, 100),
    ParamSpec('on', False, 'Whether.'),
)


def test_spec_dataclass_has_one_field_per_row_with_its_default_and_type():
    Params = spec_dataclass('Params', TABLE, 'Some parameters.', module=__name__)
    assert [(f.name, f.type, f.default) for f in fields(Params)] == [
        (s.name, type(s.default), s.default) for s in TABLE]
    p = Params(depth=20)
    assert (p.mode, p.timeout, p.depth, p.on) == ('a', 2.0, 20, False)
    with pytest.raises(FrozenInstanceError):
        p.depth = 5
    assert Params.__module__ == __name__
    assert Params.__doc__.startswith('Some parameters.\n\nParameters\n----------\n')
    assert 'timeout : float\n    How long to wait [s].\n' in Params.__doc__
    # Unchecked: the node's descriptors enforce ranges; the dataclass only holds values.
    assert Params(mode='z').mode == 'z'


def test_checked_dataclass_checks_choices_and_signs():
    Params = spec_dataclass('Params', TABLE, 'Checked.', module=__name__, check=True,
                            methods={'twice': lambda self: 2 * self.gain})
    assert Params(gain=0.0, timeout=1e6).twice() == 0.0  # sign only, not the declared range
    with pytest.raises(ValueError, match=r"^Expected `mode` 'a' or 'b', got 'z'\.$"):
        Params(mode='z')
    with pytest.raises(ValueError, match=r'^Expected `timeout` > 0 s, got 0\.0\.$'):
        Params(timeout=0.0)
    with pytest.raises(ValueError, match='timeout'):
        Params(timeout=math.inf)
    with pytest.raises(ValueError, match=r'^Expected `gain` >= 0, got -1\.0\.$'):
        Params(gain=-1.0)
    with pytest.raises(ValueError, match='gain'):
        Params(gain=math.nan)


def test_unit_is_the_bracket_at_the_end_of_the_description():
    assert [s.unit for s in TABLE] == ['', 's', 'rad/s', 'messages', '']
