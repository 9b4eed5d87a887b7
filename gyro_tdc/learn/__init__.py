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
Learning on the vehicle.

The online learner, its fit, its model temperature, its learn file and the learned model
as a model.
"""

from gyro_tdc.base.face import lazy

__all__, __getattr__, __dir__ = lazy(__name__, {
    'learner': ['LearnConfig', 'Learner'],
    'records': ['held_out_line'],
    'store': ['is_learn_file', 'LearnFile', 'model_from_file', 'open_learn_file', 'read_model'],
})
