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
The discrepancy workflow: where the model and the measurement disagree, and why.

:func:`discover` fits the current effects to measured runs on block means, then names the
catalog effect the model is missing, adds it and shows the gap shrink, until no candidate
passes the false-discovery guard (held-out gain, HAC significance, effect size). The model,
the tests and the modules of the package: ``doc/internals/identify.md``.
"""

from gyro_tdc.base.face import lazy

__all__, __getattr__, __dir__ = lazy(__name__, {
    'report': ['write_report'],
    'results': ['BinMap', 'CandidateScore', 'DiscoveryResult', 'format_summary', 'Step',
                'Unidentifiable'],
    'search': ['build_model', 'discover', 'DiscoverOptions', 'model_features'],
})
