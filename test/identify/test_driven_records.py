"""The shipped records of a driven pendulum: as published, read with their units, as documented.

The files under ``test/data/dfki_torque_limited_pendulum/`` are the DFKI lab's (BSD 3-Clause);
``driven_records`` reads them through ``pendulum_identify``'s CSV reader with their columns
mapped by header name. What ``SOURCE.md`` and ``docs/reference/measured-driven-records.md``
say of them (samples, rates, ranges, quantisation, the lab's parameters) is recomputed here.
"""
from __future__ import annotations

import hashlib
import math
import re
from pathlib import Path

import numpy as np
import pytest
from driven_records import DFKI, RUNS, published, read

ROOT = Path(__file__).resolve().parents[2]
PAGE = ROOT / 'docs' / 'reference' / 'measured-driven-records.md'
ROW = re.compile(r'^\| (?P<name>[a-z +]+) \| `(?P<file>[a-z_]+\.csv)` \| (?P<samples>\d+) \| '
                 r'(?P<dt>[\d.]+) ms \| (?P<span>[\d.]+) s \| (?P<plo>−?[\d.]+) to '
                 r'(?P<phi>−?[\d.]+) \| (?P<tlo>−?[\d.]+) to (?P<thi>−?[\d.]+) \|$')
SOURCE_ROW = re.compile(r'^\| `(?P<file>[a-z_]+\.csv)` \| (?P<samples>\d+) \| (?P<dt>[\d.]+) ms'
                        r' \| (?P<span>[\d.]+) s \| (?P<plo>−?[\d.]+) to (?P<phi>−?[\d.]+) \| '
                        r'(?P<tlo>−?[\d.]+) to (?P<thi>−?[\d.]+) \|$')
MAX_BYTES = 2_000_000
"""What the shipped data may weigh in all."""


def number(text: str) -> float:
    return float(text.replace('−', '-'))


def rows(path: Path, pattern: re.Pattern[str]) -> dict[str, re.Match[str]]:
    found = (pattern.match(line) for line in path.read_text(encoding='utf-8').splitlines())
    return {m['file']: m for m in found if m is not None}


def test_the_files_are_the_labs_with_its_licence() -> None:
    """Each file has the sha256 SOURCE.md lists; the licence is the lab's BSD 3-Clause."""
    source = (DFKI / 'SOURCE.md').read_text(encoding='utf-8')
    listed = dict(re.findall(r'^- `([^`]+)`: `([0-9a-f]{64})`$', source, re.M))
    assert set(listed) == {p.name for p in DFKI.iterdir() if p.name != 'SOURCE.md'}
    for file, digest in listed.items():
        assert hashlib.sha256((DFKI / file).read_bytes()).hexdigest() == digest, file
    licence = (DFKI / 'LICENSE').read_text(encoding='utf-8')
    assert licence.startswith('BSD 3-Clause License\n\nCopyright (c) 2021, DFKI RIC '
                              'Underactuated Robotics Lab\n')
    assert sum(p.stat().st_size for p in DFKI.iterdir()) < MAX_BYTES
    assert set(RUNS.values()) == {p.name for p in DFKI.glob('*.csv')}


@pytest.mark.parametrize('name', list(RUNS))
def test_each_run_reads_as_its_tables_say(name: str) -> None:
    """Samples, interval, duration, position and torque ranges: SOURCE.md and the docs."""
    run = read(name)
    assert run.velocity is not None and run.effort is not None
    file = RUNS[name]
    page, source = rows(PAGE, ROW)[file], rows(DFKI / 'SOURCE.md', SOURCE_ROW)[file]
    assert page['name'] == name
    for row in (page, source):
        assert int(row['samples']) == run.t.size
        dt = float(np.median(np.diff(run.t)))
        assert abs(number(row['dt']) * 1e-3 - dt) <= 0.005e-3, (file, dt)
        assert abs(number(row['span']) - (run.t[-1] - run.t[0])) <= 0.05
        for key, value in (('plo', run.position.min()), ('phi', run.position.max()),
                           ('tlo', run.effort.min()), ('thi', run.effort.max())):
            assert abs(number(row[key]) - float(value)) <= 0.005 + 1e-9, (file, key)


@pytest.mark.parametrize('name', list(RUNS))
def test_the_units_are_rad_and_rad_per_s_and_each_run_ends_upright(name: str) -> None:
    """The velocity is the rate of the position, and each swing-up ends at π + 2πk.

    The position's rate (central differences) is fitted to the velocity: a slope within
    10 % of 1 rules out every unit slip a reader could make (degrees: 57; rpm: 9.5; the
    motor's side of its 6:1 gear: 6). The PD run's is the lowest, 0.93; the others' 0.996
    to 0.999.
    """
    run = read(name)
    assert run.velocity is not None
    rate = np.gradient(run.position, run.t)
    slope = float(run.velocity @ rate / (run.velocity @ run.velocity))
    assert 0.9 < slope < 1.1, slope
    upright = (run.position[-1] - math.pi + math.pi) % (2.0 * math.pi) - math.pi
    assert abs(upright) < 0.05, upright


