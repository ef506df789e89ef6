"""Arrow drawings for sign-reading transfer: varied training styles and held-out styles.

A hybrid agent (``H5`` ... ``H15``) sees a sign as a small gray image. Trained on
the built-in ``arrow`` alone it learns that one drawing; to make it read pointing
signs drawn in ways it never saw, it can be trained on many drawings of an arrow
and tested on drawings kept out of training. This module draws both, as custom
sign images (:func:`amaze.maze.signs.register_custom_signs`):

Training styles
    :class:`ArrowStyle` holds the parameters of one arrow (shaft, head filled,
    open or hollow, scale, pixel noise), :func:`draw_arrow` draws it and
    :func:`training_styles` draws styles from fixed ranges, from a seed. Every
    style keeps a shaft at least :data:`MIN_SHAFT` (0.3) of the image long, so
    none is a bare head, a triangle or a chevron.

Held-out styles
    :data:`HELD_OUT_STYLES`: pointing signs drawn differently from every
    training style, never used in training: ``chevron`` (an open ">" of two
    strokes, no shaft), ``harpoon`` (a shaft with a single barb on one side) and
    ``outline`` (the hollow contour of a block arrow).

:func:`write_sign_styles` writes both groups as PNG files, one folder each, to
register (``amaze --signs FOLDER``, ``AMAZE_CUSTOM_SIGNS``) and name in maze
strings or in coevolution's ``shapes``; :func:`directional` tells whether a
shape can carry a direction at all (a ``star`` cannot).

Every image is a square of mode ``LA``: white, the drawing in the alpha channel
(the sign loader composites it on black, so the alpha is the gray level an agent
sees), pointing east and centred; the loader turns it for the other directions.
Drawing is deterministic: the same style and size give the same pixels.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from amaze.errors import SignError
from amaze.maze.sign_images import sign_frames
from amaze.maze.signs import Sign
from amaze.validation import check_integer, check_number

#: Side in pixels of the images :func:`write_sign_styles` writes (and the drawings' default).
IMAGE_SIZE = 64
#: Smallest and largest side :func:`draw_arrow` and the held-out drawings accept.
MIN_IMAGE_SIZE, MAX_IMAGE_SIZE = 8, 1024
#: Shortest shaft of any :class:`ArrowStyle`, as a share of the image side (after scaling).
MIN_SHAFT = 0.3
#: How many styles :func:`training_styles` draws at most.
MAX_TRAINING_STYLES = 256
#: Sub-folders of :func:`write_sign_styles` and the prefix of the training shapes' names.
TRAINING_FOLDER, HELD_OUT_FOLDER, TRAINING_PREFIX = "training", "held-out", "arrowv"
#: Side of the frames :func:`directional` compares: large enough that the drawing, not
#: pixel rounding, decides (the reference's ``star`` differs between its turns by 4 pixels
#: at 15 x 15 and its ``error`` cross at 9 x 9; at 32 x 32 both are exactly symmetric).
DIRECTIONAL_SIZE = 32
#: Two frames of a directional shape differ by more than this share of their ink
#: (summed absolute difference over the larger frame's summed gray levels). Rounding
#: in rasterising or resizing a symmetric image moves a few edge pixels, not more.
DIRECTIONAL_TOLERANCE = 0.05

#: Range of each :class:`ArrowStyle` field, as shares of the image side (noise: of
#: full white). ``training_styles`` draws uniformly inside them (the shaft's width inside
#: the narrower range it is given, :data:`DEFAULT_SHAFT_WIDTH` by default); a style
#: outside is refused. ``scale * shaft_length >= 0.75 * 0.4 = MIN_SHAFT``, the head is
#: at least twice as wide as the shaft, and the whole arrow fits the image.
RANGES: dict[str, tuple[float, float]] = {
    "shaft_length": (0.4, 0.55),
    "shaft_width": (0.05, 0.3),
    "head_length": (0.15, 0.35),
    "head_width": (0.3, 0.7),
    "scale": (0.75, 1.0),
    "noise": (0.0, 0.1),
}

#: The shaft widths :func:`training_styles` draws from by default (the thin shafts it has
#: always drawn: 1 to 2 pixels of a hybrid robot's 13-pixel sign). Any range inside
#: ``RANGES["shaft_width"]`` can be asked for: wider shafts, up to 4 pixels thick there.
DEFAULT_SHAFT_WIDTH: tuple[float, float] = (0.05, 0.16)

#: A head is at least this many times as wide as the shaft (so that it stands out).
HEAD_TO_SHAFT = 2.0
#: How a head is drawn: a filled triangle, an open V of two strokes, the
#: triangle's closed contour (hollow; the shaft stays filled), or that contour
#: drawn with a hairline (half the shaft's width, at least :data:`MIN_HAIRLINE`).
HEADS = ("filled", "open", "hollow", "hairline")
#: The heads :func:`training_styles` draws by default (the styles it has always drawn).
DEFAULT_HEADS = ("filled", "open")
#: Thinnest stroke of a ``hairline`` head, as a share of the image side. A ``hollow``
#: head's stroke is the shaft's width, and at a hybrid robot's 13-pixel sign the
#: triangle's hole closes: such a head looks filled. A hairline keeps the hole open.
MIN_HAIRLINE = 0.04

#: Widest stroke of the held-out drawings' ``stroke`` keyword, as a share of the image side.
MAX_STROKE = 0.25

_SUPERSAMPLE = 4  # drawn at 4 x the side, then averaged: smooth edges, sub-pixel widths count


@dataclass(frozen=True)
class ArrowStyle:
    """How one arrow is drawn, pointing east (lengths and widths: shares of the image side).

    The arrow is a shaft (``shaft_length`` long, ``shaft_width`` thick) ending in
    a head ``head_length`` long and ``head_width`` across, ``head`` one of
    :data:`HEADS` (a filled triangle, an open V of two strokes as thick as the shaft,
    the triangle's contour drawn with such a stroke, or with a hairline half as
    thick, at least :data:`MIN_HAIRLINE`), centred, then scaled by
    ``scale`` about the centre. ``noise`` adds Gaussian noise of that standard
    deviation (a share of full white) to every pixel's gray level, drawn from
    ``noise_seed``: the same style always gives the same image. Every field must
    lie in its :data:`RANGES` range and the head be at least :data:`HEAD_TO_SHAFT` times
    as wide as the shaft (:class:`~amaze.errors.SignError` otherwise), so that every
    style is a clear arrow whose drawn shaft is at least :data:`MIN_SHAFT` long.
    """

    shaft_length: float = 0.5
    shaft_width: float = 0.1
    head_length: float = 0.3
    head_width: float = 0.5
    head: str = "filled"
    scale: float = 1.0
    noise: float = 0.0
    noise_seed: int = 0

    def __post_init__(self) -> None:
        for name, (low, high) in RANGES.items():
            value = check_number(
                f"arrow style {name}",
                getattr(self, name),
                minimum=low,
                maximum=high,
                error=SignError,
            )
            object.__setattr__(self, name, value)
        if self.head_width < HEAD_TO_SHAFT * self.shaft_width:
            raise SignError(
                f"arrow style head_width {self.head_width!r} is less than {HEAD_TO_SHAFT} x its"
                f" shaft_width {self.shaft_width!r}: the head would not stand out of the shaft"
            )
        if not isinstance(self.head, str) or self.head not in HEADS:
            raise SignError(f"arrow style head {self.head!r} is not one of {', '.join(HEADS)}")
        seed = check_integer("arrow style noise_seed", self.noise_seed, minimum=0, error=SignError)
        object.__setattr__(self, "noise_seed", seed)


def draw_arrow(style: ArrowStyle, size: int = IMAGE_SIZE) -> Image.Image:
    """The arrow of ``style`` as a ``size x size`` image of mode ``LA``, pointing east.

    White on transparent (the drawing in the alpha channel), centred; the same
    style and size always give the same pixels (the noise comes from the style's seed).
    """
    if not isinstance(style, ArrowStyle):
        raise SignError(f"expected an ArrowStyle, not {style!r}")
    size = _check_size(size)
    s = style.scale
    half_shaft, half_head = style.shaft_width / 2, style.head_width / 2
    # A stroked head's round apex reaches half a stroke past its vertex: centre the ink.
    filled = style.head == "filled"
    head_stroke = max(MIN_HAIRLINE, half_shaft) if style.head == "hairline" else style.shaft_width
    reach = style.shaft_length + style.head_length + (0.0 if filled else head_stroke / 2)
    start = 0.5 - reach / 2
    base = start + style.shaft_length
    tip = base + style.head_length

    def paint(draw: ImageDraw.ImageDraw, at: Callable[[float, float], tuple[float, float]]) -> None:
        # ``at`` maps the unscaled arrow's unit coordinates to pixels, scaled about the centre.
        def scaled(x: float, y: float) -> tuple[float, float]:
            return at(0.5 + (x - 0.5) * s, 0.5 + (y - 0.5) * s)

        head = [(base, 0.5 - half_head), (tip, 0.5), (base, 0.5 + half_head)]
        stroke = _pixels(head_stroke * s, at)
        if filled:
            shaft_end = base + min(half_shaft, style.head_length / 2)  # overlap: no seam
            draw.polygon([scaled(x, y) for x, y in head], fill=255)
        elif style.head == "open":
            draw.line([scaled(x, y) for x, y in head], fill=255, width=stroke, joint="curve")
            shaft_end = tip
        else:  # hollow: round the triangle past its first corner again, a joint like the others
            contour = [*head, *head[:2]]
            draw.line([scaled(x, y) for x, y in contour], fill=255, width=stroke, joint="curve")
            shaft_end = base
        shaft = [
            (start, 0.5 - half_shaft),
            (shaft_end, 0.5 - half_shaft),
            (shaft_end, 0.5 + half_shaft),
            (start, 0.5 + half_shaft),
        ]
        draw.polygon([scaled(x, y) for x, y in shaft], fill=255)

    alpha = np.asarray(_supersampled(size, paint), dtype=np.float64)
    if style.noise > 0:
        rng = np.random.default_rng(style.noise_seed)
        alpha = alpha + rng.normal(0.0, 255 * style.noise, alpha.shape)
    return _white(np.clip(np.rint(alpha), 0, 255).astype(np.uint8))


def training_styles(
    count: int,
    seed: int,
    heads: Sequence[str] = DEFAULT_HEADS,
    shaft_width: Sequence[float] = DEFAULT_SHAFT_WIDTH,
) -> list[ArrowStyle]:
    """``count`` arrow styles (1 to :data:`MAX_TRAINING_STYLES`) drawn from :data:`RANGES`.

    Each field uniform in its range (the shaft's width in ``shaft_width``, a
    ``(low, high)`` range inside its :data:`RANGES` one; the head's width in the
    part of its range that :data:`HEAD_TO_SHAFT` leaves), the head one of
    ``heads`` (of :data:`HEADS`, each as likely), and each style's noise seed
    drawn too, all from ``np.random.default_rng(seed)``: the same arguments give
    the same styles, and a longer list starts with a shorter one's styles. The
    same seed draws the same shaft lengths, head lengths, scales and noise
    whichever heads and shaft widths are asked for: ``heads`` changes only the
    heads, ``shaft_width`` only the shafts' widths and the heads' widths they allow.
    """
    count = check_integer(
        "training style count", count, minimum=1, maximum=MAX_TRAINING_STYLES, error=SignError
    )
    seed = check_integer("training style seed", seed, minimum=0, error=SignError)
    heads = check_heads(heads)
    ranges = {**RANGES, "shaft_width": check_shaft_width(shaft_width)}
    rng = np.random.default_rng(seed)
    styles = []
    for _ in range(count):
        values = {name: float(rng.uniform(low, high)) for name, (low, high) in ranges.items()}
        low, high = RANGES["head_width"]  # redrawn within what the shaft allows
        low = max(low, HEAD_TO_SHAFT * values["shaft_width"])
        values["head_width"] = float(low + (high - low) * rng.random())
        head = heads[min(len(heads) - 1, int(rng.random() * len(heads)))]
        noise_seed = int(rng.integers(2**32))
        styles.append(ArrowStyle(**values, head=head, noise_seed=noise_seed))
    return styles


def check_heads(heads: object) -> tuple[str, ...]:
    """``heads`` as a tuple of distinct :data:`HEADS` names, at least one.

    Anything else raises :class:`SignError` naming the bad value.
    """
    if isinstance(heads, str) or not isinstance(heads, Sequence) or not heads:
        raise SignError(f"heads {heads!r} is not a non-empty list of {', '.join(HEADS)}")
    for head in heads:
        if head not in HEADS:
            raise SignError(f"head {head!r} is not one of {', '.join(HEADS)}")
    if len(set(heads)) < len(heads):
        raise SignError(f"heads {list(heads)!r} lists a head twice")
    return tuple(heads)


def check_shaft_width(shaft_width: object) -> tuple[float, float]:
    """``shaft_width`` as a ``(low, high)`` range of shaft widths inside ``RANGES["shaft_width"]``.

    ``low <= high``; anything else raises :class:`SignError` naming the bad value.
    """
    if isinstance(shaft_width, str) or not isinstance(shaft_width, Sequence):
        raise SignError(f"shaft_width {shaft_width!r} is not a [low, high] range")
    if len(shaft_width) != 2:
        raise SignError(f"shaft_width {list(shaft_width)!r} is not a [low, high] range")
    least, most = RANGES["shaft_width"]
    low, high = (
        check_number(f"shaft_width {name}", value, minimum=least, maximum=most, error=SignError)
        for name, value in zip(("low", "high"), shaft_width, strict=True)
    )
    if low > high:
        raise SignError(f"shaft_width [{low!r}, {high!r}] has its low end above its high end")
    return low, high


# -----------------------------------------------------------------------------
# Held-out styles


def draw_chevron(size: int = IMAGE_SIZE) -> Image.Image:
    """An open chevron ">" of two strokes, no shaft, pointing east (``LA``, white on transparent).

    The drawing ``benchmarks/bench_sign_transfer.py`` has always made (same
    pixels), so that its ``chevron`` rows stay comparable with earlier ones.
    """
    size = _check_size(size)
    image = Image.new("LA", (size, size), (0, 0))
    draw = ImageDraw.Draw(image)
    width = max(1, size // 8)
    draw.line([(size * 0.25, size * 0.1), (size * 0.8, size * 0.5)], fill=(255, 255), width=width)
    draw.line([(size * 0.8, size * 0.5), (size * 0.25, size * 0.9)], fill=(255, 255), width=width)
    return image


def draw_harpoon(size: int = IMAGE_SIZE, *, stroke: float = 0.1) -> Image.Image:
    """A shaft with a single barb on its north side, pointing east (``LA``, white on clear).

    ``stroke`` is the line's width as a share of the image side (the held-out
    ``harpoon``'s by default; up to :data:`MAX_STROKE`).
    """
    size = _check_size(size)
    stroke = _check_stroke("harpoon stroke", stroke)

    def paint(draw: ImageDraw.ImageDraw, at: Callable[[float, float], tuple[float, float]]) -> None:
        points = [at(0.08, 0.55), at(0.9, 0.55), at(0.6, 0.22)]
        draw.line(points, fill=255, width=_pixels(stroke, at), joint="curve")

    return _white(np.asarray(_supersampled(size, paint)))


def draw_outline(
    size: int = IMAGE_SIZE,
    *,
    hollow_head: bool = True,
    hollow_shaft: bool = True,
    scale: float = 1.0,
    stroke: float = 0.07,
) -> Image.Image:
    """The hollow contour of a block arrow (shaft and head), pointing east (``LA``).

    One closed stroke around the outline of the built-in arrow's kind of
    polygon; the inside stays transparent. The keywords draw its parts apart,
    to find what makes it hard to read (``benchmarks/bench_sign_transfer.py
    --outline-parts``): ``hollow_head=False`` fills the head, ``hollow_shaft=False``
    the shaft (each hollow part then keeps its own contour), ``scale`` (0.25 to 1)
    shrinks the drawing about the centre, ``stroke`` is the contour's width (a
    share of the image side before scaling, up to :data:`MAX_STROKE`). The
    defaults are the held-out ``outline``.
    """
    size = _check_size(size)
    scale = check_number("outline scale", scale, minimum=0.25, maximum=1.0, error=SignError)
    stroke = _check_stroke("outline stroke", stroke)
    contour = [(0.08, 0.38), (0.55, 0.38), (0.55, 0.14), (0.92, 0.5),
               (0.55, 0.86), (0.55, 0.62), (0.08, 0.62)]  # fmt: skip
    head = [(0.55, 0.14), (0.92, 0.5), (0.55, 0.86)]
    shaft = [(0.55, 0.62), (0.08, 0.62), (0.08, 0.38), (0.55, 0.38)]

    def paint(draw: ImageDraw.ImageDraw, at: Callable[[float, float], tuple[float, float]]) -> None:
        def scaled(points: list[tuple[float, float]]) -> list[tuple[float, float]]:
            return [at(0.5 + (x - 0.5) * scale, 0.5 + (y - 0.5) * scale) for x, y in points]

        width = _pixels(stroke * scale, at)
        if hollow_head and hollow_shaft:
            # Going round past the first corner again makes it a joint like the others.
            draw.line(scaled([*contour, *contour[:2]]), fill=255, width=width, joint="curve")
            return
        for part, hollow in ((head, hollow_head), (shaft, hollow_shaft)):
            if hollow:
                draw.line(scaled([*part, *part[:2]]), fill=255, width=width, joint="curve")
            else:
                draw.polygon(scaled(part), fill=255)

    return _white(np.asarray(_supersampled(size, paint)))


#: The held-out drawings by shape name, each ``size -> image`` (``LA``, pointing east).
HELD_OUT_STYLES: dict[str, Callable[[int], Image.Image]] = {
    "chevron": draw_chevron,
    "harpoon": draw_harpoon,
    "outline": draw_outline,
}


# -----------------------------------------------------------------------------
# Files and directions


def write_sign_styles(
    folder: str | os.PathLike,
    count: int,
    seed: int,
    heads: Sequence[str] = DEFAULT_HEADS,
    shaft_width: Sequence[float] = DEFAULT_SHAFT_WIDTH,
) -> dict[str, list[str]]:
    """Write the sign images: ``count`` training styles and the held-out styles, as PNG files.

    ``folder/training/arrowv0.png`` ... ``arrowv{count-1}.png`` are
    :func:`training_styles` ``(count, seed, heads, shaft_width)``; ``folder/held-out/chevron.png``,
    ``harpoon.png`` and ``outline.png`` the :data:`HELD_OUT_STYLES`, all
    :data:`IMAGE_SIZE` pixels square. Folders are created; files of the same
    names are overwritten. Registering a folder registers every PNG in it, so a
    folder that holds any other PNG (a larger earlier ``count``, say) is refused
    before anything is written: that image would join the group unnoticed.
    Returns the shape names of each group: ``{"training": [...], "held-out": [...]}``.
    """
    styles = training_styles(count, seed, heads, shaft_width)
    root = Path(folder).expanduser()
    groups: dict[str, dict[str, Callable[[], Image.Image]]] = {
        TRAINING_FOLDER: {
            f"{TRAINING_PREFIX}{index}": _bind(draw_arrow, style)
            for index, style in enumerate(styles)
        },
        HELD_OUT_FOLDER: {name: _bind(draw, IMAGE_SIZE) for name, draw in HELD_OUT_STYLES.items()},
    }
    for group, drawings in groups.items():
        sub = root / group
        if sub.is_dir():
            strays = sorted(p.name for p in sub.glob("*.png") if p.stem not in drawings)
            if strays:
                raise SignError(
                    f"folder '{sub}' already holds {strays[0]!r}, which is not one of the"
                    f" {len(drawings)} images to write (registering the folder would add it to"
                    " the group): write into a new folder or remove the other PNG files"
                )
    for group, drawings in groups.items():
        sub = root / group
        sub.mkdir(parents=True, exist_ok=True)
        for name, draw in drawings.items():
            draw().save(sub / f"{name}.png")
    return {group: list(drawings) for group, drawings in groups.items()}


def directional(shape: str, size: int = DIRECTIONAL_SIZE) -> bool:
    """Whether sign shape ``shape`` (built-in or registered custom) can carry a direction.

    True when its four direction frames (:func:`~amaze.maze.sign_images.sign_frames`
    at ``size`` pixels, lightness 1) are pairwise different: each pair differs by
    more than :data:`DIRECTIONAL_TOLERANCE` of the larger frame's ink, so that
    rounding in drawing a symmetric image does not count. A ``star`` (the same
    image every way) or an ``error`` cross cannot; arrows, and ``point`` (a dot
    off the centre, towards the direction), can. Unknown shapes raise
    :class:`~amaze.errors.SignError`.
    """
    frames = np.asarray(sign_frames(Sign(shape, 1.0), size), dtype=np.float64)
    ink = frames.sum(axis=(1, 2))
    for i in range(4):
        for j in range(i + 1, 4):
            difference = np.abs(frames[i] - frames[j]).sum()
            if difference <= DIRECTIONAL_TOLERANCE * max(ink[i], ink[j]):
                return False
    return True


# -----------------------------------------------------------------------------
# Drawing helpers


def _check_size(size: object) -> int:
    return check_integer(
        "sign image size", size, minimum=MIN_IMAGE_SIZE, maximum=MAX_IMAGE_SIZE, error=SignError
    )


def _supersampled(
    size: int,
    paint: Callable[[ImageDraw.ImageDraw, Callable[[float, float], tuple[float, float]]], None],
) -> Image.Image:
    """A ``size x size`` gray mask that ``paint`` draws in unit-square coordinates, antialiased.

    ``paint`` gets the drawing and a function mapping unit coordinates (x to
    the east, y to the south) to pixels of a canvas :data:`_SUPERSAMPLE` times
    larger, whose pixel blocks are then averaged.
    """
    side = size * _SUPERSAMPLE
    mask = Image.new("L", (side, side), 0)
    paint(ImageDraw.Draw(mask), lambda x, y: (x * side, y * side))
    return mask.reduce(_SUPERSAMPLE)


def _check_stroke(name: str, stroke: float) -> float:
    """``stroke``, a share of the image side in (0, :data:`MAX_STROKE`], or a SignError."""
    return check_number(
        name, stroke, minimum=0.0, strict_minimum=True, maximum=MAX_STROKE, error=SignError
    )


def _pixels(share: float, at: Callable[[float, float], tuple[float, float]]) -> int:
    """A stroke width of ``share`` of the image side, in canvas pixels (at least 1)."""
    return max(1, math.floor(at(share, 0.0)[0] + 0.5))


def _white(alpha: np.ndarray) -> Image.Image:
    """An ``LA`` image, white, with ``alpha`` (uint8) as its alpha channel."""
    mask = Image.fromarray(np.ascontiguousarray(alpha, dtype=np.uint8))
    return Image.merge("LA", (Image.new("L", mask.size, 255), mask))


def _bind(draw: Callable, argument: object) -> Callable[[], Image.Image]:
    return lambda: draw(argument)
