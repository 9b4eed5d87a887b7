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
Multi-day still logs (a motionless logger) and the learner judged on them through the core.

:func:`still_log` simulates one: a slow temperature (daily cycles, a ramp, cooling only),
an L3GD20-like drift curve, white noise, bias instability (Gauss-Markov) and rate random
walk (:mod:`gyro_tdc.sim.noise`), a turn-on offset per power cycle, quantised rate and
thermometer, continuous or in bursts. :func:`learn_through_core` streams it through
:class:`gyro_tdc.runtime.CompensatorCore` with a learner stepped as the node steps it;
:func:`judge` compares the last day with a batch fit of the days before, re-anchored.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import math

from gyro_tdc.learn.learner import LearnConfig, learned_model, Learner
from gyro_tdc.runtime import CompensatorCore, PASSTHROUGH, Policy
from gyro_tdc.runtime.reanchor import default_tolerance, reanchor_shift
from gyro_tdc.sim.noise import gauss_markov, quantise, random_walk
import numpy as np
from numpy.typing import NDArray

DEG = math.pi / 180.0
DAY = 86400.0
#: The drift curve about 25 degC (L3GD20 preset), deg/s per degC^k.
CURVE_DPS = ((0.030, -0.024, 0.012), (8.0e-4, 6.0e-4, -2.5e-4), (4.0e-6, -3.0e-6, 2.0e-6))
#: Block of the drift figure, s: the RMS of the output's block means (white noise averages out).
BLOCK_S = 600.0


@dataclass
class StillLog:
    """
    One simulated still log (reference rate zero).

    ``truth`` is the true error of the raw rate without its white noise (drift, offsets,
    wander), ``session`` the power cycle of each sample, ``days`` the log's length.
    """

    t: NDArray[np.float64]
    gyro: NDArray[np.float64]
    accel: NDArray[np.float64] | None
    temp_t: NDArray[np.float64]
    temp_c: NDArray[np.float64]
    truth: NDArray[np.float64]
    session: NDArray[np.int64]
    days: float
    day_s: float = DAY
    info: dict = field(default_factory=dict)


def temperature(t: NDArray[np.float64], profile: str, lo: float, hi: float,
                days: float, day_s: float = DAY) -> NDArray[np.float64]:
    """Return the true temperature at ``t`` (s) of a profile, degC (a day lasts ``day_s``)."""
    mid, amp = 0.5 * (lo + hi), 0.5 * (hi - lo)
    if profile == 'daily':               # lo at midnight, hi at noon, every day
        return mid - amp * np.cos(2.0 * math.pi * t / day_s)
    if profile == 'ramp':                # lo -> hi over the whole log, slowly
        return lo + (hi - lo) * t / (days * day_s)
    if profile == 'cooling':             # hi -> lo over the whole log (cooling only)
        return hi - (hi - lo) * t / (days * day_s)
    if profile == 'widening':            # daily cycles; the last day reaches beyond the rest
        grow = np.where(t < (days - 1) * day_s, 0.7, 1.0)
        return mid - amp * grow * np.cos(2.0 * math.pi * t / day_s)
    raise ValueError(f'unknown profile {profile!r}')


