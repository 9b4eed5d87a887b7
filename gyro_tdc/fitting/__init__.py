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
Identification of the compensation model from thermal runs.

Three modules, one step each: :mod:`.linear` (centres, ridge, weights: :func:`fit_linear`),
:mod:`.tau` (the time-constant search :func:`fit_time_constant` and its profile interval)
and :mod:`.identify` (:func:`fit_model`: features of the model temperature, the thermal
state and effect parameters by variable projection, the final fit and its metrics).
"""

from gyro_tdc.fitting.identify import (estimate_t0, fit_model, fit_px4_cubic, MIN_SAMPLES,
                                       MIN_SPAN_C, TAU_BOUNDS, THERMAL_CHOICES,
                                       TWO_NODE_MARGIN)
from gyro_tdc.fitting.linear import fit_linear, LinearFit, refine_rbf, RIDGE_GRID
from gyro_tdc.fitting.tau import (effective_samples, fit_time_constant, MAX_TAU_RATIO,
                                  profile_interval, PROFILE_LEVEL, TauProfile,
                                  TimeConstantFit)

__all__ = ['effective_samples', 'estimate_t0', 'fit_linear', 'fit_model', 'fit_px4_cubic',
           'fit_time_constant', 'LinearFit', 'MAX_TAU_RATIO', 'MIN_SAMPLES', 'MIN_SPAN_C',
           'PROFILE_LEVEL', 'profile_interval', 'refine_rbf', 'RIDGE_GRID', 'TAU_BOUNDS',
           'THERMAL_CHOICES', 'TimeConstantFit', 'TauProfile', 'TWO_NODE_MARGIN']
