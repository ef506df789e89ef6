"""Images of signs, without Qt.

Hybrid and continuous agents see a sign as a small gray image inside their
``v x v`` cell observation (size ``v - 2``, typically 9 or 13, see
``docs/reference-behaviour.md`` §5.2); the PNG maze renderer draws the same images
larger. :func:`sign_frames` returns the four orientations of a sign at a given
size: frame ``d`` (0 = east, 1 = north, 2 = west, 3 = south) is the sign
pointing in direction ``d``, with row 0 = north (top) and column 0 = west.

Built-in shapes
    The reference library draws them with Qt. To give agents exactly the
    reference's observations, the bitmaps Qt produces at every size from 3 to
    64 are stored in ``amaze/data/sign_rasters.npz`` (made by
    ``tools/make_sign_rasters.py`` with the reference itself) as *coverage
    levels*: 255 where the shape is drawn, 0 elsewhere and, below size 10,
    partial levels for strokes thinner than a pixel. A pixel's gray level is
    the pen gray level ``floor(255 * value + 0.5)`` (:func:`pen_gray_level`)
    where covered, and a small stored table (Qt's premultiplied-alpha rounding)
    for partial coverage. Larger sizes are drawn here with numpy from the
    reference's shape definitions (:func:`draw_builtin_mask`); they look like
    Qt's drawings but are not guaranteed to be pixel-identical.

Custom shapes
    A registered PNG (:func:`amaze.maze.signs.register_custom_signs`) is converted
    to gray levels (alpha composited on black, then Pillow's ``L`` luma
    conversion) and resized smoothly (bilinear) to the requested size. A
    square image is the sign pointing east, rotated for the other directions;
    an image four squares high holds the frames E, N, W, S from top to bottom,
    its top row the north row of each frame. Any other shape raises
    :class:`~amaze.errors.SignError`. The sign's lightness scales the
    image's gray levels (pen gray level ``g``: ``floor(k * g / 255 + 0.5)``),
    so lightness 1 shows the image as it is and clues, lures and traps of one
    custom shape differ as built-in ones do. The reference ignores the
    lightness of custom images, which makes those three look alike.

Values are ``float32``. The differences from the reference are listed in
``docs/reference-behaviour.md`` §10. Results are cached in memory and returned
read-only; importing this module reads no file (the stored bitmaps are loaded
on first use).
"""

from __future__ import annotations

import functools
import math
import operator
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np

from amaze.errors import SignError
from amaze.maze.signs import BUILTIN_SHAPES, Sign, custom_sign_path

#: Smallest image size (the reference refuses smaller ones as well).
MIN_SIZE = 3

_RASTER_RESOURCE = ("data", "sign_rasters.npz")
_PEN_WIDTH = 0.1
_CACHE_SIZE = 512


# -----------------------------------------------------------------------------
# Public API


def sign_frames(sign: Sign, size: int) -> np.ndarray:
    """The four orientations of ``sign`` as ``size x size`` gray images.

    Returns a read-only ``float32`` array of shape ``(4, size, size)`` with
    values ``k / 255`` in [0, 1] (0 = background): frame ``d`` (0 = E, 1 = N,
    2 = W, 3 = S) shows the sign pointing in direction ``d``, row 0 = north,
    column 0 = west. This is what an image-based agent sees inside a cell.

    :raises SignError: if ``size`` is not an integer >= 3, the shape is unknown,
        or a custom image cannot be used.
    """
    return _frames_float(*_cache_key(sign, size))


def sign_frames_u8(sign: Sign, size: int) -> np.ndarray:
    """:func:`sign_frames` as ``uint8`` gray levels ``k`` (``k = round(255 * x)``), read-only."""
    return _frames_u8(*_cache_key(sign, size))


def pen_gray_level(value: float) -> int:
    """The 8-bit gray level of a built-in sign of lightness ``value``.

    ``floor(255 * value + 0.5)``: what Qt's ``QColor.fromHslF(0, 0, value)``
    gives once reduced to 8 bits (0.5 -> 128, 0.25 -> 64, 0.75 -> 191).
    """
    return math.floor(255 * float(value) + 0.5)


