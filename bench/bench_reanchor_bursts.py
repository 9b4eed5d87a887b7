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
Re-anchoring on bursty and continuous streams, swept: seeded random rates, bursts, motion.

Each case is streamed through ``CompensatorCore`` with the node's defaults: a rate of 1 Hz
to 2 kHz (log-uniform), recorded continuously (a quarter of the cases) or as bursts of 1-20 s
separated by pauses of 5-500 s (one session: below ``SESSION_GAP_S``) or, in a quarter of the
bursty cases, of 700-7200 s (over the session gap: the first pauses, or every one over
``BURST_MAX_S``, start a new power cycle), a thermometer resolving 0.004-1 degC on every
sample (from 25 degC, cooling or heating by 0.5-6 degC/h but by at most 8 degC over the case:
within the training range, where the core re-anchors), a linear drift the model (a line
fitted on a continuous training run of the same sensor, 15-35 degC) knows, a turn-on offset
of 0-0.5 deg/s it does not, white noise of 0.006-0.2 deg/s; in half the cases some of the
first bursts (or 10 s stretches, continuous) move (a rate swing of 8-1000 x the noise on one
axis). Every anchor taken (one a session at most) is judged:

* error: the anchor's shift minus the mean noise-free compensated rate over the samples it
  averaged (the truth), over the anchor's own SE and over the noise floor (per-sample
  sigma); it passes when ``|error| <= 4 max(SE, tolerance)`` on every axis;
* moving samples: how many of the samples averaged move (counted, not judged: the still test
  lets a sample through whose swing it cannot see, and the error above says what it cost).

A case fires when one of its sessions anchors (it has at least 60 s of still time in its
bursts), passes when it fired and every anchor passed; ``anchored`` is the share of its
samples compensated with their session's anchor in force (what the re-anchoring covered),
``provisional`` the share with a still run's shift so far in force before it.

