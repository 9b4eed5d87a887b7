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
Signal tools on IMU samples.

Block means and the one block grid, the one estimator (least squares, sessions, folds),
noise and accuracy metrics, the one still detector (its verdict, batch and streaming forms),
the one session-break rule (batch and streaming) and the thermometer held by stamp.
"""

from gyro_tdc.base.face import lazy

__all__, __getattr__, __dir__ = lazy(__name__, {
    'blocks': ['block_counts', 'block_length', 'block_mean', 'block_sum', 'block_sumsq',
               'BlockGrid', 'PASS_ROWS'],
    'estimator': ['check_offsets', 'curve_untold', 'CURVE_SIGNIFICANCE', 'CurveVerdict',
                  'fit_columns', 'Folds', 'hat', 'heldout', 'judge_curve', 'MIN_SESSION_SPAN_C',
                  'pinv_fit', 'session_columns', 'solve_normal', 'within'],
    'hold': ['hold_readings', 'TemperatureHold'],
    'metrics': ['allan_deviation', 'bias_stability', 'mad_sigma', 'MAD_TO_SIGMA', 'noise_readouts',
                'p_ratios', 'rms_dps'],
    'sessions': ['BURST_FACTOR', 'BURST_MAX_S', 'BURST_PAUSES', 'break_why', 'GAP_PERIODS',
                 'gap_breaks', 'gap_limit', 'session_gap', 'SessionTracker'],
    'still': ['auto_window', 'detect_still', 'has_accelerometer', 'judge_windows', 'long_enough',
              'MAX_RATE', 'MAX_STILL_SE', 'MIN_STILL_S', 'MIN_STILL_SAMPLES',
              'MIN_WINDOW_SAMPLES', 'MotionReports', 'MOTION_EPS', 'motion_veto', 'NOISE_FACTOR',
              'noise_floor', 'noise_thresholds', 'NOISE_WINDOWS', 'SHORT_WINDOW_S', 'Stillness',
              'STILL_WINDOW_S', 'stretch_edges', 'windows_moving'],
    'still_stream': ['StillWindows', 'Window'],
})
