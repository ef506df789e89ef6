"""Pictures of one episode: the path an agent took through a maze (Pillow only).

:func:`render_trajectory` draws a maze (:func:`amaze.maze.render.render_maze`) with
the path of one recorded episode (:class:`amaze.agents.simulation.Trajectory`, as
returned by :func:`amaze.evaluation.policy.record_episode`) over it, and
:func:`render_episode_frames` / :func:`save_episode_gif` animate the episode.

What the pictures show:

* the path is coloured by time, along a perceptually uniform gradient (viridis)
  from the first step to the last; the optional caption band shows that
  gradient, a legend of the markers and a summary of the episode;
* discrete robots move from cell centre to cell centre. Every traversal of a
  passage after the first is drawn in its own lane, shifted sideways, so going
  back and forth stays readable (a dead end shows as a hairpin);
* a discrete move into a wall (the robot stays put) leaves a small tick at that
  wall, one more tick per repeated bump (up to three per wall);
* continuous robots leave a smooth polyline of their positions;
* the start is a ring, the final position a disc holding a check mark when the
  episode ended in the goal cell and a cross when it did not.

Pictures have exactly the size and geometry of :func:`render_maze`'s (see
:class:`amaze.maze.render.MazeLayout`), except with a caption, which adds a band
below. Overlays are drawn at a higher resolution and area-averaged down, so
diagonal and curved lines are antialiased while the maze stays pixel-sharp.
"""

from __future__ import annotations

import math
import os
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image, ImageDraw

from amaze.agents.robot import RADIUS, Robot, as_robot
from amaze.agents.simulation import Trajectory
from amaze.errors import AmazeError
from amaze.maze.directions import OFFSETS
from amaze.maze.maze import Maze, as_maze
from amaze.maze.render import (
    Color,
    MazeLayout,
    Palette,
    RenderError,
    RenderOptions,
    load_font,
    render_maze,
)
from amaze.maze.spec import MazeSpec
from amaze.validation import check_integer, check_number

__all__ = [
    "TrajectoryError",
    "frame_steps",
    "render_episode_frames",
    "render_trajectory",
    "save_episode_gif",
    "save_trajectory_png",
]


class TrajectoryError(AmazeError):
    """A trajectory, or an option for drawing it, cannot be drawn."""


# -- colours --------------------------------------------------------------------------

#: Matplotlib's viridis sampled at 17 evenly spaced points (colour-blind safe, monotonic
#: in lightness, so time reads the same in grayscale).
_VIRIDIS: tuple[str, ...] = (
    "#440154", "#48186a", "#472d7b", "#424086", "#3b528b", "#33638d", "#2c728e", "#26828e",
    "#21918c", "#1fa088", "#28ae80", "#3fbc73", "#5ec962", "#84d44b", "#addc30", "#d8e219",
    "#fde725",
)  # fmt: skip
_VIRIDIS_RGB = np.array([[int(c[k : k + 2], 16) for k in (1, 3, 5)] for c in _VIRIDIS], float)

#: The part of the gradient used per theme: the palest yellows vanish on white, the
#: darkest purples on the dark background.
_GRADIENT_SPAN = {"light": (0.0, 0.86), "dark": (0.28, 1.0)}

#: The agent disc of the animations (orange stands out of the blue-green-yellow path).
_AGENT = {False: (255, 127, 14), True: (213, 94, 0)}

#: Collision ticks: a magenta distinct from the markers and from the path gradient.
_TICK = {
    ("light", False): (214, 36, 130),
    ("dark", False): (255, 92, 180),
    ("light", True): (204, 121, 167),
    ("dark", True): (204, 121, 167),
}

#: Opacity of the trail behind the agent in animation frames.
_TRAIL_ALPHA = 0.55

#: How many of the most frequent colours of an animation its GIF palette keeps exactly.
_EXACT_COLORS = 128
#: Palette colours closer than this (RGB distance) to a more frequent one are dropped.
_MIN_PALETTE_DISTANCE = 12

#: Frame rates of animations (frames per second): from one frame per 100 s to 50 (a
#: GIF counts delays in hundredths of a second, and viewers slow down shorter ones).
MIN_FPS, MAX_FPS = 0.01, 50.0
#: The longest pause on the last frame of an animation, in seconds.
MAX_FINAL_PAUSE = 600.0
#: A GIF frame's delay is a 16-bit count of hundredths of a second: at most 655.35 s.
_MAX_GIF_DELAY_MS = 655_350


def _gradient(t: float, theme: str) -> Color:
    """The path colour at relative time ``t`` in [0, 1]."""
    low, high = _GRADIENT_SPAN[theme]
    x = (low + (high - low) * min(1.0, max(0.0, t))) * (len(_VIRIDIS) - 1)
    k = min(int(x), len(_VIRIDIS) - 2)
    mix = _VIRIDIS_RGB[k] + (x - k) * (_VIRIDIS_RGB[k + 1] - _VIRIDIS_RGB[k])
    return (round(float(mix[0])), round(float(mix[1])), round(float(mix[2])))


