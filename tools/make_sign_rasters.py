"""Build ``amaze/data/sign_rasters.npz``: the reference's built-in sign bitmaps.

The reference library (amaze-benchmarker 1.0) draws its built-in sign shapes
with Qt (non-antialiased ``QPainterPath``, pen width 0.1 of the unit square).
:mod:`amaze.maze.sign_images` must reproduce those pixels exactly without Qt, so
this script renders every built-in shape at every size from 3 to 64 with the
reference itself and stores the result as package data.

Run it with a Python environment that has the *reference* library and PyQt5
(not this project's environment: both packages are called ``amaze``)::

    python -m venv /tmp/refvenv
    /tmp/refvenv/bin/pip install amaze-benchmarker==1.0
    /tmp/refvenv/bin/python tools/make_sign_rasters.py [--out amaze/data/sign_rasters.npz]

It runs headless (``QT_QPA_PLATFORM=offscreen``), disables the reference's file
cache and works from a temporary directory (importing the reference creates
``./resources/cache``). It takes well under a minute.

What the reference produces, and hence what is stored
-----------------------------------------------------
``amaze.misc.resources.np_images(signs, size)`` gives, per sign, four frames
(directions E, N, W, S) of ``size x size`` gray levels ``k / 255``. The script
checks (and aborts if any check fails) that:

* the pen gray level of a lightness ``v`` is ``floor(255 * v + 0.5)``
  (Qt's ``QColor.fromHslF(0, 0, v)`` through 16-bit channels: round-half-up);
* every pixel's gray level is a function of two numbers only: its *coverage
  level* (the gray level it has at lightness 1) and the pen gray level. Where
  the pen is at least one pixel wide (size >= 10) coverage is all or nothing,
  so the shape's pixel mask does not depend on the lightness; thinner pens
  (sizes 3..9, for the stroked shapes ``error``, ``forbidden``, ``point``,
  ``star``, ``warning``) are drawn with a partial alpha (about the pen width in
  pixels, more where two strokes overlap), and the gray level is then
  ``lut[coverage, pen gray]``, a table with Qt's premultiplied-alpha rounding
  that is taken from the reference for every pen gray level.

The ``.npz`` (``numpy.savez_compressed``, no pickled objects) holds:

``sizes``
    int16, the sizes covered (3..64, contiguous).
``partial_sizes``
    int16, the leading sizes for which coverage levels are stored in full.
``mask_<shape>``
    uint8, ``np.packbits`` of the concatenated, C-ordered boolean arrays
    ``coverage > 0`` of shape ``(4, size, size)`` for every size of ``sizes``.
``coverage_<shape>``
    uint8, the concatenated coverage levels ``(4, size, size)`` for every size
    of ``partial_sizes`` (for larger sizes coverage is 255 inside the mask).
``lut_levels``, ``lut``
    uint8 ``(L,)`` and ``(L, 256)``: the gray level of a pixel with coverage
    ``lut_levels[i]`` drawn with pen gray level ``g`` is ``lut[i, g]``.
``source``
    str, the versions of the software that drew the bitmaps.

Frames are exactly what ``np_images`` returns: frame ``d`` points in direction
``d`` with row 0 = north (the reference's final ``np.flipud`` included).
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

SIZES = range(3, 65)
DEFAULT_OUTPUT = Path(__file__).resolve().parent.parent / "amaze" / "data" / "sign_rasters.npz"


#: Draws a built-in sign with the reference: ``render(shape, lightness, size)``
#: is its four frames ``(4, size, size)`` as gray levels 0..255.
Render = Callable[[str, float, int], np.ndarray]


def pen_gray(value: float) -> int:
    """Gray level (0..255) of the pen used for a sign of lightness ``value``."""
    return int(np.floor(255 * value + 0.5))


def main(argv: list[str] | None = None) -> int:
    """Check the reference's drawing rules (steps 1 to 3) and write the rasters (step 4)."""
    output = _parse_output(argv)
    _enter_headless_workspace()

    import PyQt5.QtCore
    from amaze.misc import resources
    from PyQt5.QtGui import QColor

    reference_version = _reference_version()
    render = _reference_renderer(resources)
    rng = np.random.default_rng(0)
    check_pen_gray(render, QColor, rng)
    shapes = sorted(resources.builtins())
    coverage, partial = coverage_levels(render, shapes)
    levels, lut = gray_level_table(render, shapes, coverage, partial, rng)
    source = (
        f"amaze-benchmarker {reference_version}, PyQt5 {PyQt5.QtCore.PYQT_VERSION_STR},"
        f" Qt {PyQt5.QtCore.QT_VERSION_STR}: amaze.misc.resources.np_images"
    )
    save_rasters(output, shapes, coverage, partial, levels, lut, source)
    return 0


