"""The reports: the --quick report run for real (subprocess and library), its numbers checked."""
from __future__ import annotations

import csv
import itertools
import math
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from pendulum_sim.core import PendulumParams
from pendulum_sim.core.analysis import undamped_period
from pendulum_sim.reports import ReportError
from pendulum_sim.reports.cli import main
from pendulum_sim.reports.output import prepare_out_dir
from pendulum_sim.reports.reference import reference
from pendulum_sim.reports.report import run_report
from pendulum_sim.reports.work_precision import fit_order, time_to_error

try:
    import matplotlib  # noqa: F401
    HAVE_MPL = True
except ImportError:
    HAVE_MPL = False

FIGURES = [
    'work_precision_paper_g1.png', 'error_vs_h_paper_g1.png', 'stability_heatmap.png',
    'fig3_phi.png', 'fig4_phi.png', 'fig5_dphi.png', 'fig6_energy.png', 'fig7_phase.png',
    'fig8_exact_vs_numerical.png', 'fig9_convergence_quotient.png', 'decay_law.png',
]
TABLES = [
    'work_precision.csv', 'work_precision_orders.csv', 'work_precision_levels.csv',
    'work_precision_reference.csv', 'stability.csv', 'paper_facts.csv', 'decay_law.csv',
    'fig3_phi.csv', 'fig9_convergence_quotient.csv',
]


def _rows(path: Path) -> list[dict[str, str]]:
    with path.open(newline='', encoding='utf-8') as fh:
        return list(csv.DictReader(fh))


def _report_command() -> list[str]:
    script = Path(sys.executable).parent / 'pendulum_report'
    if script.exists():
        return [str(script)]
    return [sys.executable, '-m', 'pendulum_sim.reports.cli']


@pytest.fixture(scope='module')
def cli_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    out = tmp_path_factory.mktemp('report') / 'tmp'
    proc = subprocess.run([*_report_command(), 'all', '--quick', '--out', str(out)],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    return out, proc.stderr


@pytest.fixture(scope='module')
def lib_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, object]]:
    out = tmp_path_factory.mktemp('report_lib') / 'tmp'
    result = run_report('all', out, quick=True, progress=False)
    return out, result


def _fact(out: Path, startswith: str) -> float:
    for row in _rows(out / 'paper_facts.csv'):
        if row['fact'].startswith(startswith):
            return float(row['value'])
    raise AssertionError(f'no fact starting with {startswith!r}')


# ------------------------------------------------------------------ the real subprocess
@pytest.mark.slow
def test_cli_writes_every_table_and_figure(cli_run: tuple[Path, str]) -> None:
    out, _ = cli_run
    summary = (out / 'summary.md').read_text(encoding='utf-8')
    assert summary.startswith('# pendulum_report all --quick\n')
    assert 'Command: `pendulum_report all --quick --out' in summary
    for name in TABLES:
        assert (out / name).stat().st_size > 0, name
    for name in FIGURES:
        if HAVE_MPL:
            data = (out / name).read_bytes()
            assert data[:8] == b'\x89PNG\r\n\x1a\n', name
            assert f'`{name}`' in summary
        else:
            assert not (out / name).exists()
    if not HAVE_MPL:
        assert 'matplotlib is not installed' in summary


@pytest.mark.slow
def test_cli_reports_progress_with_elapsed_and_eta(cli_run: tuple[Path, str]) -> None:
    _, stderr = cli_run
    lines = stderr.splitlines()
    pattern = re.compile(r'^\[(work-precision|stability|paper) (\d+)/(\d+)\] .+  elapsed '
                         r'\d+\.\d s  ETA \d+\.\d s$')
    progress = [m for m in map(pattern.match, lines) if m]
    assert [m.group(2) for m in progress if m.group(1) == 'work-precision'] == ['1', '2']
    assert any(m.group(1) == 'stability' for m in progress)
    assert progress[-1].group(1) == 'paper' and progress[-1].group(2) == progress[-1].group(3)
    assert lines[-1].startswith('wrote ') and lines[-1].endswith('summary.md')


