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


"""Tests of gyro_tdc.model.lag: the scans equal the recursion, exact ramps, no scipy."""

import math

from gyro_tdc.model.lag import first_order_lag
from hypothesis import given, settings, strategies as st
import numpy as np
import pytest


def _irregular(seed, n=6000):
    rng = np.random.default_rng(seed)
    t = 100.0 + np.cumsum(rng.uniform(0.005, 0.05, n))
    temp = 20.0 + 8.0 * np.sin(t / 40.0) + rng.normal(0.0, 0.02, n)
    return t, temp


def test_first_order_lag_matches_step_response():
    t = np.arange(0.0, 50.0, 0.01)
    u = np.where(t > 0, 1.0, 0.0)
    u[0] = 0.0
    y = first_order_lag(t, u, 5.0)
    i = np.searchsorted(t, 5.0)
    assert y[i] == pytest.approx(1 - np.exp(-1), abs=2e-3)
    assert y[-1] == pytest.approx(1.0, abs=1e-4)


def _lag_loop(t, u, tau, hold, y0=None):
    """Run the recursion of first_order_lag as a plain loop."""
    y = np.empty(u.size)
    y[0] = u[0] if y0 is None else y0
    for k in range(1, u.size):
        h = max(t[k] - t[k - 1], 0.0)
        a = math.exp(-h / tau)
        if hold == 'step':
            y[k] = a * y[k - 1] + (1.0 - a) * u[k]
        else:
            c = tau * -math.expm1(-h / tau) / h if h > 0 else 1.0
            y[k] = a * y[k - 1] + (1.0 - c) * u[k] + (c - a) * u[k - 1]
    return y


@pytest.mark.parametrize('hold', ['step', 'linear'])
@pytest.mark.parametrize('y0', [None, -3.0])
def test_first_order_lag_scan_equals_the_recursion_on_irregular_stamps(hold, y0):
    t, u = _irregular(4, 3000)
    t[50:55] = t[50]
    for tau in (0.01, 2.0, 500.0):
        np.testing.assert_allclose(first_order_lag(t, u, tau, hold=hold, y0=y0),
                                   _lag_loop(t, u, tau, hold, y0), rtol=1e-11, atol=1e-9)


def test_linear_hold_on_a_uniform_step_equals_the_same_on_its_stamps():
    t, u = _irregular(5, 2000)
    step = 0.25
    stamps = np.arange(u.size) * step
    np.testing.assert_allclose(first_order_lag(step, u, 30.0, hold='linear'),
                               first_order_lag(stamps, u, 30.0, hold='linear'),
                               rtol=1e-12, atol=1e-10)
    np.testing.assert_allclose(first_order_lag(step, u, 30.0),
                               first_order_lag(stamps, u, 30.0), rtol=1e-12, atol=1e-10)


def test_lag_is_exact_for_a_ramp():
    dt, tau, rate = 0.5, 37.0, 0.02
    t = np.arange(2000) * dt
    y = first_order_lag(dt, rate * t, tau, hold='linear')
    exact = rate * (t - tau * (1.0 - np.exp(-t / tau)))
    np.testing.assert_allclose(y, exact, atol=1e-10)
    np.testing.assert_allclose(first_order_lag(t, rate * t, tau, hold='linear'), exact,
                               atol=1e-10)


def test_lag_with_zero_tau_passes_through_and_starts_settled():
    u = np.array([1.0, 2.0, 5.0])
    np.testing.assert_array_equal(first_order_lag(1.0, u, 0.0, hold='linear'), u)
    assert first_order_lag(1.0, u, 10.0, hold='linear')[0] == 1.0
    assert first_order_lag(1.0, u, 10.0, hold='linear', y0=-3.0)[0] == -3.0
    assert first_order_lag(np.arange(3.0), u, 10.0, y0=-3.0)[0] == -3.0
    assert first_order_lag(np.zeros(0), np.zeros(0), 10.0).shape == (0,)


