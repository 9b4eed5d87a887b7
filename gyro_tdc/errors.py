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

"""Error classes of gyro_tdc; every message names what is wrong, on one line."""


class GyroTdcError(Exception):
    """Base class of every error gyro_tdc raises on bad input."""


class ModelFileError(GyroTdcError):
    """A model file is missing, malformed or inconsistent."""


class DatasetError(GyroTdcError):
    """A bag or data set cannot be read or does not hold what is needed."""


class FitError(GyroTdcError):
    """Identification cannot proceed (too few samples, too small a span...)."""


class ScenarioError(GyroTdcError):
    """A simulator scenario file is malformed."""


class DeviceError(GyroTdcError):
    """A hardware source (e.g. a Linux IIO device) is missing or returned garbage."""


class FeatureError(GyroTdcError):
    """An effect id is unknown or its parameters are invalid."""


class FleetError(GyroTdcError):
    """A fleet manifest is malformed or the Dask engine cannot be reached."""


class OutputError(GyroTdcError):
    """An output file or directory cannot be written (the message names it)."""


class LimitError(GyroTdcError):
    """An input or option exceeds a documented size limit (the message names the limit)."""


class LearnFileError(GyroTdcError, ValueError):
    """A ``learn_file`` is not a learner state this learner may use (one line naming why)."""


def one_line(text: object) -> str:
    """
    Return an error or a message on one line (newlines and runs of blanks collapsed).

    Parameters
    ----------
    text : object
        A message, or an exception (its type name when its text is empty).

    Returns
    -------
    str
        The text on one line.

    """
    out = ' '.join(str(text).split())
    return type(text).__name__ if not out and isinstance(text, BaseException) else out


class ConfigError(GyroTdcError, ValueError):
    """A node's parameters or topic names are invalid or inconsistent (one line naming them)."""