@pytest.mark.slow
def test_fitted_orders_match_the_declared_ones(cli_run: tuple[Path, str]) -> None:
    out, _ = cli_run
    orders = {(r['case'], r['solver']): r for r in _rows(out / 'work_precision_orders.csv')}
    smooth = 'paper_g1_n1'
    # (declared order, half-width of the accepted band)
    for solver, declared, band in (('euler', 1, 0.15), ('midpoint', 2, 0.15),
                                   ('sdirk2', 2, 0.15), ('sdirk3', 3, 0.25),
                                   ('rk4', 4, 0.25)):
        row = orders[(smooth, solver)]
        assert int(row['declared']) == declared
        assert int(row['points']) >= 3
        assert abs(float(row['fitted']) - declared) <= band, (solver, row['fitted'])
    dopri = orders[(smooth, 'dopri5')]
    assert abs(float(dopri['plain_fixed_step_order']) - 5.0) <= 0.3
    # Adaptive: error proportional to the tolerance.
    assert 0.7 <= float(dopri['fitted']) <= 1.3
    # n = 2: the reversal location keeps the explicit methods at their order.
    for solver, declared, band in (('midpoint', 2, 0.15), ('rk4', 4, 0.25)):
        fitted = float(orders[('paper_g1_n2', solver)]['fitted'])
        assert abs(fitted - declared) <= band, (solver, fitted)


@pytest.mark.slow
def test_work_precision_errors_fall_with_work_and_levels_are_consistent(
        cli_run: tuple[Path, str]) -> None:
    out, _ = cli_run
    rows = _rows(out / 'work_precision.csv')
    rk4 = sorted((float(r['value']), float(r['err_max'])) for r in rows
                 if r['case'] == 'paper_g1_n1' and r['solver'] == 'rk4')
    assert all(e_small < e_big for (_, e_small), (_, e_big) in itertools.pairwise(rk4))
    for r in rows:
        assert float(r['err_final']) <= float(r['err_max']) or math.isnan(float(r['err_max']))
        assert float(r['cpu_s']) > 0.0
    assert {r['solver'] for r in rows} >= {'euler', 'midpoint', 'rk4', 'dopri5', 'sdirk2',
                                           'sdirk3'}
    levels = _rows(out / 'work_precision_levels.csv')
    assert len(levels) == 2 * 10
    for r in levels:
        core, sp, ratio = float(r['core_cpu_s']), float(r['scipy_cpu_s']), float(r['ratio'])
        if math.isfinite(core) and math.isfinite(sp):
            assert ratio == pytest.approx(core / sp, rel=1e-12)
            assert r['target_met'] == str(int(ratio <= 0.5))
        else:
            assert math.isnan(ratio) and r['target_met'] == '0'
    refs = _rows(out / 'work_precision_reference.csv')
    for r in refs:
        assert float(r['disagreement']) < 1e-11, r
    floor = {r['case']: 10.0 * float(r['disagreement']) for r in refs}
    for r in levels:
        assert r['measurable'] == str(int(float(r['level']) >= floor[r['case']]))
    orders = _rows(out / 'work_precision_orders.csv')
    assert {int(r['guard_active_points']) for r in orders if r['solver'] == 'rk4'} == {0}
    assert [int(r['reversal_segments']) > 0 for r in refs] == [False, True]


@pytest.mark.slow
def test_stability_matrix_guarded_runs_are_finite_and_never_gain_energy(
        cli_run: tuple[Path, str]) -> None:
    out, _ = cli_run
    cells = _rows(out / 'stability.csv')
    assert len(cells) == 3 * 4 * 3 + 3 * 2 * 2
    for c in cells:
        assert c['guarded_finite'] == '1', c
        assert math.isfinite(float(c['final_phi'])) and math.isfinite(float(c['final_dphi']))
        if c['scenario'] != 'torque' and float(c['gamma']) > 0.0:
            # Energy never increases without input, by more than the core's declared 1e-12.
            assert float(c['max_step_energy_increase_rel']) <= 1e-12, c
            assert float(c['max_energy_excess_rel']) <= 1e-12, c


