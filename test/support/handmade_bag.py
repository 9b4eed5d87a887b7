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

"""A hand-made evaluated bag (two models, 50 samples) for the report and plot tests."""

from __future__ import annotations

from gyro_tdc.data.runs import Run
from gyro_tdc.evaluate.score import BagEval, ModelEval
import numpy as np


def model_eval(label, bs, p, *, omega=None, outside=0.0):
    """Return a ModelEval with the given BS, P and rates, and fixed Allan readouts."""
    bs = np.asarray(bs, dtype=float)
    return ModelEval(model=f'models/{label}.yaml', label=label, features=['dT'], bs=bs,
                     rms_dps=np.sqrt(bs), p_vs_raw=np.asarray(p, dtype=float),
                     adev_tau_s=np.array([0.1, 1.0]),
                     adev_dps=np.array([[0.2, 0.3, 0.4], [0.02, 0.03, 0.04]]),
                     arw_deg_sqrt_h=np.array([1.5, 1.6, 1.7]),
                     bias_instability_deg_h=np.array([10.0, 20.0, 30.0]),
                     temp_range_c=(-10.0, 30.0), outside_fraction=outside, omega=omega)


def handmade_bag():
    """Return a BagEval of 50 samples: raw, a conventional and a modified model."""
    n = 50
    t = 100.0 + np.arange(n) * 0.5
    temp = np.linspace(20.0, 40.0, n)
    ref = np.tile([0.1, 0.0, 0.0], (n, 1))
    raw = ref + 0.01 * np.arange(n)[:, None] * [1.0, 2.0, 3.0]
    run = Run(t, temp, raw, ref, 'bags/run3')
    models = [model_eval('conv', [4.0, 2.0, 1.0], [0.04, 0.02, 0.01], omega=ref + 0.001),
              model_eval('mod', [1.0, 1.0, 0.5], [0.01, 0.01, 0.005], omega=ref - 0.002,
                         outside=0.25)]
    return BagEval(bag='bags/run3', label='run3', samples=n, temperature_c=(20.0, 40.0),
                   duration_s=24.5 * 3600.0, reference='zero',
                   raw=model_eval('raw', [100.0, 100.0, 100.0], [1.0, 1.0, 1.0], omega=raw),
                   models=models, run=run)
