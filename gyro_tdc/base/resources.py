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
Locate the files shipped in ``config/``: node parameters, scenarios and models.

In a source checkout or an editable install (``pip install -e .``, ``colcon build
--symlink-install``) ``config/`` sits next to the ``gyro_tdc`` package; ``pip install -e`` installs
no ``data_files``, so that is looked at first. A regular colcon install copies it to
``share/gyro_tdc/config``, found through the ament index (``ament_index_python``, imported
lazily; no ``rclpy``).
"""

from __future__ import annotations

from contextlib import suppress
import os
from pathlib import Path
from typing import Optional, Union

from gyro_tdc.errors import GyroTdcError, ModelFileError, ScenarioError

__all__ = ['config_dir', 'model_path', 'scenario_names', 'scenario_path']

PACKAGE = 'gyro_tdc'
YAML_SUFFIXES = ('.yaml', '.yml')

PathLike = Union[str, 'os.PathLike[str]']
#: Where a source checkout (or an editable install) holds ``config/`` and ``package.xml``.
_ROOT = Path(__file__).resolve().parents[2]


def _checkout_config_dir() -> Optional[Path]:
    found = _ROOT / 'config'
    # package.xml beside config/ tells a checkout from an unrelated site-packages/config.
    return found if found.is_dir() and (_ROOT / 'package.xml').is_file() else None


def config_dir() -> Path:
    """
    Return the directory holding gyro_tdc's shipped configuration files.

    ``<checkout>/config`` in a source checkout or editable install, otherwise
    ``<prefix>/share/gyro_tdc/config`` through the ament index.

    Raises
    ------
    GyroTdcError
        If neither location exists.

    """
    found = _checkout_config_dir()
    if found is None:   # PackageNotFoundError is a KeyError; no AMENT_PREFIX_PATH: OSError
        with suppress(ImportError, LookupError, ValueError, OSError):
            from ament_index_python.packages import get_package_share_directory
            found = Path(get_package_share_directory(PACKAGE)) / 'config'
    if found is None or not found.is_dir():
        raise GyroTdcError(
            f'gyro_tdc config directory not found: expected {_ROOT / "config"} (source '
            f'checkout) or share/{PACKAGE}/config in a prefix on AMENT_PREFIX_PATH '
            f'(AMENT_PREFIX_PATH={os.environ.get("AMENT_PREFIX_PATH", "<unset>")!r})')
    return found


def _dir(config: Optional[PathLike], kind: str) -> Path:
    """Return the directory of the shipped ``kind`` files (``config/<kind>s``)."""
    return (Path(config) if config is not None else config_dir()) / f'{kind}s'


def _names(directory: Path) -> list[str]:
    if not directory.is_dir():
        return []
    return sorted(p.stem for p in directory.iterdir() if p.is_file() and p.suffix in YAML_SUFFIXES)


def _resolve(name_or_file: PathLike, kind: str, error: type[GyroTdcError],
             config: Optional[PathLike]) -> Path:
    if not isinstance(name_or_file, (str, os.PathLike)):
        raise error(f'`{kind}` must be a {kind} name or a file path, '
                    f'got {type(name_or_file).__name__}: {name_or_file!r}')
    text = os.fspath(name_or_file)
    if not text:
        raise error(f'`{kind}` must be a {kind} name or a file path, got an empty string')
    path = Path(text).expanduser()
    if path.suffix in YAML_SUFFIXES or any(c and c in text for c in (os.sep, '/', os.altsep)):
        if path.is_file():
            return path
        raise error(f'`{kind}`: {kind} file {text!r} does not exist or is not a file')
    directory = _dir(config, kind)
    for suffix in YAML_SUFFIXES:
        candidate = directory / f'{text}{suffix}'
        if candidate.is_file():
            return candidate
    if path.is_file():
        # A bare file name in the working directory that is not a shipped name.
        return path
    available = ', '.join(_names(directory)) or '<none>'
    raise error(f'`{kind}`: unknown {kind} {text!r}; expected a YAML file path or one of '
                f'the shipped {kind}s in {directory}: {available}')


def scenario_names(*, config: Optional[PathLike] = None) -> list[str]:
    """
    Return the names of the shipped scenarios, sorted.

    Parameters
    ----------
    config : str or os.PathLike, optional
        Configuration directory to search instead of :func:`config_dir`.

    Returns
    -------
    list of str
        Stems of ``config/scenarios/*.yaml``.

    """
    return _names(_dir(config, 'scenario'))


def scenario_path(name_or_file: PathLike, *, config: Optional[PathLike] = None) -> Path:
    """
    Resolve a scenario name (``config/scenarios/NAME.yaml``) or a scenario file path.

    Anything with a ``.yaml``/``.yml`` suffix or a path separator is a path; names are searched
    in ``config`` (default :func:`config_dir`). A ScenarioError lists the shipped names.
    """
    return _resolve(name_or_file, 'scenario', ScenarioError, config)


def model_path(name_or_file: PathLike, *, config: Optional[PathLike] = None) -> Path:
    """
    Resolve a model name (``config/models/NAME.yaml``) or a model file path.

    Anything with a ``.yaml``/``.yml`` suffix or a path separator is a path; names are searched
    in ``config`` (default :func:`config_dir`). A ModelFileError lists the shipped names.
    """
    return _resolve(name_or_file, 'model', ModelFileError, config)
