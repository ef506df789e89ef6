"""Arrow styles: seeded training drawings, held-out drawings, their files and directions."""

from __future__ import annotations

import dataclasses
import re

import numpy as np
import pytest
from PIL import Image

from amaze.agents.observations import cell_image
from amaze.cli.main import main
from amaze.errors import SignError
from amaze.maze.arrow_styles import (
    DEFAULT_SHAFT_WIDTH,
    HEADS,
    HELD_OUT_STYLES,
    MIN_SHAFT,
    ArrowStyle,
    directional,
    draw_arrow,
    draw_harpoon,
    draw_outline,
    training_styles,
    write_sign_styles,
)
from amaze.maze.maze import Maze
from amaze.maze.sign_images import clear_cache, sign_frames
from amaze.maze.signs import clear_custom_signs, register_custom_signs
from amaze.maze.spec import MazeSpec

#: Least mean absolute difference (gray levels in [0, 1], 64 x 64 pixels) between any
#: training style and any held-out style in any of its four quarter turns. Observed
#: (256 styles of each of the seeds 0, 1 and 2): nearest training style 0.110 to harpoon,
#: 0.132 to chevron, 0.184 to outline; for comparison two training styles differ by
#: 0.087 at the median (0.034 at least) and a style from itself with another noise seed
#: by at most 0.060. 0.09 is above both: a held-out style is farther from every training
#: style than two training styles usually are from each other.
HELD_OUT_DISTANCE = 0.09


@pytest.fixture(autouse=True)
def forget_custom_signs():
    """Leave the shape registry and image cache as other tests expect them."""
    clear_custom_signs()
    clear_cache()
    yield
    clear_custom_signs()
    clear_cache()


def gray(image: Image.Image) -> np.ndarray:
    """The gray levels an agent sees of a white-on-transparent drawing, in [0, 1]."""
    assert image.mode == "LA"
    assert np.all(np.asarray(image.getchannel("L"))[np.asarray(image.getchannel("A")) > 0] == 255)
    return np.asarray(image.getchannel("A"), dtype=np.float64) / 255


def run_cli(capsys, *args: str) -> tuple[int, str, str]:
    status = main(list(args))
    captured = capsys.readouterr()
    return status, captured.out, captured.err


# -----------------------------------------------------------------------------
# Styles and drawings


def test_styles_are_deterministic_from_their_seed():
    first, again = training_styles(8, 5), training_styles(8, 5)
    assert first == again
    for a, b in zip(first, again, strict=True):
        np.testing.assert_array_equal(np.asarray(draw_arrow(a)), np.asarray(draw_arrow(b)))
    other = training_styles(8, 6)
    assert all(a != b for a, b in zip(first, other, strict=True))
    assert any(
        not np.array_equal(np.asarray(draw_arrow(a)), np.asarray(draw_arrow(b)))
        for a, b in zip(first, other, strict=True)
    )
    assert training_styles(3, 5) == first[:3]  # a longer list starts with a shorter one


def test_noise_comes_from_the_style_seed():
    style = ArrowStyle(noise=0.05, noise_seed=1)
    same = np.asarray(draw_arrow(style))
    np.testing.assert_array_equal(
        same, np.asarray(draw_arrow(ArrowStyle(noise=0.05, noise_seed=1)))
    )
    other = np.asarray(draw_arrow(dataclasses.replace(style, noise_seed=2)))
    assert not np.array_equal(same, other)


def test_every_training_style_is_a_clear_arrow():
    styles = training_styles(256, 0)
    assert {s.head for s in styles} == {"filled", "open"}
    for style in styles:
        assert style.scale * style.shaft_length >= MIN_SHAFT - 1e-9
        assert style.head_width >= 2 * style.shaft_width
        image = draw_arrow(style, 64)
        assert image.size == (64, 64)
        heights = (gray(image) > 0.5).sum(axis=0)  # lit pixels of each column
        # The head, wider than the shaft, is in the east half: the arrow points east.
        assert heights[32:].max() > 1.5 * heights[:32].max() > 0


