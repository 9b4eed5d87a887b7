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

"""Result types of a fleet run: one line per sensor and the whole run."""

from __future__ import annotations

from dataclasses import dataclass, field

__all__ = ['FleetResult', 'SensorResult']


@dataclass
class SensorResult:
    """
    One sensor's line of the fleet summary.

    Parameters
    ----------
    sensor_id : str
        The sensor.
    status : str
        ``'ok'`` or ``'failed'``.
    error : str
        One-line reason when failed.
    model_file : str or None
        The model written (or kept, when skipped).
    train_bs, heldout_bs : list of 3 float or None, (deg/s)^2
        Training and mean held-out BS per axis.
    skipped : bool
        True when inputs and options were unchanged and the model was kept.
    drift_poly : list or None, deg/s per degC^k
        Static drift quadratic per axis (see :func:`drift_polynomial`).
    temp_range_c : list of 2 float or None, degC
        The model's trained temperature range.
    slope, curvature : list of 3 float or None, deg/s/degC and deg/s/degC^2
        Drift slope at the fleet's reference temperature and curvature per axis.
    z_slope, z_curvature : list of 3 float or None
        Their robust z-scores against the fleet (None when not computed).
    flags : list of str
        Fleet-outlier flags.
    seconds : float, s
        Wall time of the task on its worker (0 when skipped).
    constant_axes : list of str
        The gyro axes constant in the sensor's training bags (never varying beyond one
        quantum): not fitted, its model passes them through; they take no part in the fleet
        statistics (no slope, curvature or z-score there, never flagged).

    """

    sensor_id: str
    status: str
    error: str = ''
    model_file: str | None = None
    train_bs: list | None = None
    heldout_bs: list | None = None
    skipped: bool = False
    drift_poly: list | None = None
    temp_range_c: list | None = None
    slope: list | None = None
    curvature: list | None = None
    z_slope: list | None = None
    z_curvature: list | None = None
    flags: list = field(default_factory=list)
    seconds: float = 0.0
    constant_axes: list = field(default_factory=list)

    def constant_note(self) -> str:
        """Return the table's note on the constant axes ('' when none)."""
        if not self.constant_axes:
            return ''
        many = len(self.constant_axes) > 1
        return (f'gyro ax{"es" if many else "is"} {", ".join(self.constant_axes)} constant '
                '(not fitted, passed through; not in the fleet statistics)')


@dataclass
class FleetResult:
    """
    Everything a fleet run produced.

    Parameters
    ----------
    scheduler : str
        ``'local'`` for the embedded cluster, else the scheduler address.
    workers : int
        Dask workers at the start.
    sensors : list of SensorResult
        In manifest order.
    reference_c : float or None, degC
        Temperature at which drift slopes are compared (the fleet's median of the middle
        of each model's trained range).
    outlier_z : float
        Flag threshold on the robust z-score.
    seconds : float, s
        Wall time of the run.

    """

    scheduler: str
    workers: int
    sensors: list
    reference_c: float | None = None
    outlier_z: float = 3.5
    seconds: float = 0.0

    @property
    def failed(self) -> list:
        """Return the sensors that failed."""
        return [s for s in self.sensors if s.status != 'ok']