@pytest.mark.parametrize('args, kwargs, name', [
    ((0.0, np.zeros(3), 1.0), {}, 'dt'),
    ((1.0, np.zeros(3), -1.0), {}, 'tau'),
    ((1.0, np.zeros(3), math.nan), {}, 'tau'),
    ((np.arange(2.0), np.zeros(3), 1.0), {}, '`t` of shape'),
    ((1.0, np.zeros((3, 2)), 1.0), {}, '`u` to have shape'),
    ((1.0, np.zeros(3), 1.0), {'hold': 'cubic'}, 'hold')])
def test_lag_rejects_bad_arguments(args, kwargs, name):
    with pytest.raises(ValueError, match=name):
        first_order_lag(*args, **kwargs)


def test_the_lag_needs_no_scipy_and_the_uniform_linear_hold_equals_lfilter():
    """No lag imports scipy; the uniform linear hold equals scipy's lfilter to rounding."""
    import subprocess
    import sys
    code = (
        'import math, sys, numpy as np\n'
        'from gyro_tdc.model.lag import first_order_lag\n'
        'rng = np.random.default_rng(3)\n'
        'u = np.cumsum(rng.normal(size=50000))\n'
        'first_order_lag(np.arange(50000) * 0.01, u, 7.5, hold="linear")\n'
        'first_order_lag(0.01, u, 7.5, hold="step")\n'
        'ys = {tau: first_order_lag(0.01, u, tau, hold="linear", y0=u[0] + 0.3)\n'
        '      for tau in (0.02, 7.5, 600.0, 1e6)}\n'
        'assert "scipy" not in sys.modules, "scipy was imported"\n'
        'from scipy.signal import lfilter\n'
        'for tau, y in ys.items():\n'
        '    a = math.exp(-0.01 / tau); c = tau * -math.expm1(-0.01 / tau) / 0.01\n'
        '    b0, b1 = 1.0 - c, c - a\n'
        '    zi = np.array([b1 * u[0] + a * (u[0] + 0.3)])\n'
        '    ref, _ = lfilter([b0, b1], [1.0, -a], u[1:], zi=zi)\n'
        '    scale = np.abs(u).max()\n'
        '    assert np.abs(y[1:] - ref).max() <= 1e-13 * scale, (tau, np.abs(y[1:] - ref).max())\n'
        '    assert y[0] == u[0] + 0.3\n'
        'print("ok")\n')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == 'ok'


@pytest.mark.parametrize('tau', [1e-3, 0.05, 0.3, 7.0, 1e3, 1e18])
def test_the_uniform_linear_hold_matches_the_sequential_recursion(tau):
    """Every regime of the constant-factor scan (fast decay, rows, no decay) is the recursion."""
    rng = np.random.default_rng(6)
    dt = 0.1
    a = math.exp(-dt / tau)
    c = tau * -math.expm1(-dt / tau) / dt
    for n in (2, 3, 17, 1000, 4099):
        u = rng.normal(size=n)
        y = first_order_lag(dt, u, tau, hold='linear', y0=0.4)
        ref = np.empty(n)
        ref[0] = 0.4
        for k in range(1, n):
            ref[k] = a * ref[k - 1] + (1.0 - c) * u[k] + (c - a) * u[k - 1]
        np.testing.assert_allclose(y, ref, rtol=0, atol=1e-12)


def test_the_step_hold_scan_matches_the_sequential_recursion():
    """The prefix scan (in place, spare buffer) equals y[k] = a_k y[k-1] + (1 - a_k) u[k]."""
    rng = np.random.default_rng(5)
    for n in (2, 3, 17, 1000, 4099):
        t = np.cumsum(rng.uniform(0.0, 0.2, n))
        u = rng.normal(size=n)
        y = first_order_lag(t, u, 0.7)
        ref = np.empty(n)
        ref[0] = u[0]
        for k in range(1, n):
            a = np.exp(-(t[k] - t[k - 1]) / 0.7)
            ref[k] = a * ref[k - 1] + (1.0 - a) * u[k]
        np.testing.assert_allclose(y, ref, rtol=1e-12, atol=1e-12)