def still_log(*, rate_hz: float = 1.0, days: float = 3.0, profile: str = 'daily',
              t_lo: float = 5.0, t_hi: float = 25.0, seed: int = 0, temp_res_c: float = 0.01,
              temp_hz: float = 1.0, q_dps: float = 8.75e-3, arw_dps: float = 0.03,
              bi_dps: float = 0.004, bi_tau_s=(10.0, 100.0, 1000.0), rrw_dps: float = 1e-5,
              turn_on_dps: float = 0.2, power_cycles: int = 1, gap_s: float = 3600.0,
              bursts: tuple[float, float] | None = None, accel: bool = True,
              curve_scale: float = 1.0, day_s: float = DAY) -> StillLog:
    """
    Return a still log of ``days`` days (the module docstring).

    Parameters
    ----------
    rate_hz : float
        IMU rate (inside bursts, with ``bursts``).
    days : float
        Length in days.
    profile : str
        ``'daily'``, ``'ramp'``, ``'cooling'`` or ``'widening'`` (:func:`temperature`).
    t_lo, t_hi : float, degC
        The profile's range.
    seed : int
        Random seed.
    temp_res_c : float
        Thermometer resolution, degC.
    temp_hz : float
        Thermometer rate (at most the IMU's).
    q_dps, arw_dps, bi_dps, rrw_dps : float
        Rate quantum (deg/s), white noise density (deg/s/sqrt(Hz)), bias instability
        (deg/s, Gauss-Markov over ``bi_tau_s``), rate random walk (deg/s/sqrt(s)).
    bi_tau_s : sequence of float, s
        Correlation times of the bias instability.
    turn_on_dps : float
        Standard deviation of the turn-on offset drawn for every power cycle, deg/s.
    power_cycles : int
        The log is cut into this many power cycles of equal length, ``gap_s`` apart (no
        samples in the gap; the random walk starts again).
    gap_s : float, s
        The gap between power cycles.
    bursts : (burst_s, period_s), optional
        Record only ``burst_s`` of every ``period_s``.
    accel : bool
        With an accelerometer (quantised, still).
    curve_scale : float
        Multiplies the drift curve.
    day_s : float, s
        The length of a day (shorter: the same profile compressed in time).

    """
    rng = np.random.default_rng(seed)
    span = days * day_s
    dt = 1.0 / rate_hz
    if bursts is None:
        t = np.arange(0.0, span, dt)
    else:
        burst, period = bursts
        k = int(round(burst * rate_hz))
        starts = np.arange(0.0, span - burst, period)
        t = (starts[:, None] + np.arange(k)[None, :] * dt).ravel()
    cycle_len = span / power_cycles
    session = np.minimum((t // cycle_len).astype(np.int64), power_cycles - 1)
    # Gaps between power cycles: shift the stamps of the later cycles by gap_s each.
    stamps = t + session * gap_s
    n = t.size
    true_temp = temperature(t, profile, t_lo, t_hi, days, day_s)
    d = true_temp - 25.0
    curve = sum(np.asarray(c) * curve_scale * d[:, None] ** (j + 1)
                for j, c in enumerate(CURVE_DPS))
    # Slow processes on a 1 s grid over each cycle, interpolated to the stamps.
    wander = np.zeros((n, 3))
    grid_dt = 1.0
    for s in range(power_cycles):
        sel = session == s
        if not sel.any():
            continue
        g = np.arange(t[sel][0], t[sel][-1] + 2 * grid_dt, grid_dt)
        slow = (random_walk(rng, g.size, k=np.full(3, rrw_dps), dt=grid_dt)
                + gauss_markov(rng, g.size, sigma=np.full(3, bi_dps), tau_s=list(bi_tau_s),
                               dt=grid_dt)
                + turn_on_dps * rng.standard_normal(3))
        for a in range(3):
            wander[sel, a] = np.interp(t[sel], g, slow[:, a])
    bias0 = np.array([0.5, -0.4, 0.3])
    truth = (bias0 + curve + wander) * DEG
    white = rng.standard_normal((n, 3)) * (arw_dps * math.sqrt(rate_hz) * DEG)
    gyro = quantise(truth + white, q_dps * DEG)
    acc = None
    if accel:
        acc = np.array([0.02, -0.03, 9.80665]) + 0.0015 * math.sqrt(rate_hz) * \
            rng.standard_normal((n, 3))
        acc = quantise(acc, 0.0024)                   # a 16-bit +-8 g accelerometer
    # The thermometer: at temp_hz inside the recorded spans (every IMU sample at most).
    step = max(1, int(round(rate_hz / temp_hz)))
    idx = np.arange(0, n, step)
    temp_t = stamps[idx]
    temp_c = np.round(true_temp[idx] / temp_res_c) * temp_res_c
    return StillLog(stamps, gyro, acc, temp_t, temp_c, truth, session, days, day_s,
                    {'rate_hz': rate_hz, 'profile': profile, 'seed': seed,
                     'temp_res_c': temp_res_c, 'bursts': bursts,
                     'power_cycles': power_cycles, 'true_temp': true_temp})


def learn_directly(log, chunk_s=10.0):
    """Feed a log to a learner alone (no core), stepped every ``chunk_s`` of stamps."""
    learner = Learner(LearnConfig(temperature_timeout=5.0))
    j = 0
    edges = np.searchsorted(log.t, np.arange(log.t[0], log.t[-1] + chunk_s, chunk_s))
    for a, b in zip(edges[:-1], edges[1:]):
        while j < log.temp_t.size and log.temp_t[j] <= log.t[max(b - 1, a)]:
            learner.add_temperature(float(log.temp_t[j]), float(log.temp_c[j]))
            j += 1
        for k in range(a, b):
            learner.observe(float(log.t[k]), *log.gyro[k].tolist())
        learner.step()
    return learner


def learn_through_core(log: StillLog, *, step_s: float = 1.0, config: LearnConfig | None = None,
                       policy: Policy | None = None):
    """
    Stream ``log`` through a core with a learner from nothing, stepped every ``step_s`` of stamps.

    As the node does: thermometer readings and IMU samples in stamp order, the learner's step
    (:meth:`CompensatorCore.learn_step`) from a timer, off the message path. Returns the
    output rate (the raw rate where passed through), the pass-through mask and the learner.
    """
    policy = policy or Policy()
    core = CompensatorCore(policy)
    learner = Learner(config or LearnConfig(temperature_timeout=policy.temperature_timeout))
    core.learner = learner
    t = log.t.tolist()
    w = log.gyro.tolist()
    acc = [None] * len(t) if log.accel is None else log.accel.tolist()
    tt, tc = log.temp_t.tolist(), log.temp_c.tolist()
    out = np.empty((len(t), 3))
    passed = np.zeros(len(t), dtype=bool)
    j, m = 0, len(tt)
    next_step = t[0] + step_s
    process, add, step = core.process, core.add_temperature, core.learn_step
    for k, (ts, wi, ai) in enumerate(zip(t, w, acc)):
        while j < m and tt[j] <= ts:
            add(tt[j], tc[j])
            j += 1
        ox, oy, oz, _, fl, _, _ = process(ts, wi[0], wi[1], wi[2], ai)
        out[k] = (ox, oy, oz)
        passed[k] = bool(fl & PASSTHROUGH)
        if ts >= next_step:
            step()
            next_step = ts + step_s
    step()
    return out, passed, learner


def block_rms(t: NDArray[np.float64], err: NDArray[np.float64],
              block_s: float = BLOCK_S) -> NDArray[np.float64]:
    """Return the RMS of the block means of ``err`` over blocks of ``block_s`` s, per axis."""
    k = np.floor((t - t[0]) / block_s).astype(np.int64)
    _, start, counts = np.unique(k, return_index=True, return_counts=True)
    means = np.add.reduceat(err, start, axis=0) / counts[:, None]
    return np.sqrt(np.average(means ** 2, axis=0, weights=counts))


def batch_fit(log: StillLog, until_s: float, degree: int = 3):
    """
    Fit the days before ``until_s`` in batch: one offset per power cycle, a shared polynomial.

    Returns ``predict(t, temp, session) -> (N, 3)`` of the newest fitted cycle's offset, and
    the residual variance per axis.
    """
    sel = log.t < until_s
    t, w, s = log.t[sel], log.gyro[sel], log.session[sel]
    temp = np.interp(t, log.temp_t, log.temp_c)
    t0 = float(np.mean(temp))
    # Block means (1 min) keep the solve small; the fit is the same least squares.
    k = np.floor((t - t[0]) / 60.0).astype(np.int64) + s * 10 ** 7
    _, start, counts = np.unique(k, return_index=True, return_counts=True)
    wm = np.add.reduceat(w, start, axis=0) / counts[:, None]
    tm = np.add.reduceat(temp, start) / counts
    sm = s[start]
    cycles = np.unique(sm)
    x = np.column_stack([(sm == c).astype(float) for c in cycles]
                        + [(tm - t0) ** (j + 1) for j in range(degree)])
    sw = np.sqrt(counts)[:, None]
    coef = np.linalg.lstsq(x * sw, wm * sw, rcond=None)[0]
    pred = x @ coef
    resid_var = np.average((wm - pred) ** 2, axis=0, weights=counts) + np.var(w - np.repeat(
        wm, counts, axis=0), axis=0)
    k0 = cycles.size

    def predict(tq, tempq):
        d = np.asarray(tempq) - t0
        return coef[k0 - 1] + sum(coef[k0 + j] * d[:, None] ** (j + 1) for j in range(degree))
    model = learned_model(np.vstack([coef[k0 - 1:k0], coef[k0:]]),
                          ('dT', 'dT2', 'dT3')[:degree], t0,
                          (float(tm.min()), float(tm.max())), resid_var)
    return predict, resid_var, model


def through_node(model, log: StillLog, sel: NDArray[np.bool_]) -> NDArray[np.float64]:
    """Return the output on ``sel`` of a core with ``model`` and ``reanchor_on_start``."""
    core = CompensatorCore(Policy(reanchor_on_start=True), model)
    t = log.t[sel]
    tt, tc = log.temp_t, log.temp_c
    j = max(int(np.searchsorted(tt, t[0], side='right')) - 1, 0)
    out = np.empty((t.size, 3))
    acc = [None] * t.size if log.accel is None else log.accel[sel].tolist()
    for k, (ts, w, a) in enumerate(zip(t.tolist(), log.gyro[sel].tolist(), acc)):
        while j < tt.size and tt[j] <= ts:
            core.add_temperature(float(tt[j]), float(tc[j]))
            j += 1
        out[k] = core.process(ts, w[0], w[1], w[2], a)[:3]
    return out


def judge(log: StillLog, out: NDArray[np.float64], passed: NDArray[np.float64] | None = None,
          *, degree: int = 3) -> dict:
    """
    Score the last day of ``log``: the learner's output beside a batch fit of the days before.

    Drift is :func:`block_rms` of the error (the reference is zero). ``batch``: the fit of
    :func:`batch_fit` on every day but the last, in a core with the default policy and
    ``reanchor_on_start`` (the node: the shift from the anchor's stamp on, the fit's own
    offset before); ``evaluate``: the same fit re-anchored over the whole last day by
    ``evaluate --reanchor auto``'s rule (:func:`reanchor_shift`: the shift of the day's head
    applied from its first sample, which no node can); ``raw``: the raw rate with its
    last-day mean removed.
    """
    last = log.t >= log.t[-1] - log.day_s
    t = log.t[last]
    temp = np.interp(t, log.temp_t, log.temp_c)
    predict, resid, model = batch_fit(log, log.t[last][0])
    comp = log.gyro[last] - predict(t, temp)
    shift = reanchor_shift(t, comp, tolerance=default_tolerance(resid)).delta
    batch = comp - np.asarray(shift)
    raw = log.gyro[last] - log.gyro[last].mean(axis=0)
    res = {'learn': block_rms(t, out[last]), 'evaluate': block_rms(t, batch),
           'batch': block_rms(t, through_node(model, log, last)),
           'raw': block_rms(t, raw), 'passed': 0.0 if passed is None else
           float(passed[last].mean())}
    res['vs_batch'] = res['learn'] / res['batch']
    res['vs_evaluate'] = res['learn'] / res['evaluate']
    res['vs_raw'] = res['learn'] / res['raw']
    return res
