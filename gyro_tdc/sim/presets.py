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
Sensor presets: the ``gyro``, ``noise`` and ``accel`` sections of a scenario for a device.

A scenario names one with ``sensor: l3gd20``; its own sections override the preset field by
field. The datasheet figures and the chosen unit: ``doc/internals/sim.md``.
"""

from __future__ import annotations

import copy

__all__ = ['PRESETS', 'preset']


def _sensor(range_dps: float, bias: list, dT: list, dT2: list, dT3: list, dTdt: list,
            scale: list, warmup: list, warmup_tau_s: float, bias_instability: list) -> dict:
    """Return one device's sections: its datasheet figures beside what both devices share."""
    return {
        'gyro': {'t_ref_c': 25.0, 'sensitivity_mdps_per_digit': 8.75, 'range_dps': range_dps,
                 'quantise': True, 'bias_dps': bias, 'dT_dps_per_c': dT, 'dT2_dps_per_c2': dT2,
                 'dT3_dps_per_c3': dT3, 'dTdt_dps_per_c_per_s': dTdt, 'scale_ppm_per_c': scale,
                 'warmup_dps': warmup, 'warmup_tau_s': warmup_tau_s, 'power_on_s': 0.0},
        'noise': {'enabled': True, 'arw_dps_per_rt_hz': [0.03, 0.03, 0.03],
                  'bias_instability_dps': bias_instability,
                  'bias_instability_tau_s': [10.0, 100.0, 1000.0],
                  'rrw_dps_per_rt_s': [1.0e-5, 1.0e-5, 1.0e-5]},
        'accel': {'gravity_mps2': 9.80665, 'noise_mps2_per_rt_hz': 0.0015},
    }


PRESETS: dict[str, dict] = {
    'l3gd20': _sensor(250.0, [3.6, -4.3, 1.3], [0.030, -0.024, 0.012], [8.0e-4, 6.0e-4, -2.5e-4],
                      [4.0e-6, -3.0e-6, 2.0e-6], [6.0, -4.0, 3.0], [160.0, -120.0, 90.0],
                      [0.25, -0.18, 0.12], 240.0, [0.004, 0.005, 0.004]),
    'i3g4250d': _sensor(245.0, [2.6, -6.2, 1.3], [0.026, -0.032, 0.010], [5.0e-4, 8.0e-4, -2.0e-4],
                        [3.0e-6, -4.0e-6, 1.5e-6], [5.0, -5.0, 2.5], [150.0, -110.0, 130.0],
                        [0.2, -0.22, 0.1], 300.0, [0.004, 0.004, 0.005]),
}


def preset(name: str) -> dict:
    """
    Return a deep copy of the ``gyro``, ``noise`` and ``accel`` sections of a sensor preset.

    Raises
    ------
    KeyError
        If ``name`` is not a key of ``PRESETS`` (``'l3gd20'``, ``'i3g4250d'``).

    """
    return copy.deepcopy(PRESETS[name])