def test_the_samples_are_quantised_as_documented() -> None:
    """Position 2.914 mrad, velocity 0.02198 rad/s (0.04396 in the iLQR run), torque 8.791 mN m."""
    source = (DFKI / 'SOURCE.md').read_text(encoding='utf-8')
    assert ('position in steps of 2.914 mrad, velocity of 0.02198 rad/s\n(0.04396 in '
            '`ilqr.csv`), torque of 8.791 mN m') in source

    def step(x: np.ndarray) -> float:
        gaps = np.diff(np.unique(x))
        return float(gaps.min())

    for name in RUNS:
        run = read(name)
        assert run.velocity is not None and run.effort is not None
        assert round(step(run.position) * 1e3, 3) == 2.914, name
        assert round(step(run.velocity), 5) == (0.04396 if name == 'ilqr' else 0.02198), name
        assert round(step(run.effort) * 1e3, 3) == 8.791, name


def test_the_labs_parameters_in_this_packages_terms_are_the_docs() -> None:
    """system_identification.txt read, converted (SOURCE.md, the docs), every figure printed."""
    lab = published()
    assert (lab.J, lab.m_cx, lab.Fv, lab.Fc, lab.offset) == (6.259e-02, 1.022e-01, 4.707e-02,
                                                              1.839e-01, -7.586e-02)
    ours = lab.in_package_terms()
    assert ours['mgl'] == pytest.approx(1.0026, abs=5e-5)
    assert ours['omega0'] == pytest.approx(4.002, abs=5e-4)
    assert ours['gamma'] == pytest.approx(0.7520, abs=5e-5)
    assert ours['friction'] == pytest.approx(0.2889, abs=5e-5)
    assert ours['effort_offset'] == 0.07586 and ours['n'] == 1.0
    page = PAGE.read_text(encoding='utf-8')
    for text in ('| J | 0.06259 kg m² | inertia I = J | 0.06259 kg m² |',
                 f'| m·cx | 0.1022 kg m | m g l = m·cx g | {ours["mgl"]:.4f} N m (ω0 = '
                 f'{ours["omega0"]:.3f} rad/s) |',
                 f'| Fv | 0.04707 N m s | viscous, n = 1: γ = Fv / J | {ours["gamma"]:.4f} s⁻¹ |',
                 f'| Fc | 0.1839 N m | Coulomb friction f = Fc π/2 | {ours["friction"]:.4f} N m |',
                 f'| offset | −0.07586 N m | effort offset τ_off = −offset | '
                 f'+{ours["effort_offset"]:.5f} N m |',
                 '`tau = J qdotdot + m*cx g sin(q) + Fv qdot + Fc atan(100 qdot) + offset`'):
        assert text in page, text
    # The torque scale the docs question: identified m cx against the hardware's m l_COM.
    assert round(0.676 * 0.45, 3) == 0.304 and round(lab.m_cx / 0.304, 2) == 0.34



def table_rows(page: str, first: str, law: str) -> list[list[str]]:
    """Return the cells after the first two of each table row of ``page`` that starts with
    ``first`` and ``law`` (its parameters' table, then its validation table)."""
    start = f'| {first} | {law} | '
    return [[c.strip() for c in line[len(start):].rstrip(' |').split(' | ')]
            for line in page.splitlines() if line.startswith(start)]


def shown(value: float, text: str) -> bool:
    """Return whether ``text`` (significant digits, Unicode minus) is ``value`` rounded."""
    printed = text.replace('−', '-')
    mantissa = printed.split('e')[0].lstrip('-').replace('.', '').lstrip('0')
    if value == 0.0:
        return float(printed) == 0.0
    last = math.floor(math.log10(abs(value))) - max(len(mantissa), 1) + 1
    return abs(value - float(printed)) <= 0.5 * 10.0 ** last * (1 + 1e-9)