``--rule`` trains with ``train``'s start-up shift rule: an axis within the model's gate is
not shifted and is judged unshifted. ``--old COMMIT`` runs the re-anchoring of
``gyro_tdc/runtime/reanchor.py`` at that commit beside this tree's, on the same cases (the
core is this tree's). Run:
``.venv/bin/python bench/bench_reanchor_bursts.py --cases 60 --old fd17df7`` (about 10 s).
"""

from __future__ import annotations

import argparse
import importlib.util
import math
from pathlib import Path
import subprocess
import sys
import tempfile
import time

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from gyro_tdc.base import SESSION_GAP_S  # noqa: E402
from gyro_tdc.data import Run  # noqa: E402
from gyro_tdc.identify import fit_model, reanchor_rule  # noqa: E402
from gyro_tdc.model import compensate  # noqa: E402
from gyro_tdc.runtime import Policy  # noqa: E402
import gyro_tdc.runtime.core as core_mod  # noqa: E402
import gyro_tdc.runtime.state as state_mod  # noqa: E402
import numpy as np  # noqa: E402

DEG = math.pi / 180.0
#: Samples a case streams at most (so 2 kHz cases hold shorter bursts in all).
MAX_SAMPLES = 60_000
#: Still time in bursts a case holds at least, s.
STILL_S = 60.0


def load_old(commit: str):
    """Return the StillnessDetector of gyro_tdc/runtime/reanchor.py at ``commit``."""
    src = subprocess.run(['git', '-C', str(ROOT), 'show',
                          f'{commit}:gyro_tdc/runtime/reanchor.py'],
                         check=True, capture_output=True, text=True).stdout
    path = Path(tempfile.mkdtemp()) / 'reanchor_old.py'
    path.write_text(src)
    spec = importlib.util.spec_from_file_location('reanchor_old', path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod          # dataclasses look their module up
    spec.loader.exec_module(mod)
    return mod.StillnessDetector


def draw(rng: np.random.Generator, k: int, seed: int = 27) -> dict:
    """Draw one case (the pauses over the session gap from a stream of their own)."""
    rate = float(10 ** rng.uniform(0.0, math.log10(2000.0)))
    continuous = bool(rng.random() < 0.25)
    burst = float(rng.uniform(1.0, 20.0))
    pause = float(10 ** rng.uniform(math.log10(5.0), math.log10(500.0)))
    over = np.random.default_rng([seed, k])
    if over.random() < 0.25:
        pause = float(10 ** over.uniform(math.log10(700.0), math.log10(7200.0)))
    return {'k': k, 'rate': rate, 'continuous': continuous,
            'burst_s': math.inf if continuous else burst, 'pause_s': 0.0 if continuous else pause,
            'res_c': float(10 ** rng.uniform(math.log10(0.004), 0.0)),
            'offset_dps': float(rng.uniform(-0.5, 0.5)),
            'sigma': float(10 ** rng.uniform(-4.0, math.log10(3.5e-3))),
            'slope': float(rng.uniform(-2e-4, 2e-4)),
            'cool_c_h': float(rng.choice([-1.0, 1.0]) * rng.uniform(0.5, 6.0)),
            'motion': bool(rng.random() < 0.5),
            'amp': float(10 ** rng.uniform(math.log10(8.0), 3.0)),
            'seed': int(rng.integers(1 << 30))}


def stamps(d: dict, rng: np.random.Generator):
    """Return the stamps and the burst number of each sample."""
    period = 1.0 / d['rate']
    still_s = max(STILL_S, 3.0 * 10.0)
    if d['continuous']:
        n = int(min(MAX_SAMPLES, (still_s + 60.0) * d['rate']))
        t = 1000.0 + np.arange(n) * period
        seg = np.floor((t - t[0]) / 10.0).astype(np.int64)     # 10 s stretches
        return t, seg
    per = max(1, int(round(d['burst_s'] * d['rate'])))
    bursts = int(np.clip(math.ceil(still_s / max(d['burst_s'], period)) + 6, 4,
                         max(4, MAX_SAMPLES // per)))
    parts, seg = [], []
    t0 = 1000.0
    for b in range(bursts):
        parts.append(t0 + np.arange(per) * period)
        seg.append(np.full(per, b))
        t0 = parts[-1][-1] + d['pause_s'] * rng.uniform(0.9, 1.1)
    return np.concatenate(parts), np.concatenate(seg)


def model_for(d: dict, rule: bool = False):
    """Fit a line on a continuous training run of the same sensor (no offset); gated: rule."""
    rng = np.random.default_rng(d['seed'] + 1)
    t = np.arange(0.0, 3600.0, 1.0)
    temp = 15.0 + 20.0 * t / t[-1]
    tq = np.round(temp / d['res_c']) * d['res_c']
    om = d['slope'] * (temp - 25.0)[:, None] + rng.normal(0.0, d['sigma'], (t.size, 3))
    run = Run(t, tq, om, np.zeros_like(om), 'train')
    model = fit_model([run], kind='poly', features=('dT',), t0=25.0)
    return reanchor_rule(model, [run], [0], None) if rule else model


def case(d: dict, detector_cls=None, rule: bool = False) -> dict:
    """Stream one case through a core; return what its re-anchoring did."""
    rng = np.random.default_rng(d['seed'])
    t, seg = stamps(d, rng)
    n = t.size
    # From mid-range, at most 8 degC either way over the case: within the model's range (15-35
    # degC), where the core re-anchors (not on a sample out of range).
    span_h = (t[-1] - t[0]) / 3600.0
    rate = d['cool_c_h'] * min(1.0, 8.0 / max(abs(d['cool_c_h']) * span_h, 1e-9))
    temp = 25.0 + rate * (t - t[0]) / 3600.0
    tq = np.round(temp / d['res_c']) * d['res_c']
    clean = np.full((n, 3), d['offset_dps'] * DEG) + d['slope'] * (temp - 25.0)[:, None]
    raw = clean + rng.normal(0.0, d['sigma'], (n, 3))
    moving = np.zeros(n, dtype=bool)
    if d['motion']:
        segs = int(seg[-1]) + 1
        first = min(6, segs - 2)
        pick = np.flatnonzero(rng.random(first) < 0.5)
        pick = np.union1d(pick, rng.choice(segs, size=max(1, segs // 10), replace=False))
        moving = np.isin(seg, pick)
        axis = int(rng.integers(3))
        f = rng.uniform(0.05, 0.4) * min(d['rate'], 10.0)
        raw[moving, axis] += d['amp'] * d['sigma'] * np.sin(2 * math.pi * f * t[moving]
                                                            + rng.uniform(0, 6.3))
    model = model_for(d, rule)
    out_clean = compensate(model, t, tq, clean)
    saved = state_mod.StillnessDetector     # the core's detector is built in runtime.state
    if detector_cls is not None:
        state_mod.StillnessDetector = detector_cls
    try:
        core = core_mod.CompensatorCore(Policy(), model)
    finally:
        state_mod.StillnessDetector = saved
    add_t, proc = core.add_temperature, core.process
    tl, tql, rl = t.tolist(), tq.tolist(), raw.tolist()
    anchors, covered, prev = [], np.zeros(n, dtype=bool), None
    early = np.zeros(n, dtype=bool)        # a provisional shift in force
    ra = core.reanchoring
    c0 = time.process_time()
    for i in range(n):
        add_t(tl[i], tql[i])
        w = rl[i]
        proc(tl[i], w[0], w[1], w[2])
        a = ra.anchor if ra.settled else None
        early[i] = ra.anchor is not None and a is None
        if a is not None:
            covered[i] = a is prev         # output with the anchor already in force
            if a is not prev:
                anchors.append((a, ra.sessions.session, i))
        prev = a
    cpu = time.process_time() - c0
    judged = []
    for a, session, i in anchors:
        span = (t >= a.t - a.duration_s - 1e-9) & (t <= a.t + 1e-9)
        # With the rule an axis within the model's gate is not shifted (delta 0): so judged.
        err = np.abs(np.asarray(a.delta) - out_clean[span].mean(axis=0))
        gated = np.asarray(a.delta) == 0.0
        bound = 4.0 * np.maximum(np.asarray(a.se), np.asarray(a.tolerance))
        judged.append({'anchor': a, 'session': session, 'moving': int(moving[span].sum()),
                       'gated': int(gated.sum()),
                       'err_sigma': float((err / d['sigma']).max()),
                       'err_se': float((err / np.asarray(a.se)).max()),
                       'pass': bool(np.all(err <= bound))})
    return {'fired': bool(anchors), 'cpu_us': 1e6 * cpu / n, 'n': n, 'anchors': judged,
            'sessions': ra.sessions.session, 'anchored': float(covered.mean()),
            'provisional': float(early.mean()),
            'pass': bool(judged) and all(j['pass'] for j in judged),
            'key': [(j['anchor'].t, j['anchor'].delta, j['anchor'].samples) for j in judged]}


def _kind(d: dict) -> str:
    """Return the case's group: continuous, bursts within a session, or over the gap."""
    if d['continuous']:
        return 'continuous'
    return 'over gap' if d['pause_s'] > SESSION_GAP_S else 'bursty'


