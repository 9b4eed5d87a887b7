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

:func:`discover` fits the simulation model with the current effects (default ``bias`` and
``dT``, the conventional model of paper eq. 18) to measured runs, driven by their measured
temperature and reference rate, and then, step by step, names the catalog effect that the
model is missing, adds it and shows the gap shrink, until no candidate is supported by the
data. The model searched is linear in its coefficients, per axis ``a``::

    omega_a - omega_ref_a = o_{run,a} + sum_j c_{j,a} x_j(T, t) + s_a dT omega_ref_a
                            + g_a omega_ref_a + e_a

with ``x_j`` the effect features of :mod:`gyro_tdc.model.effects` (their time constants fitted by a
bounded 1-D search on the residual: variable projection), ``o`` one offset per run (session-to-
session offsets are not thermal), ``s`` the ``scale`` effect and ``g`` a constant scale-factor
error of the rate table (a nuisance, present only when the reference rate varies). ``lag``
is not a term beside the others: naming it switches the model to the thermal state, the die
temperature ``s = first_order_lag(t, T, tau)``, and every temperature term (``dT``, ``dT2``,
``dT3``, the ``dT`` of ``s_a``) is recomputed from it, tau fitted jointly (an outer search
over tau, the linear solve inside); candidates scored after it are scored on the state too.
Being no column of its own, it is tested with Davidson and MacKinnon's J test (its fitted
values added to the current model), and the result reports tau with its 95 % profile
interval (:func:`gyro_tdc.identify.profile_interval`), or says the data cannot pin it.

Everything works on block means (``block_s``, default 10 s): the thermal effects are slow, and
the averages are what the noise floor and the gaps are measured on. The *gap* is the RMS over
all axes of the block means of measured minus simulated rate, in deg/s; the *noise floor* is
what white and short-term noise alone leave in a block mean, estimated from the data inside
the blocks (second differences of block thirds, so the drift cancels; robust median scale).

A candidate is named only when three independent tests agree (the false-discovery guard):

* held-out gain: the mean squared held-out gap falls by at least ``min_heldout`` squared noise
  floors (and 1 %) under leave-one-run-out cross-validation, or, for one run, blocked
  cross-validation over interleaved segments with a noise-memory buffer around each held-out
  segment;
* significance: a Wald F test of its columns (for ``lag``, of the J column) with HAC
  (Newey-West, statsmodels' OLS) errors, the noise memory's bandwidth, below
  ``alpha`` after a Bonferroni correction over candidates and axes. Slow bias instability
  makes any HAC p-value optimistic on one run, which is why it is never the only test;
* size: it explains at least ``min_effect`` noise floors (RMS).

The best candidate (largest held-out gain) is added, the time constants are refitted, and the
search repeats until none passes. Candidates within ``alias_margin`` of its gain whose fitted
contribution correlates with its own by ``alias_corr`` or more are its aliases; of the best
and its aliases that pass, the one with the fewest parameters is named (a lagging die with a
linear drift, one time constant, rather than ``dTdt``, whose filtered derivative with its
own time constant holds the same curve with a coefficient per axis). Effects the data cannot
excite are reported as unidentifiable with the experiment that would excite them.

The package, one concept per module (each imports only those above it; :mod:`stats` names
the data and linear model in type hints only):

* :mod:`~gyro_tdc.identify.discover.results`: what was found, its JSON and text forms;
* :mod:`~gyro_tdc.identify.discover.stats`: gaps, folds, noise memory, HAC tests, correlations;
* :mod:`~gyro_tdc.identify.discover.data`: the runs as block means, the noise floor, effect
  columns;
* :mod:`~gyro_tdc.identify.discover.linear`: the linear model of one effect set, its fits and
  held-out residuals;
* :mod:`~gyro_tdc.identify.discover.maps`: residual maps and the Allan deviation of the residual;
* :mod:`~gyro_tdc.identify.discover.search`: :func:`discover`, the step-by-step search;
* :mod:`~gyro_tdc.identify.discover.model`: the compensation model of a discovery;
* :mod:`~gyro_tdc.identify.discover.report`: the markdown report with its plots.
"""

from __future__ import annotations

from gyro_tdc.identify.discover.model import build_model, model_features, model_kind
from gyro_tdc.identify.discover.report import write_report
from gyro_tdc.identify.discover.results import (BinMap, CandidateScore, DiscoveryResult,
                                                format_summary, Step, Unidentifiable)
from gyro_tdc.identify.discover.search import discover

__all__ = ['BinMap', 'CandidateScore', 'DiscoveryResult', 'Step', 'Unidentifiable',
           'build_model', 'discover', 'format_summary', 'model_features', 'model_kind',
           'write_report']
