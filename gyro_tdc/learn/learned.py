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
A learned model is a model: a ``learn_file``'s current model, wherever a model file goes.

:func:`model_from_file` reads a learn_file (bounded and checked, never written) and returns
its learned model; :func:`read_model` takes a model file, a shipped model's name or a
learn_file alike (the commands' and the node's model loading). See ``doc/internals/learn.md``.
"""

from __future__ import annotations

import os
from pathlib import Path

from gyro_tdc.base import model_path
from gyro_tdc.errors import ModelFileError
from gyro_tdc.learn.codec import decode_state, FORMAT
from gyro_tdc.learn.fit import model_of
from gyro_tdc.learn.store import LearnFile
from gyro_tdc.model import CompensationModel, load_model

__all__ = ['is_learn_file', 'model_from_file', 'read_model']

#: Bytes read to tell a learn_file from a model file (its ``format`` is on the second line).
_HEAD = 512


def is_learn_file(path: str | os.PathLike) -> bool:
    """Return whether ``path`` is a regular file that starts as a learn_file does."""
    p = Path(path)
    try:
        if not p.is_file():
            return False
        with open(p, 'rb') as stream:
            head = stream.read(_HEAD)
    except OSError:
        return False
    text = head.decode('utf-8', 'replace').lstrip()
    return text.startswith('{') and f'"{FORMAT}"' in text


def model_from_file(path: str | os.PathLike) -> CompensationModel:
    """
    Return the current learned model of a learn_file.

    The file is read as the node resumes it (bounded, every field checked) but never
    written. The model is the one the learner would install on resuming: its fit (the
    newest session's offset, the shared shape) with the thermal section it was binned at.

    Parameters
    ----------
    path : str or PathLike
        The learn_file.

    Returns
    -------
    CompensationModel
        The learned model (``created`` names the file and its last update).

    Raises
    ------
    ModelFileError
        The file is missing or holds no accepted model yet (one line: what it holds).
    LearnFileError
        The file is not a learner state.

    """
    p = Path(path)
    doc = LearnFile(p).read(fix_mode=False)
    if doc is None:
        raise ModelFileError(f'learn_file {str(p)!r} does not exist')
    values, thermal = decode_state(doc)
    fit = values['fit']
    if fit is None:
        points = sum(len(v) for v in values['bins'].values())
        raise ModelFileError(
            f'learn_file {str(p)!r} holds no accepted model yet ({points} points in '
            f'{len(values["bins"])} bins, {values["still_s"]:.0f} s still): learn longer, or '
            'give a model file')
    model = model_of(fit, thermal)
    created = dict(model.created)
    created.update({'learn_file': str(p), 'last_update_stamp_s': values['last_update_t'],
                    'sessions': values['session'] + 1, 'points': fit['points']})
    return model.replace(created=created)


def read_model(spec: str | os.PathLike) -> CompensationModel:
    """
    Return the model of a model file, of a shipped model's name or of a learn_file.

    Raises
    ------
    ModelFileError
        No such file or name, a malformed model file, or a learn_file without a model.
    LearnFileError
        A file that starts as a learn_file but is not a learner state.

    """
    if is_learn_file(spec):
        return model_from_file(spec)
    return load_model(model_path(spec))
