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

"""Launch XML as the system tests read it: its substitutions resolved."""

from __future__ import annotations

from pathlib import Path
import re

ROOT = Path(__file__).resolve().parents[2]
#: A launch substitution, ``$(kind what)``.
SUBST = re.compile(r'\$\((\S+) ([^)]*)\)')


def resolve(text: str, values: dict) -> str:
    """Resolve ``$(var X)`` from ``values`` and ``$(find-pkg-share gyro_tdc)`` to the repo."""
    def one(match):
        kind, what = match.group(1), match.group(2)
        if kind == 'var':
            return values[what]
        assert (kind, what) == ('find-pkg-share', 'gyro_tdc'), match.group(0)
        return str(ROOT)
    for _ in range(5):      # an argument's default may refer to another argument
        text = SUBST.sub(one, text)
    assert '$(' not in text, text
    return text
