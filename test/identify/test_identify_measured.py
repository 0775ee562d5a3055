"""``compare`` on measured pendulums no one here wrote: the docs' table, recomputed and checked.

The records under ``test/data/`` (MIT-licensed, see each ``SOURCE.md``) are fitted with the
table's four laws (all but ``power+coulomb``); the table in
``docs/tutorials/identify.md`` ("Measured pendulums") must be what these fits give, and what it
says of the damping laws must hold. The compiled sweep makes the fits take seconds (numpy
takes minutes on the real exponents), so the module needs numba.
"""
from __future__ import annotations

import hashlib
import re
from pathlib import Path

import numpy as np
import pytest
from measured_records import DATA, RECORDS, load, read

from pendulum_sim.core.jit import available as jit_available
from pendulum_sim.identify import Fit, compare

pytestmark = [pytest.mark.slow,
              pytest.mark.skipif(not jit_available(), reason='needs numba (the jit extra)')]

ROOT = Path(__file__).resolve().parents[2]
PAGE = ROOT / 'docs' / 'tutorials' / 'identify.md'
ROW = re.compile(r'^\| (?P<name>[^|]+?) \| (?P<samples>\d+) \| (?P<best>[a-z+]+) \| '
                 r'(?P<n>[\d.]+) \((?P<lo>[\d.]+) to (?P<hi>[\d.]+)\) \| '
                 r'(?P<rms>[\d.]+(?: / [\d.]+){3}) \|$')
ORDER = ('viscous', 'quadratic', 'coulomb', 'power')
"""The order of the table's RMS column."""


@pytest.fixture(scope='module')
def fits() -> dict[str, dict[str, Fit]]:
    """Return each record's fits by law (compare over the table's four laws, compiled)."""
    out = {}
    for name in RECORDS:
        t, y = load(name)
        ranked = compare(t, y, models=ORDER, jit=True)
        out[name] = {'best': ranked[0], **{f.model: f for f in ranked}}
    return out


def table() -> dict[str, re.Match[str]]:
    """Return the rows of the docs' table of measured records, by record name."""
    rows = [ROW.match(line) for line in PAGE.read_text(encoding='utf-8').splitlines()]
    return {m['name']: m for m in rows if m is not None}


def close(printed: str, value: float, unit: float) -> bool:
    """Say whether ``printed`` is ``value`` rounded to ``unit`` (half a unit, 0.5 % slack)."""
    return abs(float(printed) - value) <= 0.5 * unit + 5e-3 * abs(value)


def test_files_are_as_published() -> None:
    """Every shipped file has the sha256 its SOURCE.md gives, and every data set its licence."""
    for folder in {f for f, _ in RECORDS.values()}:
        source = (folder / 'SOURCE.md').read_text(encoding='utf-8')
        listed = dict(re.findall(r'^- `([^`]+)`: `([0-9a-f]{64})`$', source, re.M))
        assert set(listed) == {p.name for p in folder.iterdir() if p.name != 'SOURCE.md'}
        assert 'MIT License' in (folder / 'LICENSE').read_text(encoding='utf-8')
        for file, digest in listed.items():
            assert hashlib.sha256((folder / file).read_bytes()).hexdigest() == digest, file
    for folder in DATA.iterdir():          # every data set here says where it comes from
        assert (folder / 'SOURCE.md').is_file() and (folder / 'LICENSE').is_file(), folder


def test_fit_starts_at_a_turning_point() -> None:
    """The fitted part starts at an extremum after the first crossing, not at the release."""
    for name in RECORDS:
        t_all, y_all = read(name)
        t, _ = load(name)
        k = int(np.searchsorted(t_all, t[0]))
        c = y_all - np.median(y_all)
        assert 0 < k < t_all.size // 2, name
        assert np.any(np.sign(c[:k]) != np.sign(c[k])), name   # a crossing comes before it
        side = c * c[k] > 0              # its half swing: the samples on its side of the centre
        lo = k - int(np.argmin(side[k::-1]))
        hi = k + int(np.argmin(side[k:]))
        assert abs(c[k]) == np.abs(c[lo:hi]).max() and hi - lo > 10, name


def test_docs_table_is_what_the_fits_give(fits: dict[str, dict[str, Fit]]) -> None:
    """Each row of the docs' table: samples, the law BIC ranks first, power's n, each RMS."""
    rows = table()
    assert set(rows) == set(RECORDS)
    for name, row in rows.items():
        got = fits[name]
        power = got['power']
        assert power.ci95['n'] is not None and power.params['n'] is not None
        assert int(row['samples']) == power.samples, name
        assert row['best'] == got['best'].model, name
        assert close(row['n'], power.params['n'], 0.01), name
        assert close(row['lo'], power.ci95['n'][0], 0.01), name
        assert close(row['hi'], power.ci95['n'][1], 0.01), name
        for law, printed in zip(ORDER, row['rms'].split(' / '), strict=True):
            assert close(printed, got[law].rms_residual * 1e3, 0.1), (name, law)