def _fmt(d: dict) -> str:
    kind = ('continuous' if d['continuous']
            else f"bursts {d['burst_s']:.1f} s / {d['pause_s']:.0f} s")
    return (f"#{d['k']} {d['rate']:.1f} Hz {kind}, res {d['res_c']:.3f} C, sigma "
            f"{d['sigma'] / DEG:.3f} dps, offset {d['offset_dps']:+.2f} dps"
            + (f", motion {d['amp']:.0f}x" if d['motion'] else ''))


GROUPS = ('continuous', 'bursty', 'over gap', 'all')


def rates(cases: list, results: list) -> dict:
    """Return per group: cases, fired, passed, anchors, anchors passed, moving, anchored."""
    out = {}
    for g in GROUPS:
        rs = [r for d, r in zip(cases, results) if g == 'all' or _kind(d) == g]
        js = [j for r in rs for j in r['anchors']]
        out[g] = {'cases': len(rs), 'fired': sum(r['fired'] for r in rs),
                  'pass': sum(r['pass'] for r in rs), 'anchors': len(js),
                  'anchors_pass': sum(j['pass'] for j in js),
                  'with_moving': sum(j['moving'] > 0 for j in js),
                  'sessions': sum(r['sessions'] for r in rs),
                  'anchored': float(np.median([r['anchored'] for r in rs])) if rs else 0.0,
                  'provisional': float(np.median([r.get('provisional', 0.0) for r in rs]))
                  if rs else 0.0}
    return out


