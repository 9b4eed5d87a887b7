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

"""A short plain-type description of a model, for the tests that check what it holds."""

import math
from typing import Any, Mapping

from gyro_tdc.model.compensation import CompensationModel, FORMAT_VERSION


def summary(model: CompensationModel) -> Mapping[str, Any]:
    """Return a short plain-type description of a model (its ids, terms, range and noise)."""
    out = {'model_id': model.model_id, 'kind': model.kind, 'features': list(model.features),
           'centers': model.n_centers, 't0_c': model.t0_c,
           'temp_range_c': [float(v) for v in model.temp_range_c],
           'effect_params': model.effect_params,
           'residual_std_dps': [math.degrees(math.sqrt(v)) for v in model.residual_var],
           'format_version': FORMAT_VERSION, 'thermal': model.thermal.to_dict()}
    if model.accel is not None:
        a = model.accel
        out['accel'] = {'model_id': a.model_id, 'kind': a.kind, 'features': list(a.features),
                        'temp_range_c': [float(v) for v in a.temp_range_c],
                        'residual_std_mps2': [math.sqrt(v) for v in a.residual_var]}
    return out