def test_what_the_docs_say_of_the_laws(fits: dict[str, dict[str, Fit]]) -> None:
    """The video-tracked cup: between viscous and quadratic drag; the bearing: below viscous.

    And the paper's claim (exponents above 2 contradict experiment): no record's 95 % interval
    of n lies above 2.
    """
    def n_ci(name: str) -> tuple[float, float]:
        ci = fits[name]['power'].ci95['n']
        assert ci is not None
        return ci

    lab1 = fits['video lab 1']
    assert lab1['best'].model == 'power'
    assert 1.0 < n_ci('video lab 1')[0] and n_ci('video lab 1')[1] < 2.0
    assert lab1['power'].rms_residual < lab1['quadratic'].rms_residual < lab1[
        'viscous'].rms_residual < lab1['coulomb'].rms_residual
    omega0 = lab1['power'].params['omega0']
    assert omega0 is not None
    length = 9.81 / omega0 ** 2          # the author: 65 +- 1 cm from the pivot to the cup
    assert 0.64 < length < 0.66 + 0.01
    page = PAGE.read_text(encoding='utf-8')
    assert f'ω0 = {omega0:.3f} rad/s' in page and f'{length:.3f} m long' in page
    lab2 = fits['video lab 2']
    assert lab2['best'].model == 'quadratic'
    assert n_ci('video lab 2')[0] < 2.0 < n_ci('video lab 2')[1]
    encoders = [n_ci(f'encoder 0{i}') for i in (1, 2, 3)]
    for name in ('encoder 01', 'encoder 02', 'encoder 03'):
        assert fits[name]['best'].model == 'power', name
        assert 0.0 < n_ci(name)[0] and n_ci(name)[1] < 1.0, name
    for (lo_a, hi_a), (lo_b, hi_b) in zip(encoders, encoders[1:] + encoders[:1], strict=True):
        assert hi_a < lo_b or hi_b < lo_a    # no one exponent serves the three releases
    assert all(n_ci(name)[0] <= 2.0 for name in RECORDS)


FRICTION_ROW = re.compile(r'^\| (?P<name>[^|]+?) \| (?P<rank>\d) \| '
                          r'(?P<n>[\d.]+) \((?P<lo>[\d.]+) to (?P<hi>[\d.]+)\) \| '
                          r'(?P<f>[\d.]+) \((?P<flo>[\d.]+) to (?P<fhi>[\d.]+)\) \| '
                          r'(?P<rms>[\d.]+) \|$')


@pytest.fixture(scope='module')
def five() -> dict[str, list[Fit]]:
    """Return each record's fits over compare's default, all five laws (compiled), ranked."""
    return {name: compare(*load(name), jit=True) for name in RECORDS}


def test_docs_friction_table_is_what_the_fits_give(five: dict[str, list[Fit]]) -> None:
    """The docs' power+coulomb rows, and what they say: the cup asks for no friction, the
    bearing does on every release, and its exponents still disagree between releases."""
    rows = {m['name']: m for m in (FRICTION_ROW.match(line) for line in
                                   PAGE.read_text(encoding='utf-8').splitlines()) if m}
    assert set(rows) == set(RECORDS)
    for name, row in rows.items():
        ranked = [f.model for f in five[name]]
        pc = five[name][ranked.index('power+coulomb')]
        assert int(row['rank']) == ranked.index('power+coulomb') + 1, name
        n_ci, f_ci = pc.ci95['n'], pc.ci95['friction_accel']
        assert n_ci is not None and f_ci is not None and pc.params['n'] is not None
        for key, value in (('n', pc.params['n']), ('lo', n_ci[0]), ('hi', n_ci[1]),
                           ('f', pc.params['friction_accel']), ('flo', f_ci[0]),
                           ('fhi', f_ci[1])):
            assert close(row[key], float(value), 0.01), (name, key)   # type: ignore[arg-type]
        assert close(row['rms'], pc.rms_residual * 1e3, 0.1), name
        assert f_ci[0] >= 0.0   # an interval within the friction's range
    for name in ('video lab 1', 'video lab 2'):
        assert five[name][0].model != 'power+coulomb', name
    bearing = [five[f'encoder 0{i}'][0] for i in (1, 2, 3)]
    assert all(f.model == 'power+coulomb' for f in bearing)
    cis = [f.ci95['n'] for f in bearing]
    for a, b in zip(cis, cis[1:] + cis[:1], strict=True):
        assert a is not None and b is not None and (a[1] < b[0] or b[1] < a[0])
