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
Identification of a model from recorded runs.

Fits (linear stage, time constants, the full model), training from bags and from still
time (its choices one :class:`TrainOptions`), the accelerometer part, and discovery of
missing effects. See ``doc/internals/identify.md``.
"""

from gyro_tdc.base.face import lazy

__all__, __getattr__, __dir__ = lazy(__name__, {
    'accel': ['ACCEL_EFFECTS', 'accel_features', 'accel_scores', 'compensate_accel',
              'discovery_runs', 'fit_accel', 'MG', 'static_bs', 'static_data'],
    'axes': ['all_constant_error', 'constant_axes', 'constant_axes_of', 'constant_gyro_axes',
             'constant_note', 'constant_readings', 'constant_values', 'fit_varying',
             'identity_axes', 'neutral_runs'],
    'discover': ['build_model', 'discover', 'format_summary', 'write_report'],
    'export': ['check_instance', 'clamp_cost', 'ExportScore', 'FcExport', 'FIRMWARES',
               'fit_export', 'from_params', 'read_params', 'score_export', 'share_kept',
               'write_params'],
    'fit': ['estimate_t0', 'fit_model', 'fit_px4_cubic', 'FitOptions', 'MIN_SAMPLES',
            'PX4_FEATURES', 'TAU_BOUNDS', 'THERMAL_CHOICES'],
    'linear': ['fit_linear', 'LinearFit', 'RIDGE_GRID'],
    'power_cycles': ['check_sessions', 'offset_check_lines', 'reanchor_lines',
                     'reanchor_rule', 'session_check_lines'],
    'still_only': ['find_still', 'MAX_MOVING_SHARE', 'moving_share', 'rows_of', 'still_only_runs'],
    'tau': ['effective_samples', 'fit_time_constant', 'profile_interval', 'TimeConstantFit'],
    'train': ['AUTO', 'choose_features', 'FeatureChoice', 'train', 'train_still_only',
              'TrainOptions', 'TrainResult'],
})
