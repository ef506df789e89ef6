"""The summary picture of an input-recognition test (:mod:`amaze.evaluation.inputs`).

:func:`render_summary` draws every input of an
:class:`~amaze.evaluation.inputs.InputRecognition` and the action the policy
chose; :func:`save_summary_png` writes it as a PNG. The test itself does not
need this module (nor Pillow's drawing): the picture depends on the test, never
the reverse.

The header gives the overall rate and one rate bar per class. Below it, one
section per class shows every input as a tile: the cell as the robot
perceives it (white walls, the sign at its lightness on black, the side the
agent came from in red; hybrid robots: their own image, scaled up, with the
arrival pixel in red) and, outside the cell, a filled arrow on the side of the
chosen action: green when it is the correct one, red otherwise, the correct
side then being marked by an outlined blue arrow.
"""

from __future__ import annotations

import math
import os
from functools import lru_cache
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from amaze.evaluation.inputs import InputClass, InputRecognition, InputRecognitionError
from amaze.maze.render import Palette, load_font, palette
from amaze.maze.sign_images import sign_frames
from amaze.maze.signs import Sign
from amaze.validation import check_integer

__all__ = ["render_summary", "save_summary_png"]


def render_summary(
    recognition: InputRecognition,
    theme: str = "light",
    colorblind: bool = False,
    columns: int = 12,
) -> Image.Image:
    """The summary picture of ``recognition`` (see the module docstring), ``columns`` tiles per row.

    :raises InputRecognitionError: when ``columns`` is not a positive integer.
    :raises ValueError: for an unknown theme.
    """
    return _SummaryPicture(recognition, palette(theme, colorblind), columns).draw()


def save_summary_png(
    recognition: InputRecognition,
    path: str | os.PathLike,
    theme: str = "light",
    colorblind: bool = False,
    columns: int = 12,
) -> Path:
    """Write :func:`render_summary`'s picture to ``path`` as a PNG (folders are created)."""
    image = render_summary(recognition, theme, colorblind, columns)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    image.save(path, format="PNG")
    return path


_CLASS_TITLES = {
    InputClass.EMPTY: ("Empty", "dead ends and corridors without a sign"),
    InputClass.LURE: ("Lure", "dead ends and corridors with a lure: ignore it"),
    InputClass.CLUE: ("Clue", "intersections with a clue: follow it"),
    InputClass.TRAP: ("Trap", "intersections with a trap: avoid its way"),
    InputClass.EMPTY_INTERSECTION: ("Empty intersection", "no sign: a conventional answer"),
}

_CORRECT = (46, 160, 67)
_WRONG = (214, 39, 40)
_ORIGIN = (229, 72, 77)
_WALL = (255, 255, 255)
_TILE = (0, 0, 0)


@lru_cache(maxsize=128)
def _sign_picture(sign: Sign, direction: int, size: int) -> Image.Image:
    """The sign at its lightness, ``size`` px, antialiased by drawing 4x larger."""
    frame = np.asarray(sign_frames(sign, 4 * size)[direction], dtype=np.float64)
    big = Image.fromarray(np.round(np.clip(frame, 0, 1) * 255).astype(np.uint8), mode="L")
    return big.reduce(4).convert("RGB")


