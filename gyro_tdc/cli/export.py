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
``gyro-tdc export --px4 MODEL --out FILE.params`` (``--ardupilot``; ``--model`` -> YAML).

Fits the model's steady-state drift in the flight controller's cubic
(:mod:`gyro_tdc.identify.export`), writes the parameter file its ground station loads, says
where the firmware's clamp will cost and, with ``--eval BAG...``, how much of the held-out
improvement the form keeps against the full model (``doc/flight_controllers.md``).
``--model LEARN_FILE --out model.yaml`` writes a learn_file's learned model as a model file.
"""

from __future__ import annotations

import argparse
from typing import Optional, Sequence

from gyro_tdc.cli import PROG
from gyro_tdc.cli.common import (add_bag_options, ArgumentParser, bag_options, command_line,
                                 non_negative_float, non_negative_int, run_command, UsageError)
from gyro_tdc.data import load_runs
from gyro_tdc.identify import (check_instance, clamp_cost, fit_export, from_params, read_params,
                               score_export, share_kept, write_params)
from gyro_tdc.learn import read_model
from gyro_tdc.model import DEFAULT_OUT_OF_RANGE, save_model
import numpy as np

__all__ = ['build_parser', 'main']

#: Where each firmware's ground station loads the file.
_LOAD = {'px4': 'QGroundControl: Vehicle Setup > Parameters > Tools > Load from file, then reboot',
         'ardupilot': 'Mission Planner: Config > Full Parameter List > Load from file; '
                      'MAVProxy: param load FILE; then reboot'}


def build_parser() -> argparse.ArgumentParser:
    """Return the argument parser of ``export``."""
    p = ArgumentParser(prog=f'{PROG} export', description="Write a model's drift as a flight "
                       "controller's thermal-calibration parameters (PX4 TC_G*/TC_A*, ArduPilot "
                       'INS_TCALn_*), fitted in their exact cubic over the trained range; with '
                       '--eval, score the form as the firmware applies it beside the full model '
                       'on held-out bags. Or, with --model, write a model (a learn_file: its '
                       'learned model) as a model file. MODEL is a model file, a shipped name or '
                       'a learn_file.')
    which = p.add_mutually_exclusive_group(required=True)
    which.add_argument('--model', metavar='MODEL', help='model file or learn_file to write as a '
                       'gyro_tdc model file (YAML) at --out: the learned model of a learn_file, '
                       'to evaluate, inspect or ship to another vehicle as model_file')
    which.add_argument('--px4', metavar='MODEL', help='model file (or shipped name) to export as '
                       'PX4 TC_* parameters (a QGroundControl .params file)')
    which.add_argument('--ardupilot', metavar='MODEL',
                       help='model file (or shipped name) to export as ArduPilot INS_TCALn_* '
                            'parameters (a Mission Planner / MAVProxy .parm file)')
    p.add_argument('-o', '--out', required=True, metavar='FILE',
                   help='parameter file to write (with --model: the model file)')
    p.add_argument('--instance', type=non_negative_int, default=0, metavar='N',
                   help='PX4 calibration slot 0..3 (TC_G<N>) or ArduPilot IMU 0..2 '
                        '(INS_TCAL<N+1>) (default: %(default)s)')
    p.add_argument('--device-id', type=non_negative_int, metavar='ID',
                   help="PX4 TC_Gn_ID: the gyro's device_id (sensor_gyro.device_id, "
                        "CAL_GYRn_ID); default: the model's sensor_id when it is a number, "
                        'else 0 (PX4 then applies the slot to no gyro)')
    p.add_argument('--eval', nargs='+', metavar='BAG',
                   help='held-out bags (or flight logs): BS and RMS of raw, full model and '
                        'the exported form applied as the firmware applies it')
    p.add_argument('--reanchor', type=non_negative_float, default=0.0, metavar='S',
                   help="with --eval: remove the model's and the form's mean error over the "
                        'first S s of each bag (the offset a gyro calibration at boot takes; '
                        'default 0: off)')
    add_bag_options(p)
    return p


def _axes(values) -> str:
    return ' '.join(f'{v:10.3e}' for v in values)


def _model_line(spec: str, model, what: str) -> str:
    """Return ``model SPEC (id, kind features), WHAT lo .. hi degC``: the model at hand."""
    lo, hi = model.temp_range_c
    return (f'model {spec} ({model.model_id}, {model.kind} {",".join(model.features)}), '
            f'{what} {lo:.2f} .. {hi:.2f} degC')


def _write_model(args: argparse.Namespace) -> int:
    """Write ``--model`` (a learn_file's learned model) as a model file at ``--out``."""
    if args.eval or args.reanchor:
        raise UsageError('--eval and --reanchor are for --px4/--ardupilot; evaluate a model '
                         'with gyro-tdc evaluate BAG --model MODEL')
    model = read_model(args.model)
    path = save_model(model, args.out)
    learned = model.created.get('learn_file')
    print(_model_line(args.model, model, 'range')
          + (f': learned, {model.created.get("points")} points, last update at stamp '
             f'{model.created.get("last_update_stamp_s")} s' if learned else ''))
    print(f'wrote {path}' + (' (its offset is that of the last session: re-anchor it on another '
                             'power cycle, reanchor_on_start / evaluate --reanchor auto)'
                             if learned else ''))
    return 0


def _run(args: argparse.Namespace, argv: list) -> int:
    """Run ``export`` with parsed arguments."""
    if args.model is not None:
        return _write_model(args)
    firmware, spec = ('px4', args.px4) if args.px4 is not None else ('ardupilot', args.ardupilot)
    check_instance(firmware, args.instance, '--instance')
    if args.reanchor and not args.eval:
        raise UsageError('--reanchor is only used with --eval BAG...')
    model = read_model(spec)
    lo, hi = model.temp_range_c
    state = ('steady-state drift vs temperature (the thermal state settled)'
             if model.thermal.kind != 'none' else 'drift vs temperature')
    print(_model_line(spec, model, 'trained') + f': its {state} fitted on a uniform '
          'temperature grid')
    # PX4 TC_Gn_ID: --device-id, or the model's numeric sensor_id, or 0.
    sid = str(model.sensor_id).strip()
    device_id = args.device_id if args.device_id is not None else int(sid) if sid.isdigit() else 0
    fitted = fit_export(model, firmware, instance=args.instance,
                        device_id=device_id if firmware == 'px4' else 0)
    path = write_params(fitted, args.out, header=[
        ('Sensor thermal compensation parameters' if firmware == 'px4' else
         'IMU temperature calibration') + f' from gyro_tdc model {model.model_id}',
        f'{command_line("export", argv)}',
        f'fitted over {lo:.2f} .. {hi:.2f} degC; clamped there by the firmware'])
    form = from_params(read_params(path), firmware, instance=args.instance)
    g = form.gyro
    if firmware == 'px4':
        print(f'px4 form: TC_G{args.instance}_X0..X3 about TREF {g.tref:.2f} degC, clamped '
              f'to TMIN {g.tmin:.2f} .. TMAX {g.tmax:.2f} degC'
              + ('; TC_A too' if form.accel is not None else ''))
    else:
        print(f'ardupilot form: INS_TCAL{args.instance + 1}_GYR1..3 (x1e6) about 35 degC '
              f'without constant, clamped to TMIN {g.tmin:.2f} .. TMAX {g.tmax:.2f} degC, '
              f'offsets at CALTEMP {g.caltemp:.2f} degC')
    print('form minus model over the range (RMS, deg/s): ' + _axes(fitted.fit_rms_dps))
    print(f'wrote {path} ({len(fitted.params)} parameters; {_LOAD[firmware]})')
    print(''.join(f'note: {note}\n' for note in fitted.notes), end='')
    print(f'clamp: outside TMIN..TMAX the firmware holds the correction, the model continues '
          f'({DEFAULT_OUT_OF_RANGE}, as the compensator node); largest axis gap:')
    print('\n'.join(f'  at {c["temp_c"]:7.2f} degC: {c["gap_dps"]:.4f} deg/s'
                    for c in clamp_cost(model, form)))
    if args.eval:
        _evaluate(args, model, form, firmware)
    return 0


def _evaluate(args: argparse.Namespace, model, form, firmware: str) -> None:
    """Score the held-out bags and print the tables and the share of the improvement kept."""
    runs = load_runs(args.eval, bag_options(args), log=print)
    how = (f', mean error of the first {args.reanchor:g} s removed (model and form)'
           if args.reanchor else '')
    print(f'held out: BS (deg/s)^2 and RMS deg/s per axis x y z; {firmware} applied as the '
          f'firmware does (raw minus its correction at the measured temperature, clamped)' + how)
    scores = score_export(model, {firmware: form}, runs, reanchor_s=args.reanchor)
    labels = ('raw', 'model', firmware)
    for s in scores:
        print(f'{s.name}: {s.samples} samples, {100 * s.outside_fraction:.1f} % outside '
              'TMIN..TMAX')
        for label in labels:
            print(f'  {label:<10} BS {_axes(s.bs[label])}   RMS {_axes(s.rms_dps[label])}')
        print(f"  {firmware} keeps {100 * s.kept(firmware):.2f} % of the full model's "
              f'improvement over raw (BS {firmware}/model '
              f'{np.mean(s.bs[firmware]) / np.mean(s.bs["model"]):.2f})')
    if len(scores) > 1:
        mean = {k: float(np.mean([np.mean(s.bs[k]) for s in scores])) for k in labels}
        kept = share_kept(mean['raw'], mean['model'], mean[firmware])
        print(f'mean over {len(scores)} bags: {firmware} keeps {100 * kept:.2f} % (BS raw '
              f'{mean["raw"]:.3e}, model {mean["model"]:.3e}, {firmware} {mean[firmware]:.3e})')


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Run ``gyro-tdc export``: 0 on success, 2 on bad input (see ``run_command``)."""
    return run_command('export', build_parser, _run, argv)
