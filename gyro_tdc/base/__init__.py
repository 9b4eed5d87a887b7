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
The base every package stands on.

Atomic writes, PNG figures, bounded YAML, plain types, limits, shipped resources, parameter
specs, the one field checker, the latest-job worker, the axes and unit factors.
"""

from gyro_tdc.base.face import lazy

__all__, __getattr__, __dir__ = lazy(__name__, {
    'atomicio': ['atomic_dir', 'atomic_json', 'atomic_write', 'clean_leftovers'],
    'face': ['lazy'],
    'figures': ['figure', 'save_png'],
    'fields': ['FieldChecker', 'is_number', 'MAX_COUNT', 'shown'],
    'limits': ['check_bin_width', 'check_centers', 'check_sim_samples',
               'MAX_ACCEL_DRIFT_MPS2', 'MAX_CENTERS', 'MAX_DRIFT_RAD_S', 'MAX_RATE_RAD_S',
               'MAX_SIM_RUNS', 'MAX_SIM_SAMPLES', 'MAX_TEMP_LEAD_S', 'MAX_TEMP_RATE_C_S',
               'MAX_TEMP_SLEW_C_S', 'RESTART_BACK_S', 'SESSION_GAP_PERIODS', 'SESSION_GAP_S',
               'TEMP_PLAUSIBLE_C', 'TEMP_SLEW_MARGIN_C'],
    'plain': ['plain'],
    'preload': ['need', 'start_imports'],
    'plausible': ['plausible_temperatures', 'temperature_ok', 'TemperatureGate'],
    'paramspec': ['format_help', 'help_requested', 'INPUT_FRAMES', 'ParamSpec', 'spec_dataclass',
                  'TEMPERATURE_QUIRKS'],
    'resources': ['config_dir', 'model_path', 'scenario_names', 'scenario_path'],
    'units': ['AXES', 'DEG2_PER_RAD2', 'DEG_PER_RAD', 'G0', 'MG', 'RAD_PER_DEG'],
    'worker': ['Job', 'LatestJob'],
    'yamlio': ['BAG_METADATA_LIMITS', 'load_yaml', 'read_text', 'read_yaml', 'SCENARIO_LIMITS',
               'YamlLimits'],
})
