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
The model.

The effect library, the thermal state, the compensation model, its out-of-range rules and
the versioned model file; the flight controllers' thermal calibration.
"""

from gyro_tdc.base.face import lazy

__all__, __getattr__, __dir__ = lazy(__name__, {
    'compensation': ['compensate', 'CompensationModel', 'drift', 'KINDS', 'model_temperature',
                     'rbf_design', 'static_slope', 'steady_drift', 'StreamingCompensator'],
    'effects': ['batch_features', 'EFFECT_IDS', 'EFFECTS', 'input_ids',
                'NONLINEAR_EFFECTS', 'normalise_ids', 'REFERENCE_EFFECTS', 'resolve_params',
                'STATE_TERMS', 'STATIC_EFFECTS', 'TEMPERATURE_EFFECTS', 'THERMAL_EFFECTS',
                'with_implied'],
    'fc_tempcal': ['ARDUPILOT_SCALE', 'ARDUPILOT_TREF_C', 'ardupilot_correction',
                   'ArduPilotTempCal', 'onboard_status', 'px4_correction', 'px4_slot',
                   'Px4TempCal'],
    'lag': ['first_order_lag'],
    'modelfile': ['load_model', 'model_from_dict', 'model_to_dict', 'save_model'],
    'out_of_range': ['check_policy', 'DEFAULT_OUT_OF_RANGE', 'MAX_EXTRAPOLATION_C',
                     'OPERATING_RANGE_C', 'OUT_OF_RANGE_POLICIES', 'range_shortfall',
                     'variance_growth'],
    'thermal_state': ['SETTLE_TAUS', 'ThermalState'],
    'validate': ['check_accel', 'check_model', 'MAX_PARAM'],
})
