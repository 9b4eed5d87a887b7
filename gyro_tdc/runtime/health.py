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
The compensator's health as /diagnostics shows it: a level, a message and key/value pairs.

Pure (no rclpy); what it judges and shows: doc/internals/runtime.md.
"""

from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Any, Mapping, NamedTuple, TYPE_CHECKING

from gyro_tdc.base import MAX_TEMP_SLEW_C_S, TEMP_PLAUSIBLE_C
from gyro_tdc.model import SETTLE_TAUS
from gyro_tdc.runtime.flags import (describe_flags, IMPLAUSIBLE_INPUT, IMPLAUSIBLE_OUTPUT,
                                    NO_ACCEL_DATA, NO_MODEL, NO_TEMPERATURE, NON_FINITE,
                                    OUT_OF_RANGE, PASSTHROUGH, STALE, UPSTREAM)
from gyro_tdc.runtime.reanchor import PROVISIONAL

if TYPE_CHECKING:  # pragma: no cover - typing only (core does not import this module)
    from gyro_tdc.model import CompensationModel
    from gyro_tdc.runtime.core import CompensatorCore
    from gyro_tdc.runtime.policy import Policy

__all__ = ['ERROR', 'Health', 'InputStatus', 'OK', 'WARN', 'accel_state', 'counters',
           'frame_mismatch', 'health', 'sensor_mismatch', 'upstream_note']


def accel_state(core: CompensatorCore) -> str:
    """
    Say whether the accelerometer is compensated (the ``accelerometer`` value of /diagnostics).

    Returns
    -------
    str
        ``'compensated'``, ``'not in model'`` (no model, or one without an accelerometer
        part) or ``'passthrough (why)'`` for the last sample.

    """
    flags = core.accel_flags
    return ('not in model' if getattr(core.model, 'accel', None) is None else
            'passthrough (no sample yet)' if flags == -1 else
            'passthrough (no accelerometer data in the Imu)' if flags & NO_ACCEL_DATA else
            f'passthrough ({describe_flags(flags & ~PASSTHROUGH)})' if flags & PASSTHROUGH
            else 'compensated')


#: Levels of :class:`Health` (the byte values of diagnostic_msgs/DiagnosticStatus).
OK, WARN, ERROR = 0, 1, 2


@dataclass
class InputStatus:
    """What the node knows of its input beyond the samples themselves (kept by the node)."""

    #: QoS reliability of the IMU subscription (``best_effort`` or ``reliable``).
    reliability: str = 'best_effort'
    #: Input messages DDS reported lost (the subscription's message-lost event, cumulative).
    lost: int = 0
    #: Input samples that carried the compensation mark (:mod:`gyro_tdc.data.mark`).
    already_compensated: int = 0
    #: Input messages that could not be read as an Imu (dropped, nothing to republish).
    malformed: int = 0
    #: Nodes publishing the input topic that look like gyro_tdc compensators.
    upstream: tuple[str, ...] = ()


class Health(NamedTuple):
    """
    The compensator's state as /diagnostics shows it.

    ``level`` is ``OK``, ``WARN`` or ``ERROR``; ``hardware_id`` the ``sensor_id`` parameter,
    else the data's frame id (never the model's: it names the hardware reporting);
    ``values`` the key/value pairs in display order; ``mark`` the cumulative counters now
    (:func:`counters`), to pass to the next :func:`health` call.
    """

    level: int
    message: str
    hardware_id: str
    values: dict[str, str]
    mark: dict[int | str, int]


def counters(core: CompensatorCore, inputs: InputStatus) -> dict[int | str, int]:
    """
    Return the cumulative counters a report counts its news from.

    Samples per flag bit, then ``rejected`` (non-finite readings), ``implausible`` (readings
    the plausibility gate refused), ``errors``, and the inputs ``lost``, ``malformed`` and
    ``marked`` (already compensated).
    """
    return {**core.flag_counts, 'rejected': core.temps.rejected,
            'implausible': core.temps.implausible, 'errors': core.tally.errors,
            'lost': inputs.lost, 'malformed': inputs.malformed,
            'marked': inputs.already_compensated}


def sensor_mismatch(model: CompensationModel | None, sensor_id: str) -> str:
    """
    Say why ``model`` was not trained for the sensor ``sensor_id`` ('' when it was).

    One line naming both ids and what to do; '' without a model, with ``sensor_id`` '' (no
    check) or on a match.
    """
    if not sensor_id or model is None or model.sensor_id == sensor_id:
        return ''
    trained = (f'sensor_id {model.sensor_id!r}' if model.sensor_id else
               'no sensor_id (the shipped l3gd20_modified is a simulated L3GD20)')
    return (f'model {model.model_id} was trained for {trained}, not for this IMU '
            f"(sensor_id {sensor_id!r}): its drift curve is another sensor's; train one on "
            "this IMU's recordings (gyro-tdc train --sensor-id)")


def frame_mismatch(model: CompensationModel | None, frame_id: str) -> str:
    """
    Say why ``model`` was not trained in the frame of the data ``frame_id`` ('' when it was).

    ``frame_id`` is ``header.frame_id`` of the latest imu/data_raw message. One line naming
    both frames; '' without a model, without a frame on either side, or on a match.
    """
    if model is None or not frame_id or not model.frame_id or model.frame_id == frame_id:
        return ''
    return (f'imu/data_raw is in frame {frame_id!r} but model {model.model_id} was trained in '
            f'{model.frame_id!r} (sensor.frame_id): its per-axis correction assumes that '
            "frame's axes; train on data in this frame, or check the driver's frame_id")


def upstream_note(policy: Policy) -> str:
    """
    Say what the compensator does about a declared upstream correction ('' none).

    Parameters
    ----------
    policy : Policy
        The compensator's policy (``upstream_correction``, ``upstream_policy``).

    Returns
    -------
    str
        '' when no upstream correction is declared; else one line starting with
        ``gyro already thermally corrected upstream (<which>)`` (``gyro already corrected
        upstream`` for px4_ekf, ``gyro bias removed upstream at start`` for bias_at_start)
        and saying whether the raw rate passes through or is compensated on top.

    """
    if not (which := policy.upstream_correction):
        return ''
    passthrough = policy.upstream_policy == 'passthrough'
    if which == 'bias_at_start':
        return 'gyro bias removed upstream at start (bias_at_start): ' + (
            'raw rate passed through, its thermal drift since the start stays (upstream_policy '
            'compensate corrects it, re-anchoring takes the removed bias out)' if passthrough
            else 'compensating, re-anchoring takes the removed bias out (reanchor_on_start)'
            if policy.reanchor_on_start else 'compensating, but reanchor_on_start is false: '
            "the output is off by the model's bias at the start temperature; set it true")
    head, instead = (
        ('gyro already corrected upstream (px4_ekf: the EKF gyro bias off HIGHRES_IMU)',
         'take the rate without the EKF bias, e.g. PX4 uXRCE-DDS sensor_gyro, and clear '
         'upstream_correction') if which == 'px4_ekf' else
        (f'gyro already thermally corrected upstream ({which})', 'disable the upstream '
         'correction, e.g. TC_G_ENABLE=0 or INS_TCALn_ENABLE=0, and clear upstream_correction'))
    return f'{head}: ' + (
        f'raw rate passed through, not corrected twice (to compensate here instead, {instead})'
        if passthrough else 'compensating on top of it (upstream_policy compensate: the model '
        'must be trained on the already corrected rate)')


def health(core: CompensatorCore, since: Mapping | None = None, *, model_file: str = '',
           last_reload: str = 'none', inputs: InputStatus | None = None,
           sensor_id: str = '', frame_id: str = '') -> Health:
    """
    Judge the compensator's state: what went wrong since ``since``, and its figures.

    ERROR without a model (unless the gyro is declared corrected upstream and passes
    through) or when a compensation raised. WARN on a declared upstream correction
    (:func:`upstream_note`); on samples with a missing, stale, out-of-range, non-finite or
    implausible input or an implausible output; on rejected thermometer samples, lost or
    already compensated input, another gyro_tdc compensator on the input topic; on a refused
    model file (``last_reload`` 'rejected: ...'); on a model of another sensor
    (:func:`sensor_mismatch`) or frame (:func:`frame_mismatch`). Else OK ('compensating',
    or 'waiting for imu/data_raw'). ``since`` is the previous report's ``mark`` (None: from
    the start); ``inputs`` the losses, marked samples and upstream compensators the node saw;
    ``frame_id`` also stands for the ``hardware_id`` when ``sensor_id`` is ''.
    """
    inputs = inputs or InputStatus()
    mark = counters(core, inputs)
    new = {k: n - (since or {}).get(k, 0) for k, n in mark.items()}
    level, problems = _problems(core, new, inputs, last_reload, sensor_id, frame_id)
    message = '; '.join(problems) or ('compensating' if core.counts['in'] else
                                      'waiting for imu/data_raw')
    if new[PASSTHROUGH]:
        message += f'; {new[PASSTHROUGH]} samples passed through uncompensated'
    values = _values(core, inputs, model_file, last_reload, frame_id).items()
    return Health(level, message, sensor_id or frame_id, {k: str(v) for k, v in values}, mark)


def _problems(core: CompensatorCore, new: dict[int | str, int], inputs: InputStatus,
              last_reload: str, sensor_id: str, frame_id: str) -> tuple[int, list[str]]:
    """Return the level and the problems of :func:`health` (``new``: counters since the last)."""
    model, found = core.model, []         # found: (level, problem)
    if (upstream := upstream_note(core.policy)) and core.upstream_pass:
        found.append((WARN, upstream))
    if model is None and not core.upstream_pass:
        found.append((ERROR, f'no model loaded ({last_reload})'))
    elif last_reload.startswith('rejected: '):
        found.append((WARN, f'model file refused, keeping {model.model_id}: '
                            f'{last_reload[len("rejected: "):]}'))
    found += [(WARN, why) for why in (sensor_mismatch(model, sensor_id),
                                      frame_mismatch(model, frame_id)) if why]
    found += [(WARN, f'{describe_flags(bit)} ({new[bit]} samples)')
              for bit in (NO_TEMPERATURE, STALE, OUT_OF_RANGE, NON_FINITE, IMPLAUSIBLE_INPUT,
                          IMPLAUSIBLE_OUTPUT) if new[bit]]
    lo, hi = TEMP_PLAUSIBLE_C
    rejected, implausible, lost, malformed, marked = (
        new[k] for k in ('rejected', 'implausible', 'lost', 'malformed', 'marked'))
    found += [(WARN, text) for count, text in (
        (rejected, f'non-finite temperature ({rejected} samples rejected)'),
        (implausible, f'temperatures rejected (implausible): {implausible} (outside {lo:g}..'
                      f'{hi:g} degC, faster than {MAX_TEMP_SLEW_C_S:g} degC/s from the last '
                      'good one, or stamped too far ahead of the IMU; the last good one is '
                      'held)'),
        (lost, f'input messages lost ({lost}, reported by DDS; at least that many)'),
        (malformed, f'malformed input messages dropped ({malformed}: not a serialized '
                    'sensor_msgs/Imu)'),
        (marked, f'input already compensated by gyro_tdc ({marked} samples): the model is '
                 'applied twice')) if count]
    if inputs.upstream:
        found.append((WARN, f'imu/data_raw is published by gyro_tdc compensator '
                            f'{", ".join(inputs.upstream)}: chained compensators apply the '
                            'drift model twice'))
    if errors := new['errors']:
        found.append((ERROR, f'compensation failed on {errors} samples, passed through: '
                             f'{core.last_error}'))
    return max((level for level, _ in found), default=OK), [why for _, why in found]


def _values(core: CompensatorCore, inputs: InputStatus, model_file: str, last_reload: str,
            frame_id: str) -> dict[str, Any]:
    """Return :func:`health`'s key/value pairs (not yet strings)."""
    model, anchor, flags, counts = core.model, core.anchor, core.last_flags, core.flag_counts
    age, k = core.temperature_age(), core.reanchoring.sessions
    session = (f' (session {k.session} from t={k.t0:.3f} s, after a {k.why})'
               if k.session > 1 else '')
    mid, features, kind, frame, lims = ('',) * 5 if model is None else (
        model.model_id, ','.join(model.features), model.kind, model.frame_id,
        '{:.2f}..{:.2f}'.format(*model.temp_range_c))
    values = {
        'compensation active': (model is not None and core.counts['compensated'] > 0
                                and not flags & PASSTHROUGH),
        'why not': describe_flags(flags & ~OUT_OF_RANGE) if flags & PASSTHROUGH else '',
        'model id': mid, 'model file': model_file, 'model features': features,
        'model kind': kind, 'model frame': frame, 'data frame': frame_id,
        'model range degC': lims, 'last reload': last_reload,
        'temperature degC': f'{core.stream.temp:.3f}' if core.stream.temp is not None else '',
        'temperature age s': f'{age:.3f}' if age is not None else '',
        'temperature stale': bool(flags & STALE), 'in range': not flags & OUT_OF_RANGE,
        'out of range policy': core.policy.out_of_range,
        'range distance degC': f'{core.stream.distance_c:+.2f}',
        'messages in': core.counts['in'], 'messages out': core.counts['out'],
        'compensated': core.counts['compensated'], 'passed through': counts[PASSTHROUGH],
        'no temperature yet': counts[NO_TEMPERATURE], 'stale': counts[STALE],
        'out of range': counts[OUT_OF_RANGE], 'non-finite': counts[NON_FINITE],
        'no model': counts[NO_MODEL], 'implausible input': counts[IMPLAUSIBLE_INPUT],
        'implausible output': counts[IMPLAUSIBLE_OUTPUT],
        'temperatures rejected': core.temps.rejected,
        'temperatures rejected (implausible)': core.temps.implausible,
        'errors': core.tally.errors, 'last error': core.last_error,
        'input reliability': inputs.reliability, 'input lost': inputs.lost,
        'input malformed': inputs.malformed, 'already compensated': inputs.already_compensated,
        'upstream compensators': ','.join(inputs.upstream),
        'upstream correction': upstream_note(core.policy) or 'none declared',
        'passed through as corrected upstream': counts[UPSTREAM],
        'accelerometer': accel_state(core),
        'reanchor': ('off' if not core.policy.reanchor_on_start else
                     'offset from the learner' if anchor is None and core.reanchoring.learned
                     else 'waiting for stillness' if anchor is None else
                     f'averaging, provisional shift at t={anchor.t:.3f} s'
                     if anchor.reason == PROVISIONAL else f'done at t={anchor.t:.3f} s') + session,
    }
    if core.accel_on:
        values.update((f'accelerometer {k}', v) for k, v in core.tally.accel.items())
    # The lagged state's start-up assumption (3 tau); None: no model or no lagged state.
    if (settling := getattr(core.slot.comp, 'thermal_progress', None)) is not None:
        values['thermal state'] = (f'settling ({settling:.1f} of {SETTLE_TAUS:g} tau)'
                                   if settling < SETTLE_TAUS else 'settled')
    if anchor is not None:
        def dps(v: tuple[float, ...]) -> str:
            return ','.join(f'{math.degrees(x):.5f}' for x in v)
        values.update({'reanchor shift dps': dps(anchor.delta), 'reanchor samples': anchor.samples,
                       'reanchor duration s': f'{anchor.duration_s:.3f}',
                       'reanchor se dps': dps(anchor.se),
                       'reanchor tolerance dps': dps(anchor.tolerance),
                       'reanchor stopped on': anchor.reason or 'one window'})
    return values
