"""``curriculum.png``: a whole curriculum at a glance (and ``population.png``, a maze population).

One row per stage, one column per branch: each branch's maze as a thumbnail,
captioned with its success rate and R̄ on its own maze's 4 rotations, the
maze's size and sign kinds (C clues, L lures, T traps, U unicursive) and the
steps the branch trained for; the row's label gives the stage's steps. The
branch selected to go on is framed in red, and lines join it to the branches
of the next stage it was copied into, so the lineage of the final agent reads
from top to bottom; the final choice is framed in green and marked "final".
A long (open-ended) curriculum shows :data:`MAX_ROWS` stages spread evenly
over it, the first and the last ones included, and says how many stages lie
between two rows that do not follow each other.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

from PIL import Image, ImageDraw

from amaze.curriculum.curators import StageRecord
from amaze.curriculum.maze_population import MazePopulation
from amaze.maze.render import MIN_CELL_SIZE, load_font, render_maze, save_picture
from amaze.maze.spec import MazeSpec

__all__ = [
    "render_curriculum",
    "render_population",
    "save_curriculum_png",
    "save_curriculum_progress",
    "save_population_png",
]

#: Side of a maze thumbnail, in pixels (about).
THUMBNAIL = 112
PAD = 14
CAPTION = 47
LABEL = 84
SELECTED = (214, 39, 40)
FINAL = (17, 128, 64)
LINEAGE = (31, 119, 180)
TEXT = (30, 30, 30)
#: Most stages drawn in a curriculum picture.
MAX_ROWS = 24


def _count(steps: int) -> str:
    """A step count in a few characters: 950, 12.3k, 4.1M."""
    for size, unit in ((1e6, "M"), (1e3, "k")):
        if steps >= size:
            return f"{steps / size:.1f}{unit}"
    return str(steps)


def _fields(spec: MazeSpec) -> str:
    """The maze's size and sign kinds, e.g. ``20x20 CLT`` or ``5x5 U``."""
    kinds = "".join(k for k, on in (("C", spec.clue), ("L", spec.lure), ("T", spec.trap)) if on)
    return f"{spec.width}x{spec.height} {'U' if spec.unicursive else ''}{kinds}".rstrip()


def shown_stages(records: Sequence[StageRecord], rows: int = MAX_ROWS) -> list[StageRecord]:
    """At most ``rows`` of ``records``, spread evenly, the first and the last ones included."""
    if len(records) <= rows:
        return list(records)
    step = (len(records) - 1) / (rows - 1)
    return [records[round(row * step)] for row in range(rows)]