# -- validated episodes ---------------------------------------------------------------


@dataclass(frozen=True)
class _Episode:
    """A checked trajectory: ``states[k]`` is the position before step ``k``, and
    ``states[n]`` the final one (maze units, cell ``(i, j)`` spans ``[i, i+1] x [j, j+1]``).
    """

    states: np.ndarray
    actions: np.ndarray | None
    rewards: np.ndarray | None
    discrete: bool
    success: bool
    #: ``(step, cell, side)`` of each discrete move into a wall.
    collisions: tuple[tuple[int, tuple[int, int], int], ...]

    @property
    def n_steps(self) -> int:
        return len(self.states) - 1

    def time(self, step: float) -> float:
        """Relative time in [0, 1] of a step (0 = first step, 1 = last)."""
        return step / max(1, self.n_steps - 1)


def _check_episode(maze: Maze, trajectory: Trajectory, robot: Robot | str | None) -> _Episode:
    """Check a trajectory against ``maze``, tell discrete from continuous moves and
    find the discrete moves into walls (the robot stayed put, pushing against one).
    """
    positions = getattr(trajectory, "positions", None)
    if positions is None or not hasattr(trajectory, "final_position"):
        raise TrajectoryError(f"expected a Trajectory, not {trajectory!r}")
    if len(positions) == 0:
        raise TrajectoryError("the trajectory is empty: it records no step to draw")
    if trajectory.final_position is None:
        raise TrajectoryError("the trajectory has no final_position (where the robot ended)")
    try:
        states = np.array([*positions, trajectory.final_position], dtype=float)
    except (TypeError, ValueError):
        raise TrajectoryError(f"trajectory positions must be (x, y) pairs: {positions!r}") from None
    n = len(positions)
    if states.shape != (n + 1, 2):
        raise TrajectoryError(
            f"trajectory positions must be (x, y) pairs, got shape {states.shape}"
        )
    outside = ~np.isfinite(states).all(axis=1)
    outside |= (states[:, 0] < 0) | (states[:, 0] > maze.width)
    outside |= (states[:, 1] < 0) | (states[:, 1] > maze.height)
    if outside.any():
        k = int(np.argmax(outside))
        what = "final position" if k == n else f"position at step {k}"
        raise TrajectoryError(
            f"{what} {tuple(float(v) for v in states[k])} is outside the"
            f" {maze.width}x{maze.height} maze"
        )
    actions = _optional_series(trajectory, "actions", n, (n, 2))
    rewards = _optional_series(trajectory, "rewards", n, (n,))

    if robot is not None:
        try:
            discrete = as_robot(robot).discrete_outputs
        except ValueError as error:
            raise TrajectoryError(str(error)) from None
    else:
        on_centres = bool(np.all(states - np.floor(states) == 0.5))
        unit_moves = actions is None or all(tuple(a) in OFFSETS for a in actions.astype(float))
        discrete = on_centres and unit_moves

    final_cell = (min(int(states[n, 0]), maze.width - 1), min(int(states[n, 1]), maze.height - 1))
    collisions: list[tuple[int, tuple[int, int], int]] = []
    if discrete and actions is not None:
        for k in range(n):
            if not np.array_equal(states[k], states[k + 1]):
                continue
            offset = (round(float(actions[k, 0])), round(float(actions[k, 1])))
            if offset not in OFFSETS:
                continue
            side = OFFSETS.index(offset)
            cell = (min(int(states[k, 0]), maze.width - 1), min(int(states[k, 1]), maze.height - 1))
            if maze.walls[cell[0], cell[1], side]:
                collisions.append((k, cell, side))
    return _Episode(
        states=states,
        actions=actions,
        rewards=rewards,
        discrete=discrete,
        success=final_cell == maze.end,
        collisions=tuple(collisions),
    )


def _optional_series(
    trajectory: Trajectory, name: str, n: int, shape: tuple[int, ...]
) -> np.ndarray | None:
    """``trajectory.<name>`` as a float array of ``shape``, or None when not recorded."""
    values = getattr(trajectory, name, None)
    if values is None or len(values) == 0:
        return None
    try:
        array = np.array(values, dtype=float)
    except (TypeError, ValueError):
        raise TrajectoryError(f"trajectory {name} are not numbers: {values!r}") from None
    if array.shape != shape:
        raise TrajectoryError(
            f"trajectory has {len(values)} {name} for {n} positions (expected shape {shape},"
            f" got {array.shape})"
        )
    return array


