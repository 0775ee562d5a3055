"""pendulum_identify as a user runs it: its own process, real files, exit codes, outputs."""
from __future__ import annotations

import csv
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from mcap_ros2.writer import Writer

from pendulum_sim.core import PendulumParams, simulate
from pendulum_sim.joint.scenes import read_params_file
from pendulum_sim.testing.campaign.spec import parse_spec
from pendulum_sim.testing.scene import scene_values

REPO = Path(__file__).resolve().parents[2]
SCRIPT = Path(sys.executable).parent / 'pendulum_identify'
STATIC = REPO / 'docs' / '_static' / 'controller_test.mcap'
FAST = ['--models', 'viscous,quadratic', '--no-jit', '--no-progress']

HEADER_DEF = 'builtin_interfaces/Time stamp\nstring frame_id'
JOINT_STATE_DEF = (
    'std_msgs/Header header\nstring[] name\nfloat64[] position\nfloat64[] velocity\n'
    'float64[] effort\n'
    '================================================================================\n'
    'MSG: std_msgs/Header\n' + HEADER_DEF + '\n'
    '================================================================================\n'
    'MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n')


def run(*args: str | Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([str(SCRIPT), *map(str, args)], capture_output=True, text=True,
                          timeout=300, check=False)


def swing_samples(t_end: float = 10.0, every: int = 20, seed: int = 1
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    run_ = simulate(PendulumParams.from_omega0_sq(9.8, 0.2, 2.0), 0.9, 0.0, t_end, 1e-3)
    rng = np.random.default_rng(seed)
    idx = np.arange(0, run_.t.size, every)
    idx = np.unique(np.clip(idx + rng.integers(-4, 5, idx.size), 0, run_.t.size - 1))
    return (run_.t[idx], run_.phi[idx] + 0.05 + rng.normal(0, 1e-3, idx.size),
            run_.dphi[idx])


def write_csv(path: Path, header: list[str], rows: list[list[object]]) -> Path:
    with path.open('w', newline='') as fh:
        w = csv.writer(fh)
        w.writerow(header)
        w.writerows(rows)
    return path


def write_other_bag(path: Path, joints: tuple[str, ...] = ('shoulder', 'pendulum'),
                    topic: str = '/arm/joint_states') -> Path:
    """An MCAP of another writer (mcap-ros2-support): two joints, header stamps, no effort."""
    t, y, v = swing_samples()
    with path.open('wb') as fh:
        writer = Writer(fh)
        schema = writer.register_msgdef('sensor_msgs/msg/JointState', JOINT_STATE_DEF)
        for ti, yi, vi in zip(t, y, v, strict=True):
            ns = 1_700_000_000_000_000_000 + round(ti * 1e9)
            stamp = {'sec': ns // 1_000_000_000, 'nanosec': ns % 1_000_000_000}
            msg = {'header': {'stamp': stamp, 'frame_id': ''}, 'name': list(joints),
                   'position': [0.1, yi + 2 * math.pi * (yi > 0.5)][:len(joints)],
                   'velocity': [0.0, vi][:len(joints)], 'effort': []}
            writer.write_message(topic, schema, msg, log_time=ns + 5_000_000)
        writer.finish()
    return path


def test_a_csv_in_degrees_gives_a_scene_a_table_a_figure_and_a_campaign_block(tmp_path: Path
                                                                              ) -> None:
    t, y, v = swing_samples()
    rows = [[f'{a:.6f}', 'x', f'{math.degrees(b):.4f}', f'{math.degrees(c):.4f}']
            for a, b, c in zip(t, y, v, strict=True)]
    src = write_csv(tmp_path / 'lab.csv', ['t', 'note', 'position', 'velocity'], rows)
    out = tmp_path / 'fit'
    res = run(src, '--columns', 't,_,position,velocity', '--units', 'deg', '--out', out, *FAST)
    assert res.returncode == 0, res.stderr
    assert res.stdout.splitlines()[0].split()[:3] == ['rank', 'model', 'omega0']
    assert res.stdout.splitlines()[1].split()[:2] == ['1', 'quadratic']
    assert sorted(p.name for p in out.iterdir()) == ['campaign_parameters.yaml', 'fit.png',
                                                    'fit.yaml', 'models.csv']
    # fit.yaml is a scene the node and closed_loop read as it is.
    scene = read_params_file(out / 'fit.yaml')
    assert scene['n'] == 2.0 and abs(scene['gamma'] - 0.2) < 0.01
    omega0_sq = scene['m'] * scene['g'] * scene['l'] / scene['inertia']
    assert abs(omega0_sq - 9.8) < 0.01
    values = scene_values(str(out / 'fit.yaml'))
    assert values['gamma'] == scene['gamma'] and values['phi0'] == scene['phi0']
    # models.csv: both laws, ranked by BIC.
    with (out / 'models.csv').open() as fh:
        table = list(csv.DictReader(fh))
    assert [r['model'] for r in table] == ['quadratic', 'viscous']
    assert float(table[0]['bic']) < float(table[1]['bic'])
    lo, hi = float(table[0]['gamma_ci95_low']), float(table[0]['gamma_ci95_high'])
    assert lo < float(table[0]['gamma']) < hi
    # campaign_parameters.yaml: a parameters block pendulum_campaign takes.
    block = (out / 'campaign_parameters.yaml').read_text()
    spec = parse_spec('controller: pendulum_sim.testing.examples:pd\nepisodes: 4\nseed: 1\n'
                      'periods: 50\ntarget: 0.5\nrequirements: []\n' + block)
    assert {'g', 'gamma', 'n'} == set(spec.parameter_names)
    params = yaml.safe_load(block)['parameters']
    assert params['gamma']['distribution'] == 'normal' and params['n'] == 2.0
    assert params['g']['mean'] == pytest.approx(scene['g'], rel=1e-12)
    assert (out / 'fit.png').read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'


def test_a_lab_csv_headed_time_angle_is_identified_without_editing(tmp_path: Path) -> None:
    """Its header names no role: the roles in order, or its names mapped, both give the fit."""
    t, y, _ = swing_samples()
    rows = [[f'{a:.6f}', f'{b:.6f}'] for a, b in zip(t, y, strict=True)]
    src = write_csv(tmp_path / 'lab.csv', ['time', ' angle'], rows)
    fitted = []
    for i, columns in enumerate(('t,position', 'time=t,angle=position')):
        out = tmp_path / f'fit{i}'
        res = run(src, '--columns', columns, '--out', out, *FAST)
        assert res.returncode == 0, res.stderr
        fitted.append(read_params_file(out / 'fit.yaml'))
    assert fitted[0] == fitted[1]
    assert fitted[0]['n'] == 2.0 and abs(fitted[0]['gamma'] - 0.2) < 0.01


def test_another_writers_bag_with_two_joints_and_a_wrapping_encoder(tmp_path: Path) -> None:
    bag = write_other_bag(tmp_path / 'arm.mcap')
    out = tmp_path / 'fit'
    res = run(bag, '--joint', 'pendulum', '--out', out, *FAST)
    assert res.returncode == 0, res.stderr
    scene = read_params_file(out / 'fit.yaml')
    assert scene['n'] == 2.0 and abs(scene['gamma'] - 0.2) < 0.01
    assert 'topic /arm/joint_states, joint pendulum' in (out / 'fit.yaml').read_text()


def one_line(res: subprocess.CompletedProcess[str]) -> str:
    assert res.returncode == 2, (res.stdout, res.stderr)
    lines = res.stderr.splitlines()
    assert len(lines) == 1 and 'Traceback' not in res.stderr, res.stderr
    return lines[0]


def bad_cases(tmp: Path) -> list[tuple[list[str | Path], str]]:
    empty = tmp / 'empty.mcap'
    empty.write_bytes(b'')
    cut = tmp / 'cut.mcap'
    cut.write_bytes(STATIC.read_bytes()[:20000])
    floats = tmp / 'floats.mcap'
    with floats.open('wb') as fh:
        writer = Writer(fh)
        schema = writer.register_msgdef('std_msgs/msg/Float64', 'float64 data')
        for i in range(20):
            writer.write_message('/energy', schema, {'data': 1.0}, log_time=i * 1000)
        writer.finish()
    t, y, _ = swing_samples()
    nan = write_csv(tmp / 'nan.csv', ['t', 'position'],
                    [[a, 'nan' if i == 7 else b] for i, (a, b) in enumerate(zip(t, y,
                                                                                strict=True))])
    back = write_csv(tmp / 'back.csv', ['t', 'position'],
                     [[t[4] if i == 9 else a, b] for i, (a, b) in enumerate(zip(t, y,
                                                                                strict=True))])
    rest = write_csv(tmp / 'rest.csv', ['t', 'position'], [[a, 0.3] for a in t])
    other = write_csv(tmp / 'other.csv', ['time', 'angle'], [[a, b] for a, b in zip(
        t, y, strict=True)])
    two = write_other_bag(tmp / 'two.mcap')
    return [
        ([tmp / 'missing.mcap'], f'{tmp}/missing.mcap does not exist; pass a .mcap recording '
                                 'or a .csv file'),
        ([empty], f'{empty} is empty (0 bytes); pass a recording'),
        ([cut], f'{cut} is truncated'),
        ([floats], f'{floats} has no sensor_msgs/msg/JointState topic (its topics: /energy); '
                   'pass a recording of joint states'),
        ([STATIC, '--joint', 'elbow'], f"{STATIC}: joint 'elbow' is not in the messages of "
                                       '/joint_states (they name pendulum_joint); pass --joint '
                                       'with one of them'),
        ([STATIC, '--topic', '/arm/joint_states'],
         f"{STATIC} has no JointState topic '/arm/joint_states'; pass --topic with one of "
         '/joint_states'),
        ([two], f'{two}: /arm/joint_states carries the joints shoulder, pendulum; pass --joint'),
        ([nan], 'position has 1 samples that are NaN or infinite (the first at index 7); drop '
                'them before fitting'),
        ([back], f't must increase strictly: t[9] = {float(t[4])!r} s follows t[8] = '
                 f'{float(t[8])!r} s; sort the samples and drop repeated stamps'),
        ([rest], 'the joint is at rest: its position spans 0 rad over the record, within its '
                 'noise; record a free swing from a release angle'),
        ([other, '--columns', 'time=t,theta=position'],
         f"{other}: --columns names a column 'theta' that the header 'time,angle' does not "
         "have; pass --columns with the file's header names"),
        ([other, '--columns', 't=time,position=angle'],
         "--columns maps a header name to a role as NAME=ROLE, the role one of t, position, "
         "velocity, effort; got 't=time'"),
        ([rest, '--models', 'power,cubic'],
         "--models takes viscous, quadratic, coulomb, power, power+coulomb, got 'cubic'"),
    ]


def test_bad_input_exits_2_with_one_line_and_writes_nothing(tmp_path: Path) -> None:
    for i, (args, message) in enumerate(bad_cases(tmp_path)):
        out = tmp_path / f'out{i}'
        line = one_line(run(*args, '--out', out, '--no-progress'))
        if message.endswith('is truncated'):
            assert line.startswith(f'pendulum_identify: error: {message} ('), line
            assert line.endswith('; pass a recording that was closed'), line
        else:
            assert line == f'pendulum_identify: error: {message}'
        assert not out.exists(), args
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith('.identify')] == []


def test_a_folder_with_files_is_not_written_into(tmp_path: Path) -> None:
    out = tmp_path / 'full'
    out.mkdir()
    (out / 'keep.txt').write_text('mine')
    line = one_line(run(STATIC, '--out', out))
    assert line == (f'pendulum_identify: error: --out {out} exists and is not an empty folder; '
                    'pass a new or empty folder, or --force')
    assert [p.name for p in out.iterdir()] == ['keep.txt']


@pytest.mark.parametrize('argv', [['--help']])
def test_the_parser_is_built_for_the_reference(argv: list[str]) -> None:
    from pendulum_sim.identify.cli import build_parser

    text = build_parser().format_help()
    for option in ('--topic', '--joint', '--columns', '--units', '--out', '--models'):
        assert option in text
    assert run(*argv).returncode == 0
