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
The plots' figures: made on matplotlib's Agg canvas and written as PNG atomically.

matplotlib is imported when a figure is made, so a package that plots loads it only then;
no global backend is set, so a caller's own matplotlib set-up is left alone.
"""

from __future__ import annotations

import os
from typing import Any

from gyro_tdc.base.atomicio import atomic_write

__all__ = ['figure', 'save_png']


def figure(**kw: Any) -> Any:
    """Return a constrained-layout matplotlib figure on its own Agg canvas (``kw``: Figure's)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    fig = Figure(constrained_layout=True, **kw)
    FigureCanvasAgg(fig)
    return fig


def save_png(fig: Any, path: str | os.PathLike) -> str | os.PathLike:
    """Write ``fig`` as a 90 dpi PNG at ``path``, atomically (OutputError); return ``path``."""
    atomic_write(path, lambda fh: fig.savefig(fh, dpi=90, format='png'), binary=True, what='plot')
    return path