@pytest.mark.slow
def test_unguarded_rk4_at_60hz_with_gamma_1000_is_flagged_guarded_is_accurate(
        cli_run: tuple[Path, str]) -> None:
    out, _ = cli_run
    cells = {(c['scenario'], float(c['gamma']), float(c['n']), float(c['h'])): c
             for c in _rows(out / 'stability.csv')}
    cell = cells[('paper', 1000.0, 1.0, 1 / 60)]
    assert cell['rk4_unstable_run'] == '1'
    assert cell['rk4_criterion_stable'] == '0'
    assert float(cell['h_lambda_max']) > 2.785
    assert cell['guarded_finite'] == '1'
    assert int(cell['substeps']) > 0
    assert float(cell['error_final']) < 1e-8
    calm = cells[('paper', 1.0, 1.0, 1e-3)]
    assert calm['rk4_unstable_run'] == '0' and calm['rk4_criterion_stable'] == '1'
    assert int(calm['substeps']) == int(calm['fallbacks']) == 0


@pytest.mark.slow
def test_paper_figures_show_the_papers_facts(cli_run: tuple[Path, str]) -> None:
    out, _ = cli_run
    assert _fact(out, 'n = 1, γ = 10 is overdamped') > 0.0
    assert _fact(out, 'zero crossings of φ, n = 1, γ = 1') >= 3
    assert _fact(out, 'largest increase of E between steps') <= 0.0
    assert _fact(out, "max of φ'² − 2ω0²") <= 0.0
    assert _fact(out, 'undamped run back at its start') < 1e-9
    assert _fact(out, 'ω = sqrt') == pytest.approx(3.130095845, abs=5e-10)
    assert _fact(out, 'α (paper') == pytest.approx(-0.01597259328, abs=5e-12)
    assert _fact(out, 'A (paper') == pytest.approx(0.1000127575, abs=5e-11)
    assert _fact(out, 'max |x_RK4 − x_exact|') < 1e-7
    for n in range(1, 6):
        assert 14.0 <= _fact(out, f'median Q(t), n = {n}, core') <= 18.0
    assert not 12.0 <= _fact(out, 'median Q(t), n = 2, plain RK4') <= 20.0
    assert _fact(out, 'fraction of t with Q outside [12, 20], n = 2, plain') > 0.3
    assert _fact(out, 'fraction of t with Q outside [12, 20], n = 2, core') == 0.0
    for n in range(2, 6):
        assert _fact(out, f'n = {n}: A_sim / A_law') == pytest.approx(1.0, abs=0.01)
        assert _fact(out, f'n = {n}: log-log slope') == pytest.approx(-1.0 / (n - 1), abs=0.02)


# ------------------------------------------------------------------ the library functions
@pytest.mark.slow
def test_library_run_matches_the_subprocess(cli_run: tuple[Path, str],
                                            lib_run: tuple[Path, dict[str, object]]) -> None:
    cli_out, _ = cli_run
    lib_out, result = lib_run
    assert sorted(p.name for p in cli_out.iterdir()) == sorted(p.name for p in lib_out.iterdir())
    assert result['summary_path'] == lib_out / 'summary.md'
    assert "Command: `run_report('all', quick=True)`" in (lib_out / 'summary.md').read_text()
    # Everything but timings is deterministic.
    for name in ('work_precision_orders.csv', 'stability.csv', 'paper_facts.csv'):
        a, b = _rows(cli_out / name), _rows(lib_out / name)
        drop = {'cpu_s', 'cpu_us_per_step'}
        assert [{k: v for k, v in r.items() if k not in drop} for r in a] == \
            [{k: v for k, v in r.items() if k not in drop} for r in b]


def test_without_matplotlib_tables_are_written_with_a_note(tmp_path: Path) -> None:
    code = ('import sys; sys.modules["matplotlib"] = None\n'
            'from pendulum_sim.reports.paper_figures import run_paper, QUICK\n'
            'from dataclasses import replace\n'
            'from pathlib import Path\n'
            'grid = replace(QUICK, t_end=1.0, q_t_end=1.0, decay_t_end=20.0)\n'
            f'run_paper(Path({str(tmp_path)!r}), grid, progress=False)\n')
    proc = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert not list(tmp_path.glob('*.png'))
    assert (tmp_path / 'fig3_phi.csv').stat().st_size > 0
    assert 'matplotlib is not installed: no figures were drawn.' in (
        tmp_path / 'paper.md').read_text(encoding='utf-8')


# ------------------------------------------------------------------ pieces
def test_reference_returns_after_one_undamped_period() -> None:
    p = PendulumParams(gamma=0.0, n=1.0)
    period = undamped_period(p.omega0_sq, 2.0)
    ref = reference(p, 2.0, 0.0, np.linspace(0.0, period, 5))
    assert ref is not None
    assert ref.phi[-1] == pytest.approx(2.0, abs=1e-11)
    assert ref.dphi[-1] == pytest.approx(0.0, abs=1e-10)
    assert ref.phi[2] == pytest.approx(-2.0, abs=1e-11)  # half a period: the other side