def _prefix_scan(t, u, tau, hold, y0=None):
    """Run the recursion of first_order_lag as the full affine prefix scan (the former path)."""
    start = u[0] if y0 is None else y0
    step = np.maximum(np.diff(t), 0.0)
    a = np.exp(-step / tau)
    if hold == 'step':
        b = (1.0 - a) * u[1:]
    else:
        with np.errstate(divide='ignore', invalid='ignore'):
            c = np.where(step > 0.0, tau * -np.expm1(-step / tau) / step, 1.0)
        b = (1.0 - c) * u[1:] + (c - a) * u[:-1]
    shift = 1
    while shift < a.size:
        b[shift:] = b[shift:] + a[shift:] * b[:-shift]
        a[shift:] = a[shift:] * a[:-shift]
        shift *= 2
    return np.r_[start, a * start + b]


def _assert_same(y, ref, u, y0):
    scale = max(np.abs(u).max(), 0.0 if y0 is None else abs(y0))
    assert np.abs(y - ref).max() <= 1e-12 * scale


# Steps in units of the typical step: none, backwards (no time), jitter, a gap of up to 1e7.
_STEPS = st.lists(st.one_of(st.just(0.0), st.floats(-3.0, -0.01), st.floats(0.5, 1.5),
                            st.floats(10.0, 1e7)), min_size=1, max_size=300)


@settings(max_examples=300)
@given(steps=_STEPS, dt=st.floats(-4.0, 0.0), tau=st.floats(-3.0, 4.0),
       hold=st.sampled_from(['step', 'linear']), y0=st.none() | st.floats(-500.0, 500.0),
       seed=st.integers(0, 2**32 - 1), t0=st.floats(0.0, 1e5))
def test_irregular_stamps_equal_the_prefix_scan_and_the_recursion(steps, dt, tau, hold, y0,
                                                                  seed, t0):
    """Rows of closed sums equal the affine prefix scan and the loop to 1e-12 of the scale."""
    rng = np.random.default_rng(seed)
    t = t0 + np.r_[0.0, np.cumsum(np.array(steps) * 10.0 ** dt)]
    u = rng.uniform(-100.0, 100.0) + np.cumsum(rng.normal(size=t.size)) * rng.uniform(0.0, 3.0)
    y = first_order_lag(t, u, 10.0 ** tau, hold=hold, y0=y0)
    _assert_same(y, _prefix_scan(t, u, 10.0 ** tau, hold, y0), u, y0)
    _assert_same(y, _lag_loop(t, u, 10.0 ** tau, hold, y0), u, y0)


@pytest.mark.parametrize('hold', ['step', 'linear'])
def test_many_rows_and_a_gap_row_equal_the_recursion(hold):
    """200 s at 1 kHz, a 1e5 s gap, tau 5 s: 2,532 rows, the gap row by the prefix scan."""
    rng = np.random.default_rng(8)
    steps = rng.uniform(0.0008, 0.0012, 200_000)
    steps[120_000] = 1e5
    steps[50_000:50_100] = 0.0
    t = 3000.0 + np.cumsum(steps)
    u = 20.0 + np.cumsum(rng.normal(size=t.size)) * 1e-2
    y = first_order_lag(t, u, 5.0, hold=hold, y0=21.0)
    _assert_same(y, _lag_loop(t, u, 5.0, hold, 21.0), u, 21.0)
    _assert_same(y, _prefix_scan(t, u, 5.0, hold, 21.0), u, 21.0)
    g = 120_000                          # the first sample after the gap forgot the past
    assert abs(y[g] - u[g]) <= 5.0 * abs(u[g] - u[g - 1]) / 1e5 + 1e-9
