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

"""The learn_file (``learn.store``): read bounded, written atomically, its model a model."""

from __future__ import annotations

from contextlib import contextmanager
import copy
import json
import math
import os
from pathlib import Path
import re
import shutil
import stat
import tempfile

from gyro_tdc.errors import LearnFileError, ModelFileError
from gyro_tdc.learn import is_learn_file, model_from_file, read_model
from gyro_tdc.learn import learner as learning
from gyro_tdc.learn.codec import decode_state, encode_state, FORMAT
from gyro_tdc.learn.learner import Learner
from gyro_tdc.learn.store import LearnFile
from gyro_tdc.model import drift
from gyro_tdc.model.modelfile import load_model, save_model
from hypothesis import given, HealthCheck, settings, strategies as st
from learn_states import (curved_prior, fresh_learner, hostile_files, HOSTILE_NAMES, learned,
                          plain_state)
import numpy as np
import pytest

NOBODY = 65534


@pytest.fixture(scope='module')
def base():
    """Return a learner that learned two still stretches, and its state as a file holds it."""
    learner = learned()
    return learner, plain_state(learner)


def test_state_round_trips_through_a_file(tmp_path, base):
    learner, _ = base
    state = encode_state(learner)
    assert state['format'] == FORMAT and len(state['bins']) == 2 and state['fit'] is not None
    assert state == learner.state()
    path = tmp_path / 'learn.json'
    LearnFile(path).write(state)
    assert LearnFile(path).read() == json.loads(json.dumps(state))
    values, thermal = decode_state(LearnFile(path).read())
    assert thermal is None
    for name, value in values.items():
        owner = learner.still if name in ('gyro_floor', 'accel_floor', 't_first') else learner
        if name == 'last_save_t':
            assert value == learner.last_t
        elif isinstance(value, np.ndarray):
            np.testing.assert_array_equal(value, getattr(owner, name))
        else:
            assert value == getattr(owner, name), name
    again = fresh_learner()
    assert again.load(path) and again.state() == json.loads(json.dumps(state))
    assert again.take_model() is not None         # the learned model is current at once


def test_the_file_is_strict_json_and_an_unknown_floor_is_null(tmp_path):
    learner = fresh_learner()                             # nothing learned: the floors are unknown
    assert np.all(np.isinf(learner.still.gyro_floor))
    path = tmp_path / 'learn.json'
    learner.save(path)
    text = path.read_text()
    assert 'Infinity' not in text and 'NaN' not in text
    doc = json.loads(text, parse_constant=lambda c: pytest.fail(f'non-JSON constant {c}'))
    assert doc['gyro_floor'] == [None] * 3
    again = fresh_learner()
    assert again.load(path) and np.all(np.isinf(again.still.gyro_floor))
    # Infinity is no JSON a learner writes (0.1.0 is the first release): refused, named.
    path.write_text(json.dumps({**doc, 'gyro_floor': [math.inf] * 3}))
    with pytest.raises(LearnFileError, match=r'`gyro_floor\[0\]`'):
        fresh_learner().load(path)


def test_bad_states_and_files_are_refused(tmp_path):
    assert LearnFile(tmp_path / 'missing.json').read() is None
    bad = tmp_path / 'bad.json'
    bad.write_text('{"format": ')
    with pytest.raises(ValueError, match='not JSON'):
        LearnFile(bad).read()
    for state in ({'format': 'gyro_tdc learn 0'}, [FORMAT], None):
        with pytest.raises(ValueError, match='not a learner state'):
            decode_state(state)
    state = {**encode_state(learned(temps=(20.0,))), 'thermal': {'kind': 'first_order'}}
    with pytest.raises(ValueError, match='`thermal` missing field `tau_s`'):
        decode_state(state)


def test_learning_re_exports_the_format():
    assert learning.FORMAT is FORMAT


# -- a learn_file the learner cannot read ------------------------------------------------


@pytest.mark.parametrize('name', [n for n in HOSTILE_NAMES if n not in (
    'model_yaml', 'truncated', 'list', 'text', 'empty', 'not_utf8')])   # not JSON: save tests
