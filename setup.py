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

"""Build gyro_tdc as an ament_python package (colcon) or a plain pip package."""

import os

from setuptools import find_packages
from setuptools import setup

package_name = 'gyro_tdc'
here = os.path.dirname(os.path.abspath(__file__))


def config_data_files(root='config'):
    """
    List every file under ``config/`` as ``data_files`` entries, keeping sub-directories.

    Parameters
    ----------
    root : str
        Directory relative to this file whose tree goes to ``share/gyro_tdc/<root>``.

    Returns
    -------
    list of (str, list of str)
        ``(install directory, [source files relative to setup.py])`` pairs, sorted.

    """
    entries = []
    for dirpath, dirnames, filenames in os.walk(os.path.join(here, root)):
        dirnames[:] = sorted(d for d in dirnames if not d.startswith(('.', '__')))
        files = sorted(f for f in filenames if not f.startswith('.'))
        if not files:
            continue
        rel_dir = os.path.relpath(dirpath, here)
        entries.append((
            os.path.join('share', package_name, rel_dir),
            [os.path.join(rel_dir, f) for f in files]))
    return entries


setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(where=here, exclude=['test', 'test.*']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        # ros2 launch gyro_tdc gyro_tdc.launch.xml (test/test_launch.py checks it).
        ('share/' + package_name + '/launch', sorted(
            os.path.join('launch', f) for f in os.listdir(os.path.join(here, 'launch'))
            if f.endswith('.launch.xml'))),
        # The driver recipes: ros2 launch gyro_tdc recipes/<driver>.launch.xml (doc/drivers.md).
        ('share/' + package_name + '/launch/recipes', sorted(
            os.path.join('launch', 'recipes', f)
            for f in os.listdir(os.path.join(here, 'launch', 'recipes'))
            if f.endswith('.launch.xml'))),
    ] + config_data_files(),
    python_requires='>=3.10',
    # What the robot needs: the nodes import numpy and PyYAML and nothing else outside ROS
    # (test/system/test_packaging.py starts them with every training module blocked).
    install_requires=[
        'setuptools',
        'numpy>=1.26',
        'PyYAML>=6.0',
    ],
    extras_require={
        # Training, evaluation, reports, simulation, fleet calibration and flight-controller
        # logs: pip install 'gyro_tdc[train]' (package.xml: the GYRO_TDC_TRAINING condition).
        'train': [
            'scipy>=1.11',
            'matplotlib>=3.6',
            'rosbags>=0.11.9,<0.12',   # the public API read_bag is tested against
            'statsmodels>=0.14',
            'AllanTools>=2019.9',
            'tqdm>=4.60',
            'dask[distributed]>=2024.1',
            'pyulog>=1.1',
            'pymavlink>=2.4.40,<2.5',  # DFReader_binary's record index: no documented API
        ],
        'test': ['pytest'],
    },
    zip_safe=True,
    maintainer='gyro_tdc maintainers',
    maintainer_email='maintainer@gyro-tdc.dev',
    description='Temperature drift compensation for MEMS gyroscopes (ROS 2 Jazzy).',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            # The two ROS 2 nodes (`ros2 run gyro_tdc driver_node`, `... compensator_node`).
            'driver_node = gyro_tdc.nodes.driver_node:main',
            'compensator_node = gyro_tdc.nodes.compensator_node:main',
            # One entry point for every offline command: `gyro-tdc <command> [args...]`
            # (the same as `python -m gyro_tdc <command>`), no generic names in bin/.
            'gyro-tdc = gyro_tdc.__main__:main',
        ],
    },
)
