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

"""Never twice: a gyro declared thermally corrected upstream passes through, warned about."""

from __future__ import annotations

from compensator_rig import rates
from diagnostic_msgs.msg import DiagnosticStatus
from gyro_tdc.data.mark import diagonal_marked
from gyro_tdc.identify import fit_model
from gyro_tdc.model.compensation import compensate
from gyro_tdc.model.modelfile import save_model
from gyro_tdc.runtime import CompensatorCore, Policy, UPSTREAM
import numpy as np
import pytest
from rclpy.parameter import Parameter
from synth import synth_run


@pytest.fixture(scope='module')
def model_file(tmp_path_factory):
    run = synth_run(hours=1.0, rate_hz=2.0, cooling=True, seed=5)
    model = fit_model([run], features=('dT', 'dT2'), n_centers=6)
    return save_model(model, tmp_path_factory.mktemp('models') / 'paper.yaml'), model


def stream(n=300, rate_hz=100.0, t0=1_700_000_000.0):
    """IMU stamps (ns) and rates of a warming run, with a thermometer sample per 0.5 s."""
    rng = np.random.default_rng(3)
    imu_ns = np.array([int(round((t0 + k / rate_hz) * 1e9)) for k in range(n)])
    temp_ns = np.array([int(round((t0 - 0.1 + k * 0.5) * 1e9)) for k in range(n // 50 + 2)])
    temp_c = np.linspace(10.0, 20.0, temp_ns.size)
    return imu_ns, 0.02 + rng.normal(0, 2e-3, (n, 3)), temp_ns, temp_c


def values(status):
    return {kv.key: kv.value for kv in status.values}


@pytest.mark.parametrize('which', ['px4', 'ardupilot'])
def test_declared_upstream_correction_passes_the_raw_rate_through(
        model_file, rig_factory, which):
    path, _ = model_file
    rig = rig_factory(model_file=str(path), upstream_correction=which,
                      passthrough_variance=0.25)
    imu_ns, omega, temp_ns, temp_c = stream()
    sent = rig.feed(imu_ns, omega, temp_ns, temp_c)
    assert len(rig.out) == len(sent) == len(imu_ns)
    np.testing.assert_array_equal(rates(rig.out), rates(sent))        # raw out, bit for bit
    assert not any(diagonal_marked(o.angular_velocity_covariance) for o in rig.out)
    assert all(o.angular_velocity_covariance[0] == 1e-6 + 0.25 for o in rig.out)  # flagged
    core = rig.node.core
    assert core.counts['compensated'] == 0 and core.flag_counts[UPSTREAM] == len(imu_ns)
    st = rig.node.diagnostic_status()
    assert st.level == DiagnosticStatus.WARN
    assert st.message.startswith(f'gyro already thermally corrected upstream ({which})')
    v = values(st)
    assert v['compensation active'] == 'False'
    assert 'gyro already thermally corrected upstream' in v['why not']
    assert v['passed through as corrected upstream'] == str(len(imu_ns))


def test_no_model_is_no_error_when_the_rate_passes_through_as_corrected(rig_factory):
    rig = rig_factory(upstream_correction='other')
    imu_ns, omega, temp_ns, temp_c = stream(n=50)
    rig.feed(imu_ns, omega, temp_ns, temp_c)
    st = rig.node.diagnostic_status()
    assert st.level == DiagnosticStatus.WARN and 'no model loaded' not in st.message
    assert rig.node.core.flag_counts[UPSTREAM] == 50


def test_upstream_policy_compensate_corrects_on_top_without_warning(model_file, rig_factory):
    path, model = model_file
    rig = rig_factory(model_file=str(path), upstream_correction='px4',
                      upstream_policy='compensate', reanchor_on_start=False)
    imu_ns, omega, temp_ns, temp_c = stream()
    rig.feed(imu_ns, omega, temp_ns, temp_c)
    t = imu_ns * 1e-9
    held = np.asarray(temp_c)[np.searchsorted(temp_ns * 1e-9, t, side='right') - 1]
    np.testing.assert_allclose(rates(rig.out), compensate(model, t, held, omega), atol=1e-9)
    assert all(diagonal_marked(o.angular_velocity_covariance) for o in rig.out)
    st = rig.node.diagnostic_status()
    assert st.level == DiagnosticStatus.OK
    assert 'compensating on top' in values(st)['upstream correction']


def test_default_is_no_upstream_correction_and_bad_values_stop_the_node(ros_context):
    from gyro_tdc.errors import ConfigError
    from gyro_tdc.nodes.compensator_node import CompensatorNode
    assert Policy().upstream_correction == '' and Policy().upstream_policy == 'passthrough'
    assert not CompensatorCore(Policy()).upstream_pass
    assert not CompensatorCore(Policy(upstream_correction='px4',
                                      upstream_policy='compensate')).upstream_pass
    with pytest.raises(ConfigError, match='upstream_correction'):
        CompensatorNode(context=ros_context, parameter_overrides=[
            Parameter('upstream_correction', value='betaflight')])