def draw_builtin_mask(shape: str, size: int) -> np.ndarray:
    """Draw a built-in shape with numpy: boolean ``(4, size, size)``, frames as in
    :func:`sign_frames`.

    Each pixel is set when its centre lies inside the shape (filled paths,
    strokes of width 0.1 with square caps, discs), the shapes being the
    reference's definitions in the unit square. This is how sizes beyond the
    stored reference bitmaps are made; at small sizes strokes thinner than a
    pixel may vanish (the stored bitmaps cover those sizes).
    """
    size = _check_size(size)
    if shape not in BUILTIN_SHAPES:
        raise SignError(f"'{shape}' is not a built-in sign shape ({', '.join(BUILTIN_SHAPES)})")
    return _draw_builtin(shape, size).copy()


def clear_cache() -> None:
    """Forget the cached images (the stored bitmaps stay loaded)."""
    _frames_u8.cache_clear()
    _frames_float.cache_clear()


# -----------------------------------------------------------------------------
# Cache keys and dispatch


def _check_size(size: object) -> int:
    if isinstance(size, bool):
        raise SignError(f"sign image size must be an integer, not {size!r}")
    try:
        value = operator.index(size)
    except TypeError:
        raise SignError(f"sign image size must be an integer, not {size!r}") from None
    if value < MIN_SIZE:
        raise SignError(f"sign image size {value} is too small (minimum {MIN_SIZE})")
    return value


def _cache_key(sign: Sign, size: int) -> tuple[str, int, int, str | None, int]:
    """``(shape, pen gray level, size, custom file, its mtime)``: what an image depends on."""
    if not isinstance(sign, Sign):
        raise SignError(f"expected a Sign, not {sign!r}")
    size = _check_size(size)
    path = custom_sign_path(sign.shape)
    if path is not None:
        try:
            mtime = path.stat().st_mtime_ns
        except OSError as error:
            raise SignError(f"custom sign image '{path}' cannot be read: {error}") from None
        return sign.shape, pen_gray_level(sign.value), size, str(path), mtime
    if sign.shape not in BUILTIN_SHAPES:
        raise SignError(
            f"unknown sign shape '{sign.shape}' (is its custom image still registered?)"
        )
    return sign.shape, pen_gray_level(sign.value), size, None, 0


@functools.lru_cache(maxsize=_CACHE_SIZE)
def _frames_u8(shape: str, gray: int, size: int, path: str | None, mtime: int) -> np.ndarray:
    if path is not None:
        frames = _lit(_custom_frames(Path(path), size), gray)
    else:
        frames = _builtin_frames(shape, gray, size)
    frames = np.ascontiguousarray(frames, dtype=np.uint8)
    frames.flags.writeable = False
    return frames


@functools.lru_cache(maxsize=_CACHE_SIZE)
def _frames_float(shape: str, gray: int, size: int, path: str | None, mtime: int) -> np.ndarray:
    frames = _frames_u8(shape, gray, size, path, mtime).astype(np.float32) / np.float32(255)
    frames.flags.writeable = False
    return frames


# -----------------------------------------------------------------------------
# Built-in shapes: stored reference bitmaps


@dataclass(frozen=True)
class _RasterTable:
    """The reference's built-in bitmaps, as stored by ``tools/make_sign_rasters.py``."""

    sizes: range
    partial_sizes: range
    masks: dict[str, np.ndarray]  # packed bits, all sizes
    coverages: dict[str, np.ndarray]  # uint8 levels, partial sizes only
    lut: np.ndarray  # (256, 256) uint8: gray level for [coverage, pen gray]

    @staticmethod
    def _offset(size: int, first: int) -> int:
        return sum(4 * s * s for s in range(first, size))

    def coverage(self, shape: str, size: int) -> np.ndarray | None:
        """Coverage levels ``(4, size, size)`` (0..255), or ``None`` if not stored."""
        count = 4 * size * size
        if size in self.partial_sizes:
            start = self._offset(size, self.partial_sizes.start)
            flat = self.coverages[shape][start : start + count]
            return flat.reshape(4, size, size)
        if size in self.sizes:
            start = self._offset(size, self.sizes.start)
            bits = np.unpackbits(self.masks[shape], count=start + count)[start:]
            return (bits * np.uint8(255)).reshape(4, size, size)
        return None


