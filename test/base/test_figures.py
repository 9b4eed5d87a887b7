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

"""Tests of gyro_tdc.base.figures: figures on the Agg canvas, written as PNG atomically."""

from __future__ import annotations

import subprocess
import sys

from gyro_tdc.base.figures import figure, save_png
from gyro_tdc.errors import OutputError
import pytest

PNG = b'\x89PNG\r\n\x1a\n'


def test_matplotlib_is_loaded_only_when_a_figure_is_made():
    code = ('import sys; from gyro_tdc.base import figures; '
            'print("matplotlib" in sys.modules); figures.figure(); '
            'print("matplotlib" in sys.modules)')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         check=True).stdout.split()
    assert out == ['False', 'True']


def test_a_figure_is_drawn_on_agg_without_setting_a_backend(tmp_path):
    import matplotlib
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    backend = matplotlib.get_backend()
    fig = figure(figsize=(2.0, 1.5))
    assert isinstance(fig.canvas, FigureCanvasAgg) and fig.get_constrained_layout()
    assert tuple(fig.get_size_inches()) == (2.0, 1.5)
    assert matplotlib.get_backend() == backend          # the caller's set-up is left alone
    fig.subplots().plot([0, 1], [1, 0])
    path = tmp_path / 'sub' / 'p.png'
    assert save_png(fig, path) == path
    data = path.read_bytes()
    assert data.startswith(PNG)
    assert int.from_bytes(data[16:20], 'big') == 180    # 2 in at 90 dpi
    assert [p.name for p in path.parent.iterdir()] == ['p.png']    # no temporary left


def test_a_plot_that_cannot_be_written_is_one_output_error(tmp_path):
    (tmp_path / 'p.png').mkdir()
    with pytest.raises(OutputError, match='plot .*p.png.*it is a directory'):
        save_png(figure(), tmp_path / 'p.png')
    old = tmp_path / 'old.png'
    old.write_bytes(b'old')
    fig = figure()
    fig.savefig = lambda *a, **k: (_ for _ in ()).throw(RuntimeError('draw failed'))
    with pytest.raises(RuntimeError, match='draw failed'):
        save_png(fig, old)
    assert old.read_bytes() == b'old' and sorted(p.name for p in tmp_path.iterdir()) == [
        'old.png', 'p.png']
