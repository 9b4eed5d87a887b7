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

"""A model in a flight controller's form: fit, parameter files, held-out scores, clamp cost."""

from __future__ import annotations

import math

from fc_scripts import ardupilot_script, heating_leg, px4_script
from gyro_tdc.errors import FitError, ModelFileError
from gyro_tdc.identify import fit_model
from gyro_tdc.identify.export import (clamp_cost, FIRMWARES, fit_export, from_params,
                                      read_params, score_export, steady_drift, write_params)
from gyro_tdc.model import drift
from gyro_tdc.model.fc_tempcal import px4_names
import numpy as np
import pytest
from synth import synth_run


@pytest.fixture(scope='module')
def lagged():
    """Return a heating-and-cooling session whose die lags the thermometer, and a held-out one."""
    train = synth_run(hours=2.0, rate_hz=2.0, cooling=True, seed=1, tau_die=300.0)
    held = synth_run(hours=2.0, rate_hz=2.0, cooling=True, seed=2, tau_die=300.0,
                     offset_dps=(0.02, -0.01, 0.01))
    return train, held, fit_model([train], kind='poly', features=('dT', 'dT2', 'dT3', 'lag'))


@pytest.fixture(scope='module')
def static():
    """Return a cubic model of a session without lag: its drift is a cubic in the measured T."""
    run = synth_run(hours=1.0, rate_hz=2.0, seed=3)
    return fit_model([run], kind='poly', features=('dT', 'dT2', 'dT3'))


def test_steady_drift_is_the_drift_after_a_long_hold(lagged):
    model = fit_model([lagged[0]], features=('dT', 'dT2', 'dTdt', 'lag', 'warmup'),
                      n_centers=6, fit_params=False)
    temps = np.array([0.0, 17.5, 40.0])
    held = [drift(model, np.arange(4000) * 50.0, np.full(4000, t))[-1] for t in temps]
    np.testing.assert_allclose(steady_drift(model, temps), held, rtol=0, atol=1e-12)


def test_a_cubic_model_is_reproduced_by_both_forms_and_their_files(static, tmp_path):
    lo, hi = static.temp_range_c
    grid = np.linspace(lo, hi, 57)
    want = steady_drift(static, grid)
    got = {}
    for fw in FIRMWARES:
        exp = fit_export(static, fw)
        assert np.all(exp.fit_rms_dps < 1e-5)               # float32 storage, nothing else
        back = from_params(read_params(write_params(exp, tmp_path / fw)), fw)
        np.testing.assert_array_equal(back.correction(grid), exp.correction(grid))
        got[fw] = back.correction(grid)
        np.testing.assert_allclose(got[fw], want, rtol=0, atol=2e-7)
    np.testing.assert_allclose(got['px4'], got['ardupilot'], rtol=0, atol=2e-7)


def test_the_files_are_what_the_ground_stations_load(static, tmp_path):
    px4 = write_params(fit_export(static, 'px4', instance=1, device_id=2293768),
                       tmp_path / 'tc.params', header=['from a test'])
    lines = px4.read_text().splitlines()
    assert lines[0] == '# from a test' and '# Vehicle-Id Component-Id Name Value Type' in lines
    rows = [ln.split('\t') for ln in lines if not ln.startswith('#')]
    assert all(len(r) == 5 and r[:2] == ['1', '1'] for r in rows)
    assert [r[2] for r in rows] == ['TC_G_ENABLE'] + px4_names('gyro', 1)
    types = {r[2]: r[4] for r in rows}
    assert types['TC_G_ENABLE'] == types['TC_G1_ID'] == '6' and types['TC_G1_X3_2'] == '9'
    assert read_params(px4)['TC_G1_ID'] == 2293768
    ap = write_params(fit_export(static, 'ardupilot', instance=2), tmp_path / 'tc.parm')
    params = read_params(ap)
    assert all(len(ln.split(' ')) == 2 for ln in ap.read_text().splitlines())
    assert params['INS_TCAL3_ENABLE'] == 1 and 'INS_TCAL3_GYR3_Z' in params
    assert 'INS_GYR3_CALTEMP' in params and 'INS_GYR3OFFS_X' in params
    assert all(params[f'INS_TCAL3_ACC{k}_{a}'] == 0 for k in (1, 2, 3) for a in 'XYZ')
    assert params['INS_TCAL3_TMIN'] == pytest.approx(static.temp_range_c[0], abs=1e-5)


def test_exported_forms_are_no_worse_held_out_than_the_firmware_scripts(lagged):
    train, held, model = lagged
    heat = heating_leg(train)
    assert heat.temp[-1] == train.temp.max() and len(heat) < len(train)
    forms = {fw: fit_export(model, fw) for fw in FIRMWARES}
    forms.update({'px4 script': px4_script(heat), 'ardupilot script': ardupilot_script(heat)})
    for reanchor in (0.0, 60.0):
        s = score_export(model, forms, [held], reanchor_s=reanchor)[0]
        bs = {k: float(np.mean(v)) for k, v in s.bs.items()}
        for fw in FIRMWARES:
            assert bs[fw] <= bs[f'{fw} script'], (reanchor, bs)
            # The static form cannot hold the lag: a gap to the full model remains.
            assert bs['model'] < bs[fw] < bs['raw']
            assert 0.9 < s.kept(fw) < 1.0
        assert s.kept('px4') == pytest.approx(s.kept('ardupilot'), abs=1e-4)


def test_the_clamp_holds_the_correction_where_the_model_goes_on(lagged):
    model = lagged[2]
    exp = fit_export(model, 'px4')
    cost = clamp_cost(model, exp, beyond_c=(0.0, 5.0, 10.0))
    lo_end, hi_end = cost[0], cost[3]
    assert lo_end['gap_dps'] < 1e-5 and hi_end['gap_dps'] < 1e-5
    assert 0 < cost[1]['gap_dps'] < cost[2]['gap_dps']
    assert 0 < cost[4]['gap_dps'] < cost[5]['gap_dps']
    assert cost[1]['form_dps'] == cost[2]['form_dps'] == lo_end['form_dps']


def test_bad_input_is_refused(static, tmp_path):
    with pytest.raises(FitError, match='firmware'):
        fit_export(static, 'betaflight')
    with pytest.raises(FitError, match='instance'):
        fit_export(static, 'ardupilot', instance=3)
    assert any('device_id' in n for n in fit_export(static, 'px4').notes)
    bad = tmp_path / 'bad.parm'
    bad.write_text('INS_TCAL1_ENABLE 1\nthis is not a parameter line\n')
    with pytest.raises(ModelFileError, match='bad.parm:2'):
        read_params(bad)


def test_share_kept_is_nan_without_a_gain_and_the_share_otherwise():
    from gyro_tdc.identify import share_kept
    assert math.isnan(share_kept(2.0, 2.0, 1.0))      # a model no better than raw: no share
    assert math.isnan(share_kept(1.0, 2.0, 1.5))      # a model worse than raw
    assert share_kept(4.0, 2.0, 3.0) == pytest.approx(0.5)
