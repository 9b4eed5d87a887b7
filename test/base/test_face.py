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

"""Tests of gyro_tdc.base.face: a package's lazy face of its modules' names."""

import sys

from gyro_tdc.base.face import lazy
import gyro_tdc.signal
import pytest


def test_a_face_imports_a_module_at_its_first_name_and_keeps_it():
    names, getattr_, dir_ = lazy('gyro_tdc.signal', {'blocks': ['block_sum', 'block_mean']})
    assert names == ['block_mean', 'block_sum'] and dir_() == names
    from gyro_tdc.signal.blocks import block_sum
    assert getattr_('block_sum') is block_sum
    assert gyro_tdc.signal.__dict__['block_sum'] is block_sum      # cached on the package
    with pytest.raises(AttributeError, match="module 'gyro_tdc.signal' has no attribute 'nope'"):
        getattr_('nope')


def test_the_faces_name_only_what_their_modules_define():
    for pkg in ('gyro_tdc.base', 'gyro_tdc.model', 'gyro_tdc.signal'):
        face = sys.modules.get(pkg) or __import__(pkg, fromlist=['_'])
        for name in face.__all__:
            assert getattr(face, name) is not None, (pkg, name)