@functools.cache
def _raster_table() -> _RasterTable:
    resource = resources.files("amaze").joinpath(*_RASTER_RESOURCE)
    with resource.open("rb") as file, np.load(file, allow_pickle=False) as data:
        arrays = {name: data[name] for name in data.files}
    sizes = arrays["sizes"].astype(int)
    partial = arrays["partial_sizes"].astype(int)
    lut = np.zeros((256, 256), dtype=np.uint8)
    lut[arrays["lut_levels"].astype(int)] = arrays["lut"]
    return _RasterTable(
        sizes=range(int(sizes[0]), int(sizes[-1]) + 1),
        partial_sizes=range(int(partial[0]), int(partial[-1]) + 1) if len(partial) else range(0),
        masks={s: arrays[f"mask_{s}"] for s in BUILTIN_SHAPES},
        coverages={s: arrays[f"coverage_{s}"] for s in BUILTIN_SHAPES},
        lut=lut,
    )


def _builtin_frames(shape: str, gray: int, size: int) -> np.ndarray:
    table = _raster_table()
    coverage = table.coverage(shape, size)
    if coverage is None:
        coverage = _draw_builtin(shape, size).astype(np.uint8) * np.uint8(255)
    return table.lut[coverage, gray]


# -----------------------------------------------------------------------------
# Built-in shapes: own drawing
#
# Coordinates are the reference's: the unit square, x to the right and y
# *down* (screen), the east-pointing sign. Like the reference, the frame for
# direction d is the east frame turned d quarter turns clockwise on screen and
# then flipped vertically, which makes it point towards d with row 0 = north.

_Point = tuple[float, float]


def _rotate(points: list[_Point], degrees: float, centre: _Point = (0.5, 0.5)) -> list[_Point]:
    """Rotate clockwise on screen (Qt's ``rotate`` with y pointing down)."""
    angle = math.radians(degrees)
    c, s = math.cos(angle), math.sin(angle)
    cx, cy = centre
    return [(cx + (x - cx) * c - (y - cy) * s, cy + (x - cx) * s + (y - cy) * c) for x, y in points]