def _parse_output(argv: list[str] | None) -> Path:
    """The ``.npz`` file to write (``--out``), as an absolute path: the script changes folder."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", type=Path, default=DEFAULT_OUTPUT, help="output .npz file")
    args = parser.parse_args(argv)
    return args.out.resolve()


def _enter_headless_workspace() -> None:
    """Run Qt headless, disable the reference's file cache, work from a temporary folder.

    Importing the reference creates ``./resources/cache``: the temporary
    folder keeps it out of the caller's folder.
    """
    os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
    os.environ["KGD_AMAZE_NOCACHE"] = "1"
    os.chdir(tempfile.mkdtemp(prefix="sign_rasters_"))


def _reference_version() -> str:
    """The installed amaze-benchmarker's version, with a warning if it is not 1.0 (reproduced)."""
    try:
        from importlib.metadata import version

        reference_version = version("amaze-benchmarker")
    except Exception:  # pragma: no cover - informative only
        reference_version = "unknown"
    if not reference_version.startswith("1.0"):
        print(
            f"warning: expected amaze-benchmarker 1.0, found {reference_version}", file=sys.stderr
        )
    return reference_version


def _reference_renderer(resources: Any) -> Render:
    """:data:`Render` through the reference's ``resources.np_images`` (frames checked)."""

    def render(shape: str, value: float, size: int) -> np.ndarray:
        frames = resources.np_images([resources.Sign(shape, value)], size)[0]
        out = np.rint(np.asarray(frames, dtype=np.float64) * 255)
        assert out.shape == (4, size, size) and out.min() >= 0 and out.max() <= 255
        return out.astype(np.uint8)

    return render


def check_pen_gray(render: Render, qcolor: Any, rng: np.random.Generator) -> None:
    """Step 1: check that lightness ``v`` gives the pen gray level :func:`pen_gray` ``(v)``.

    Checked on Qt's colour conversion (``QColor.fromHslF``) for many values,
    the half points and their neighbours included, and on drawn signs for a
    sample of them; aborts (``AssertionError``) otherwise.
    """
    half_points = (np.arange(255) + 0.5) / 255
    values = np.concatenate(
        [
            np.linspace(0.001, 1, 1000),
            np.arange(1, 256) / 255,
            half_points,
            half_points - 1e-6,
            half_points + 1e-6,
            rng.uniform(0, 1, 5000),
        ]
    )
    values = values[(values > 0) & (values <= 1)]
    for v in values:
        qt_gray = qcolor.fromHslF(0, 0, float(v)).red()
        assert qt_gray == pen_gray(v), (v, qt_gray, pen_gray(v))
    for v in values[::25]:
        assert render("arrow", float(v), 5).max() == pen_gray(v), v
    print(f"pen gray level = floor(255 * v + 0.5): checked on {len(values)} lightness values")


def coverage_levels(
    render: Render, shapes: list[str]
) -> tuple[dict[str, dict[int, np.ndarray]], list[int]]:
    """Step 2: the coverage levels (lightness 1) of every shape at every size.

    Also returns the sizes at which some pixel is partly covered (neither 0
    nor 255), checked to be the leading sizes 3..n: coverage is stored in full
    for those only.
    """
    coverage = {shape: {size: render(shape, 1.0, size) for size in SIZES} for shape in shapes}
    partial = sorted(
        size
        for size in SIZES
        if any(np.isin(coverage[s][size], (0, 255), invert=True).any() for s in shapes)
    )
    assert partial == list(range(SIZES[0], partial[-1] + 1)), partial
    print(f"partial coverage levels at sizes {partial[0]}..{partial[-1]}")
    return coverage, partial