def test_a_file_that_is_not_a_learner_state_is_refused_in_one_line(tmp_path, base, name):
    """``"bins": []``, deep nesting, NaN, wrong signs and shapes: a ValueError, no change."""
    _, state = base
    path = tmp_path / 'learn.json'
    path.write_bytes(hostile_files(state)[name])
    learner = fresh_learner()
    before = learner.state()
    with pytest.raises(ValueError) as err:
        learner.load(path)
    assert '\n' not in str(err.value)
    assert learner.state() == before and learner.take_model() is None


def test_a_file_over_the_size_limit_is_refused_before_it_is_read(tmp_path, base,
                                                                 monkeypatch):
    """A valid state padded past 4 MiB (a 41 MB one stalled the node): refused, unparsed."""
    _, state = base
    big = {**state, 'motion': [[float(k), False] for k in range(300_000)]}
    path = tmp_path / 'learn.json'
    path.write_text(json.dumps(big))
    assert path.stat().st_size > 4 * 1024 * 1024
    calls = []
    monkeypatch.setattr(json, 'loads', lambda *a, **k: calls.append(a) or {})
    with pytest.raises(ValueError, match='4194304-byte'):
        fresh_learner().load(path)
    assert not calls


def test_the_saved_state_stays_under_the_size_limit(tmp_path, base):
    """Three day-long still stretches: the newest day of windows of each is written."""
    learner = learned(temps=(20.0,))
    row = learner.recent[-1][2][-1]
    learner.recent = [[k + 1, 0, [list(row)] * 20_000] for k in range(3)]
    path = tmp_path / 'learn.json'
    learner.save(path)
    assert path.stat().st_size < 4 * 1024 * 1024
    again = fresh_learner()
    assert again.load(path)
    assert [len(s[2]) for s in again.recent] == [8640] * 3


@pytest.mark.parametrize('name', ['model_yaml', 'truncated', 'list', 'text'])
def test_save_never_overwrites_a_file_that_is_not_a_learner_state(tmp_path, base, name):
    """A model YAML given as learn_file by mistake (and the like) is kept, byte for byte."""
    learner, state = base
    path = tmp_path / 'learn.json'
    content = hostile_files(state)[name]
    path.write_bytes(content)
    with pytest.raises(Exception, match='not overwritten, kept as it is'):
        learner.save(path)
    assert path.read_bytes() == content
    assert sorted(p.name for p in tmp_path.iterdir()) == ['learn.json']   # no temporary left


def test_save_replaces_an_older_learner_state(tmp_path, base):
    learner, _ = base
    path = tmp_path / 'learn.json'
    fresh_learner().save(path)
    learner.save(path)
    assert LearnFile(path).read() == plain_state(learner)


def test_a_symbolic_link_is_neither_read_nor_written_through(tmp_path, base):
    """A link to a copy of /etc/passwd (as root, the real one would be hit): refused."""
    learner, state = base
    target = tmp_path / 'passwd'
    shutil.copyfile('/etc/passwd', target)
    content = target.read_bytes()
    link = tmp_path / 'learn.json'
    link.symlink_to(target)
    with pytest.raises(Exception, match='symbolic link'):
        learner.save(link)
    assert target.read_bytes() == content and link.is_symlink()
    with pytest.raises(ValueError, match='symbolic link'):
        fresh_learner().load(link)
    # Not even to a learner state, nor dangling (a new file would appear at its target).
    good = tmp_path / 'good.json'
    good.write_text(json.dumps(state))
    for to in (good, tmp_path / 'nowhere' / 'new.json'):
        link.unlink()
        link.symlink_to(to)
        with pytest.raises(Exception, match='symbolic link'):
            learner.save(link)
        with pytest.raises(ValueError, match='symbolic link'):
            fresh_learner().load(link)
    assert good.read_text() == json.dumps(state) and not (tmp_path / 'nowhere').exists()


@contextmanager
def _as_nobody(directory: Path):
    """Run the block with the effective user ``nobody`` when root (as a node would run)."""
    if os.geteuid() != 0:
        yield
        return
    os.chown(directory, NOBODY, NOBODY)
    os.seteuid(NOBODY)
    try:
        yield
    finally:
        os.seteuid(0)