class _Canvas:
    """A boolean image sampled at pixel centres; shapes are given in unit-square coordinates.

    A pixel is inside a filled polygon when its centre is, centres on an edge
    counting for the polygon's bottom and right edges (on screen) but not for
    its top and left ones; vertices are first rounded to 1/64 pixel. This is
    the rule that reproduces Qt's non-antialiased fills most often.
    """

    def __init__(self, size: int) -> None:
        self.size = size
        centres = np.arange(size) + 0.5
        self.x, self.y = np.meshgrid(centres, centres)  # pixels; [row, col], row 0 = top of screen
        self.mask = np.zeros((size, size), dtype=bool)

    def _pixels(self, x: float, y: float) -> _Point:
        return round(x * self.size * 64) / 64, round(y * self.size * 64) / 64

    def polygon_inside(self, points: list[_Point]) -> np.ndarray:
        """Even-odd rule (Qt's default fill rule)."""
        inside = np.zeros_like(self.mask)
        corners = [self._pixels(x, y) for x, y in points]
        for (x1, y1), (x2, y2) in zip(corners, corners[1:] + corners[:1], strict=True):
            if y1 == y2:
                continue
            crosses = (y1 >= self.y) != (y2 >= self.y)
            x_cross = x1 + (self.y - y1) * (x2 - x1) / (y2 - y1)
            inside ^= crosses & (self.x <= x_cross)
        return inside

    def fill_polygon(self, points: list[_Point]) -> None:
        self.mask |= self.polygon_inside(points)

    def stroke(self, points: list[_Point], closed: bool = False) -> None:
        """A pen line through ``points``: square caps when open, bevel joins."""
        half = _PEN_WIDTH / 2
        ends = points[1:] + points[:1] if closed else points[1:]
        segments = list(zip(points[: len(ends)], ends, strict=True))
        normals = []
        for (x1, y1), (x2, y2) in segments:
            length = math.hypot(x2 - x1, y2 - y1)
            dx, dy = (x2 - x1) / length * half, (y2 - y1) / length * half
            normals.append((-dy, dx))
            cap = 0.0 if closed else 1.0
            a = (x1 - cap * dx, y1 - cap * dy)
            b = (x2 + cap * dx, y2 + cap * dy)
            self.fill_polygon(
                [
                    (a[0] - dy, a[1] + dx),
                    (b[0] - dy, b[1] + dx),
                    (b[0] + dy, b[1] - dx),
                    (a[0] + dy, a[1] - dx),
                ]
            )
        joints = range(len(segments)) if closed else range(1, len(segments))
        for i in joints:
            (vx, vy), (n1x, n1y), (n2x, n2y) = segments[i][0], normals[i - 1], normals[i]
            for sign in (1, -1):
                self.fill_polygon(
                    [
                        (vx, vy),
                        (vx + sign * n1x, vy + sign * n1y),
                        (vx + sign * n2x, vy + sign * n2y),
                    ]
                )

    def _distance(self, centre: _Point) -> np.ndarray:
        """Distance of the pixel centres to ``centre``, in units of the square's side."""
        return np.hypot(self.x / self.size - centre[0], self.y / self.size - centre[1])

    def fill_disc(self, centre: _Point, radius: float) -> None:
        self.mask |= self._distance(centre) <= radius

    def stroke_circle(self, centre: _Point, radius: float) -> None:
        self.mask |= np.abs(self._distance(centre) - radius) <= _PEN_WIDTH / 2

    def fill_rect(self, x: float, y: float, width: float, height: float) -> None:
        self.fill_polygon([(x, y), (x + width, y), (x + width, y + height), (x, y + height)])


_ARROW = [
    (0.0, 0.425),
    (0.0, 0.575),
    (0.6, 0.575),
    (0.6, 0.8),
    (1.0, 0.5),
    (0.6, 0.2),
    (0.6, 0.425),
]
_ALIEN = [
    (0.0, 0.0),
    (0.4, 0.0),
    (1.0, 0.5),
    (0.4, 1.0),
    (0.0, 1.0),
    (0.0, 0.625),
    (0.4, 0.75),
    (0.6, 0.5),
    (0.4, 0.25),
    (0.0, 0.375),
]
_RARROW = [
    (0.0, 0.4),
    (0.0, 0.6),
    (0.4, 0.6),
    (0.6, 0.9),
    (0.8, 1.0),
    (1.0, 1.0),
    (1.0, 0.8),
    (0.7, 0.7),
    (0.6, 0.5),
    (0.7, 0.3),
    (1.0, 0.2),
    (1.0, 0.0),
    (0.8, 0.0),
    (0.6, 0.1),
    (0.4, 0.4),
]
_STAR_RAY = [
    (0.5, 0.55),
    (0.85, 0.55),
    (0.85, 0.6),
    (1.0, 0.5),
    (0.85, 0.4),
    (0.85, 0.45),
    (0.5, 0.45),
]


