"""The compiled MT19937 and CPython's conversions against ``random.Random``, draw for draw."""

from __future__ import annotations

import math
import random

import numba
import numpy as np
import pytest

from amaze.maze import mersenne

SEEDS = [0, 1, 2, 5489, 2**31 - 1, 2**32 - 1, 2**32, 2**63 + 12345, 10**40 + 7, 3**200]


@numba.njit
def _words(mt, count):
    out = np.empty(count, dtype=np.int64)
    for c in range(count):
        out[c] = mersenne.next_word(mt)
    return out


@numba.njit
def _below(mt, bounds):
    out = np.empty(bounds.shape[0], dtype=np.int64)
    for c in range(bounds.shape[0]):
        out[c] = mersenne.randbelow(mt, bounds[c])
    return out


def _state(seed: int) -> np.ndarray:
    return mersenne.seeded_state(mersenne.seed_key(seed))


def _python_words(seed: int, count: int) -> np.ndarray:
    bits = random.Random(seed).getrandbits(32 * count)
    return np.frombuffer(bits.to_bytes(4 * count, "little"), dtype="<u4").astype(np.int64)


@pytest.mark.parametrize("seed", SEEDS)
def test_words_equal_getrandbits_over_many_refills(seed):
    count = 200_000  # 320 refills of the 624-word state; 2M words over all seeds
    assert np.array_equal(_words(_state(seed), count), _python_words(seed, count))


def test_seed_key_is_cpythons():
    assert mersenne.seed_key(0).tolist() == [0]
    assert mersenne.seed_key(2**32).tolist() == [0, 1]
    assert mersenne.seed_key(-7).tolist() == [7]  # CPython seeds with abs(n)
    assert np.array_equal(_words(_state(-7), 10), _python_words(-7, 10))


def test_getrandbits_takes_the_top_bits():
    mt, rng = _state(99), random.Random(99)
    for k in [0, 1, 2, 3, 7, 16, 31, 32] * 50:
        assert mersenne.getrandbits(mt, k) == rng.getrandbits(k)


def test_randbelow_over_a_million_draws():
    rng = random.Random(2024)
    bounds = np.array(
        [rng.choice([1, 2, 3, 4, 5, 7, 100, 1000, 2**31 + 1, 2**32 - 1]) for _ in range(1_000_000)]
    )
    ours = _below(_state(2024), bounds)
    python = random.Random(2024)
    assert ours.tolist() == [python._randbelow(int(n)) for n in bounds]


def test_shuffle_and_choice():
    mt, rng = _state(7), random.Random(7)
    for length in [*range(40), 200, 1000]:
        ours, theirs = np.arange(length), list(range(length))
        mersenne.shuffle(mt, ours)
        rng.shuffle(theirs)
        assert ours.tolist() == theirs
        if length:
            assert mersenne.choice_index(mt, length) == theirs.index(rng.choice(theirs))


def _uses_pool(n: int, k: int) -> bool:
    setsize = 21 + (4 ** math.ceil(math.log(k * 3, 4)) if k > 5 else 0)
    return n <= setsize


def test_sample_both_algorithms():
    mt, rng = _state(11), random.Random(11)
    algorithms = set()
    for n in [0, 1, 2, 5, 6, 20, 21, 22, 40, 85, 86, 200, 1000, 5000]:
        for k in sorted({k for k in (0, 1, n // 3, n // 2, n - 1, n) if 0 <= k <= n}):
            population = np.arange(n) * 3 + 1  # not the indices themselves
            ours = mersenne.sample(mt, population, k)
            assert ours.tolist() == rng.sample(population.tolist(), k), (n, k)
            algorithms.add(_uses_pool(n, k))
    assert algorithms == {True, False}
    with pytest.raises(ValueError, match="larger than the population"):
        mersenne.sample(mt, np.arange(3), 4)
