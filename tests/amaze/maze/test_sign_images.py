"""Sign images: reference-identical built-ins, own drawing for any size, custom PNG files."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from amaze.errors import SignError
from amaze.maze.sign_images import (
    clear_cache,
    draw_builtin_mask,
    pen_gray_level,
    sign_frames,
    sign_frames_u8,
)
from amaze.maze.signs import BUILTIN_SHAPES, Sign, clear_custom_signs, register_custom_signs
from tests.amaze.conftest import load_reference

REFERENCE = load_reference()
SIGN_IMAGES = REFERENCE["sign_images_u8"]
RASTER_FILE = Path(__file__).parents[3] / "amaze" / "data" / "sign_rasters.npz"

# Direction d of a frame as a (row, column) step, row 0 = north: E, N, W, S.
STEPS = [(0, 1), (-1, 0), (0, -1), (1, 0)]


def centroid_offset(image: np.ndarray) -> np.ndarray:
    """(row, column) of the image's centre of mass, relative to the image centre."""
    rows, cols = np.nonzero(image)
    weights = image[rows, cols].astype(float)
    centre = (image.shape[0] - 1) / 2
    return np.array([np.average(rows, weights=weights), np.average(cols, weights=weights)]) - centre


# -----------------------------------------------------------------------------
# Built-ins: exactly the reference's pixels


@pytest.mark.parametrize("key", sorted(SIGN_IMAGES))
def test_builtin_frames_match_reference(key):
    shape, value, size = key.split("|")
    expected = np.array(SIGN_IMAGES[key], dtype=np.uint8)
    actual = sign_frames_u8(Sign(shape, float(value)), int(size))
    assert actual.shape == expected.shape == (4, int(size), int(size))
    np.testing.assert_array_equal(actual, expected)


@pytest.mark.parametrize("run", sorted(REFERENCE["image_runs"]))
def test_observation_interiors_are_sign_frames(run):
    """In the reference's H15/H11 runs, every non-empty cell interior is a sign frame."""
    observations = np.array(REFERENCE["image_runs"][run]["observations_u8"], dtype=np.uint8)
    vision = observations.shape[-1]
    # M10_10x10_C1_l.2_L.25_t.5_T.5: arrow clues (1), lures (.25) and traps (.5).
    frames = [
        frame
        for value in (1.0, 0.25, 0.5)
        for frame in sign_frames_u8(Sign("arrow", value), vision - 2)
    ]
    interiors = [obs[1:-1, 1:-1] for obs in observations if obs[1:-1, 1:-1].any()]
    assert interiors, "the run should see some signs"
    for interior in interiors:
        assert any(np.array_equal(interior, frame) for frame in frames)


def test_pen_gray_level():
    assert [pen_gray_level(v) for v in (1.0, 0.5, 0.25, 0.75, 0.2, 1 / 255)] == [
        255,
        128,
        64,
        191,
        51,
        1,
    ]
    assert pen_gray_level(0.5 / 255) == 1  # round half up
    assert pen_gray_level(0.49 / 255) == 0


@pytest.mark.parametrize("size", [5, 9, 13, 40, 100])
@pytest.mark.parametrize("value", [1.0, 0.75, 0.5, 0.3, 0.25, 0.01])
def test_lightness_only_changes_the_gray_level(size, value):
    """Fully drawn pixels have the pen gray level; the shape does not depend on the value."""
    full = sign_frames_u8(Sign("arrow", 1.0), size)
    image = sign_frames_u8(Sign("arrow", value), size)
    assert set(np.unique(image[full == 255])) == {pen_gray_level(value)}
    assert not image[full == 0].any()


def test_thin_strokes_are_partially_covered():
    """Below size 10 the reference draws pen strokes thinner than a pixel with a partial alpha."""
    error = sign_frames_u8(Sign("error", 1.0), 9)
    assert set(np.unique(error)) == {0, 229}
    dim = sign_frames_u8(Sign("error", 0.25), 9)
    assert set(np.unique(dim)) == {0, 57}
    assert ((error > 0) == (dim > 0)).all()


def test_types_shapes_and_read_only():
    sign = Sign("arrow", 0.5)
    u8 = sign_frames_u8(sign, 13)
    frames = sign_frames(sign, 13)
    assert u8.dtype == np.uint8 and u8.shape == (4, 13, 13)
    assert frames.dtype == np.float32 and frames.shape == (4, 13, 13)
    assert 0 <= frames.min() and frames.max() <= 1
    np.testing.assert_array_equal(np.rint(frames * 255).astype(np.uint8), u8)
    np.testing.assert_allclose(frames.max(), 128 / 255)
    for array in (u8, frames):
        assert not array.flags.writeable
        with pytest.raises(ValueError):
            array[0, 0, 0] = 1
    assert sign_frames(sign, 13) is frames  # cached