class _SummaryPicture:
    """Lays out and draws the summary of an :class:`InputRecognition`."""

    PAD = 20
    GAP = 6
    GUTTER = 96

    def __init__(self, result: InputRecognition, colors: Palette, columns: int) -> None:
        self.result = result
        self.colors = colors
        self.columns = check_integer("columns", columns, minimum=1, error=InputRecognitionError)
        robot = result.inputs.robot
        if robot.discrete_inputs:
            self.cell = 42
        else:
            v = int(robot.vision)
            self.cell = v * max(1, math.ceil(42 / v))
        self.wall = max(2, round(self.cell / 14))
        # A black plate around the cell, so that its walls show on any background.
        self.ring = 4
        self.arrow = self.ring + max(10, round(self.cell * 0.28))
        self.slot = self.cell + 2 * self.arrow
        self.expected_color = colors.path
        self.fonts = {size: load_font(size) for size in (12, 13, 15, 22)}
        self.muted = _mix(colors.text, colors.background, 0.45)
        self.faint = _mix(colors.text, colors.background, 0.85)
        self.plate_edge = _mix(colors.text, colors.background, 0.7)

    # layout helpers
    @property
    def width(self) -> int:
        return 2 * self.PAD + self.GUTTER + self.columns * (self.slot + self.GAP) - self.GAP

    def _groups(self) -> list[tuple[InputClass, list[list[int]]]]:
        """Per class present: its inputs split by cell type (each group starts a row)."""
        cases = self.result.inputs.cases
        groups: list[tuple[InputClass, list[list[int]]]] = []
        for input_class in InputClass:
            indices = [k for k, case in enumerate(cases) if case.input_class is input_class]
            if not indices:
                continue
            by_type: list[list[int]] = []
            for k in indices:
                if by_type and cases[by_type[-1][0]].input_type is cases[k].input_type:
                    by_type[-1].append(k)
                else:
                    by_type.append([k])
            groups.append((input_class, by_type))
        return groups

    def draw(self) -> Image.Image:
        groups = self._groups()
        header_h = 150
        section_title_h = 44
        row_h = self.slot + self.GAP
        height = self.PAD + header_h
        for _, by_type in groups:
            rows = sum(math.ceil(len(g) / self.columns) for g in by_type)
            height += section_title_h + rows * row_h + 14
        height += self.PAD
        image = Image.new("RGB", (self.width, height), self.colors.background)
        draw = ImageDraw.Draw(image)
        self._draw_header(draw, image)
        y = self.PAD + header_h
        for input_class, by_type in groups:
            y = self._draw_section(image, draw, y, input_class, by_type)
        return image

    def _draw_header(self, draw: ImageDraw.ImageDraw, image: Image.Image) -> None:
        result = self.result
        inputs = result.inputs
        x, y = self.PAD, self.PAD
        text = self.colors.text
        draw.text((x, y), "Input recognition", fill=text, font=self.fonts[22])
        signs = [
            f"{name} {' '.join(s.to_string() for s in lst) or '-'}"
            for name, lst in (
                ("clues", inputs.clues),
                ("lures", inputs.lures),
                ("traps", inputs.traps),
            )
        ]
        subtitle = f"robot {inputs.robot}  ·  {len(inputs)} inputs  ·  " + "  ·  ".join(signs)
        draw.text((x, y + 30), subtitle, fill=self.muted, font=self.fonts[13])
        # Rate cards: overall, then each class.
        cards = [("overall", int(result.success.sum()), len(result))]
        counts, totals = result.counts, result.totals
        cards += [(c.value.replace("_", " "), counts[c], totals[c]) for c in totals]
        card_w = min(170, (self.width - 2 * self.PAD - 10 * (len(cards) - 1)) // len(cards))
        cy = y + 58
        for k, (name, correct, total) in enumerate(cards):
            cx = x + k * (card_w + 10)
            rate = correct / total if total else 0.0
            draw.text((cx, cy), name, fill=self.muted, font=self.fonts[13])
            draw.text((cx, cy + 16), f"{100 * rate:.1f}%", fill=text, font=self.fonts[22])
            draw.text(
                (cx + card_w, cy + 24),
                f"{correct}/{total}",
                fill=self.muted,
                font=self.fonts[12],
                anchor="ra",
            )
            bar_y = cy + 48
            draw.rectangle((cx, bar_y, cx + card_w, bar_y + 6), fill=self.faint)
            filled = round(card_w * rate)
            if filled > 0:
                draw.rectangle((cx, bar_y, cx + filled, bar_y + 6), fill=_rate_color(rate))
        self._draw_legend(image, draw, x, cy + 66)

    def _draw_legend(self, image: Image.Image, draw: ImageDraw.ImageDraw, x: int, y: int) -> None:
        font = self.fonts[12]
        size = 14
        items = [
            ("expected, when missed", "outline", self.expected_color),
            ("chosen, correct", "fill", _CORRECT),
            ("chosen, wrong", "fill", _WRONG),
            ("came from", "origin", _ORIGIN),
        ]
        for label, style, color in items:
            box = (x, y, x + size, y + size)
            if style == "origin":
                draw.rectangle((x, y + 4, x + size, y + size - 4), fill=color)
            else:
                points = _triangle(box, 0)
                if style == "fill":
                    draw.polygon(points, fill=color)
                else:
                    draw.polygon(points, outline=color, width=2)
            draw.text((x + size + 6, y), label, fill=self.muted, font=font)
            x += size + 6 + int(draw.textlength(label, font=font)) + 22

    def _draw_section(
        self,
        image: Image.Image,
        draw: ImageDraw.ImageDraw,
        y: int,
        input_class: InputClass,
        by_type: list[list[int]],
    ) -> int:
        result = self.result
        text = self.colors.text
        x0 = self.PAD
        draw.line((x0, y + 4, self.width - self.PAD, y + 4), fill=self.faint, width=1)
        title, description = _CLASS_TITLES[input_class]
        draw.text((x0, y + 14), title, fill=text, font=self.fonts[15])
        offset = int(draw.textlength(title, font=self.fonts[15])) + 10
        draw.text((x0 + offset, y + 16), description, fill=self.muted, font=self.fonts[13])
        correct, total = result.counts[input_class], result.totals[input_class]
        rate = correct / total
        draw.text(
            (self.width - self.PAD, y + 14),
            f"{correct}/{total} correct  ·  {100 * rate:.1f}%",
            fill=_rate_color(rate),
            font=self.fonts[15],
            anchor="ra",
        )
        y += 44
        cases = result.inputs.cases
        for group in by_type:
            label = cases[group[0]].input_type.value.replace("-", " ").lower()
            label_y = y + self.slot // 2
            draw.text((x0, label_y), label, fill=self.muted, font=self.fonts[13], anchor="lm")
            for start in range(0, len(group), self.columns):
                for col, k in enumerate(group[start : start + self.columns]):
                    left = x0 + self.GUTTER + col * (self.slot + self.GAP)
                    self._draw_tile(image, draw, left, y, k)
                y += self.slot + self.GAP
        return y + 14

    def _draw_tile(
        self, image: Image.Image, draw: ImageDraw.ImageDraw, left: int, top: int, k: int
    ) -> None:
        case = self.result.inputs.cases[k]
        c, a, w = self.cell, self.arrow, self.wall
        x0, y0 = left + a, top + a
        x1, y1 = x0 + c - 1, y0 + c - 1
        ring = self.ring
        draw.rectangle(
            (x0 - ring, y0 - ring, x1 + ring, y1 + ring), fill=_TILE, outline=self.plate_edge
        )
        if self.result.inputs.robot.discrete_inputs:
            if case.sign is not None:
                inset = w + max(2, c // 14)
                size = c - 2 * inset
                picture = _sign_picture(case.sign, int(case.sign_direction), size)
                image.paste(picture, (x0 + inset, y0 + inset))
            bands = {
                0: (x1 - w + 1, y0, x1, y1),
                1: (x0, y0, x1, y0 + w - 1),
                2: (x0, y0, x0 + w - 1, y1),
                3: (x0, y1 - w + 1, x1, y1),
            }
            for side, walled in enumerate(case.walls):
                if walled:
                    draw.rectangle(bands[side], fill=_WALL)
            if case.arrival is not None:
                half = max(3, c // 8)
                mid_x, mid_y = (x0 + x1) // 2, (y0 + y1) // 2
                marker = {
                    0: (x1 - w + 1, mid_y - half, x1, mid_y + half),
                    1: (mid_x - half, y0, mid_x + half, y0 + w - 1),
                    2: (x0, mid_y - half, x0 + w - 1, mid_y + half),
                    3: (mid_x - half, y1 - w + 1, mid_x + half, y1),
                }[int(case.arrival)]
                draw.rectangle(marker, fill=_ORIGIN)
        else:
            observation = self.result.inputs.observations[k, 0]
            v = observation.shape[0]
            rgb = np.repeat(observation[:, :, None], 3, axis=2)
            if case.arrival is not None:
                middle = v // 2
                r, col = [(middle, v - 1), (0, middle), (middle, 0), (v - 1, middle)][
                    int(case.arrival)
                ]
                rgb[r, col] = _ORIGIN
            picture = Image.fromarray(rgb, mode="RGB").resize((c, c), Image.Resampling.NEAREST)
            image.paste(picture, (x0, y0))
        chosen = int(self.result.actions[k])
        expected = int(case.expected)
        if chosen == expected:
            draw.polygon(_triangle(self._arrow_box(x0, y0, chosen), chosen), fill=_CORRECT)
            return
        draw.polygon(_triangle(self._arrow_box(x0, y0, chosen), chosen), fill=_WRONG)
        draw.polygon(
            _triangle(self._arrow_box(x0, y0, expected), expected),
            outline=self.expected_color,
            width=2,
        )

    def _arrow_box(self, x0: int, y0: int, side: int) -> tuple[int, int, int, int]:
        """The square outside side ``side`` of the cell at ``(x0, y0)`` that holds an arrow."""
        c, a = self.cell, self.arrow
        gap = self.ring + 2
        depth = a - gap - 1
        half = min(c // 2 - 2, round(0.75 * a))
        mid_x, mid_y = x0 + c // 2, y0 + c // 2
        if side == 0:
            return (x0 + c + gap, mid_y - half, x0 + c + gap + depth, mid_y + half)
        if side == 2:
            return (x0 - gap - depth - 1, mid_y - half, x0 - gap - 1, mid_y + half)
        if side == 1:
            return (mid_x - half, y0 - gap - depth - 1, mid_x + half, y0 - gap - 1)
        return (mid_x - half, y0 + c + gap, mid_x + half, y0 + c + gap + depth)


def _triangle(box: tuple[int, int, int, int], side: int) -> list[tuple[float, float]]:
    """A triangle filling ``box`` and pointing towards ``side`` (0 = E, 1 = N, 2 = W, 3 = S)."""
    x0, y0, x1, y1 = box
    mx, my = (x0 + x1) / 2, (y0 + y1) / 2
    return {
        0: [(x0, y0), (x1, my), (x0, y1)],
        1: [(x0, y1), (mx, y0), (x1, y1)],
        2: [(x1, y0), (x0, my), (x1, y1)],
        3: [(x0, y0), (mx, y1), (x1, y0)],
    }[side]


def _mix(a: tuple[int, int, int], b: tuple[int, int, int], t: float) -> tuple[int, int, int]:
    """The colour ``t`` of the way from ``a`` to ``b``."""
    r, g, b_ = (round(x + (y - x) * t) for x, y in zip(a, b, strict=True))
    return r, g, b_


def _rate_color(rate: float) -> tuple[int, int, int]:
    """Red for 0, amber around 0.5, green for 1."""
    amber = (222, 143, 5)
    if rate < 0.5:
        return _mix(_WRONG, amber, rate / 0.5)
    return _mix(amber, _CORRECT, (rate - 0.5) / 0.5)
