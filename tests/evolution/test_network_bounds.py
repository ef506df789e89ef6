"""A :class:`~evolution.networks.NetworkSpec`'s hidden layers are bounded as every trainer's:
at most :data:`~amaze.validation.MAX_HIDDEN_LAYERS` layers of at most
:data:`~amaze.validation.MAX_LAYER_WIDTH` units, checked before anything is copied or built.
"""

from __future__ import annotations

import pytest

from amaze.validation import MAX_HIDDEN_LAYERS, MAX_LAYER_WIDTH
from evolution import EvolutionConfigError
from evolution.networks import MAX_WIDTH, NetworkSpec


def test_the_bounds_are_the_shared_ones() -> None:
    assert MAX_WIDTH == MAX_LAYER_WIDTH
    spec = NetworkSpec("DD", hidden=[MAX_LAYER_WIDTH] * MAX_HIDDEN_LAYERS)
    assert spec.hidden == (MAX_LAYER_WIDTH,) * MAX_HIDDEN_LAYERS


@pytest.mark.parametrize(
    ("hidden", "words"),
    [
        ([16] * (MAX_HIDDEN_LAYERS + 1), f"hidden has 17 layers, more than {MAX_HIDDEN_LAYERS}"),
        (range(10**12), f"hidden has 1000000000000 layers, more than {MAX_HIDDEN_LAYERS}"),
        ([16, MAX_LAYER_WIDTH + 1], "hidden layer 4097 is not an integer in [1, 4096]"),
        (0, "hidden layer 0 is not an integer in [1, 4096]"),
        ([16, 2.5], "hidden layer 2.5 is not an integer in [1, 4096]"),
        ("16", "hidden '16' must be a list of layer widths"),
    ],
)
def test_hidden_layers_past_the_bounds_are_refused(hidden: object, words: str) -> None:
    with pytest.raises(EvolutionConfigError) as refused:
        NetworkSpec("DD", hidden=hidden)
    assert str(refused.value) == words