def _check_gray_levels(
    render: Render,
    coverage: dict[str, dict[int, np.ndarray]],
    table: dict[tuple[int, int], int],
    shape: str,
    value: float,
    size: int,
) -> None:
    """Check that ``shape`` at lightness ``value`` and ``size`` fits ``table``, adding to it.

    Every pixel of one coverage level must have one gray level, the same one
    (for that pen gray level) as everywhere else: the ``(coverage, pen gray)``
    pair determines the pixel.
    """
    gray = pen_gray(value)
    image = render(shape, value, size)
    base = coverage[shape][size]
    for level in np.unique(base):
        seen = np.unique(image[base == level])
        assert len(seen) == 1, (shape, value, size, level, seen)
        known = table.setdefault((int(level), gray), int(seen[0]))
        assert known == seen[0], (shape, value, size, level, known, seen)


def gray_level_table(
    render: Render,
    shapes: list[str],
    coverage: dict[str, dict[int, np.ndarray]],
    partial: list[int],
    rng: np.random.Generator,
) -> tuple[list[int], np.ndarray]:
    """Step 3: gray level = ``lut[coverage, pen gray]``, checked; the levels and the table.

    Every pen gray level is drawn at the small sizes (and a bit beyond),
    sampled lightness values at every size; the table must be complete for
    every coverage level, with full coverage giving the pen gray level itself.
    """
    table: dict[tuple[int, int], int] = {}
    for shape in shapes:
        for size in range(SIZES[0], partial[-1] + 3):
            for gray in range(1, 256):
                _check_gray_levels(render, coverage, table, shape, gray / 255, size)
        for size in SIZES:
            for value in (0.001, 0.003, 0.01, 0.1, 0.25, 0.3333, 0.5, 0.75, 0.999):
                _check_gray_levels(render, coverage, table, shape, value, size)
        for value in rng.uniform(0, 1, 60):
            _check_gray_levels(render, coverage, table, shape, float(value), int(rng.choice(SIZES)))
    levels = sorted({level for level, _ in table})
    lut = np.zeros((len(levels), 256), dtype=np.uint8)
    for (level, gray), out in table.items():
        lut[levels.index(level), gray] = out
    full = lut[levels.index(255)]
    assert (full == np.arange(256)).all(), "fully covered pixels must have the pen gray level"
    assert (lut[levels.index(0)] == 0).all()
    for level in levels:
        grays = {g for lv, g in table if lv == level}
        assert grays >= set(range(1, 256)), f"pen gray levels missing for coverage {level}"
    print(f"gray level = lut[coverage, pen gray] for coverage levels {levels}")
    return levels, lut


def save_rasters(
    output: Path,
    shapes: list[str],
    coverage: dict[str, dict[int, np.ndarray]],
    partial: list[int],
    levels: list[int],
    lut: np.ndarray,
    source: str,
) -> None:
    """Step 4: write the ``.npz`` described in the module docstring to ``output``."""
    arrays: dict[str, np.ndarray] = {
        "sizes": np.asarray(list(SIZES), dtype=np.int16),
        "partial_sizes": np.asarray(partial, dtype=np.int16),
        "lut_levels": np.asarray(levels, dtype=np.uint8),
        "lut": lut,
        "source": np.asarray(source),
    }
    for shape in shapes:
        masks = np.concatenate([(coverage[shape][size] > 0).ravel() for size in SIZES])
        arrays[f"mask_{shape}"] = np.packbits(masks)
        arrays[f"coverage_{shape}"] = np.concatenate(
            [coverage[shape][size].ravel() for size in partial]
        )
    output.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(output, **arrays)
    print(f"wrote {output} ({output.stat().st_size} bytes)")


if __name__ == "__main__":
    sys.exit(main())