def _draw_east(shape: str, canvas: _Canvas) -> None:
    """Draw the east-pointing frame of a square built-in shape (screen coordinates)."""
    if shape == "arrow":
        canvas.fill_polygon(_ARROW)
    elif shape == "alien":
        canvas.fill_polygon(_ALIEN)
    elif shape == "rarrow":
        canvas.fill_polygon(_RARROW)
    elif shape == "point":
        # Qt draws a wide-pen point as a line 1/63 long (logical units) with square caps.
        canvas.stroke([(0.75, 0.5), (0.75 + 1 / 63, 0.5)])
    elif shape == "warning":
        canvas.stroke([(0.05, 0.05), (0.95, 0.5), (0.05, 0.95)], closed=True)
        canvas.fill_rect(0.3, 0.45, 0.4, 0.1)
        canvas.fill_disc((0.2, 0.5), 0.1)
    elif shape == "star":
        canvas.stroke_circle((0.5, 0.5), 0.25)
        for i in range(8):
            canvas.fill_polygon(_rotate(_STAR_RAY, 45 * i))
    elif shape == "error":
        canvas.stroke([(0.0, 0.0), (1.0, 1.0)])
        canvas.stroke([(0.0, 1.0), (1.0, 0.0)])
    else:  # pragma: no cover - guarded by the callers
        raise SignError(f"no drawing for shape '{shape}'")


def _draw_forbidden(canvas: _Canvas, direction: int) -> None:
    """One frame of ``forbidden``: a barred circle with a tick towards ``direction`` (on screen)."""
    canvas.stroke_circle((0.5, 0.5), 0.25)
    canvas.stroke(_rotate([(0.25, 0.5), (0.75, 0.5)], -45))
    canvas.stroke(_rotate([(0.75, 0.5), (0.9, 0.5)], 90 * direction))


@functools.lru_cache(maxsize=64)
def _draw_builtin(shape: str, size: int) -> np.ndarray:
    if shape == "forbidden":
        screen = []
        for direction in range(4):
            canvas = _Canvas(size)
            _draw_forbidden(canvas, direction)
            screen.append(canvas.mask)
    else:
        canvas = _Canvas(size)
        _draw_east(shape, canvas)
        screen = [np.rot90(canvas.mask, -d) for d in range(4)]
    frames = np.stack([np.flipud(frame) for frame in screen])
    frames.flags.writeable = False
    return frames


# -----------------------------------------------------------------------------
# Custom shapes


def _custom_frames(path: Path, size: int) -> np.ndarray:
    from PIL import Image, UnidentifiedImageError

    try:
        with Image.open(path) as image:
            image.load()
            gray = _to_gray(image)
    except (OSError, ValueError, UnidentifiedImageError) as error:
        raise SignError(f"custom sign image '{path}' cannot be read: {error}") from None
    width, height = gray.size
    if height == width:
        count = 1
    elif height == 4 * width:
        count = 4
    else:
        raise SignError(
            f"custom sign image '{path}' is {width}x{height} pixels: expected a square"
            " or four squares stacked vertically (height = 4 x width)"
        )
    frames = [
        np.asarray(
            gray.crop((0, i * width, width, (i + 1) * width)).resize(
                (size, size), Image.Resampling.BILINEAR
            ),
            dtype=np.uint8,
        )
        for i in range(count)
    ]
    if count == 1:
        frames = [np.rot90(frames[0], d) for d in range(4)]
    return np.stack(frames)


def _lit(frames: np.ndarray, gray: int) -> np.ndarray:
    """Gray levels ``frames`` (uint8) scaled by pen gray level ``gray``, rounded half up."""
    levels = frames.astype(np.int64)
    return ((2 * levels * gray + 255) // 510).astype(np.uint8)


def _to_gray(image):  # PIL.Image.Image -> PIL.Image.Image (mode 'L')
    """Gray levels of any PNG: transparency composited on black, colours as luma."""
    from PIL import Image

    if image.mode.startswith("I"):  # 16-bit gray: keep the 8 most significant bits
        levels = np.asarray(image, dtype=np.int64)
        return Image.fromarray(np.clip(levels >> 8, 0, 255).astype(np.uint8), mode="L")
    rgba = image.convert("RGBA")
    black = Image.new("RGBA", rgba.size, (0, 0, 0, 255))
    return Image.alpha_composite(black, rgba).convert("L")
