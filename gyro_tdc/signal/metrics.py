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
Accuracy metrics in the paper's terms, plus the usual inertial-sensor noise figures.

* bias stability, ``BS = MSE(x - x_ref)`` per axis (paper eq. 30), in (deg/s)^2;
* the P ratios of tables 3-7: ``P1 = BS2/BS1``, ``P2 = BS3/BS1``, ``P3 = P2/P1 = BS3/BS2``
  (eq. 32 defines P_i = BS_(i+1)/BS_i; the tables report P2 against BS1, and so do we);
* RMS in deg/s;
* overlapping Allan deviation (allantools, gyro rate as its ``freq`` data type) with the
  angle random walk (deg/sqrt(h)) and bias instability (deg/h) read off it;
* the robust standard deviation ``1.4826 MAD`` (median absolute deviation) outlier tests use.
"""

from __future__ import annotations

from gyro_tdc.base import DEG_PER_RAD
import numpy as np
from numpy.typing import NDArray

__all__ = ['allan_deviation', 'bias_stability', 'mad_sigma', 'MAD_TO_SIGMA', 'noise_readouts',
           'p_ratios', 'rms_dps']

#: The median absolute deviation (MAD) of normal data times this is its standard deviation.
MAD_TO_SIGMA = 1.4826


def bias_stability(omega: NDArray[np.float64], omega_ref: NDArray[np.float64]
                   ) -> NDArray[np.float64]:
    """
    Return BS = MSE(omega - omega_ref) per axis, (deg/s)^2 (paper eq. 30).

    ``omega`` (N, 3) is the evaluated rate (raw or compensated), ``omega_ref`` (N, 3) or (3,)
    the reference, both rad/s.
    """
    e = (np.asarray(omega, dtype=np.float64)
         - np.asarray(omega_ref, dtype=np.float64)) * DEG_PER_RAD
    return np.mean(e * e, axis=0)


def rms_dps(err: NDArray[np.float64]) -> NDArray[np.float64]:
    """Return the RMS per axis, in deg/s, of an error signal (N, 3) given in rad/s."""
    return np.sqrt(bias_stability(err, 0.0))


def p_ratios(bs1: NDArray[np.float64], bs2: NDArray[np.float64], bs3: NDArray[np.float64]
             ) -> dict[str, NDArray[np.float64]]:
    """
    Return the paper's improvement ratios (tables 3-7).

    Parameters
    ----------
    bs1, bs2, bs3 : NDArray[np.float64], shape (3,)
        BS of the raw data, after the conventional model and after the modified model.

    Returns
    -------
    dict
        ``{'P1': BS2/BS1, 'P2': BS3/BS1, 'P3': BS3/BS2}``.

    """
    bs1, bs2, bs3 = (np.asarray(b, dtype=np.float64) for b in (bs1, bs2, bs3))
    return {'P1': bs2 / bs1, 'P2': bs3 / bs1, 'P3': bs3 / bs2}


def allan_deviation(omega: NDArray[np.float64], rate_hz: float, *,
                    taus: NDArray[np.float64] | str = 'octave'
                    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """
    Compute the overlapping Allan deviation of each axis: ``(taus, adev)``.

    ``omega`` (N, 3, rad/s) is sampled at the constant ``rate_hz``; ``taus`` are averaging
    times in s or an allantools keyword (``'octave'``). Returns the times used (M,), common to
    the three axes, and the deviation (M, 3) in deg/s.
    """
    omega = np.asarray(omega, dtype=np.float64) * DEG_PER_RAD
    import allantools   # slow with scipy.stats: imported when an Allan deviation is asked for
    runs = [allantools.oadev(omega[:, ax], rate=float(rate_hz), data_type='freq', taus=taus)[:2]
            for ax in range(3)]                 # (taus, deviation) per axis
    m = min(len(runs[0][0]), *(len(dev) for _, dev in runs))
    return np.asarray(runs[0][0])[:m], np.column_stack([np.asarray(d)[:m] for _, d in runs])


def noise_readouts(taus: NDArray[np.float64], adev: NDArray[np.float64]
                   ) -> dict[str, NDArray[np.float64]]:
    """
    Read angle random walk and bias instability off an Allan deviation curve.

    ``taus`` (M,) s, ``adev`` (M, 3) deg/s. Angle random walk is ``sigma(tau) * sqrt(tau)``
    on the -1/2 slope at the shortest averaging times (IEEE 952), in deg/sqrt(h); bias
    instability is the curve's minimum / 0.664, in deg/h. Returns
    ``{'arw_deg_sqrt_h': (3,), 'bias_instability_deg_h': (3,)}``.
    """
    taus, adev = np.asarray(taus, dtype=np.float64), np.asarray(adev, dtype=np.float64)
    if taus.size == 0:
        nan = np.full(3, np.nan)
        return {'arw_deg_sqrt_h': nan, 'bias_instability_deg_h': nan}
    short = taus <= max(taus[min(2, taus.size - 1)], 1.0)
    arw = np.median(adev[short] * np.sqrt(taus[short])[:, None], axis=0) * 60.0
    bi = adev.min(axis=0) / 0.664 * 3600.0
    return {'arw_deg_sqrt_h': arw, 'bias_instability_deg_h': bi}


def mad_sigma(values: NDArray[np.float64]) -> NDArray[np.float64]:
    """Return ``1.4826 MAD`` along the first axis: a standard deviation outliers barely move."""
    return MAD_TO_SIGMA * np.median(np.abs(values - np.median(values, axis=0)), axis=0)
