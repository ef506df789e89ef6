"""The summary picture of the input-recognition test (:mod:`amaze.evaluation.inputs_picture`)."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from PIL import Image

from amaze.evaluation.inputs import InputRecognitionError, enumerate_inputs, evaluate_inputs
from amaze.evaluation.inputs_picture import render_summary, save_summary_png

SIGNS = (["1"], [".25"], [".5"])
MULTI = (["1", "point-.75"], [".25", "warning-.2"], [".5"])

WRONG = (214, 39, 40)
CORRECT = (46, 160, 67)


def always_east(observations: np.ndarray) -> np.ndarray:
    return np.zeros(len(observations), dtype=np.int64)


def expected_policy(inputs):
    return lambda observations: inputs.expected


def _pixels(path) -> np.ndarray:
    with Image.open(path) as image:
        assert image.mode == "RGB"
        return np.asarray(image)


def _count(pixels: np.ndarray, color) -> int:
    return int((pixels == np.array(color, dtype=np.uint8)).all(axis=2).sum())


@pytest.mark.parametrize("robot", ["DD", "H15"])
def test_summary_png_shows_every_input_and_its_outcome(tmp_path, robot):
    inputs = enumerate_inputs(robot, *SIGNS)
    east = evaluate_inputs(always_east, inputs)
    path = save_summary_png(east, tmp_path / "pictures" / "east.png")
    pixels = _pixels(path)
    height, width, _ = pixels.shape
    assert width >= 800
    assert height >= 900
    assert len(np.unique(pixels.reshape(-1, 3), axis=0)) > 20
    legend = 200  # the legend's red and green arrows
    # 105 wrong choices drawn as red arrows, 35 right ones as green arrows.
    assert _count(pixels, WRONG) > legend + 105 * 40
    assert _count(pixels, CORRECT) > legend + 35 * 40

    perfect = evaluate_inputs(expected_policy(inputs), inputs)
    pixels = _pixels(save_summary_png(perfect, tmp_path / "perfect.png", theme="dark"))
    assert _count(pixels, CORRECT) > legend + 140 * 40
    assert _count(pixels, WRONG) < legend


def test_summary_png_grows_with_the_number_of_inputs(tmp_path):
    small = evaluate_inputs(always_east, enumerate_inputs("DD", ["1"]))
    large = evaluate_inputs(always_east, enumerate_inputs("DD", *MULTI))
    a = _pixels(save_summary_png(small, tmp_path / "small.png"))
    b = _pixels(save_summary_png(large, tmp_path / "large.png"))
    assert b.shape[0] > a.shape[0] + 400
    assert a.shape[1] == b.shape[1]


def test_summary_png_rejects_a_bad_column_count(tmp_path):
    result = evaluate_inputs(always_east, enumerate_inputs("DD", ["1"]))
    with pytest.raises(InputRecognitionError, match="columns 0"):
        save_summary_png(result, tmp_path / "x.png", columns=0)
    with pytest.raises(ValueError, match="purple"):
        save_summary_png(result, tmp_path / "x.png", theme="purple")


def test_the_saved_png_is_the_rendered_picture(tmp_path):
    result = evaluate_inputs(always_east, enumerate_inputs("DD", *SIGNS))
    picture = render_summary(result, theme="dark", columns=8)
    path = save_summary_png(result, tmp_path / "f" / "summary.png", theme="dark", columns=8)
    assert np.array_equal(_pixels(path), np.asarray(picture.convert(Image.open(path).mode)))


def test_the_test_loads_without_the_picture_and_the_picture_module_alone():
    """No import circle: the picture module imports the test, never the reverse at load time."""
    code = (
        "import sys; import amaze.evaluation.inputs; "
        "assert 'amaze.evaluation.inputs_picture' not in sys.modules"
    )
    subprocess.run([sys.executable, "-c", code], check=True)
    subprocess.run([sys.executable, "-c", "import amaze.evaluation.inputs_picture"], check=True)
