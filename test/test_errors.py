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

"""Tests of gyro_tdc.errors: one error family, messages on one line."""

from gyro_tdc import errors
from gyro_tdc.errors import ConfigError, GyroTdcError, LearnFileError, one_line


def test_every_error_is_a_gyro_tdc_error_and_the_value_errors_are_value_errors():
    kinds = [v for v in vars(errors).values() if isinstance(v, type) and issubclass(v, Exception)]
    assert len(kinds) >= 12 and all(issubclass(k, GyroTdcError) for k in kinds)
    assert issubclass(ConfigError, ValueError) and issubclass(LearnFileError, ValueError)


def test_one_line_collapses_blanks_and_names_a_silent_exception():
    assert one_line('a\n  b\tc ') == 'a b c'
    assert one_line(KeyError()) == 'KeyError'
    assert one_line(ValueError('bad\nvalue')) == 'bad value'
