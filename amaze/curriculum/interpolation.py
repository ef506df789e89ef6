"""The interpolation curriculum: stages from a trivial maze to a target maze.

The AMaze paper trains agents in *interpolation* mode: ten stages that go
"smoothly" from a trivial maze to the final (target) maze, each atomic field
of the maze string being interpolated by its own rule. The reference's
``amaze-interpolate`` tool never ran (``docs/reference-behaviour.md`` §8.3), so the
rules are defined here afresh. For stage ``i`` of ``n``, with ``u = i / (n - 1)``:

==================  ==========================================================
field               rule
==================  ==========================================================
``width/height``    linear, rounded half up to an integer
``seed``            the end maze's seed (or the ``seed`` argument), so the
                    curriculum is deterministic
``start, rotated``  the end maze's corner and rotation flag
``unicursive``      the start maze's flag while ``u < 1/2``, then the end's
                    (intersections appear half-way, not at the very start)
``p_lure``          linear (a maze without lures counts as 0), rounded half up
                    to :data:`PROBABILITY_DIGITS` decimals
``p_trap``          the same, but 0 in unicursive stages: traps are placed at
                    intersections, which unicursive mazes do not have
lure/trap signs     present from the first stage whose probability is > 0
clue signs          present in every stage with intersections (not unicursive)
sign types          the end maze's list (the start's when the end has none of
                    that kind); when both mazes have that kind, each lightness
                    is linear between the start's and the end's (paired by
                    position, the start's last sign reused), rounded half up
                    to :data:`LIGHTNESS_DIGITS` decimals
==================  ==========================================================

Stage 0 is the start maze and stage ``n - 1`` the end maze, exactly (the same
canonical strings). Rounding is exact (rational arithmetic) and monotone, so
when the start maze is no harder than the end maze (sizes, lure and trap
probabilities no larger; unicursive or the end is not), sizes and
probabilities never decrease from one stage to the next.

:func:`interpolation_start` gives the default start of a target (a trivial
5x5 unicursive maze with the target's seed, corner and rotation) and
:func:`curriculum` the paper's protocol from it.
"""

from __future__ import annotations

import math
from fractions import Fraction

from amaze.errors import AmazeError, MazeStringError
from amaze.maze.signs import Sign
from amaze.maze.spec import MazeSpec
from amaze.validation import check_integer

#: Number of stages of the paper's interpolation protocol.
DEFAULT_STAGES = 10
#: Most stages an interpolation may have (a sanity bound: past a few hundred,
#: consecutive stages are mostly the same maze, and a mistyped count would
#: otherwise build a list of billions).
MAX_STAGES = 10_000
#: Side of the default trivial start maze (smaller if the target is smaller).
TRIVIAL_SIDE = 5
#: Intersections (and so clues and traps) appear from the first stage with ``u >= 1/2``.
UNICURSIVE_UNTIL = Fraction(1, 2)
#: Decimals kept for interpolated lure and trap probabilities (short, readable strings).
PROBABILITY_DIGITS = 3
#: Decimals kept for interpolated sign lightness values.
LIGHTNESS_DIGITS = 3


class InterpolationError(AmazeError):
    """Bad arguments for an interpolation (stage count, seed or maze)."""


def interpolate(
    start: MazeSpec | str,
    end: MazeSpec | str,
    n: int = DEFAULT_STAGES,
    *,
    seed: int | None = None,
) -> list[MazeSpec]:
    """The ``n`` stages from ``start`` to ``end`` under the module's per-field rules.

    ``start`` and ``end`` are specs or maze strings. ``seed`` replaces the end
    maze's seed in the intermediate stages (stage 0 and ``n - 1`` are always
    the start and end mazes themselves). The result is deterministic as long
    as both mazes carry a seed (a string without ``M`` draws a random one).
    """
    first, last = _as_spec(start, "start"), _as_spec(end, "end")
    n = check_integer(
        "number of stages n", n, minimum=2, maximum=MAX_STAGES, error=InterpolationError
    )
    if seed is not None:
        seed = check_integer("seed", seed, minimum=0, error=InterpolationError)
    stage_seed = last.seed if seed is None else seed
    stages = [first]
    for i in range(1, n - 1):
        stages.append(_stage(first, last, Fraction(i, n - 1), stage_seed))
    stages.append(last)
    return stages