def test_hollow_heads_are_drawn_only_when_asked_for_and_keep_the_rest_of_the_style():
    plain, hollow = training_styles(64, 3), training_styles(64, 3, HEADS)
    assert {s.head for s in hollow} == set(HEADS)
    for a, b in zip(plain, hollow, strict=True):  # the same draws but the heads
        assert dataclasses.replace(a, head=b.head) == b
    assert {s.head for s in training_styles(32, 3, ("hollow",))} == {"hollow"}


def test_wider_shafts_are_drawn_only_when_asked_for_and_keep_the_rest_of_the_style():
    thin, wide = training_styles(64, 3), training_styles(64, 3, shaft_width=(0.05, 0.3))
    assert training_styles(64, 3, shaft_width=DEFAULT_SHAFT_WIDTH) == thin
    assert max(s.shaft_width for s in thin) <= DEFAULT_SHAFT_WIDTH[1]
    assert max(s.shaft_width for s in wide) > 0.25  # up to 4 pixels of a 13-pixel sign
    assert all(0.05 <= s.shaft_width <= 0.3 for s in wide)
    for a, b in zip(thin, wide, strict=True):  # the same draws but the widths
        assert b.shaft_width >= a.shaft_width and b.head_width >= 2 * b.shaft_width
        assert dataclasses.replace(a, shaft_width=b.shaft_width, head_width=b.head_width) == b
    narrow = training_styles(8, 3, shaft_width=(0.2, 0.2))
    assert {s.shaft_width for s in narrow} == {0.2}


def test_a_hollow_head_is_the_contour_of_the_filled_one():
    filled, hollow = ArrowStyle(head_width=0.6), ArrowStyle(head="hollow", head_width=0.6)
    solid, ring = gray(draw_arrow(filled, 256)), gray(draw_arrow(hollow, 256))
    # Inside the head (its base at x = 147 px, its tip at 224, the shaft's line at
    # y = 115 to 141), clear of the strokes: the filled head is lit there, the hollow dark.
    inside = (slice(96, 106), slice(166, 174))
    assert solid[inside].min() > 0.9 and ring[inside].max() < 0.1
    heights = (ring > 0.5).sum(axis=0)
    assert heights[32:].max() > 1.5 * heights[:32].max() > 0  # still an arrow pointing east


def test_a_hairline_head_keeps_its_hole_in_a_hybrid_robots_sign():
    # A thick shaft (0.16 of the side) strokes a hollow head so thick that its hole
    # closes in a 13-pixel sign (an H15 cell's); a hairline (0.08) keeps it dark.
    def drawn(head: str, size: int) -> np.ndarray:
        style = ArrowStyle(shaft_width=0.16, head=head, head_width=0.6, head_length=0.3)
        return gray(draw_arrow(style, size))

    inside = (slice(5, 8), slice(8, 10))  # around the head's centroid (row 6, column 8.7)
    assert drawn("hollow", 13)[inside].min() > 0.2
    assert drawn("hairline", 13)[inside].min() < 0.05
    hollow, hairline = drawn("hollow", 256), drawn("hairline", 256)
    head = (slice(None), slice(150, 230))  # east of the shaft: the head's strokes only
    assert 0 < (hairline[head] > 0.5).sum() < 0.7 * (hollow[head] > 0.5).sum()
    heights = (hairline > 0.5).sum(axis=0)
    assert heights[32:].max() > 1.5 * heights[:32].max() > 0  # still an arrow pointing east


