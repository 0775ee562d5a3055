"""The measured pendulum records under ``test/data/``, read as their sources describe them.

Each ``SOURCE.md`` there says where a record comes from, its licence and its columns. A
record is fitted from its first turning point after the first crossing of its centre: before
it, the hand that let the pendulum go may still be on it.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]
DATA = Path(__file__).resolve().parents[1] / 'data'
TIAN = DATA / 'tian_phy180_video'
JENSEN = DATA / 'jensen_benard_encoder'
ENCODER_RATE = 1000.0
"""Samples per second the encoder records name in their header (times are index / rate)."""

RECORDS = {
    'video lab 1': (TIAN, 'lab1_data.txt'),
    'video lab 2': (TIAN, 'trial1_rawdata.txt'),
    'encoder 01': (JENSEN, 'pendulum_free_swing_data_01.txt'),
    'encoder 02': (JENSEN, 'pendulum_free_swing_data_02.txt'),
    'encoder 03': (JENSEN, 'pendulum_free_swing_data_03.txt'),
}
"""Each record's name in the docs, its folder and its file."""


def read(name: str) -> tuple[FloatArray, FloatArray]:
    """Return a record's times (s) and angles (rad) as its file holds them."""
    folder, file = RECORDS[name]
    path = folder / file
    if folder == TIAN:
        data = np.loadtxt(path)
        return data[:, 0], data[:, 1]
    header = path.read_text(encoding='utf-8').splitlines()[:2]
    assert header[0].split(', ') == ['trigger_start_deg', 'sample_rate', 'duration_sec']
    assert float(header[1].split(',')[1]) == ENCODER_RATE
    deg = np.loadtxt(path, skiprows=2)
    return np.arange(deg.size) / ENCODER_RATE, np.radians(deg)


def free_swing(t: FloatArray, y: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Return the record from its first turning point after its first crossing of the centre."""
    c = y - np.median(y)
    above = c >= 0.0           # the median is a sample: a sign of 0 would cross twice
    crossings = np.flatnonzero(above[1:] != above[:-1])
    first, second = int(crossings[0]) + 1, int(crossings[1]) + 1
    k = first + int(np.argmax(np.abs(c[first:second])))
    return t[k:], y[k:]


def load(name: str) -> tuple[FloatArray, FloatArray]:
    """Return the free swing of record ``name``: times (s) and angles (rad)."""
    return free_swing(*read(name))
