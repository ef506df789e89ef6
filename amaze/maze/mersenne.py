"""CPython's ``random.Random`` for integer seeds, in compiled code (numba).

Maze generation must draw exactly what the reference draws from
``random.Random(seed)``. CPython's generator is MT19937 (Matsumoto and
Nishimura's ``mt19937ar.c``) plus a few documented conversions, all of which
the generator's phases use and this module reproduces:

* seeding from an int: ``init_by_array`` with the absolute value's 32-bit
  little-endian words as the key (one zero word for 0), see :func:`seed_key`;
* ``getrandbits(k)`` for ``0 < k <= 32``: one 32-bit output shifted right by ``32 - k``;
* ``_randbelow(n)``: ``getrandbits(n.bit_length())`` until the value is below ``n``;
* ``choice(seq)``: ``seq[_randbelow(len(seq))]``;
* ``shuffle(x)``: for ``i`` from ``len(x) - 1`` down to 1, swap ``x[i]`` and
  ``x[_randbelow(i + 1)]``;
* ``sample(population, k)``: CPython's pool or set algorithm, chosen by the
  same size rule.

A generator's state is one ``int64`` array of :data:`STATE_SIZE`: the 624 words
(each below 2**32, so every product of the seeding fits in 63 bits) and, last,
the index of the next word. ``tests/amaze/maze/test_mersenne.py`` checks every
function against ``random.Random`` on millions of draws.
"""

from __future__ import annotations

import math

import numba
import numpy as np

__all__ = [
    "STATE_SIZE",
    "choice_index",
    "getrandbits",
    "next_word",
    "randbelow",
    "sample",
    "seed_key",
    "seeded_state",
    "shuffle",
]

_N = 624
_M = 397
_MASK = 0xFFFFFFFF
_UPPER = 0x80000000
_LOWER = 0x7FFFFFFF
_MATRIX_A = 0x9908B0DF
#: Length of a generator state: 624 words and the index of the next one.
STATE_SIZE = _N + 1


def seed_key(seed: int) -> np.ndarray:
    """The ``init_by_array`` key CPython derives from an int seed (``random_seed``).

    The absolute value's 32-bit words, least significant first; ``[0]`` for 0.
    """
    n = abs(int(seed))
    count = max(1, (n.bit_length() + 31) // 32)
    return np.frombuffer(n.to_bytes(4 * count, "little"), dtype="<u4").astype(np.int64)


@numba.njit(cache=True, nogil=True, inline="always")
def _twisted(y: int) -> int:
    return (y >> 1) ^ (_MATRIX_A if y & 1 else 0)


@numba.njit(cache=True, nogil=True)
def _regenerate(mt: np.ndarray) -> None:
    """Generate the next 624 words in place (``genrand_uint32``'s refill)."""
    for k in range(_N - _M):
        y = (mt[k] & _UPPER) | (mt[k + 1] & _LOWER)
        mt[k] = mt[k + _M] ^ _twisted(y)
    for k in range(_N - _M, _N - 1):
        y = (mt[k] & _UPPER) | (mt[k + 1] & _LOWER)
        mt[k] = mt[k + _M - _N] ^ _twisted(y)
    y = (mt[_N - 1] & _UPPER) | (mt[0] & _LOWER)
    mt[_N - 1] = mt[_M - 1] ^ _twisted(y)
    mt[_N] = 0


@numba.njit(cache=True, nogil=True)
def seeded_state(key: np.ndarray) -> np.ndarray:
    """A generator state seeded as ``init_by_array(key)`` (``mt19937ar.c``)."""
    mt = np.empty(STATE_SIZE, dtype=np.int64)
    mt[0] = 19650218
    for i in range(1, _N):
        mt[i] = (1812433253 * (mt[i - 1] ^ (mt[i - 1] >> 30)) + i) & _MASK
    i, j = 1, 0
    n_key = key.shape[0]
    for _ in range(max(_N, n_key)):
        mixed = ((mt[i - 1] ^ (mt[i - 1] >> 30)) * 1664525) & _MASK
        mt[i] = ((mt[i] ^ mixed) + key[j] + j) & _MASK
        i += 1
        j += 1
        if i >= _N:
            mt[0] = mt[_N - 1]
            i = 1
        if j >= n_key:
            j = 0
    for _ in range(_N - 1):
        mixed = ((mt[i - 1] ^ (mt[i - 1] >> 30)) * 1566083941) & _MASK
        mt[i] = ((mt[i] ^ mixed) - i) & _MASK
        i += 1
        if i >= _N:
            mt[0] = mt[_N - 1]
            i = 1
    mt[0] = _UPPER  # most significant bit 1: a non-zero initial array
    # CPython refills on the first draw; refilling now gives the same outputs
    # and lets a caller that restarts from a copy of this state skip the refill.
    _regenerate(mt)
    return mt


@numba.njit(cache=True, nogil=True)
def next_word(mt: np.ndarray) -> int:
    """The next 32-bit output (``genrand_uint32``), as a non-negative int."""
    if mt[_N] >= _N:
        _regenerate(mt)
    y = mt[mt[_N]]
    mt[_N] += 1
    y ^= y >> 11
    y ^= (y << 7) & 0x9D2C5680
    y ^= (y << 15) & 0xEFC60000
    y ^= y >> 18
    return y


@numba.njit(cache=True, nogil=True)
def getrandbits(mt: np.ndarray, k: int) -> int:
    """``random.getrandbits(k)`` for ``0 <= k <= 32``."""
    if k == 0:
        return 0
    return next_word(mt) >> (32 - k)


@numba.njit(cache=True, nogil=True)
def randbelow(mt: np.ndarray, n: int) -> int:
    """``random._randbelow(n)`` for ``0 < n < 2**32``: rejection on ``n.bit_length()`` bits."""
    shift = 32
    while (n >> (32 - shift)) != 0:
        shift -= 1
    r = next_word(mt) >> shift  # getrandbits(32 - shift)
    while r >= n:
        r = next_word(mt) >> shift
    return r


@numba.njit(cache=True, nogil=True)
def choice_index(mt: np.ndarray, n: int) -> int:
    """The index ``random.choice`` picks in a sequence of length ``n > 0``."""
    return randbelow(mt, n)


@numba.njit(cache=True, nogil=True)
def shuffle(mt: np.ndarray, x: np.ndarray) -> None:
    """``random.shuffle(x)`` in place."""
    for i in range(x.shape[0] - 1, 0, -1):
        j = randbelow(mt, i + 1)
        x[i], x[j] = x[j], x[i]


@numba.njit(cache=True, nogil=True)
def sample(mt: np.ndarray, population: np.ndarray, k: int) -> np.ndarray:
    """``random.sample(population, k)`` for ``0 <= k <= len(population)``.

    CPython tracks a pool (an ``n``-long list) when ``n`` is at most the size
    of a ``k``-element set, and the selected indices otherwise; the two draw
    differently, so the same rule picks the algorithm here.
    """
    n = population.shape[0]
    if not 0 <= k <= n:
        raise ValueError("sample larger than the population or negative")
    result = np.empty(k, dtype=population.dtype)
    setsize = 21
    if k > 5:
        setsize += 4 ** math.ceil(math.log(k * 3) / math.log(4))
    if n <= setsize:
        pool = population.copy()
        for i in range(k):
            j = randbelow(mt, n - i)
            result[i] = pool[j]
            pool[j] = pool[n - i - 1]
    else:
        selected = np.zeros(n, dtype=np.bool_)
        for i in range(k):
            j = randbelow(mt, n)
            while selected[j]:
                j = randbelow(mt, n)
            selected[j] = True
            result[i] = population[j]
    return result