def test_the_outline_taken_apart_fills_the_parts_asked_for():
    outline = gray(draw_outline(256))
    assert np.array_equal(outline, gray(HELD_OUT_STYLES["outline"](256)))
    shaft, head = (128, 77), (128, 170)  # (row, column): inside the shaft, inside the head
    for hollow_head, hollow_shaft in ((False, False), (True, False), (False, True)):
        part = gray(draw_outline(256, hollow_head=hollow_head, hollow_shaft=hollow_shaft))
        assert (part[shaft] < 0.05) == hollow_shaft and (part[head] < 0.05) == hollow_head
    assert outline[shaft] < 0.05 and outline[head] < 0.05
    small = gray(draw_outline(256, scale=0.7))
    columns = np.flatnonzero((small > 0.5).any(axis=0))
    wide = np.flatnonzero((outline > 0.5).any(axis=0))
    assert 0.65 < (columns[-1] - columns[0]) / (wide[-1] - wide[0]) < 0.75
    with pytest.raises(SignError, match=r"outline scale 0\.1"):
        draw_outline(64, scale=0.1)


def test_bolder_strokes_light_a_robots_sign_more(tmp_path):
    """Strokes under a pixel of a 13-pixel sign are dim there: the harpoon's and the
    outline's lit pixels are about half bright. Drawn twice as wide they are brighter."""
    assert np.array_equal(gray(draw_harpoon(256, stroke=0.1)), gray(draw_harpoon(256)))
    assert np.array_equal(gray(draw_outline(256, stroke=0.07)), gray(draw_outline(256)))
    drawings = {
        "harpoon": draw_harpoon(),
        "harpoonbold": draw_harpoon(stroke=0.2),
        "outline": draw_outline(),
        "outlinebold": draw_outline(stroke=0.14),
    }
    for name, image in drawings.items():
        image.save(tmp_path / f"{name}.png")
    register_custom_signs(tmp_path)

    def lit(shape: str) -> tuple[float, int]:
        """Median of the 13-pixel clue's lit pixels, and how many 256-pixel ones are inked."""
        maze = Maze.from_string(f"M4_10x10_C{shape}-1")
        sign = next(maze.sign_at(c) for c in maze.solution if maze.sign_at(c) is not None)
        frame = sign_frames(sign.sign, 13)[0]
        return float(np.median(frame[frame > 0.05])), int((gray(drawings[shape]) > 0.5).sum())

    for thin in ("harpoon", "outline"):
        (dim, ink), (bright, bold_ink) = lit(thin), lit(f"{thin}bold")
        assert dim < 0.6 < 0.7 < bright and bold_ink > 1.5 * ink
    for bad in (0, -0.1, 0.3, float("nan")):
        with pytest.raises(SignError, match="stroke"):
            draw_harpoon(64, stroke=bad)
        with pytest.raises(SignError, match="stroke"):
            draw_outline(64, stroke=bad)


@pytest.mark.parametrize("name", sorted(HELD_OUT_STYLES))
def test_held_out_drawings_are_square_white_on_transparent(name):
    image = HELD_OUT_STYLES[name](48)
    assert image.size == (48, 48)
    pixels = gray(image)
    assert pixels.max() == 1.0 and pixels.min() == 0.0


@pytest.mark.parametrize(
    ("call", "named"),
    [
        (lambda: training_styles(0, 1), "0"),
        (lambda: training_styles(257, 1), "257"),
        (lambda: training_styles(1.5, 1), "1.5"),
        (lambda: training_styles(True, 1), "True"),
        (lambda: training_styles(4, -1), "-1"),
        (lambda: ArrowStyle(shaft_length=0.2), "0.2"),
        (lambda: ArrowStyle(noise=float("nan")), "nan"),
        (lambda: ArrowStyle(shaft_width=0.16, head_width=0.3), "0.3"),
        (lambda: ArrowStyle(head="yes"), "'yes'"),
        (lambda: training_styles(4, 1, heads=("star",)), "'star'"),
        (lambda: training_styles(4, 1, heads=()), "()"),
        (lambda: training_styles(4, 1, heads="open"), "'open'"),
        (lambda: training_styles(4, 1, heads=("open", "open")), "twice"),
        (lambda: training_styles(4, 1, shaft_width=(0.1, 0.31)), "0.31"),
        (lambda: training_styles(4, 1, shaft_width=(0.01, 0.1)), "0.01"),
        (lambda: training_styles(4, 1, shaft_width=(0.2, 0.1)), "low end"),
        (lambda: training_styles(4, 1, shaft_width=(0.1,)), "[0.1]"),
        (lambda: training_styles(4, 1, shaft_width="thin"), "'thin'"),
        (lambda: training_styles(4, 1, shaft_width=(0.1, float("nan"))), "nan"),
        (lambda: draw_arrow(ArrowStyle(), 4), "4"),
        (lambda: HELD_OUT_STYLES["chevron"](2000), "2000"),
    ],
)
def test_bad_values_are_refused_by_name(call, named):
    with pytest.raises(SignError, match=re.escape(f" {named}")):
        call()