@pytest.mark.parametrize("size", [9, 13, 32, 100])
def test_arrow_frames_point_their_way(size):
    frames = sign_frames_u8(Sign("arrow", 1.0), size)
    assert len({frame.tobytes() for frame in frames}) == 4
    for direction, step in enumerate(STEPS):
        offset = centroid_offset(frames[direction])
        along = offset[0] * step[0] + offset[1] * step[1]
        across = offset[0] * step[1] - offset[1] * step[0]
        assert along > 0.03 * size and abs(across) < 0.01 * size, (direction, offset)


def test_forbidden_tick_points_its_way():
    """``forbidden`` is a four-frame built-in: a barred circle with a tick towards d."""
    for size in (13, 64, 120):
        frames = sign_frames_u8(Sign("forbidden", 1.0), size) > 0
        middle, near, far = size // 2, int(0.85 * size), size - 1 - int(0.85 * size)
        assert frames[0][middle, near] and not frames[0][middle, far]
        assert frames[1][far, middle] and not frames[1][near, middle]
        assert frames[2][middle, far] and not frames[2][middle, near]
        assert frames[3][near, middle] and not frames[3][far, middle]


@pytest.mark.parametrize("size", [2, 1, 0, -5])
def test_too_small_size_is_refused(size):
    with pytest.raises(SignError, match=str(size)):
        sign_frames(Sign("arrow", 1.0), size)


@pytest.mark.parametrize("size", [9.0, "9", True, None])
def test_non_integer_size_is_refused(size):
    with pytest.raises(SignError, match="integer"):
        sign_frames_u8(Sign("arrow", 1.0), size)


def test_numpy_integer_size_is_accepted():
    np.testing.assert_array_equal(
        sign_frames_u8(Sign("arrow", 1.0), np.int64(9)), sign_frames_u8(Sign("arrow", 1.0), 9)
    )


def test_not_a_sign_is_refused():
    with pytest.raises(SignError):
        sign_frames(("arrow", 1.0), 9)


# -----------------------------------------------------------------------------
# Own drawing (any size)


@pytest.mark.parametrize("shape", BUILTIN_SHAPES)
def test_own_drawing_looks_like_the_reference(shape):
    for size in range(13, 65):
        reference = sign_frames_u8(Sign(shape, 1.0), size) > 0
        drawn = draw_builtin_mask(shape, size)
        iou = (reference & drawn).sum() / (reference | drawn).sum()
        assert iou >= 0.6, (shape, size, iou)


@pytest.mark.parametrize("shape", BUILTIN_SHAPES)
@pytest.mark.parametrize("size", [3, 65, 100, 150])
def test_any_size(shape, size):
    frames = sign_frames_u8(Sign(shape, 0.5), size)
    assert frames.shape == (4, size, size)
    assert all(frame.any() for frame in frames)
    assert set(np.unique(frames)) <= set(range(129))
    if size > 64:
        np.testing.assert_array_equal(frames > 0, draw_builtin_mask(shape, size))


def test_draw_builtin_mask_refuses_unknown_shapes():
    with pytest.raises(SignError, match="nosuchshape"):
        draw_builtin_mask("nosuchshape", 20)


def test_stored_rasters_are_small():
    assert RASTER_FILE.stat().st_size < 1_000_000
    with np.load(RASTER_FILE, allow_pickle=False) as data:
        assert list(data["sizes"]) == list(range(3, 65))
        assert {f"mask_{shape}" for shape in BUILTIN_SHAPES} <= set(data.files)


def test_import_reads_no_file():
    code = (
        "import amaze.maze.sign_images as m, sys; sys.exit(m._raster_table.cache_info().currsize)"
    )
    root = Path(__file__).parents[3]
    env = dict(os.environ, PYTHONPATH=str(root))
    subprocess.run([sys.executable, "-c", code], check=True, cwd=root, env=env)


# -----------------------------------------------------------------------------
# Custom images


@pytest.fixture
def custom(tmp_path):
    """Write PNG files under tmp_path and register them; forget them afterwards."""

    def make(name: str, image: Image.Image) -> Sign:
        path = tmp_path / f"{name}.png"
        image.save(path)
        register_custom_signs(path)
        return Sign(name, 1.0)  # lightness 1: the image as it is

    clear_custom_signs()
    clear_cache()
    yield make
    clear_custom_signs()
    clear_cache()