def render_curriculum(
    records: Sequence[StageRecord], title: str = "", finished: bool = True
) -> Image.Image:
    """The picture of ``records`` (stages in order, each with its candidates).

    The last stage's selected branch is marked final when the run is ``finished``
    (a curriculum still being played shows its selections alike).
    """
    records = shown_stages(records)
    columns = max((len(r.candidates) for r in records), default=1)
    cell_w, cell_h = THUMBNAIL + PAD, THUMBNAIL + CAPTION + PAD
    top = 30 if title else PAD
    width = LABEL + columns * cell_w + PAD
    height = top + max(len(records), 1) * cell_h + PAD
    image = Image.new("RGB", (width, height), "white")
    draw = ImageDraw.Draw(image)
    font, small = load_font(14), load_font(11)
    if title:
        draw.text((PAD, 8), title, fill=TEXT, font=font)

    def box(stage: int, branch: int) -> tuple[int, int, int, int]:
        x = LABEL + branch * cell_w
        y = top + stage * cell_h
        return x, y, x + THUMBNAIL, y + THUMBNAIL

    for row, record in enumerate(records):
        y_label = top + row * cell_h + THUMBNAIL // 2 - 7
        draw.text((PAD, y_label), f"stage {record.stage}", fill=TEXT, font=small)
        spent = sum(c.env_steps for c in record.candidates)
        draw.text((PAD, y_label + 14), f"{_count(spent)} steps", fill=TEXT, font=small)
        final = finished and row == len(records) - 1
        for candidate in record.candidates:
            x0, y0, x1, y1 = box(row, candidate.branch)
            maze = candidate.mazes[0]
            spec = MazeSpec.from_string(maze)
            side = max(spec.width, spec.height)
            thumbnail = render_maze(maze, cell_size=max(MIN_CELL_SIZE, THUMBNAIL // side))
            thumbnail.thumbnail((THUMBNAIL, THUMBNAIL))
            image.paste(thumbnail, (x0 + (THUMBNAIL - thumbnail.width) // 2, y0))
            if record.selected == candidate.branch:
                colour = FINAL if final else SELECTED
                draw.rectangle((x0 - 4, y0 - 4, x1 + 3, y1 + 3), outline=colour, width=3)
                if final:
                    draw.text((x1 - 28, y1 + 17), "final", fill=FINAL, font=small)
            caption = f"b{candidate.branch}: success {candidate.success_rate:.2f}"
            draw.text((x0, y1 + 4), caption, fill=TEXT, font=small)
            draw.text((x0, y1 + 17), f"R̄ {candidate.normalized_reward:+.2f}", fill=TEXT, font=small)
            details = f"{_fields(spec)}, {_count(candidate.env_steps)} st"
            draw.text((x0, y1 + 30), details, fill=TEXT, font=small)
        if row + 1 < len(records) and records[row + 1].stage > record.stage + 1:
            skipped = records[row + 1].stage - record.stage - 1
            y_gap = top + row * cell_h + THUMBNAIL + CAPTION - 3
            draw.text((PAD, y_gap), f"+{skipped} stages", fill=LINEAGE, font=small)
        elif row + 1 < len(records) and record.selected is not None:
            px0, _, px1, py1 = box(row, record.selected)
            for child in records[row + 1].candidates:
                cx0, cy0, cx1, _ = box(row + 1, child.branch)
                draw.line(
                    ((px0 + px1) // 2, py1 + CAPTION - 2, (cx0 + cx1) // 2, cy0 - 5),
                    fill=LINEAGE,
                    width=2,
                )
    return image


def save_curriculum_png(
    records: Sequence[StageRecord], path: str | os.PathLike, title: str = ""
) -> Path:
    """Write :func:`render_curriculum` to ``path`` atomically."""
    return save_picture(render_curriculum(records, title), path)


def save_curriculum_progress(
    records: Sequence[StageRecord], target: str, path: str | os.PathLike, title: str = ""
) -> Path:
    """``progress.png``: how the selected agents fared and how hard their mazes were.

    Top: per stage, at the env steps spent by its end, the selected branch's
    success on its own maze, on every maze of the stage and (when the curator
    has validation mazes) on the validation mazes. Bottom: the
    :func:`~amaze.curriculum.difficulty.difficulty` of every branch's maze, the
    selected one's joined by a line, and the target's as a dashed line.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from amaze.curriculum.difficulty import difficulty

    steps, spent = [], 0
    for record in records:
        spent += sum(c.env_steps for c in record.candidates)
        steps.append(spent)
    chosen = [
        (s, r.candidates[r.selected])
        for s, r in zip(steps, records, strict=True)
        if r.selected is not None
    ]
    figure, (top, bottom) = plt.subplots(2, 1, figsize=(7, 6), dpi=110, sharex=True)
    series = [
        ("own maze", lambda c: c.success_rate),
        ("stage's mazes", lambda c: c.overall_success_rate),
    ]
    if any(c.validation for _, c in chosen):
        series.append(("validation mazes", lambda c: c.validation_success_rate))
    for label, value in series:
        top.plot([s for s, _ in chosen], [value(c) for _, c in chosen], "o-", label=label)
    top.set_ylabel("success of the selected branch")
    top.set_ylim(-0.05, 1.05)
    top.legend(loc="lower right")
    top.grid(alpha=0.3)
    for s, record in zip(steps, records, strict=True):
        hardness = [difficulty(c.mazes[0]) for c in record.candidates]
        bottom.plot([s] * len(hardness), hardness, ".", color="grey")
    selected = [difficulty(c.mazes[0]) for _, c in chosen]
    bottom.plot([s for s, _ in chosen], selected, "o-", label="selected branch's maze")
    bottom.axhline(difficulty(target), linestyle="--", color="black", label="target")
    bottom.set_ylabel("maze difficulty")
    bottom.set_xlabel("environment steps (end of stage)")
    bottom.legend(loc="lower right")
    bottom.grid(alpha=0.3)
    if title:
        top.set_title(title)
    figure.tight_layout()
    try:
        return save_picture(figure, path)
    finally:
        plt.close(figure)


#: Most members drawn by :func:`save_population_png` (the best scores first).
POPULATION_PICTURE_MAZES = 64
#: Members per row of ``population.png``.
POPULATION_COLUMNS = 8


def render_population(population: MazePopulation, title: str = "") -> Image.Image:
    """The members of a co-evolved maze population as captioned thumbnails, best score first.

    Each thumbnail is captioned with the maze's record id, size and sign
    kinds, its score, the agents' success rate on it (the last time it was
    played) and its difficulty; at most :data:`POPULATION_PICTURE_MAZES` members.
    """
    members = sorted(population.member_records(), key=lambda r: (-r.score, r.id))
    members = members[:POPULATION_PICTURE_MAZES]
    columns = min(POPULATION_COLUMNS, max(len(members), 1))
    rows = -(-len(members) // columns)
    cell_w, cell_h = THUMBNAIL + PAD, THUMBNAIL + CAPTION + PAD
    top = 30 if title else PAD
    width, height = max(PAD + columns * cell_w, 420), top + max(rows * cell_h, 30)
    image = Image.new("RGB", (width, height), "white")
    draw = ImageDraw.Draw(image)
    font, small = load_font(14), load_font(11)
    if title:
        draw.text((PAD, 8), title, fill=TEXT, font=font)
    if not members:
        draw.text((PAD, top), "no maze has met the minimal criterion yet", fill=TEXT, font=small)
    for index, record in enumerate(members):
        row, column = divmod(index, columns)
        x0, y0 = PAD + column * cell_w, top + row * cell_h
        spec = MazeSpec.from_string(record.maze)
        side = max(spec.width, spec.height)
        thumbnail = render_maze(record.maze, cell_size=max(MIN_CELL_SIZE, THUMBNAIL // side))
        thumbnail.thumbnail((THUMBNAIL, THUMBNAIL))
        image.paste(thumbnail, (x0 + (THUMBNAIL - thumbnail.width) // 2, y0))
        y1 = y0 + THUMBNAIL
        draw.text((x0, y1 + 4), f"#{record.id} {_fields(spec)}", fill=TEXT, font=small)
        draw.text((x0, y1 + 17), f"score {record.score:.3f}", fill=TEXT, font=small)
        caption = f"success {record.success_rate:.2f} d {record.difficulty:.1f}"
        draw.text((x0, y1 + 30), caption, fill=TEXT, font=small)
    return image


def save_population_png(
    population: MazePopulation, path: str | os.PathLike, title: str = ""
) -> Path:
    """Write :func:`render_population` to ``path`` atomically."""
    return save_picture(render_population(population, title), path)
