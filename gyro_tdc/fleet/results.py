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
What a fleet run produced and how it is reported.

The result types (one line per sensor, the whole run) and the summary written from them:
``summary.json`` (documented shape), ``summary.csv`` and the console table.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass, field
import io
import os
from pathlib import Path

from gyro_tdc.base import atomic_json, atomic_write, AXES
from gyro_tdc.evaluate import axes_words

__all__ = ['FleetResult', 'SensorResult', 'format_table', 'summary_dict', 'write_summary']


@dataclass
class SensorResult:
    """One sensor's line of the fleet summary: its model, its scores and its outlier flags."""

    #: The sensor.
    sensor_id: str
    #: ``'ok'`` or ``'failed'``.
    status: str
    #: One-line reason when failed.
    error: str = ''
    #: The model written (or kept, when skipped).
    model_file: str | None = None
    #: Training BS per axis, (deg/s)^2.
    train_bs: list | None = None
    #: Mean held-out BS per axis, (deg/s)^2.
    heldout_bs: list | None = None
    #: True when inputs and options were unchanged and the model was kept.
    skipped: bool = False
    #: Static drift quadratic per axis, deg/s per degC^k (see :func:`drift_polynomial`).
    drift_poly: list | None = None
    #: The model's trained temperature range (2 floats), degC.
    temp_range_c: list | None = None
    #: Drift slope per axis at the fleet's reference temperature, deg/s/degC.
    slope: list | None = None
    #: Drift curvature per axis, deg/s/degC^2.
    curvature: list | None = None
    #: Robust z-score of ``slope`` per axis against the fleet (None when not computed).
    z_slope: list | None = None
    #: Robust z-score of ``curvature`` per axis against the fleet (None when not computed).
    z_curvature: list | None = None
    #: Fleet-outlier flags.
    flags: list = field(default_factory=list)
    #: Wall time of the task on its worker, s (0 when skipped).
    seconds: float = 0.0
    #: The gyro axes constant in the sensor's training bags (never varying beyond one
    #: quantum): not fitted, its model passes them through; they take no part in the fleet
    #: statistics (no slope, curvature or z-score there, never flagged).
    constant_axes: list = field(default_factory=list)

    def constant_note(self) -> str:
        """Return the table's note on the constant axes ('' when none)."""
        return (f'gyro {axes_words(self.constant_axes)} constant (not fitted, passed through; '
                'not in the fleet statistics)' if self.constant_axes else '')


@dataclass
class FleetResult:
    """Everything a fleet run produced: the summary's lines and how they were computed."""

    #: ``'local'`` for the embedded cluster, else the scheduler address.
    scheduler: str
    #: Dask workers at the start.
    workers: int
    #: One :class:`SensorResult` per sensor, in manifest order.
    sensors: list
    #: Temperature at which drift slopes are compared, degC (the fleet's median of the
    #: middle of each model's trained range).
    reference_c: float | None = None
    #: Flag threshold on the robust z-score.
    outlier_z: float = 3.5
    #: Wall time of the run, s.
    seconds: float = 0.0

    @property
    def failed(self) -> list:
        """Return the sensors that failed."""
        return [s for s in self.sensors if s.status != 'ok']


def summary_dict(result: FleetResult) -> dict:
    """
    Return the ``summary.json`` content (doc/json.md).

    Per sensor its status, error, model file, training and held-out BS ((deg/s)^2 per axis),
    flags, and the axes constant in its training bags (passed through, left out of the
    fleet statistics).
    """
    rows = [{'sensor_id': s.sensor_id, 'status': s.status,
             **({'error': s.error} if s.status != 'ok' else {}),
             'model_file': s.model_file, 'train_bs': s.train_bs, 'heldout_bs': s.heldout_bs,
             'flags': list(s.flags),
             **({'constant_axes': list(s.constant_axes)} if s.constant_axes else {})}
            for s in result.sensors]
    return {'engine': 'dask', 'scheduler': result.scheduler, 'workers': result.workers,
            'sensors': rows}


