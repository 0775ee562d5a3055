"""Many episodes' random streams at once: numpy's SeedSequence and PCG64, on arrays.

Episode ``i`` of a campaign seeded ``s`` draws from
``numpy.random.default_rng(SeedSequence(s, spawn_key=(i,)))`` (:mod:`.scenarios`). Making that
generator costs tens of microseconds, more than a control period of a batched episode, so a
batch of episodes (the autoreset of a vector environment's many environments) takes the same
streams here, all together: :class:`Streams` holds one PCG64 state per episode as arrays of
64-bit words and draws one uniform number from each at a time, to the bit what numpy's
``Generator.uniform`` draws from that episode's own generator (``test/testing/
test_testing_streams.py`` holds them to numpy's over seeds and episode numbers of one and two
words).

The algorithms are numpy's, written over arrays:

- ``SeedSequence`` (M. E. O'Neill's ``seed_seq`` alternative, numpy's
  ``random/bit_generator.pyx``): the entropy (the seed's 32-bit words padded with zeros to the
  pool size of 4, then the spawn key's words) hashed into a pool of four words
  (``mix_entropy``), and the pool hashed out into the bit generator's seed
  (``generate_state``);
- ``PCG64`` (O'Neill, "PCG: A Family of Simple Fast Space-Efficient Statistically Good
  Algorithms for Random Number Generation", 2014; numpy's ``random/src/pcg64``): a 128-bit
  linear congruential state, each output the XSL-RR permutation of the state after a step;
- ``Generator.uniform(low, high)``: ``low + (high − low) · u`` with ``u`` the top 53 bits of
  an output times 2⁻⁵³ (numpy's ``random_uniform`` and ``next_double``).

The 128-bit products are taken from 32-bit halves in unsigned 64-bit arrays, which wrap.
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from ..errors import TestingError

U32 = NDArray[np.uint32]
U64 = NDArray[np.uint64]
FloatArray = NDArray[np.float64]

POOL_SIZE = 4
INIT_A = 0x43B0D7E5
MULT_A = 0x931E8875
INIT_B = 0x8B51F9DD
MULT_B = 0x58F38DED
MIX_MULT_L = 0xCA01F9DD
MIX_MULT_R = 0x4973F715
XSHIFT = 16
MASK32 = 0xFFFFFFFF
PCG_MULT_HIGH = 2549297995355413924   # PCG_DEFAULT_MULTIPLIER_128, its two 64-bit words
PCG_MULT_LOW = 4865540595714422341
DOUBLE_UNIT = 1.0 / 9007199254740992.0   # 2**-53
MAX_WORD = 2**64


def _u32(x: int) -> np.uint32:
    return np.uint32(x & MASK32)


def _u64(x: int) -> np.uint64:
    return np.uint64(x % MAX_WORD)


class _Hash:
    """The running hash constant of ``mix_entropy`` (the same for every stream)."""

    def __init__(self) -> None:
        self.const = INIT_A

    def mix(self, value: U32) -> U32:
        """Return ``hashmix(value)`` and advance the constant."""
        value = value ^ _u32(self.const)
        self.const = (self.const * MULT_A) & MASK32
        value = value * _u32(self.const)
        return value ^ (value >> np.uint32(XSHIFT))


def _mix(x: U32, y: U32) -> U32:
    result: U32 = _u32(MIX_MULT_L) * x - _u32(MIX_MULT_R) * y
    return result ^ (result >> np.uint32(XSHIFT))


def _words(values: Sequence[int], name: str) -> tuple[U32, U32, NDArray[np.bool_]]:
    """Return the low and high 32-bit words of non-negative integers below 2**64, and where
    the high one counts (numpy's ``_int_to_uint32_array``: 0 is one word, [1, 2**32) one)."""
    if any(v < 0 or v >= MAX_WORD for v in values):
        bad = next(v for v in values if v < 0 or v >= MAX_WORD)
        raise TestingError(f'{name} must be an integer in [0, 2**64), got {bad}')
    arr = np.array(values, dtype=np.uint64)
    low = (arr & np.uint64(MASK32)).astype(np.uint32)
    high = (arr >> np.uint64(32)).astype(np.uint32)
    return low, high, high != 0


def _pool(seeds: Sequence[int], episodes: Sequence[int]) -> list[U32]:
    """Return the four pool words of ``SeedSequence(seed, spawn_key=(episode,))`` per stream."""
    s_low, s_high, _ = _words(seeds, 'seed')
    e_low, e_high, two = _words(episodes, 'episode')
    zero = np.zeros_like(s_low)
    # The entropy: the seed's words padded to the pool size (a spawn key is given), the key's.
    entropy = [s_low, s_high, zero, zero]
    hashing = _Hash()
    pool = [hashing.mix(word) for word in entropy]
    for src in range(POOL_SIZE):
        for dst in range(POOL_SIZE):
            if src != dst:
                pool[dst] = _mix(pool[dst], hashing.mix(pool[src]))
    for dst in range(POOL_SIZE):
        pool[dst] = _mix(pool[dst], hashing.mix(e_low))
    if two.any():   # a key of two words mixes its second word in too (the hash runs on alike)
        for dst in range(POOL_SIZE):
            pool[dst] = np.where(two, _mix(pool[dst], hashing.mix(e_high)), pool[dst])
    return pool


def _generate_state(pool: list[U32], words: int) -> list[U64]:
    """Return ``generate_state(words, uint64)`` of each pool, word by word."""
    hash_const = INIT_B
    out32 = []
    for i in range(2 * words):
        value = pool[i % POOL_SIZE] ^ _u32(hash_const)
        hash_const = (hash_const * MULT_B) & MASK32
        value = value * _u32(hash_const)
        out32.append(value ^ (value >> np.uint32(XSHIFT)))
    return [out32[2 * i].astype(np.uint64) | (out32[2 * i + 1].astype(np.uint64)
                                              << np.uint64(32)) for i in range(words)]


def _mul_high(a: U64, b: U64) -> U64:
    """Return the high 64 bits of the 128-bit products ``a · b``."""
    m32 = np.uint64(MASK32)
    s32 = np.uint64(32)
    a0, a1 = a & m32, a >> s32
    b0, b1 = b & m32, b >> s32
    p00, p01, p10, p11 = a0 * b0, a0 * b1, a1 * b0, a1 * b1
    mid = (p00 >> s32) + (p01 & m32) + (p10 & m32)
    return np.asarray(p11 + (p01 >> s32) + (p10 >> s32) + (mid >> s32), dtype=np.uint64)


def _add128(hi: U64, lo: U64, add_hi: U64, add_lo: U64) -> tuple[U64, U64]:
    low = lo + add_lo
    carry = (low < lo).astype(np.uint64)
    return hi + add_hi + carry, low


class Streams:
    """The generators of many episodes, ``default_rng(SeedSequence(seed, spawn_key=(i,)))``.

    Parameters
    ----------
    seeds, episodes : sequences of int
        One campaign seed and one episode number per stream, each in [0, 2**64).
    """

    def __init__(self, seeds: Sequence[int], episodes: Sequence[int]) -> None:
        if len(seeds) != len(episodes):
            raise TestingError(f'one seed per episode: got {len(seeds)} seeds for '
                             f'{len(episodes)} episodes')
        s_hi, s_lo, i_hi, i_lo = _generate_state(_pool(seeds, episodes), 4)
        one = np.uint64(1)
        # pcg_setseq_128_srandom_r: inc = initseq << 1 | 1; state = 0, step, += initstate, step
        self._inc_hi = (i_hi << one) | (i_lo >> np.uint64(63))
        self._inc_lo = (i_lo << one) | one
        self._hi, self._lo = self._inc_hi.copy(), self._inc_lo.copy()
        self._hi, self._lo = _add128(self._hi, self._lo, s_hi, s_lo)
        self._step()

    def __len__(self) -> int:
        return int(self._lo.size)

    def _step(self) -> None:
        """Advance every state: ``state · M + inc`` modulo 2**128."""
        m_hi, m_lo = _u64(PCG_MULT_HIGH), _u64(PCG_MULT_LOW)
        lo = self._lo * m_lo
        hi = _mul_high(self._lo, np.full_like(self._lo, m_lo)) + self._hi * m_lo + self._lo * m_hi
        self._hi, self._lo = _add128(hi, lo, self._inc_hi, self._inc_lo)

    def next64(self) -> U64:
        """Return each stream's next 64-bit output (a step, then XSL-RR of the state)."""
        self._step()
        rot = self._hi >> np.uint64(58)
        x = self._hi ^ self._lo
        return np.asarray((x >> rot) | (x << ((np.uint64(64) - rot) & np.uint64(63))),
                          dtype=np.uint64)

    def uniform(self, low: float, high: float) -> FloatArray:
        """Return each stream's ``Generator.uniform(low, high)`` (one draw from each)."""
        width = float(high) - float(low)
        u = (self.next64() >> np.uint64(11)).astype(np.float64) * DOUBLE_UNIT
        return np.asarray(float(low) + width * u)


__all__ = ['Streams']