def test_the_docs_row_of_a_fit_and_its_held_out_validation_is_what_the_fit_gives() -> None:
    """The direct-collocation run's fit by the lab's law: its parameters and its fit % on ddp,
    and the lab's fit % on ddp, as ``bench/bench_measured_driven.py`` wrote them in the docs.

    Recomputed through the public API (the run's angle and torque, windows of half a period,
    the k-step horizon 0.15 s); each figure as printed, to its last digit.
    """
    from pendulum_sim.identify import driven_record, fit, joint_fit, validate

    def run(name: str):  # type: ignore[no-untyped-def]
        s = read(name)
        return driven_record(s.t, s.position, s.effort)

    page = PAGE.read_text(encoding='utf-8')
    [runs] = table_rows(page, 'fitted on', 'law')[1:]
    assert runs == list(RUNS)
    params, validation = table_rows(page, 'direct collocation', 'power+coulomb, n = 1')
    joint = fit([run('direct collocation')], model='power+coulomb', known={'n': 1.0})
    names = ('inertia', 'mgl', 'gamma', 'n', 'friction', 'effort_offset', 'command_delay')
    for key, text in zip((*names, 'rms'), params, strict=True):
        value = joint.rms_residual if key == 'rms' else joint.params[key]
        assert value is not None and shown(value, text), (key, value, text)
    ddp = run('ddp')
    k = round(0.15 / float(np.median(np.diff(ddp.t))))
    ours = validate(joint, ddp, k=k)
    assert validation[runs.index('ddp')] == (
        f'{ours.fit_prediction:.1f} / {ours.fit_simulation:.1f}'.replace('-', '−'))
    lab = published().in_package_terms()
    theirs = validate(joint_fit('power+coulomb', inertia=lab['inertia'], mgl=lab['mgl'],
                                gamma=lab['gamma'], n=1.0, friction=lab['friction'],
                                effort_offset=lab['effort_offset']), ddp, k=k)
    lab_validation = table_rows(page, 'lab (pd)', 'power+coulomb, n = 1')[1]
    assert lab_validation[runs.index('ddp')] == (
        f'{theirs.fit_prediction:.1f} / {theirs.fit_simulation:.1f}'.replace('-', '−'))
    assert theirs.fit_prediction < ours.fit_prediction


@pytest.mark.parametrize('name', ['direct collocation', 'energy shaping + lqr'])
def test_each_law_ends_no_worse_than_the_laws_it_nests_on_a_measured_run(name: str) -> None:
    """On these two runs ``power+coulomb`` once ended above ``viscous`` (0.0053 against 0.0043
    rad, 0.061 against 0.058 rad): each law had windows of its own first guess, and no start
    at the optima of the laws it nests. Within ``compare`` every law has the same windows and
    starts from those optima too, so the ranking by BIC compares laws, not local minima."""
    from pendulum_sim.identify import compare, driven_record
    from pendulum_sim.identify.solver import TOLERANCE

    s = read(name)
    fits = {f.model: f for f in compare([driven_record(s.t, s.position, s.effort)],
                                        models=['power+coulomb', 'viscous', 'power'])}
    assert len({(f.window, f.samples) for f in fits.values()}) == 1
    rss = {k: f.rms_residual ** 2 for k, f in fits.items()}
    # No worse: within the solver's stop (two ends of one optimum differ by less).
    assert rss['power+coulomb'] <= rss['power'] * (1 + TOLERANCE), rss
    assert rss['power'] <= rss['viscous'] * (1 + TOLERANCE), rss
    assert all(f.at_optimum >= 1 for f in fits.values())


def test_a_nested_optimum_is_a_second_start_only_where_it_is_below_the_laws_own_reach() -> None:
    """``solve_sets`` solves a nested law's optimum as a further start only where its cost
    (on the same windows) is below what the law's first guesses reached; then the law ends no
    higher than that optimum. Here the viscous optimum as a start of ``power``, told once
    that it is below everything (cost 0) and once above (cost inf), and as it is."""
    from dataclasses import replace

    from pendulum_sim.core.jit import available
    from pendulum_sim.identify import driven_record
    from pendulum_sim.identify.driven import _same_windows, nested_start, solve_sets
    from pendulum_sim.identify.laws import get_law

    s = read('direct collocation')
    sets = [[driven_record(s.t, s.position, s.effort)]]
    power, jit = get_law('power'), available()
    (viscous,) = solve_sets(get_law('viscous'), sets, {}, None, jit)
    (own,) = solve_sets(power, sets, {}, None, jit)
    assert viscous is not None and own is not None
    seed = nested_start(viscous, power)
    assert seed.cost == viscous.problem.cost and _same_windows(seed.windows, own.windows)
    (above,) = solve_sets(power, sets, {}, None, jit, seeds=[[replace(seed, cost=math.inf)]])
    (below,) = solve_sets(power, sets, {}, None, jit, seeds=[[replace(seed, cost=0.0)]])
    (real,) = solve_sets(power, sets, {}, None, jit, seeds=[[seed]])
    assert above is not None and below is not None and real is not None
    assert (above.starts, above.problem.cost) == (own.starts, own.problem.cost)
    assert below.starts == own.starts + 1
    assert below.problem.cost <= min(own.problem.cost, seed.cost)
    assert real.starts == own.starts + (seed.cost < own.problem.cost)
    assert real.problem.cost <= min(own.problem.cost, seed.cost)