def test_learning_survives_a_restart_from_a_mode_000_file(base):
    """A learn_file of mode 000: read (the owner given u+rw back) and written 0600-ish."""
    learner, state = base
    directory = Path(tempfile.mkdtemp(prefix='gyro_tdc-learn-'))
    try:
        path = directory / 'learn.json'
        fresh_learner().load(path)                       # everything imported before the switch
        with _as_nobody(directory):
            learner.save(path)
            os.chmod(path, 0)
            resumed = fresh_learner()
            assert resumed.load(path), 'the saved state was not resumed'
            assert plain_state(resumed) == state
            os.chmod(path, 0)
            resumed.save(path)                    # the node's save at shutdown
            mode = stat.S_IMODE(path.stat().st_mode)
            assert mode & 0o600 == 0o600, oct(mode)
            assert fresh_learner().load(path)
    finally:
        shutil.rmtree(directory)


def test_a_learned_candidate_is_checked_like_a_model_file(monkeypatch):
    """A refit whose model computes NaN is never swapped in; it is counted on /diagnostics."""
    def nan_fit(*args, **kwargs):
        return {'features': ['dT'], 't0_c': 20.0, 'coef': [[math.nan] * 3, [0.0] * 3],
                'range_c': [20.0, 20.0], 'resid_var': [1e-8] * 3, 'points': 1}
    monkeypatch.setattr(learning, 'fit_points', nan_fit)
    learner = learned(temps=(20.0,))
    assert learner.take_model() is None and learner.fit is None and learner.swaps == 0
    refused = learner.diagnostic_values()['learn candidates refused']
    assert re.fullmatch(r'[1-9][0-9]* \(last: field `intercept` .*nan.*\)', refused), refused


# -- property: no content crashes the loader or loads a state with non-finite output ----

_SCALARS = (st.none() | st.booleans() | st.integers(-10 ** 20, 10 ** 20)
            | st.floats(allow_nan=True, allow_infinity=True) | st.text(max_size=6))
_JSON = st.recursive(_SCALARS, lambda c: st.lists(c, max_size=4)
                     | st.dictionaries(st.text(max_size=6), c, max_size=4), max_leaves=12)
_HOSTILE = st.sampled_from([math.nan, math.inf, -math.inf, -1, 0, -0.0, 1e308, -1e308,
                            10 ** 400, 1e-320, 2.5, [], {}, '', None, True, [[]], [0] * 7,
                            [math.nan] * 3, 1e30, -300.0, 300.0]) | _JSON
# Plausible values too, so that many mutated files load and their output is checked.
_PLAUSIBLE = st.floats(-60.0, 120.0) | st.integers(0, 50) | st.floats(-1e-2, 1e-2)


def _paths(doc, prefix=()):
    """Return every path into ``doc`` (keys and indices), containers included."""
    out = [prefix] if prefix else []
    if isinstance(doc, dict):
        for k, v in doc.items():
            out += _paths(v, prefix + (k,))
    elif isinstance(doc, list):
        for i, v in enumerate(doc[:3]):
            out += _paths(v, prefix + (i,))
    return out


def _mutate(doc, path, value):
    """Return ``doc`` with the item at ``path`` replaced by ``value`` (or deleted: Ellipsis)."""
    node = doc
    for k in path[:-1]:
        node = node[k]
    if value is Ellipsis:
        del node[path[-1]]
    else:
        node[path[-1]] = value
    return doc


def _check_loaded(learner):
    """Check a loaded learner: its model (if any) finite and plausible; it goes on learning."""
    model = learner.take_model()
    if model is not None:
        lo, hi = model.temp_range_c
        temps = np.linspace(lo - 25.0, hi + 25.0, 101)
        b = drift(model, np.arange(temps.size) * 10.0, temps, out_of_range='linear')
        assert np.all(np.isfinite(b)) and np.abs(b).max() <= 5.0
    learner.diagnostic_values()
    t0 = (learner.last_t or 0.0) + 1.0
    rng = np.random.default_rng(0)
    learner.add_temperature(t0, 25.0)
    for k in range(700):                     # 70 s still at 10 Hz, then motion
        learner.observe(t0 + k / 10.0, *(0.01 + 1e-4 * rng.standard_normal(3)))
    for k in range(700, 720):
        learner.observe(t0 + k / 10.0, *(0.3 * rng.standard_normal(3)))
    learner.step()
    model = learner.take_model()
    if model is not None:
        b = drift(model, np.zeros(3), np.array([0.0, 25.0, 50.0]), out_of_range='linear')
        assert np.all(np.isfinite(b))
    learner.diagnostic_values()


