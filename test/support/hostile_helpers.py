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

"""A small hand-made model and a one-line-error check, shared by the hostile-input tests."""

from __future__ import annotations

from gyro_tdc.model.compensation import CompensationModel
import numpy as np


def small_model(k: int = 4, **changes) -> CompensationModel:
    """Return a small hand-made RBF model (no fitting), seeded."""
    rng = np.random.default_rng(5)
    centers, widths = rng.normal(size=(k, 2)), rng.uniform(0.2, 1.0, k)
    weights, linear = rng.normal(scale=1e-3, size=(k, 3)), rng.normal(scale=1e-3, size=(2, 3))
    norm = (np.array([10.0, 300.0]), np.array([20.0, 400.0]), centers, widths)
    coef = np.vstack([[1e-3, -2e-3, 5e-4], linear, weights])
    m = CompensationModel.network(
        'rbf', ('dT', 'dT2'), {}, 20.0, norm, coef, temp_range_c=(-10.0, 50.0),
        residual_var=np.full(3, 1e-8), frame_id='imu_link', sensor_id='unit-7',
        metrics={'samples': 1000, 'runs': ['/bags/run1']},
        created={'utc': '2026-01-01T00:00:00+00:00', 'command': 'test'})
    return m.replace(**changes) if changes else m


def one_line_error(exc_info) -> str:
    """Return the message of a raised error after checking it is one line."""
    text = str(exc_info.value)
    assert '\n' not in text and text
    return text
