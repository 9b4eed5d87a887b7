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
Publish a burst of Imu messages as fast as one process can (a child of the node tests).

``python test/burst_publisher.py COUNT RELIABILITY HISTORY [DEPTH]`` (``best_effort``/
``reliable``, ``keep_last``/``keep_all``, history depth default COUNT) on ``imu/data_raw``,
stamps 1 ms apart from 1,700,000,500 s and ``orientation.x`` = the sequence number,
angular-velocity covariance 1e-6. Talks to the test on stdin/stdout: prints ``matched`` once
a subscription matched, publishes when it reads ``go``, prints ``published COUNT`` (after
every message was acknowledged, when reliable keep-all) and exits when stdin closes. A reliable
keep-all publisher whose reader falls behind is held back by DDS flow control: ``publish``
then fails (Fast DDS: after its 100 ms blocking time) and the same message is published
again, as a driver that must not lose data would.
"""

import sys
import time

import rclpy
from rclpy.duration import Duration
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Imu


def main(argv):
    """Run the burst; return the exit status."""
    count, reliability, history = int(argv[0]), argv[1], argv[2]
    depth = int(argv[3]) if len(argv) > 3 else count
    rclpy.init()
    node = rclpy.create_node('burst_publisher')
    qos = QoSProfile(
        history=HistoryPolicy.KEEP_ALL if history == 'keep_all' else HistoryPolicy.KEEP_LAST,
        depth=depth, reliability=(ReliabilityPolicy.RELIABLE if reliability == 'reliable'
                                  else ReliabilityPolicy.BEST_EFFORT))
    pub = node.create_publisher(Imu, 'imu/data_raw', qos)
    deadline = time.monotonic() + 30.0
    while pub.get_subscription_count() < 1 and time.monotonic() < deadline:
        time.sleep(0.01)  # discovery: polled with a deadline
    print('matched', flush=True)
    if sys.stdin.readline().strip() != 'go':
        return 1
    msg = Imu()
    msg.header.frame_id = 'imu_link'
    msg.orientation_covariance[0] = -1.0
    msg.angular_velocity.x = 0.01
    msg.angular_velocity_covariance[0] = msg.angular_velocity_covariance[4] = 1e-6
    msg.angular_velocity_covariance[8] = 1e-6
    msg.linear_acceleration_covariance[0] = -1.0
    retries = 0
    for k in range(count):
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(1_700_000_500_000_000_000
                                                                + k * 1_000_000, 10 ** 9)
        msg.orientation.x = float(k)
        while True:
            try:
                pub.publish(msg)
                break
            except RuntimeError:  # rclpy's RCLError: held back by flow control, again
                retries += 1
    if reliability == 'reliable' and history == 'keep_all':
        pub.wait_for_all_acked(Duration(seconds=60))
    print(f'published {count} ({retries} publish calls held back)', flush=True)
    sys.stdin.read()
    node.destroy_node()
    rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