def _load_bytes(directory, data, prior=None):
    path = directory / 'learn.json'
    path.write_bytes(data)
    learner = learning.Learner(learning.LearnConfig(temperature_timeout=1e9), prior=prior)
    before = learner.state()
    try:
        learner.load(path)
    except ValueError as exc:
        assert '\n' not in str(exc)
        assert learner.state() == before
        return
    _check_loaded(learner)


_SETTINGS = settings(max_examples=200, deadline=None, derandomize=True,
                     suppress_health_check=[HealthCheck.too_slow,
                                            HealthCheck.function_scoped_fixture])


@_SETTINGS
@given(doc=_JSON | st.fixed_dictionaries({'format': st.just(FORMAT)},
                                         optional={k: _JSON for k in (
                                             'bins', 'session', 'gyro_floor', 'fit', 'recent',
                                             'check', 'motion', 'thermal', 'thermal_state')}))
def test_random_json_never_crashes_the_loader(tmp_path_factory, doc):
    _load_bytes(tmp_path_factory.mktemp('random'), json.dumps(doc).encode())


def _mutated(state, data, paths_of):
    """Return a copy of ``state`` with one or two of the paths ``paths_of`` gives mutated."""
    doc = json.loads(json.dumps(state))
    for _ in range(data.draw(st.integers(1, 2))):
        paths = paths_of(doc)
        if not paths:
            break
        path = data.draw(st.sampled_from(paths))
        value = data.draw(_PLAUSIBLE | _HOSTILE | st.just(Ellipsis))
        _mutate(doc, path, copy.deepcopy(value))
    return doc


@_SETTINGS
@given(data=st.data())
def test_mutated_learn_files_load_finite_or_are_refused(tmp_path_factory, base, data):
    _, state = base
    doc = _mutated(state, data, _paths)
    text = json.dumps(doc).encode()
    if data.draw(st.integers(0, 3)) == 0:     # and maybe damage the bytes themselves
        k = data.draw(st.integers(0, len(text)))
        text = text[:k] + data.draw(st.binary(max_size=4)) + text[k + data.draw(
            st.integers(0, 8)):]
    _load_bytes(tmp_path_factory.mktemp('mutated'), text)


@pytest.fixture(scope='module')
def corrected():
    """Return a learner that learned a correction to its prior, and its state."""
    learner = learned(prior=curved_prior())
    return learner, plain_state(learner)


@_SETTINGS
@given(data=st.data())
def test_mutated_correction_files_load_finite_or_are_refused(tmp_path_factory, corrected, data):
    """The same over the prior the file corrects: its fit, its prior and their ids mutated."""
    learner, state = corrected
    doc = _mutated(state, data, lambda d: [p for p in _paths(d) if p[0] in ('fit', 'prior')])
    _load_bytes(tmp_path_factory.mktemp('corrected'), json.dumps(doc).encode(), learner.prior)


_RATE = st.floats(-0.1, 0.1) | st.floats(-100.0, 100.0)
_COEF = st.floats(-1e9, 1e9) | st.floats(-1e-2, 1e-2) | st.sampled_from([0.0, 1e-4, -3e-3])


@st.composite
def _typed_states(draw, base_state):
    """Return a state of the right types and shapes, with random (often wild) values."""
    bins = {}
    for k in draw(st.sets(st.integers(-100, 199), min_size=1, max_size=6)):
        bins[str(k)] = [[draw(st.floats(0.0, 1e5)), draw(st.floats(1.0, 1e4)),
                         k + draw(st.floats(0.0, 0.999)), [draw(_RATE) for _ in range(3)],
                         draw(st.integers(1, 10)), draw(st.integers(0, 3))]
                        for _ in range(draw(st.integers(1, 4)))]
    fit = None
    if draw(st.booleans()):
        feats = draw(st.sampled_from([[], ['dT'], ['dT', 'dT2'], ['dT', 'dT2', 'dT3']]))
        lo, hi = sorted(draw(st.floats(-100.0, 200.0)) for _ in range(2))
        fit = {'features': feats, 't0_c': draw(st.floats(-100.0, 200.0)),
               'coef': [[draw(_COEF) for _ in range(3)] for _ in range(1 + len(feats))],
               'range_c': [lo, hi], 'resid_var': [draw(st.floats(0.0, 1.0)) for _ in range(3)],
               'points': draw(st.integers(1, 50))}
    recent = [[draw(st.integers(1, 10)), draw(st.integers(0, 3)),
               [[draw(st.integers(3, 1000)), draw(st.floats(-100.0, 200.0)),
                 *(draw(_RATE) for _ in range(3)), draw(st.floats(0.0, 1e5))]
                for _ in range(draw(st.integers(0, 5)))]]
              for _ in range(draw(st.integers(0, 3)))]
    return {**base_state, 'bins': bins, 'fit': fit, 'recent': recent,
            'session': draw(st.integers(0, 3)), 'last_t': draw(st.floats(0.0, 1e5))}


