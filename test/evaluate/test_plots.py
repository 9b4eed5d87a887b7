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

"""Tests of gyro_tdc.evaluate.plots: the three PNGs of a hand-made evaluated bag, legend texts."""

from __future__ import annotations

from types import SimpleNamespace
import warnings

from gyro_tdc.evaluate.plots import model_description, write_plots
from handmade_bag import handmade_bag
import numpy as np
import pytest


@pytest.fixture
def bag():
    return handmade_bag()


def test_three_plots_per_bag(bag, tmp_path):
    files = write_plots(bag, tmp_path / 'png', points=10)
    assert [f.name for f in files] == ['run3_timeseries.png', 'run3_residual_vs_temperature.png',
                                       'run3_allan.png']
    for f in files:
        assert f.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
    # Legends per model and the options in the titles; one description per model.
    files = write_plots(bag, tmp_path / 'described', points=10, reanchor_s=300.0,
                        descriptions=['conv.yaml: poly f(dT)', 'mod.yaml: poly f(dT, dT2)'],
                        options='re-anchored: mean error of the first 300 s removed')
    assert [f.read_bytes()[:8] for f in files] == [b'\x89PNG\r\n\x1a\n'] * 3
    with pytest.raises(ValueError, match='one per model'):
        write_plots(bag, tmp_path, descriptions=['only one'])

    def model(kind, features, tau_s=None):
        th = SimpleNamespace(kind='none' if tau_s is None else 'first_order', tau_total_s=tau_s)
        return SimpleNamespace(kind=kind, features=features, thermal=th)
    assert model_description('out/m/modified.yaml', model('poly', ['dT', 'dT2'])) == \
        'modified.yaml: poly f(dT, dT2)'
    assert model_description('px4', model('poly', ['dT', 'dT2', 'dT3'])).startswith('px4: cubic')
    assert model_description('a/auto.yaml', model('rbf', ['dT', 'dT2', 'lag'], 175.95)) == \
        'auto.yaml: rbf f(dT, dT2, lag 176 s)'
    bag.release()
    with pytest.raises(ValueError, match='released'):
        write_plots(bag, tmp_path)


def test_a_bag_scored_still_only_plots_without_an_allan_curve_or_a_warning(bag, tmp_path):
    # Still stretches have no Allan deviation (the gaps break the series): no empty legend.
    bag.still = {'samples': 50, 'total_samples': 120, 'sessions': 1}
    for m in [bag.raw] + bag.models:
        m.adev_tau_s, m.adev_dps = np.zeros(0), np.zeros((0, 3))
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        files = write_plots(bag, tmp_path / 'still', points=10)
    assert [f.read_bytes()[:8] for f in files] == [b'\x89PNG\r\n\x1a\n'] * 3