def interpolation_start(end: MazeSpec | str) -> MazeSpec:
    """The default first stage for ``end``: a trivial maze of the smallest curriculum size.

    It is ``TRIVIAL_SIDE`` x ``TRIVIAL_SIDE`` (5x5, or the target's side when
    smaller), unicursive, without signs, and shares the target's seed, start
    corner and rotation flag, e.g. ``M2000007_5x5_U`` for
    ``M2000007_20x20_C1_l.25_L.25_t.5_T.5``.
    """
    target = _as_spec(end, "end")
    return MazeSpec(
        width=min(TRIVIAL_SIDE, target.width),
        height=min(TRIVIAL_SIDE, target.height),
        seed=target.seed,
        start=target.start,
        rotated=target.rotated,
        unicursive=True,
    )


def curriculum(end: MazeSpec | str, n: int = DEFAULT_STAGES) -> list[MazeSpec]:
    """The paper's interpolation protocol: ``n`` stages from the trivial start to ``end``."""
    target = _as_spec(end, "end")
    return interpolate(interpolation_start(target), target, n)


def effective_p_trap(spec: MazeSpec) -> float:
    """The trap probability that matters: 0 without traps or in a unicursive maze."""
    return 0.0 if spec.unicursive or not spec.p_trap else spec.p_trap


def _as_spec(maze: MazeSpec | str, role: str) -> MazeSpec:
    if isinstance(maze, MazeSpec):
        return maze
    if isinstance(maze, str):
        try:
            return MazeSpec.from_string(maze)
        except MazeStringError as error:
            raise InterpolationError(f"{role} maze: {error}") from None
    raise InterpolationError(f"{role} maze {maze!r} is neither a MazeSpec nor a maze string")


def _round_half_up(value: Fraction, digits: int) -> Fraction:
    scale = 10**digits
    return Fraction(math.floor(value * scale + Fraction(1, 2)), scale)


def _linear(a: float, b: float, u: Fraction) -> Fraction:
    fa = Fraction(a)
    return fa + (Fraction(b) - fa) * u


def _probability(a: float | None, b: float | None, u: Fraction) -> float:
    return float(_round_half_up(_linear(a or 0.0, b or 0.0, u), PROBABILITY_DIGITS))


def _signs(start: tuple[Sign, ...], end: tuple[Sign, ...], u: Fraction) -> tuple[Sign, ...]:
    if not end:
        return start
    if not start:
        return end
    result = []
    for k, sign in enumerate(end):
        a = start[min(k, len(start) - 1)].value
        value = _round_half_up(_linear(a, sign.value, u), LIGHTNESS_DIGITS)
        result.append(Sign(sign.shape, max(float(value), min(a, sign.value))))
    return tuple(result)


def _stage(first: MazeSpec, last: MazeSpec, u: Fraction, seed: int) -> MazeSpec:
    unicursive = first.unicursive if u < UNICURSIVE_UNTIL else last.unicursive
    p_lure = _probability(first.p_lure, last.p_lure, u)
    p_trap = _probability(effective_p_trap(first), effective_p_trap(last), u)
    return MazeSpec(
        width=int(_round_half_up(_linear(first.width, last.width, u), 0)),
        height=int(_round_half_up(_linear(first.height, last.height, u), 0)),
        seed=seed,
        start=last.start,
        rotated=last.rotated,
        unicursive=unicursive,
        clue=() if unicursive else _signs(first.clue, last.clue, u),
        lure=_signs(first.lure, last.lure, u) if p_lure > 0 else (),
        p_lure=p_lure or None,
        trap=_signs(first.trap, last.trap, u) if p_trap > 0 and not unicursive else (),
        p_trap=None if unicursive else p_trap or None,
    )