def test_custom_square_image_is_not_mirrored(custom):
    picture = np.zeros((20, 20), dtype=np.uint8)
    picture[:5, :] = 200  # top rows: north
    picture[:, 15:] = 100  # right columns: east (the direction the sign points)
    picture[:5, 15:] = 250
    sign = custom("testflag", Image.fromarray(picture))
    frames = sign_frames_u8(sign, 20)
    np.testing.assert_array_equal(frames[0], picture)
    for direction in range(4):
        np.testing.assert_array_equal(frames[direction], np.rot90(picture, direction))
    assert frames[1][:, 0].mean() > 150  # north side of the picture is west when pointing north
    small = sign_frames_u8(sign, 10)
    assert small[0][0].mean() > small[0][-1].mean()  # still north-up after resizing
    assert small[0][:, -1].mean() > small[0][:, 0].mean()


def test_custom_four_frame_image(custom):
    stacked = np.zeros((64, 16), dtype=np.uint8)
    for direction, level in enumerate((40, 80, 120, 160)):
        stacked[16 * direction : 16 * (direction + 1)] = level
    stacked[0:4, :] = 255  # top of the east frame
    sign = custom("testquad", Image.fromarray(stacked))
    frames = sign_frames_u8(sign, 8)
    assert frames.shape == (4, 8, 8)
    for direction, level in enumerate((40, 80, 120, 160)):
        assert (frames[direction][3:] == level).all()
    assert (frames[0][0] == 255).all() and (frames[0][-1] == 40).all()


def test_custom_image_takes_the_lightness(custom):
    # The reference ignores it: clues, lures and traps of one custom shape would look alike.
    picture = np.array([[0, 1, 77, 128, 200, 255]] * 6, dtype=np.uint8)
    sign = custom("testgray", Image.fromarray(picture))
    full = Sign("testgray", 1.0)
    np.testing.assert_array_equal(sign_frames_u8(full, 6)[0], picture)
    for value in (0.1, 0.25, 0.5, 0.75):
        gray = pen_gray_level(value)
        expected = np.floor(picture.astype(np.float64) * gray / 255 + 0.5).astype(np.uint8)
        np.testing.assert_array_equal(sign_frames_u8(Sign("testgray", value), 6)[0], expected)
    assert sign_frames_u8(Sign("testgray", 0.1), 6)[0, 0, 2] == 8  # 77 * 26 / 255 = 7.85
    dim = sign_frames(Sign("testgray", 0.25), 6)
    assert dim.max() < sign_frames(sign, 6).max() / 1.9


def test_custom_colour_and_transparency_become_gray(custom):
    red = custom("testred", Image.new("RGB", (10, 10), (255, 0, 0)))
    assert (sign_frames_u8(red, 9) == 76).all()  # luma 0.299 * 255
    half = custom("testhalf", Image.new("RGBA", (10, 10), (255, 255, 255, 128)))
    assert (sign_frames_u8(half, 9) == 128).all()  # composited on black
    clear = custom("testclear", Image.new("RGBA", (10, 10), (255, 255, 255, 0)))
    assert not sign_frames_u8(clear, 9).any()


def test_custom_16_bit_image(custom):
    deep = custom("testdeep", Image.fromarray(np.full((6, 6), 40000, dtype=np.uint16)))
    assert (sign_frames_u8(deep, 5) == 40000 >> 8).all()


def test_malformed_custom_image_is_refused(custom):
    sign = custom("testbad", Image.new("L", (10, 7), 255))
    with pytest.raises(SignError, match=r"testbad\.png"):
        sign_frames(sign, 9)


def test_unreadable_custom_image_is_refused(custom, tmp_path):
    sign = custom("testjunk", Image.new("L", (4, 4)))
    (tmp_path / "testjunk.png").write_bytes(b"not a png")
    with pytest.raises(SignError, match=r"testjunk\.png"):
        sign_frames_u8(sign, 9)


def test_custom_image_changes_are_seen(custom, tmp_path):
    sign = custom("testedit", Image.new("L", (8, 8), 10))
    assert (sign_frames_u8(sign, 5) == 10).all()
    path = tmp_path / "testedit.png"
    Image.new("L", (8, 8), 90).save(path)
    stat = path.stat()
    os.utime(path, ns=(stat.st_atime_ns, stat.st_mtime_ns + 10**9))
    assert (sign_frames_u8(sign, 5) == 90).all()


def test_forgotten_custom_shape_is_refused(custom):
    sign = custom("testgone", Image.new("L", (8, 8), 10))
    clear_custom_signs()
    with pytest.raises(SignError, match="testgone"):
        sign_frames_u8(sign, 5)