def side_by_side(names: list, tables: list) -> None:
    """Print the pass rates of each variant, one column each."""
    print('\n  ' + ' ' * 24 + ''.join(f'{n:>30s}' for n in names))
    rows = (('cases fired', 'fired', 'cases'), ('cases passed', 'pass', 'cases'),
            ('sessions anchored', 'anchors', 'sessions'),
            ('anchors passed', 'anchors_pass', 'anchors'),
            ('anchors with moving samples', 'with_moving', 'anchors'))
    for g in GROUPS:
        print(f'  {g}')
        for label, k, of in rows:
            cells = [f'{t[g][k]}/{t[g][of]}' for t in tables]
            print(f'    {label:28s}' + ''.join(f'{c:>30s}' for c in cells))
        for label, k in (('anchored share (median)', 'anchored'),
                         ('provisional share (median)', 'provisional')):
            print(f'    {label:28s}' + ''.join(f'{t[g][k]:30.3f}' for t in tables))


def report(name: str, cases: list, results: list) -> None:
    """Print the worst anchors and the cases that never fired of one variant."""
    print(f'\n== {name}')
    js = [(j, d, r) for d, r in zip(cases, results) for j in r['anchors']]
    js.sort(key=lambda x: -x[0]['err_se'])
    print('  worst anchors (|error| / own SE, / noise sigma):')
    for j, d, r in js[:6]:
        a = j['anchor']
        print(f'    {j["err_se"]:.2f} SE, {j["err_sigma"]:.4f} sigma '
              f'{"pass" if j["pass"] else "FAIL"} ({a.reason}, {a.samples} samples, '
              f'{a.duration_s:.1f} s, session {j["session"]}/{r["sessions"]}, '
              f'{j["moving"]} moving): {_fmt(d)}')
    moved = [(j, d) for j, d, _ in js if j['moving']]
    print(f'  anchors with moving samples: {len(moved)}' + ''.join(
        f'\n    {j["moving"]} of {j["anchor"].samples} moving, {j["err_se"]:.2f} SE: {_fmt(d)}'
        for j, d in moved[:6]))
    miss = [(d, r) for d, r in zip(cases, results) if not r['fired']]
    print(f'  not fired ({len(miss)}):')
    for d, r in miss[:8]:
        print(f'    {_fmt(d)} ({r["sessions"]} sessions)')
    print("  anchor axes within the model's gate (not shifted): "
          f'{sum(j["gated"] for j, _, _ in js)} of {3 * len(js)}')
    print(f'  CPU per sample (process + add_temperature): median '
          f'{np.median([r["cpu_us"] for r in results]):.2f} us')


def main(argv: list | None = None) -> int:
    """Run the sweep; print pass rates and worst cases."""
    p = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    p.add_argument('--cases', type=int, default=60)
    p.add_argument('--seed', type=int, default=27)
    p.add_argument('--old', default=None, metavar='COMMIT',
                   help='also run the re-anchoring of this commit, alternating')
    p.add_argument('--rule', action='store_true',
                   help="train with train's start-up shift rule (the model's gate)")
    args = p.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    cases = [draw(rng, k, args.seed) for k in range(args.cases)]
    old_cls = load_old(args.old) if args.old else None
    new, old = [], []
    for i, d in enumerate(cases):
        order = [('new', None), ('old', old_cls)] if old_cls is not None else [('new', None)]
        if i % 2 and old_cls is not None:
            order.reverse()
        for name, cls in order:
            (new if name == 'new' else old).append(case(d, cls, args.rule))
    names, tables = ['new (this tree)'], [rates(cases, new)]
    if old:
        names.insert(0, f'old ({args.old})')
        tables.insert(0, rates(cases, old))
    side_by_side(names, tables)
    if old:
        for g in ('continuous', 'bursty', 'over gap'):
            same = sum(1 for d, a, b in zip(cases, old, new)
                       if _kind(d) == g and a['key'] == b['key'])
            print(f'  {g} cases with the identical anchors old and new: {same}/'
                  f'{sum(_kind(d) == g for d in cases)}')
        ratio = [b['cpu_us'] / a['cpu_us'] for a, b in zip(old, new)]
        print(f'  CPU per sample new/old: median {np.median(ratio):.3f}, '
              f'max {max(ratio):.3f}')
        report(f'old ({args.old})', cases, old)
    report('new (this tree)', cases, new)
    return 0


if __name__ == '__main__':
    sys.exit(main())