@_SETTINGS
@given(data=st.data())
def test_well_formed_states_with_wild_values_load_finite_or_are_refused(tmp_path_factory,
                                                                        base, data):
    """Types and shapes right, values anywhere: a wild fit is refused by the model check."""
    _, state = base
    doc = data.draw(_typed_states(state))
    _load_bytes(tmp_path_factory.mktemp('typed'), json.dumps(doc).encode())


# -- a learned model is a model ------------------------------------------------------------


@pytest.fixture(scope='module')
def learner():
    return learned()


def test_the_file_gives_the_learners_model(learner, tmp_path):
    path = tmp_path / 'learn.json'
    learner.save(path)
    assert is_learn_file(path)
    model = model_from_file(path)
    assert model.model_id == learner.model.model_id
    t, temp = np.arange(5.0), np.linspace(15.0, 30.0, 5)
    np.testing.assert_array_equal(drift(model, t, temp), drift(learner.model, t, temp))
    assert model.created['learn_file'] == str(path) and model.created['points'] == 2
    # A model file written from it reads back as the same model.
    again = load_model(save_model(model, tmp_path / 'm.yaml'))
    assert again.model_id == model.model_id


def test_read_model_takes_model_files_and_learn_files(learner, tmp_path):
    yaml_path = save_model(learner.model, tmp_path / 'model.yaml')
    assert not is_learn_file(yaml_path)
    assert read_model(str(yaml_path)).model_id == learner.model.model_id
    learner.save(tmp_path / 'l.json')
    assert read_model(str(tmp_path / 'l.json')).model_id == learner.model.model_id
    assert read_model('l3gd20_modified').kind        # a shipped name still resolves


def test_no_accepted_model_yet_is_one_line(tmp_path):
    path = tmp_path / 'empty.json'
    Learner().save(path)
    with pytest.raises(ModelFileError, match='no accepted model yet') as err:
        read_model(str(path))
    assert '\n' not in str(err.value)


def test_a_broken_learn_file_is_refused_and_left_as_it_is(learner, tmp_path):
    path = tmp_path / 'bad.json'
    learner.save(path)
    text = path.read_text().replace('"session": 0', '"session": -3')
    path.write_text(text)
    os.chmod(path, 0o400)
    with pytest.raises(LearnFileError, match='session'):
        read_model(str(path))
    assert stat.S_IMODE(os.stat(path).st_mode) == 0o400 and path.read_text() == text


def test_a_newest_stretch_of_another_session_is_no_crash(tmp_path):
    # The file's newest recent stretch (of session 0) has the number of the learner's next
    # stretch (of session 1): the windows that follow are session 1's own and judge its next
    # candidate (they were added to session 0's, leaving none: ZeroDivisionError).
    entry = [0.0, 1.0, 0.0, [0.0, 0.0, 0.0], 1, 0]
    doc = {'format': FORMAT, 'bins': {'0': [entry, entry]}, 'session': 1,
           'gyro_floor': [9.3e-05, 9.6e-05, 9.5e-05], 'accel_floor': [None] * 3,
           't_first': 0.0, 'still_s': 240.0, 'stretches': 2, 'windows': 29,
           'recent': [[3, 0, []]], 'fit': None, 'last_update_t': 209.99, 'last_t': 0.0,
           'check': None, 'swaps': 2, 'motion': [[300.0, True]], 'thermal': None,
           'thermal_state': None, 'segment': [2, 150.0],
           'config': {'bin_c': 1.0, 'half_life_s': 86400.0, 'window_s': 10.0,
                      'min_still_s': 60.0}}
    _load_bytes(tmp_path, json.dumps(doc).encode())
