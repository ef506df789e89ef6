"""curriculum.png renders a curriculum, its selections and its final choice."""

from __future__ import annotations

import itertools
from dataclasses import replace
from pathlib import Path

import numpy as np

from amaze.curriculum.curators import Candidate, MazeResults, StageRecord
from amaze.curriculum.picture import FINAL, SELECTED, render_curriculum, save_curriculum_png


def candidate(stage: int, branch: int, maze: str) -> Candidate:
    result = MazeResults(maze, (True, False, True, False), (0.5,) * 4, (10,) * 4)
    return Candidate(stage, branch, (maze,), (result,), (), (branch,), 1500, 1.0, False, 1500)


def records() -> list[StageRecord]:
    first = StageRecord(0, ("M1_5x5_U",), (candidate(0, 0, "M1_5x5_U"),), selected=0)
    mazes = ("M2_8x8_C1", "M3_6x9_C1_l.25_L.25")
    second = StageRecord(1, mazes, tuple(candidate(1, b, m) for b, m in enumerate(mazes)), 1)
    return [first, second]


def colour_count(image, colour) -> int:
    return int(np.all(np.asarray(image) == colour, axis=-1).sum())


def test_a_curriculum_renders_with_its_selections_and_final_choice(tmp_path: Path) -> None:
    image = render_curriculum(records(), title="toy")
    assert image.width > 200 and image.height > 300
    assert colour_count(image, SELECTED) > 100  # stage 0's choice
    assert colour_count(image, FINAL) > 100  # the last stage's choice
    path = save_curriculum_png(records(), tmp_path / "out" / "curriculum.png")
    assert path.read_bytes().startswith(b"\x89PNG")
    # an unfinished curriculum (no final choice yet) has no final frame
    unfinished = [*records()[:1], StageRecord(1, records()[1].mazes, records()[1].candidates)]
    assert colour_count(render_curriculum(unfinished), FINAL) == 0


def test_large_mazes_shrink_to_thumbnails_of_the_same_size() -> None:
    mazes = ("M2_8x8_C1", "M3_100x100_C1", "M4_30x45_U")
    stage = StageRecord(0, mazes, tuple(candidate(0, b, m) for b, m in enumerate(mazes)), 0)
    small = render_curriculum([StageRecord(0, mazes[:1], stage.candidates[:1], 0)])
    large = render_curriculum([stage])
    assert large.height == small.height  # one row, thumbnails no taller than small ones


def test_the_progress_plot_renders_with_and_without_validation(tmp_path: Path) -> None:
    from PIL import Image

    from amaze.curriculum.picture import save_curriculum_progress

    path = save_curriculum_progress(records(), "M5_12x12_C1", tmp_path / "a" / "progress.png")
    plain = Image.open(path)
    assert plain.size[0] > 400 and plain.size[1] > 400
    validation = (MazeResults("M9_12x12_C1", (True, True, False, False), (0.1,) * 4, (9,) * 4),)
    timed = [
        replace(r, candidates=tuple(replace(c, validation=validation) for c in r.candidates))
        for r in records()
    ]
    other = save_curriculum_progress(timed, "M5_12x12_C1", tmp_path / "b.png", title="edens")
    assert other.read_bytes() != path.read_bytes()  # the validation series is drawn


def test_a_maze_population_renders_best_score_first(tmp_path: Path) -> None:
    from amaze.curriculum.maze_population import (
        BatchMaze,
        MazePopulation,
        MazePopulationConfig,
        MazeResult,
    )
    from amaze.curriculum.picture import THUMBNAIL, render_population, save_population_png

    def population(sides: tuple[int, ...]) -> MazePopulation:
        members = MazePopulation("M7_12x12_C1", MazePopulationConfig(capacity=9, batch=1), seed=1)
        for side in sides:  # the 12x12 maze is half solved: the best score
            success = (np.arange(32) < {5: 4, 9: 8, 12: 16}[side]).reshape(8, 4)
            maze = f"M{side}_{side}x{side}_C1"
            members.update([BatchMaze(maze, origin="family")], [MazeResult.of(success, success)])
        return members

    empty = render_population(population(()))
    assert empty.height < THUMBNAIL  # a line saying so, no thumbnail
    image = render_population(population((5, 9, 12)), title="three")
    assert image.width > 3 * THUMBNAIL and THUMBNAIL < image.height < 2 * THUMBNAIL + 100
    alone = render_population(population((12,)), title="three")
    tile = (14, 30, 14 + THUMBNAIL, 30 + THUMBNAIL)
    assert np.array_equal(np.asarray(image.crop(tile)), np.asarray(alone.crop(tile)))
    path = save_population_png(population((5,)), tmp_path / "population.png")
    assert path.read_bytes().startswith(b"\x89PNG")


def test_a_long_curriculum_shows_its_stages_spread_evenly() -> None:
    from amaze.curriculum.picture import MAX_ROWS, shown_stages

    long = [
        StageRecord(s, ("M1_5x5_U",), (candidate(s, 0, "M1_5x5_U"),), selected=0) for s in range(60)
    ]
    shown = shown_stages(long)
    assert len(shown) == MAX_ROWS and shown[0].stage == 0 and shown[-1].stage == 59
    assert all(a.stage < b.stage for a, b in itertools.pairwise(shown))
    assert shown_stages(long[:5]) == long[:5]
    full, short = render_curriculum(long), render_curriculum(long[:MAX_ROWS])
    assert full.height == short.height  # no taller than MAX_ROWS rows
    assert colour_count(full, FINAL) > 100
