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
Evaluation and reporting.

Held-out scores in the paper's terms, baselines, reports, plots and the bursty real-data
evaluation.
"""

from gyro_tdc.base.face import lazy

__all__, __getattr__, __dir__ = lazy(__name__, {
    'models': ['axes_words', 'imu_mismatch', 'load_models', 'NamedModel', 'ONBOARD',
               'onboard_model', 'PX4'],
    'plots': ['model_description', 'write_plots'],
    'report': ['format_bag', 'format_coverage', 'format_means', 'format_sessions', 'format_still',
               'format_training', 'is_coverage_line', 'POLICY_WORDS', 'REANCHOR_SPREAD_DPS',
               'write_csv', 'write_json'],
    'score': ['AUTO_REANCHOR', 'BagEval', 'evaluate', 'mean_scores'],
})
