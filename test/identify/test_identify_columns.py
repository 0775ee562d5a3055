"""``--columns`` on the CSV files labs write: roles in order whatever the header says, or by name.

Each file is written here with known numbers and read back through ``read_record`` (the CLI's
reader); every refusal is matched to its exact message.
"""
from __future__ import annotations

import math
from pathlib import Path

import pytest

from pendulum_sim.identify import IdentifyError
from pendulum_sim.identify.inputs import Columns, parse_columns, read_record

T = [0.0, 0.05, 0.1, 0.15]
DEG = [40.0, 38.5, 34.0, 27.0]
OMEGA = [0.0, -0.5, -1.0, -1.5]


def lab(path: Path, header: str | None, rows: list[str]) -> Path:
    path.write_text(('' if header is None else header + '\n') + '\n'.join(rows) + '\n')
    return path


def rows3() -> list[str]:
    return [f'{a}, {b}, {c}' for a, b, c in zip(T, DEG, OMEGA, strict=True)]


@pytest.mark.parametrize('header', ['time, angle, omega', 't,position,velocity',
                                    '# time (s), angle (deg), speed (deg/s)', None])
def test_roles_in_order_read_the_columns_whatever_the_header_says(tmp_path: Path,
                                                                  header: str | None) -> None:
    src = lab(tmp_path / 'lab.csv', header, rows3())
    got = read_record(src, columns='t,position,velocity', units='deg')
    assert got.t.tolist() == T
    assert got.position.tolist() == [math.radians(d) for d in DEG]
    assert got.velocity is not None
    assert got.velocity.tolist() == [math.radians(d) for d in OMEGA]
    assert got.effort is None


def test_a_time_angle_header_works_with_the_default_columns(tmp_path: Path) -> None:
    src = lab(tmp_path / 'lab.csv', 'time, angle', [f'{a}, {b}' for a, b in zip(T, DEG,
                                                                                strict=True)])
    got = read_record(src)
    assert got.t.tolist() == T and got.position.tolist() == DEG


def test_header_names_map_to_roles_in_any_order(tmp_path: Path) -> None:
    src = lab(tmp_path / 'lab.csv', 'angle, note, time, omega',
              [f'{b}, x{i}, {a}, {c}' for i, (a, b, c) in enumerate(zip(T, DEG, OMEGA,
                                                                        strict=True))])
    got = read_record(src, columns='time=t,angle=position', units='deg')
    assert got.t.tolist() == T
    assert got.position.tolist() == [math.radians(d) for d in DEG]
    assert got.velocity is None
    both = read_record(src, columns=' omega = velocity , time=t,angle=position')
    assert both.velocity is not None and both.velocity.tolist() == OMEGA


def test_a_skipped_text_column_does_not_make_a_header(tmp_path: Path) -> None:
    src = lab(tmp_path / 'lab.csv', None, [f'{a}, trial {i}, {b}' for i, (a, b) in enumerate(
        zip(T, DEG, strict=True))])
    got = read_record(src, columns='t,_,position')
    assert got.t.tolist() == T and got.position.tolist() == DEG


def test_parse_columns_keeps_what_it_was_given() -> None:
    assert parse_columns('t,_,position') == Columns(roles=('t', '_', 'position'))
    parsed = parse_columns('time=t,angle=position')
    assert parsed == Columns(names=(('t', 'time'), ('position', 'angle')))
    assert parsed.text() == 'time=t,angle=position'


BAD_TEXT = [
    ('t,angle', "--columns names t, position, velocity, effort or _ (a column to skip), or "
                "maps header names to them (time=t,angle=position); got 'angle'"),
    ('t,t,position', "--columns must name t and position once each (and velocity, effort at "
                     "most once), got 't,t,position'"),
    ('time=t,angle', "--columns either names the roles of the columns in order (t,_,position) "
                     "or maps header names to roles (time=t,angle=position), not both; got "
                     "'time=t,angle'"),
    ('time=t,angle=theta', "--columns maps a header name to a role as NAME=ROLE, the role one "
                           "of t, position, velocity, effort; got 'angle=theta'"),
    ('t=time,position=angle', "--columns maps a header name to a role as NAME=ROLE, the role "
                              "one of t, position, velocity, effort; got 't=time'"),
    ('=t,angle=position', "--columns maps a header name to a role as NAME=ROLE, the role one "
                          "of t, position, velocity, effort; got '=t'"),
    ('time=t,angle=velocity', "--columns must name t and position once each (and velocity, "
                              "effort at most once), got 'time=t,angle=velocity'"),
    ('a=t,a=position', "--columns maps the header name 'a' to two roles; map each column once, "
                       "got 'a=t,a=position'"),
]


@pytest.mark.parametrize(('text', 'message'), BAD_TEXT)
def test_a_bad_columns_text_is_refused_with_its_reason(text: str, message: str) -> None:
    with pytest.raises(IdentifyError) as exc:
        parse_columns(text)
    assert str(exc.value) == message


def test_a_mapping_the_file_cannot_serve_is_refused_with_its_reason(tmp_path: Path) -> None:
    named = lab(tmp_path / 'named.csv', 'time, angle', ['0, 1', '1, 2'])
    bare = lab(tmp_path / 'bare.csv', None, ['0, 1', '1, 2'])
    twice = lab(tmp_path / 'twice.csv', 'time, angle, angle', ['0, 1, 2', '1, 2, 3'])
    short = lab(tmp_path / 'short.csv', 'time, angle', ['0, 1', '1'])
    text = lab(tmp_path / 'text.csv', 'time, angle', ['0, 1', '1, two'])
    header_only = lab(tmp_path / 'header.csv', 'time, angle', [])
    cases = [
        (named, 'time=t,theta=position',
         f"{named}: --columns names a column 'theta' that the header 'time,angle' does not "
         "have; pass --columns with the file's header names"),
        (bare, 'time=t,angle=position',
         f"{bare} has no header row (its first line is numbers) to find the columns "
         "'time=t,angle=position' by name; pass --columns with the roles of the columns in "
         "order (_ for one to skip)"),
        (twice, 'time=t,angle=position',
         f"{twice}: the header 'time,angle,angle' has 2 columns named 'angle'; pass --columns "
         "with the roles of the columns in order"),
        (named, 't,position,velocity',
         f"{named}: the header 'time,angle' has 2 columns but --columns 't,position,velocity' "
         "names 3; pass --columns with a role for each column (_ for one to skip)"),
        (bare, 't,position,velocity', f'{bare}: line 1 has 2 fields, --columns names 3'),
        (short, 't,position', f'{short}: line 3 has 1 fields, the header 2'),
        (text, 'time=t,angle=position',
         f"{text}: line 3, column position: ' two' is not a number"),
        (header_only, 't,position',
         f'{header_only} has a header row and no samples; pass a CSV with samples'),
    ]
    for path, columns, message in cases:
        with pytest.raises(IdentifyError) as exc:
            read_record(path, columns=columns)
        assert str(exc.value) == message, columns