def test_reference_restarts_at_reversals_and_agrees_with_the_core() -> None:
    ref = reference(PendulumParams(gamma=1.0, n=2.0), 2.0, 0.0, np.linspace(0.0, 5.0, 51))
    assert ref is not None
    assert ref.segments >= 3
    assert ref.disagreement < 1e-11


def test_fit_order_recovers_an_exact_power_law_above_the_floor() -> None:
    hs = [0.1 / 2**k for k in range(8)]
    errs = [3.0 * h**4 for h in hs]
    slope, used = fit_order(hs, errs, floor=3.0 * hs[5] ** 4 * 1.5)
    assert used == 4
    assert slope == pytest.approx(4.0, abs=1e-12)
    assert fit_order(hs[:2], errs[:2], floor=0.0) == (math.nan, 2) or math.isnan(
        fit_order(hs[:2], errs[:2], floor=0.0)[0])


def test_time_to_error_interpolates_log_log_and_never_extrapolates() -> None:
    rows = [{'cpu_s': 1.0, 'err_max': 1e-2}, {'cpu_s': 100.0, 'err_max': 1e-6}]
    assert time_to_error(rows, 1e-4) == pytest.approx(10.0, rel=1e-12)
    assert time_to_error(rows, 1e-2) == pytest.approx(1.0, rel=1e-12)
    assert math.isnan(time_to_error(rows, 1e-7))
    assert time_to_error(rows, 1e-1) == 1.0
    exact = [{'cpu_s': 1.0, 'err_max': 1e-2}, {'cpu_s': 2.0, 'err_max': 0.0}]
    assert 1.0 < time_to_error(exact, 1e-12) < 2.0


# ------------------------------------------------------------------ bad arguments
@pytest.mark.parametrize('argv, message', [
    (['foo', '--out', 'x'], "argument what: invalid choice: 'foo' (choose from "
                            "'work-precision', 'stability', 'paper', 'all')"),
    (['all'], 'the following arguments are required: --out'),
    (['all', '--out', 'x', '--repeats', '0'], "argument --repeats: must be an integer >= 1, "
                                              "got '0'"),
    (['all', '--out', 'x', '--repeats', 'three'], "argument --repeats: must be an integer "
                                                  ">= 1, got 'three'"),
])
def test_bad_arguments_give_exact_errors(argv: list[str], message: str,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    assert capsys.readouterr().err.splitlines()[-1] == f'pendulum_report: error: {message}'


def test_non_empty_out_is_refused_without_force(tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / 'old.txt').write_text('keep me')
    with pytest.raises(SystemExit) as exc:
        main(['paper', '--quick', '--out', str(tmp_path)])
    assert exc.value.code == 2
    assert capsys.readouterr().err.splitlines()[-1] == (
        f"pendulum_report: error: --out '{tmp_path}' is not empty; use --force to write into it")
    assert prepare_out_dir(tmp_path, force=True) == tmp_path
    assert (tmp_path / 'old.txt').read_text() == 'keep me'


def test_unwritable_out_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    blocker = tmp_path / 'file'
    blocker.write_text('')
    with pytest.raises(SystemExit):
        main(['stability', '--out', str(blocker / 'sub')])
    assert capsys.readouterr().err.splitlines()[-1] == (
        f"pendulum_report: error: --out '{blocker / 'sub'}' cannot be created: Not a directory")
    with pytest.raises(SystemExit):
        main(['stability', '--out', str(blocker)])
    assert capsys.readouterr().err.splitlines()[-1] == (
        f"pendulum_report: error: --out '{blocker}' exists and is not a directory")


def test_run_report_rejects_unknown_reports_and_bad_repeats(tmp_path: Path) -> None:
    with pytest.raises(ReportError, match=re.escape(
            "unknown report 'bogus'; choose from work-precision, stability, paper, all")):
        run_report('bogus', tmp_path)
    with pytest.raises(ReportError, match=re.escape('repeats must be an integer >= 1, got 0')):
        run_report('all', tmp_path, repeats=0)
    assert not list(tmp_path.iterdir())
