"""The value checks every config and constructor uses."""

from __future__ import annotations

import math

import numpy as np
import pytest

from amaze.errors import AmazeError
from amaze.validation import check_integer, check_number


@pytest.mark.parametrize("value", [1, 7, np.int64(3), np.uint8(200)])
def test_integers_within_bounds_come_back_as_int(value):
    checked = check_integer("n", value, minimum=1)
    assert checked == int(value) and type(checked) is int


@pytest.mark.parametrize(
    ("value", "minimum", "maximum", "message"),
    [
        (True, 1, None, "n True is not a positive integer"),
        (0, 1, None, "n 0 is not a positive integer"),
        (-1, 0, None, "n -1 is not a non-negative integer"),
        (2.0, 1, None, "n 2.0 is not a positive integer"),
        ("3", None, None, "n '3' is not an integer"),
        (101, 2, 100, "n 101 is not an integer in [2, 100]"),
        (4, 5, None, "n 4 is not an integer >= 5"),
        (9, None, 8, "n 9 is not an integer <= 8"),
    ],
)
def test_bad_integers_name_the_value(value, minimum, maximum, message):
    with pytest.raises(AmazeError, match=r"^" + message.replace("[", r"\[") + "$"):
        check_integer("n", value, minimum=minimum, maximum=maximum, error=AmazeError)


@pytest.mark.parametrize("value", [0.5, 1, np.float32(0.25), 1e300])
def test_numbers_come_back_as_float(value):
    checked = check_number("x", value, minimum=0, strict_minimum=True)
    assert checked == float(value) and type(checked) is float


@pytest.mark.parametrize(
    ("value", "kwargs", "message"),
    [
        (True, {}, "x True is not a number"),
        ("1", {}, "x '1' is not a number"),
        (math.nan, {"finite": False}, "x nan is not a finite number"),
        (math.inf, {}, "x inf is not a finite number"),
        (0, {"minimum": 0, "strict_minimum": True}, "x 0 is not a number > 0"),
        (-0.5, {"minimum": 0}, "x -0.5 is not a number >= 0"),
        (2, {"minimum": 0, "maximum": 1}, r"x 2 is not a number in \[0, 1\]"),
        (2, {"maximum": 1}, "x 2 is not a number <= 1"),
    ],
)
def test_bad_numbers_name_the_value(value, kwargs, message):
    with pytest.raises(ValueError, match=r"^" + message + "$"):
        check_number("x", value, **kwargs)


def test_integers_too_large_for_a_float_are_not_finite_numbers():
    with pytest.raises(ValueError, match=r"is not a finite number$"):
        check_number("x", 10**400)
    with pytest.raises(ValueError, match=r"is not a finite number$"):
        check_number("x", -(10**400), maximum=0)
    assert check_number("x", 10**400, finite=False) == math.inf
    assert check_number("x", -(10**400), finite=False) == -math.inf


def test_infinity_is_accepted_only_when_asked():
    assert check_number("x", math.inf, minimum=0, finite=False) == math.inf