def _resolve(
    maze: Maze | MazeSpec | str, options: RenderOptions | None, overrides: dict[str, Any]
) -> tuple[Maze, RenderOptions, MazeLayout]:
    """The maze, options and layout, with bad values reported as :class:`TrajectoryError`."""
    try:
        maze = as_maze(maze)
        if options is None:
            options = RenderOptions()
        elif not isinstance(options, RenderOptions):
            raise TrajectoryError(f"options must be a RenderOptions, not {options!r}")
        options = options.with_overrides(**overrides)
        layout = MazeLayout.of(maze, options)
    except RenderError as error:
        raise TrajectoryError(str(error)) from None
    except AmazeError:
        raise
    except ValueError as error:
        raise TrajectoryError(str(error)) from None
    return maze, options, layout


# -- drawing --------------------------------------------------------------------------


def _supersampling(cell: int) -> int:
    """How many times larger overlays are drawn before being averaged down."""
    return 4 if cell <= 24 else 3 if cell <= 48 else 2


class _Painter:
    """Draws an episode's overlay on a transparent layer ``scale`` times the picture.

    Coordinates passed in are maze units (north up); strokes are laid out once,
    then drawn step by step so that animations can add to the same layer.
    """

    def __init__(
        self, maze: Maze, layout: MazeLayout, options: RenderOptions, episode: _Episode
    ) -> None:
        self.maze, self.layout, self.episode = maze, layout, episode
        self.theme = options.theme
        self.colors: Palette = options.colors
        self.colorblind = bool(options.colorblind)
        self.scale = _supersampling(layout.cell_size)
        cell = layout.cell_size
        if episode.discrete:
            self.line_px = max(2.0, cell * 0.09)
        else:
            self.line_px = max(1.5, cell * 0.055)
        width, height = layout.size
        self.layer = Image.new("RGBA", (width * self.scale, height * self.scale), (0, 0, 0, 0))
        self.draw = ImageDraw.Draw(self.layer)
        self.strokes = self._discrete_strokes() if episode.discrete else None
        self.ticks_done: Counter[tuple[tuple[int, int], int]] = Counter()
        self.drawn_until = 0
        #: Layer box ``[x0, y0, x1, y1]`` drawn on since the last :meth:`overlay`.
        self.dirty: list[float] | None = None
        self.small: Image.Image | None = None

    # coordinates

    def px(self, x: float, y: float) -> tuple[float, float]:
        """Picture pixel coordinates (edges at integers) of maze point ``(x, y)``.

        With an even cell size, everything moves half a pixel south-east so that
        a cell's centre is the middle of its :meth:`MazeLayout.cell_center` pixel,
        as for the solution path of :func:`render_maze`.
        """
        layout = self.layout
        shift = 0.5 if layout.cell_size % 2 == 0 else 0.0
        return (
            layout.margin + x * layout.cell_size + shift,
            layout.margin + (self.maze.height - y) * layout.cell_size + shift,
        )

    def big(self, x: float, y: float) -> tuple[float, float]:
        """Layer coordinates (pixel centres at integers) of maze point ``(x, y)``."""
        px, py = self.px(x, y)
        return px * self.scale - 0.5, py * self.scale - 0.5

    # path layout

    def _discrete_strokes(self) -> dict[int, list[tuple[float, float]]]:
        """For each step that moved, the polyline (maze units) it adds to the path.

        The ``n``-th traversal of a passage runs in lane ``0, +1, -1, +2, -2, ...``
        (shifted north or east), and the corners between consecutive moves meet
        where their lanes cross, so repeated visits stay apart.
        """
        states = self.episode.states
        cell = self.layout.cell_size
        gap = (self.line_px + max(1.0, self.line_px / 3)) / cell
        max_lane = max(1, int(0.3 / gap))
        traversals: Counter[tuple[tuple[float, float], tuple[float, float]]] = Counter()
        moves: list[tuple[int, np.ndarray, np.ndarray, np.ndarray]] = []
        for k in range(self.episode.n_steps):
            a, b = states[k], states[k + 1]
            if np.array_equal(a, b):
                continue
            key = tuple(sorted((tuple(a), tuple(b))))
            count = traversals[key]
            traversals[key] += 1
            count %= 2 * max_lane + 1
            lane = (count + 1) // 2 * (1 if count % 2 else -1)
            direction = (b - a) / np.hypot(*(b - a))
            normal = np.array([abs(direction[1]), abs(direction[0])])  # north or east
            moves.append((k, a, b, normal * lane * gap))
        strokes: dict[int, list[tuple[float, float]]] = {}
        joint_in: list[np.ndarray] | None = None
        for index, (k, a, b, offset) in enumerate(moves):
            start = joint_in if joint_in is not None else [a + offset]
            following = moves[index + 1] if index + 1 < len(moves) else None
            if following is not None and np.array_equal(following[1], b):
                joint_out = _joint(a, b, offset, following[2], following[3])
            else:
                joint_out = [b + offset]
                following = None
            strokes[k] = [(float(p[0]), float(p[1])) for p in [*start, joint_out[0]]]
            joint_in = joint_out if following is not None else None
        return strokes

    # primitives

    def _line(self, points: Sequence[tuple[float, float]], color: Color, width_px: float) -> None:
        big = [self.big(x, y) for x, y in points]
        _polyline(self.draw, big, color, width_px * self.scale)
        pad = width_px * self.scale
        xs, ys = [p[0] for p in big], [p[1] for p in big]
        self._touch((min(xs) - pad, min(ys) - pad, max(xs) + pad, max(ys) + pad))

    def _touch(self, box: tuple[float, float, float, float]) -> None:
        """Remember that the layer changed inside ``box``."""
        if self.dirty is None:
            self.dirty = list(box)
        else:
            self.dirty = [
                min(self.dirty[0], box[0]),
                min(self.dirty[1], box[1]),
                max(self.dirty[2], box[2]),
                max(self.dirty[3], box[3]),
            ]

    # episode

    def draw_steps(self, until: int) -> None:
        """Add the path of steps ``drawn_until .. until - 1`` (and their collisions)."""
        episode = self.episode
        start, until = self.drawn_until, min(until, episode.n_steps)
        if until <= start:
            return
        if self.strokes is not None:
            for k in range(start, until):
                stroke = self.strokes.get(k)
                if stroke is not None:
                    self._line(stroke, _gradient(episode.time(k), self.theme), self.line_px)
            for k, cell, side in episode.collisions:
                if start <= k < until:
                    self._tick(cell, side, self.ticks_done[(cell, side)])
                    self.ticks_done[(cell, side)] += 1
        else:
            self._continuous(start, until)
        self.drawn_until = until

    def _continuous(self, start: int, until: int) -> None:
        """Polyline pieces of at most ``1/96`` of the episode, each of one colour."""
        n = self.episode.n_steps
        chunk = max(1, math.ceil(n / 96))
        k = start
        while k < until:
            end = min(until, (k // chunk + 1) * chunk)
            points = [tuple(p) for p in self.episode.states[k : end + 1]]
            color = _gradient(self.episode.time((k + end - 1) / 2), self.theme)
            self._line(points, color, self.line_px)
            k = end

    def _tick(self, cell: tuple[int, int], side: int, repeat: int) -> None:
        """A short tick across the wall on ``side`` of ``cell``; repeats spread along it."""
        i, j = cell
        slots = (0.0, 0.16, -0.16)
        if repeat >= len(slots):
            return
        along = slots[repeat]
        length = 0.18
        dx, dy = OFFSETS[side]
        wall = np.array([i + 0.5 + 0.5 * dx, j + 0.5 + 0.5 * dy])
        tangent = np.array([abs(dy), abs(dx)], float)
        base = wall + tangent * along
        inner = base - np.array([dx, dy], float) * length
        color = _TICK[(self.theme, self.colorblind)]
        width = max(1.5, self.layout.cell_size * 0.06)
        self._line([tuple(inner), tuple(base)], color, width)

    def disc(
        self,
        center: tuple[float, float],
        radius: float,
        fill: Color | None,
        outline: Color,
        outline_px: float,
    ) -> None:
        """A disc of ``radius`` (maze units) with an outline ``outline_px`` wide."""
        cx, cy = self.big(*center)
        r = radius * self.layout.cell_size * self.scale
        rim = max(1, round(outline_px * self.scale))
        box = (cx - r, cy - r, cx + r, cy + r)
        self._touch((box[0] - 1, box[1] - 1, box[2] + 1, box[3] + 1))
        self.draw.ellipse(
            box, fill=None if fill is None else (*fill, 255), outline=(*outline, 255), width=rim
        )

    def glyph(
        self, center: tuple[float, float], radius: float, success: bool, color: Color
    ) -> None:
        """A check mark (success) or a cross (failure) inside a disc of ``radius``."""
        scale = self.layout.cell_size * self.scale
        _glyph(self.draw, self.big(*center), radius * scale, success, color)

    def start_marker(self) -> None:
        """A ring around the first position, in the path's first colour."""
        cell = self.layout.cell_size
        ring = max(1.5, cell * 0.06)
        center = tuple(self.episode.states[0])
        self.disc(center, 0.3, None, self.colors.background, ring + 2)
        self.disc(center, 0.3 - 1 / cell, None, _gradient(0.0, self.theme), ring)

    def final_marker(self) -> None:
        """A disc in the path's last colour holding a check mark or a cross."""
        cell = self.layout.cell_size
        center = tuple(self.episode.states[-1])
        radius = 0.22 if self.episode.discrete else 0.18
        self.disc(center, radius, _gradient(1.0, self.theme), self.colors.wall, max(1.0, cell / 28))
        if radius * cell >= 4:
            self.glyph(center, radius, self.episode.success, self.colors.background)

    def overlay(self, alpha: float = 1.0) -> Image.Image:
        """The layer averaged down to the picture's size, its opacity scaled by ``alpha``.

        Only the part drawn on since the previous call is averaged again, so that
        animations pay for the new steps only. Callers must not modify the result.
        """
        size = self.layout.size
        if self.small is None:
            self.small = Image.new("RGBA", size, (0, 0, 0, 0))
            self.dirty = [0, 0, self.layer.width, self.layer.height]
        if self.dirty is not None:
            s = self.scale
            x0 = max(0, math.floor(self.dirty[0] / s) - 1)
            y0 = max(0, math.floor(self.dirty[1] / s) - 1)
            x1 = min(size[0], math.ceil(self.dirty[2] / s) + 2)
            y1 = min(size[1], math.ceil(self.dirty[3] / s) + 2)
            if x1 > x0 and y1 > y0:
                # Crop first: resizing an RGBA image premultiplies all of it.
                region = self.layer.crop((x0 * s, y0 * s, x1 * s, y1 * s))
                region = region.resize((x1 - x0, y1 - y0), Image.Resampling.BOX)
                if alpha < 1.0:
                    pixels = np.array(region)
                    pixels[..., 3] = np.round(pixels[..., 3] * alpha).astype(np.uint8)
                    region = Image.fromarray(pixels, "RGBA")
                self.small.paste(region, (x0, y0))
            self.dirty = None
        return self.small


def _joint(
    a: np.ndarray, b: np.ndarray, offset: np.ndarray, after: np.ndarray, after_offset: np.ndarray
) -> list[np.ndarray]:
    """The corner points where a move ``a -> b`` in lane ``offset`` hands over to the next
    move ``b -> after`` in lane ``after_offset``: one point where perpendicular lanes
    cross, else the end of one lane and the start of the other (a jog or a hairpin).
    """
    incoming, outgoing = b - a, after - b
    if abs(float(np.dot(incoming, outgoing))) < 1e-9:
        return [b + offset + after_offset]
    if np.array_equal(offset, after_offset) and float(np.dot(incoming, outgoing)) > 0:
        return [b + offset]
    return [b + offset, b + after_offset]


def _polyline(
    draw: ImageDraw.ImageDraw, points: Sequence[tuple[float, float]], color: Color, width: float
) -> None:
    """An opaque polyline about ``width`` px wide with round joints and round ends.

    Points are snapped to pixels and the width made odd, so that a line and its
    end caps are symmetric about the same pixel (no notch where strokes meet).
    """
    fill = (*color, 255)
    width_px = max(1, round(width)) | 1
    snapped = [(round(x), round(y)) for x, y in points]
    if len(snapped) > 1:
        draw.line(snapped, fill=fill, width=width_px, joint="curve")
    radius = (width_px - 1) / 2
    for cx, cy in (snapped[0], snapped[-1]):
        draw.ellipse((cx - radius, cy - radius, cx + radius, cy + radius), fill=fill)


def _glyph(
    draw: ImageDraw.ImageDraw,
    center: tuple[float, float],
    radius: float,
    success: bool,
    color: Color,
) -> None:
    """A check mark (success) or a cross (failure) fitting a disc of ``radius`` px."""
    cx, cy = center
    r = radius * 0.55
    width = max(1.2, radius * 0.22)
    if success:
        points = [(cx - r, cy), (cx - 0.3 * r, cy + 0.7 * r), (cx + r, cy - 0.75 * r)]
        _polyline(draw, points, color, width)
    else:
        q = r * 0.8
        _polyline(draw, [(cx - q, cy - q), (cx + q, cy + q)], color, width)
        _polyline(draw, [(cx - q, cy + q), (cx + q, cy - q)], color, width)


# -- captions -------------------------------------------------------------------------


def _summary(episode: _Episode) -> str:
    n = episode.n_steps
    parts = [f"goal reached in {n} steps" if episode.success else f"goal not reached, {n} steps"]
    if episode.discrete and episode.actions is not None:
        count = len(episode.collisions)
        parts.append(f"{count} collision{'s' if count != 1 else ''}")
    if episode.rewards is not None:
        parts.append(f"return {float(episode.rewards.sum()):.2f}")
    return " · ".join(parts)


def _wrap_words(text: str, font: Any, width: float) -> list[str]:
    lines: list[str] = []
    for paragraph in text.splitlines() or [""]:
        current = ""
        for word in paragraph.split(" "):
            candidate = f"{current} {word}" if current else word
            if current and font.getlength(candidate) > width:
                lines.append(current)
                current = word
            else:
                current = candidate
        lines.append(current)
    return lines


def _legend_icons(
    size: int, options: RenderOptions, episode: _Episode
) -> list[tuple[Image.Image, str]]:
    """Small antialiased icons, ``size`` px square, with the words they stand for."""
    colors = options.colors
    factor = 4
    big = size * factor
    centre = (big - 1) / 2

    def tile() -> tuple[Image.Image, ImageDraw.ImageDraw]:
        image = Image.new("RGBA", (big, big), (0, 0, 0, 0))
        return image, ImageDraw.Draw(image)

    def shrink(image: Image.Image) -> Image.Image:
        return image.resize((size, size), Image.Resampling.BOX)

    icons = []
    image, draw = tile()
    r, rim = big * 0.4, max(1, round(big * 0.13))
    draw.ellipse(
        (centre - r, centre - r, centre + r, centre + r),
        outline=(*_gradient(0.0, options.theme), 255),
        width=rim,
    )
    icons.append((shrink(image), "start"))
    image, draw = tile()
    draw.ellipse(
        (centre - r, centre - r, centre + r, centre + r),
        fill=(*_gradient(1.0, options.theme), 255),
        outline=(*colors.wall, 255),
        width=max(1, round(big * 0.06)),
    )
    _glyph(draw, (centre, centre), r, episode.success, colors.background)
    icons.append((shrink(image), "end" if not episode.success else "end (goal)"))
    if episode.collisions:
        image, draw = tile()
        wall = max(2, round(big * 0.12))
        draw.rectangle((0, big - wall, big - 1, big - 1), fill=(*colors.wall, 255))
        tick = _TICK[(options.theme, bool(options.colorblind))]
        _polyline(draw, [(centre, big * 0.35), (centre, big - wall)], tick, big * 0.16)
        icons.append((shrink(image), "wall bump"))
    return icons


def _add_caption(
    image: Image.Image, layout: MazeLayout, options: RenderOptions, episode: _Episode, text: str
) -> Image.Image:
    """The picture with a band below: the time gradient (first to last step) under
    which a legend of the markers sits, then ``text``.
    """
    colors = options.colors
    left = layout.margin
    width = layout.width * layout.cell_size
    font = load_font(max(10, min(15, image.width // 40)))
    line_h = int(font.getbbox("Mg_0")[3]) + 3
    bar_h = max(4, line_h // 3)
    lines = _wrap_words(text, font, width)
    pad = max(4, layout.margin // 2)
    band = pad + bar_h + 3 + line_h + 4 + len(lines) * line_h + pad
    picture = Image.new("RGB", (image.width, image.height + band), colors.background)
    picture.paste(image, (0, 0))
    draw = ImageDraw.Draw(picture)
    y = image.height - layout.margin + layout.wall_width + pad
    ramp = np.array([_gradient(x, options.theme) for x in np.linspace(0, 1, width)], np.uint8)
    picture.paste(Image.fromarray(np.repeat(ramp[None], bar_h, axis=0), "RGB"), (left, y))
    y += bar_h + 3
    first, last = "step 1", f"step {episode.n_steps}"
    draw.text((left, y), first, fill=colors.text, font=font)
    last_w = draw.textlength(last, font=font)
    draw.text((left + width - last_w, y), last, fill=colors.text, font=font)
    # The legend, centred between the two step labels when it fits there.
    icon = max(8, line_h - 3)
    icons = _legend_icons(icon, options, episode)
    gap = icon // 2
    items = [icon + 3 + draw.textlength(word, font=font) for _, word in icons]
    legend_w = sum(items) + gap * 2 * (len(items) - 1)
    free = width - draw.textlength(first, font=font) - last_w - 4 * gap
    if legend_w <= free:
        x = left + (width - legend_w) / 2
        for (tile, word), item_w in zip(icons, items, strict=True):
            picture.paste(tile, (round(x), y + (line_h - 3 - icon) // 2 + 1), tile)
            draw.text((x + icon + 3, y), word, fill=colors.text, font=font)
            x += item_w + 2 * gap
    y += line_h + 4
    for line in lines:
        draw.text((left, y), line, fill=colors.text, font=font)
        y += line_h
    return picture


# -- public API -----------------------------------------------------------------------


def render_trajectory(
    maze: Maze | MazeSpec | str,
    trajectory: Trajectory,
    *,
    options: RenderOptions | None = None,
    robot: Robot | str | None = None,
    caption: str | bool | None = None,
    **overrides: Any,
) -> Image.Image:
    """The maze with the path of one episode drawn over it, as an RGB image.

    ``trajectory`` is a recorded :class:`~amaze.agents.simulation.Trajectory` of at least
    one step. ``robot`` tells discrete moves (cell to cell) from continuous ones;
    without it, a trajectory whose positions all lie on cell centres and whose
    actions are unit moves is taken as discrete. ``caption`` adds a band below
    the maze with the time gradient and a line of text: ``True`` for a summary
    (steps, success, collisions, the return when rewards were recorded), a string
    for that text followed by the summary; ``None`` or ``False`` (default) keeps
    the picture the size of :func:`~amaze.maze.render.render_maze`'s. Other keyword
    arguments override fields of ``options`` (``theme="dark"``, ``cell_size=32``...).
    Bad input raises :class:`TrajectoryError` naming the value.
    """
    maze, options, layout = _resolve(maze, options, overrides)
    episode = _check_episode(maze, trajectory, robot)
    if caption is not None and not isinstance(caption, (bool, str)):
        raise TrajectoryError(f"caption={caption!r} must be a string, True or False")
    background = render_maze(maze, options)
    painter = _Painter(maze, layout, options, episode)
    painter.draw_steps(episode.n_steps)
    painter.start_marker()
    painter.final_marker()
    overlay = painter.overlay()
    image = background.copy()
    image.paste(overlay, (0, 0), overlay)
    if caption:
        summary = _summary(episode)
        text = summary if caption is True else f"{caption}\n{summary}"
        image = _add_caption(image, layout, options, episode, text)
    return image


def save_trajectory_png(
    maze: Maze | MazeSpec | str,
    trajectory: Trajectory,
    path: str | os.PathLike,
    **kwargs: Any,
) -> Path:
    """Write :func:`render_trajectory`'s picture as a PNG file (folders are created).

    Keyword arguments are those of :func:`render_trajectory`.
    """
    image = render_trajectory(maze, trajectory, **kwargs)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    image.save(path, format="PNG")
    return path


def frame_steps(n_steps: int, max_frames: int) -> list[int]:
    """The states shown by an animation of ``n_steps`` steps: evenly spread, at most
    ``max_frames``, always the first (0, before any step) and the last (``n_steps``).
    """
    frames = check_integer("max_frames", max_frames, minimum=2, error=TrajectoryError)
    count = min(n_steps + 1, frames)
    # floor(x + 1/2) rather than round(): ties to even could give two equal indices.
    return [int(v) for v in np.floor(np.linspace(0, n_steps, count) + 0.5)]


def render_episode_frames(
    maze: Maze | MazeSpec | str,
    trajectory: Trajectory,
    *,
    options: RenderOptions | None = None,
    max_frames: int = 200,
    robot: Robot | str | None = None,
    **overrides: Any,
) -> list[Image.Image]:
    """One RGB picture per step of an episode, for animations.

    Frame ``m`` shows the robot where it stood before step ``m`` (the last frame:
    where it ended, with a check mark or a cross when the disc is large enough)
    as a disc (0.3 cell for discrete robots, the physical radius for continuous
    ones) over the faded path it took so far; a discrete robot that just bumped
    into a wall is drawn nudged towards it. Long episodes are subsampled evenly
    to at most ``max_frames`` frames (see :func:`frame_steps`). Frames have the
    size of :func:`~amaze.maze.render.render_maze`'s picture; the maze is rendered
    once and the path is drawn incrementally. ``options``, ``robot`` and the
    keyword overrides are those of :func:`render_trajectory`.
    """
    maze, options, layout = _resolve(maze, options, overrides)
    episode = _check_episode(maze, trajectory, robot)
    steps = frame_steps(episode.n_steps, max_frames)
    background = render_maze(maze, options)
    painter = _Painter(maze, layout, options, episode)
    bumps = {k: side for k, _, side in episode.collisions}
    colors = options.colors
    fill = _AGENT[bool(options.colorblind)]
    radius = max(0.3 if episode.discrete else RADIUS, 2.5 / layout.cell_size)
    frames = []
    for m in steps:
        painter.draw_steps(m)
        image = background.copy()
        # Pasting through the alpha band is "over" compositing on an opaque picture.
        trail = painter.overlay(_TRAIL_ALPHA)
        image.paste(trail, (0, 0), trail)
        x, y = episode.states[m]
        if m - 1 in bumps:
            dx, dy = OFFSETS[bumps[m - 1]]
            x, y = x + 0.08 * dx, y + 0.08 * dy
        tile, corner = _agent_picture(
            painter, (x, y), radius, fill, colors, last=m == episode.n_steps
        )
        image.paste(tile, corner, tile)
        frames.append(image)
    return frames


def _agent_picture(
    painter: _Painter,
    center: tuple[float, float],
    radius: float,
    fill: Color,
    colors: Palette,
    last: bool,
) -> tuple[Image.Image, tuple[int, int]]:
    """The antialiased agent disc on a small transparent tile, and where it goes.

    On the last frame it holds a check mark or a cross when large enough.
    """
    cell = painter.layout.cell_size
    scale = painter.scale
    px, py = painter.px(*center)
    r = radius * cell
    x0, y0 = math.floor(px - r - 2), math.floor(py - r - 2)
    side = math.ceil(2 * r + 5)
    tile = Image.new("RGBA", (side * scale, side * scale), (0, 0, 0, 0))
    draw = ImageDraw.Draw(tile)
    cx, cy = (px - x0) * scale - 0.5, (py - y0) * scale - 0.5
    rim = max(1, round(max(1.0, cell / 40) * scale))
    big_r = r * scale
    draw.ellipse(
        (cx - big_r, cy - big_r, cx + big_r, cy + big_r),
        fill=(*fill, 255),
        outline=(*colors.wall, 255),
        width=rim,
    )
    if last and r >= 7:
        _glyph(draw, (cx, cy), big_r, painter.episode.success, colors.background)
    return tile.resize((side, side), Image.Resampling.BOX), (x0, y0)


def save_episode_gif(
    maze: Maze | MazeSpec | str,
    trajectory: Trajectory,
    path: str | os.PathLike,
    *,
    fps: float = 10,
    max_frames: int = 200,
    final_pause: float = 1.5,
    **kwargs: Any,
) -> Path:
    """Write the episode as a looping animated GIF (folders are created).

    Frames come from :func:`render_episode_frames` (keyword arguments are its
    own), shown ``1/fps`` s each (``fps`` in [:data:`MIN_FPS`, :data:`MAX_FPS`]);
    the last one stays ``final_pause`` s (at least one frame's time, at most
    :data:`MAX_FINAL_PAUSE`): a GIF cannot hold longer delays. Bad values raise
    :class:`TrajectoryError` naming them. All frames share one adaptive palette, without dithering,
    so colours do not flicker; each frame is written once (the first is not
    repeated) and consecutive frames that are identical once quantised are merged
    into one longer frame, as GIF viewers would show them anyway.
    """
    fps = check_number("fps", fps, minimum=MIN_FPS, maximum=MAX_FPS, error=TrajectoryError)
    final_pause = check_number(
        "final_pause", final_pause, minimum=0, maximum=MAX_FINAL_PAUSE, error=TrajectoryError
    )
    frames = render_episode_frames(maze, trajectory, max_frames=max_frames, **kwargs)
    frame_ms = max(20, round(1000 / float(fps)))
    durations = [frame_ms] * len(frames)
    durations[-1] = max(frame_ms, round(1000 * float(final_pause)))
    quantised = _quantise(frames)
    merged: list[Image.Image] = []
    merged_ms: list[int] = []
    previous: bytes | None = None
    for frame, duration in zip(quantised, durations, strict=True):
        data = frame.tobytes()
        if data == previous and merged_ms[-1] + duration <= _MAX_GIF_DELAY_MS:
            merged_ms[-1] += duration
            continue
        merged.append(frame)
        merged_ms.append(duration)
        previous = data
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    merged[0].save(
        path,
        format="GIF",
        save_all=True,
        append_images=merged[1:],
        duration=merged_ms,
        loop=0,
        optimize=False,
        disposal=1,
    )
    return path


def _quantise(frames: list[Image.Image]) -> list[Image.Image]:
    """The frames in one shared palette, without dithering.

    The palette is made from the first, middle and last frames: their most
    frequent colours (background, walls, markers, sign grays, the agent) come
    first, then median cut's colours for the rest (antialiased edges, the path).
    Pillow maps pixels to a palette through a cache of 6 bits per channel, so a
    colour too close to one already chosen is left out: otherwise it could
    capture the pixels of that more frequent colour (white would turn off-white).
    """
    sample = [frames[0], frames[len(frames) // 2], frames[-1]]
    width, height = frames[0].size
    sheet = Image.new("RGB", (width, height * len(sample)))
    for index, frame in enumerate(sample):
        sheet.paste(frame, (0, index * height))
    counts = sheet.getcolors(maxcolors=width * height * len(sample)) or []
    counts.sort(key=lambda item: -item[0])
    candidates = [color for _, color in counts[:_EXACT_COLORS]]
    if len(counts) > _EXACT_COLORS:
        flat = sheet.quantize(colors=256, method=Image.Quantize.MEDIANCUT).getpalette() or []
        candidates += [tuple(flat[k : k + 3]) for k in range(0, len(flat), 3)]
    chosen = np.zeros((0, 3))
    for color in candidates:
        rgb = np.array(color[:3], dtype=float)
        if len(chosen) and np.min(np.sum((chosen - rgb) ** 2, axis=1)) <= _MIN_PALETTE_DISTANCE**2:
            continue
        chosen = np.vstack([chosen, rgb])
        if len(chosen) == 256:
            break
    palette = Image.new("P", (1, 1))
    palette.putpalette([int(v) for v in chosen.reshape(-1)])
    return [frame.quantize(palette=palette, dither=Image.Dither.NONE) for frame in frames]
