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
The runtime core of the compensator, free of rclpy.

The per-sample decisions through the core's parts (the model's drift, the state, the learning
hand-off), the policy table, health and flags, priming and re-anchoring.
"""

from gyro_tdc.base.face import lazy

__all__, __getattr__, __dir__ = lazy(__name__, {
    'blockstats': ['default_tolerance', 'STILL_WINDOW_MAX_S'],
    'core': ['CompensatorCore'],
    'flags': ['PASSTHROUGH', 'UPSTREAM'],
    'handoff': ['BLOCK_FIELDS', 'NO_ACCEL', 'power_up', 'POWER_UP_KEY'],
    'health': ['frame_mismatch', 'health', 'InputStatus', 'sensor_mismatch', 'upstream_note'],
    'liveness': ['InputRate', 'RateReport'],
    'policy': ['PARAMS', 'Policy', 'TEMPERATURE_TYPES', 'UPSTREAM_CORRECTIONS',
               'UPSTREAM_POLICIES'],
    'priming': ['prepare', 'PreparedModel'],
    'reanchor': ['gated_shift', 'REANCHOR_KEY', 'reanchor_shift', 'shift_gate'],
    'startup_gate': ['MAX_ANCHORS', 'MAX_ROWS', 'reanchor_rule', 'SIGNIFICANCE'],
})