def test_every_training_style_differs_from_every_held_out_style():
    held_out = {name: gray(draw(64)) for name, draw in HELD_OUT_STYLES.items()}
    nearest = dict.fromkeys(held_out, np.inf)
    for seed in (0, 1):
        for style in [*training_styles(64, seed), *training_styles(64, seed, HEADS, (0.05, 0.3))]:
            pixels = gray(draw_arrow(style, 64))
            for name, other in held_out.items():
                distance = min(np.abs(pixels - np.rot90(other, k)).mean() for k in range(4))
                nearest[name] = min(nearest[name], distance)
    print("nearest training style to each held-out style:", nearest)
    assert all(distance > HELD_OUT_DISTANCE for distance in nearest.values()), nearest


# -----------------------------------------------------------------------------
# Files, registration and directions


def test_written_styles_are_directional_and_star_is_not(tmp_path):
    groups = write_sign_styles(tmp_path, 8, 3)
    assert groups == {
        "training": [f"arrowv{i}" for i in range(8)],
        "held-out": ["chevron", "harpoon", "outline"],
    }
    for group, names in groups.items():
        assert register_custom_signs(tmp_path / group) == sorted(names)
        for name in names:
            assert directional(name), name
    assert directional("arrow") and directional("rarrow")
    # A star and the error cross look the same every way round; a point is a dot off
    # the centre, towards its direction, so it carries one (agents read points).
    assert not directional("star") and not directional("error")
    assert directional("point")
    with pytest.raises(SignError, match="nosuchshape"):
        directional("nosuchshape")


def test_written_files_are_the_drawings(tmp_path):
    write_sign_styles(tmp_path, 2, 7)
    style = training_styles(2, 7)[1]
    with Image.open(tmp_path / "training" / "arrowv1.png") as image:
        np.testing.assert_array_equal(np.asarray(image), np.asarray(draw_arrow(style)))
    with Image.open(tmp_path / "held-out" / "harpoon.png") as image:
        np.testing.assert_array_equal(np.asarray(image), np.asarray(HELD_OUT_STYLES["harpoon"](64)))


def test_rewriting_overwrites_and_stray_images_are_refused(tmp_path):
    write_sign_styles(tmp_path, 4, 0)
    write_sign_styles(tmp_path, 4, 1)  # the same names: overwritten
    with pytest.raises(SignError, match=r"arrowv2\.png"):
        write_sign_styles(tmp_path, 2, 0)  # arrowv2 and arrowv3 would stay in the group
    assert sorted(p.name for p in (tmp_path / "training").iterdir()) == [
        f"arrowv{i}.png" for i in range(4)
    ]


def test_a_written_style_is_usable_in_a_maze_and_seen_by_a_robot(tmp_path):
    write_sign_styles(tmp_path, 2, 0)
    register_custom_signs(tmp_path / "training")
    register_custom_signs(tmp_path / "held-out")
    spec = MazeSpec.from_string("M4_10x10_Carrowv0-1_l.3_Lharpoon-.25")
    assert spec.to_string() == "M4_10x10_Carrowv0-1_l0.3_Lharpoon-.25"
    maze = Maze.from_string(spec.to_string())
    placed = [maze.sign_at(cell) for cell in maze.solution]
    shapes = {p.sign.shape for p in placed if p is not None}
    assert shapes == {"arrowv0", "harpoon"}
    for p in placed:
        if p is not None:
            image = cell_image(maze, p.cell, 15)
            assert image.shape == (15, 15)
            frame = sign_frames(p.sign, 13)[int(p.direction)]
            np.testing.assert_allclose(image[1:-1, 1:-1], frame)  # the sign, inside the walls
            # drawn at the sign's lightness: the clue at 1, the harpoon lures at a quarter
            assert 0.8 * p.sign.value < frame.max() <= p.sign.value + 1 / 255