def _csv_text(result: FleetResult) -> str:
    """Return ``summary.csv``: one row per sensor: BS, drift coefficients, z-scores, flags."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator='\n')
    per_axis = ('train_bs', 'heldout_bs', 'slope', 'curvature', 'z_slope', 'z_curvature')
    w.writerow(['sensor_id', 'status', 'skipped', 'seconds', 'model_file', 'slope_at_c']
               + [f'{c}_{a}' for c in per_axis for a in AXES]
               + ['flags', 'constant_axes', 'error'])

    def cells(values: list | None) -> list:
        return ['' if values is None or values[a] is None else f'{values[a]:.6g}'
                for a in range(3)]

    ref = '' if result.reference_c is None else f'{result.reference_c:.3f}'
    w.writerows([s.sensor_id, s.status, int(s.skipped), f'{s.seconds:.3f}', s.model_file or '',
                 ref if s.slope is not None else '']
                + [c for name in per_axis for c in cells(getattr(s, name))]
                + ['; '.join(s.flags), ' '.join(s.constant_axes), s.error] for s in result.sensors)
    return buf.getvalue()


def write_summary(result: FleetResult, out_dir: str | os.PathLike) -> tuple[Path, Path]:
    """Write ``summary.json`` and ``summary.csv`` into ``out_dir`` atomically; return the paths."""
    d = Path(out_dir)
    js = atomic_json(d / 'summary.json', summary_dict(result), what='fleet summary',
                     ensure_ascii=False)
    return js, atomic_write(d / 'summary.csv', _csv_text(result), what='fleet summary', newline='')


def format_table(result: FleetResult, *, max_rows: int = 40) -> str:
    """
    Return the console table: one line per sensor (when many, the noteworthy ones only).

    With more than ``max_rows`` sensors, only the failed ones, the flagged ones and those
    with a constant gyro axis are listed.

    Parameters
    ----------
    result : FleetResult
        The fleet run.
    max_rows : int
        Above this many sensors, list only failed and flagged sensors.

    Returns
    -------
    str
        The table and a count line.

    """
    def bs(values: list | None) -> str:
        return ' '.join(f'{v:9.3g}' for v in values) if values else f'{"-":>29}'

    shown = result.sensors
    if len(shown) > max_rows:
        shown = [s for s in shown if s.status != 'ok' or s.flags or s.constant_axes]
    w = max([len(s.sensor_id) for s in shown] + [9])
    lines = [f'{"sensor_id":<{w}}  {"status":<7}  {"train BS x y z (deg/s)^2":<29}  '
             f'{"held-out BS x y z":<29}  flags / error']
    for s in shown:
        status = 'skipped' if s.skipped else s.status
        note = (s.error if s.status != 'ok'
                else '; '.join(s.flags + ([s.constant_note()] if s.constant_axes else [])))
        lines.append(f'{s.sensor_id:<{w}}  {status:<7}  {bs(s.train_bs)}  '
                     f'{bs(s.heldout_bs)}  {note}'.rstrip())
    n_ok = sum(s.status == 'ok' for s in result.sensors)
    n_flag = sum(bool(s.flags) for s in result.sensors)
    n_skip = sum(s.skipped for s in result.sensors)
    n_const = sum(bool(s.constant_axes) for s in result.sensors if s.status == 'ok')
    lines.append(f'{len(result.sensors)} sensors: {n_ok} ok ({n_skip} unchanged, skipped), '
                 f'{len(result.sensors) - n_ok} failed, {n_flag} flagged as fleet outliers '
                 f'(|z| > {result.outlier_z:g})'
                 + (f', {n_const} with a constant gyro axis (not in the statistics)'
                    if n_const else '')
                 + f'; {result.workers} Dask worker(s), {result.seconds:.1f} s')
    return '\n'.join(lines)