# -----------------------------------------------------------------------------
# amaze draw-signs


def test_cli_writes_the_styles(tmp_path, capsys):
    status, out, err = run_cli(capsys, "draw-signs", str(tmp_path / "s"), "--training", "3")
    assert status == 0, err
    assert sorted(p.name for p in (tmp_path / "s" / "training").iterdir()) == [
        "arrowv0.png",
        "arrowv1.png",
        "arrowv2.png",
    ]
    assert sorted(p.name for p in (tmp_path / "s" / "held-out").iterdir()) == [
        "chevron.png",
        "harpoon.png",
        "outline.png",
    ]
    assert "arrowv0 arrowv1 arrowv2" in out and "chevron harpoon outline" in out
    assert f"--signs {tmp_path / 's' / 'training'}" in out
    assert '{"coevolution": {"shapes": ["arrow", "arrowv0", "arrowv1", "arrowv2"]}}' in out
    drawn = '{"coevolution": {"shapes": ["arrow"], "sign_styles": 3, "sign_styles_seed": 0}}'
    assert drawn in out
    default = tmp_path / "d"
    assert run_cli(capsys, "draw-signs", str(default))[0] == 0
    assert len(list((default / "training").glob("*.png"))) == 16


@pytest.mark.parametrize("count", ["0", "257", "1.5", "many"])
def test_cli_refuses_a_bad_count(tmp_path, capsys, count):
    status, out, err = run_cli(capsys, "draw-signs", str(tmp_path / "s"), "--training", count)
    assert status == 2, (out, err)
    assert err.startswith("error: ") and err.count("\n") == 1, err
    assert count in err and "Traceback" not in err
    assert out == ""
    assert not (tmp_path / "s").exists()


def test_cli_draws_the_heads_asked_for(tmp_path, capsys):
    status, out, _ = run_cli(
        capsys, "draw-signs", str(tmp_path / "h"), "--training", "2", "--heads", "hollow,open"
    )
    assert status == 0
    assert '"sign_styles_heads": ["hollow", "open"]' in out
    style = training_styles(2, 0, ("hollow", "open"))[0]
    with Image.open(tmp_path / "h" / "training" / "arrowv0.png") as image:
        assert np.array_equal(np.asarray(image), np.asarray(draw_arrow(style)))
    status, out, err = run_cli(capsys, "draw-signs", str(tmp_path / "b"), "--heads", "round")
    assert status == 2 and "'round'" in err and "Traceback" not in err


def test_cli_draws_the_shaft_widths_asked_for(tmp_path, capsys):
    status, out, _ = run_cli(
        capsys, "draw-signs", str(tmp_path / "w"), "--training", "2", "--shaft-width", "0.2,0.3"
    )
    assert status == 0
    assert '"sign_styles_shaft_width": [0.2, 0.3]' in out
    style = training_styles(2, 0, shaft_width=(0.2, 0.3))[1]
    with Image.open(tmp_path / "w" / "training" / "arrowv1.png") as image:
        assert np.array_equal(np.asarray(image), np.asarray(draw_arrow(style)))
    for bad in ("0.2", "0.2,0.4", "thin,wide", "0.3,0.2"):
        status, out, err = run_cli(capsys, "draw-signs", str(tmp_path / "b"), "--shaft-width", bad)
        assert status == 2 and "--shaft-width" in err and "Traceback" not in err, (bad, err)
        assert not (tmp_path / "b").exists()
    assert not (tmp_path / "b").exists()
