"""Robots: what an agent perceives and how it acts (reference §4.1).

A robot string is ``IO[V]`` or a shorthand ``S[V]``:

* ``DD``: discrete inputs (the 8-float vector), discrete actions (E, N, W, S);
* ``CD`` or ``H``: *hybrid*, a ``V x V`` image of the cell in, discrete actions out;
* ``CC`` or ``C``: continuous, a ``V x V`` image window in, an acceleration out.

``V`` (vision) must be odd and within [5, 65] when given for image inputs (default
15). Discrete inputs see no image, so they take no vision: ``DD15`` or ``D11`` is
an error. The reference accepted and ignored it (``D11`` was ``DD``), so a
mistyped hybrid robot (``D15`` for ``H15``) silently became another robot.
Discrete inputs with continuous outputs (``DC``) are not allowed.

Why 65 at most (:data:`MAX_VISION`): a sign is drawn on the ``V - 2`` pixels
inside the cell's walls, and the reference's own drawings of the built-in
signs are stored for sizes 3 to 64 only (``amaze.maze.sign_images``), so up
to 65 every observation is the reference's, pixel for pixel. It is already
more than four times the paper's 15 (and the reference's default); beyond it an
observation grows with ``V^2`` bytes per agent for nothing: ``H10001`` asked for
images of 10^8 pixels.
Canonical strings: ``DD``, ``CD15``, ``CC11``.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

from amaze.errors import AmazeError
from amaze.validation import check_integer

DEFAULT_VISION = 15
MIN_VISION = 5
#: The largest vision (see the module docstring).
MAX_VISION = 65

#: Physics constants of continuous control (reference §4.1).
RADIUS = 0.1
INERTIAL_LOSS = 0.5
ACCELERATION_SCALE = 0.5
#: The time step of continuous robots (discrete ones step by 1).
CONTINUOUS_DT = 0.1
#: Below this speed a continuous robot stops (its velocity is set to zero).
MIN_SPEED = min(0.01, ACCELERATION_SCALE / 2)


class RobotStringError(AmazeError):
    """A robot string is malformed or describes an unsupported robot."""


def _no_vision(vision: object) -> str:
    """Why discrete inputs refuse a vision, and what the user may have meant."""
    text = f"DD (discrete inputs) takes no vision size, got {vision!r}; write DD"
    if isinstance(vision, int) and vision % 2 == 1 and MIN_VISION <= vision <= MAX_VISION:
        text += f", or H{vision} / CC{vision} for {vision}x{vision} images"
    return text


class IOType(StrEnum):
    """Whether an input or output side is discrete or continuous."""

    DISCRETE = "D"
    CONTINUOUS = "C"


@dataclass(frozen=True)
class Robot:
    """A robot's input and output types and its vision (image side, odd, or None)."""

    inputs: IOType = IOType.DISCRETE
    outputs: IOType = IOType.DISCRETE
    vision: int | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "inputs", IOType(self.inputs))
        object.__setattr__(self, "outputs", IOType(self.outputs))
        if self.inputs is IOType.DISCRETE:
            if self.outputs is IOType.CONTINUOUS:
                raise RobotStringError(
                    "robot 'DC': discrete inputs with continuous outputs are not supported"
                )
            if self.vision is not None:
                raise RobotStringError(_no_vision(self.vision))
            return
        vision = DEFAULT_VISION if self.vision is None else self.vision
        vision = check_integer("robot vision", vision, error=RobotStringError)
        if vision % 2 != 1 or not MIN_VISION <= vision <= MAX_VISION:
            raise RobotStringError(
                f"robot vision {vision} must be odd and within [{MIN_VISION}, {MAX_VISION}]"
            )
        object.__setattr__(self, "vision", vision)

    @classmethod
    def from_string(cls, text: str) -> Robot:
        """Parse ``DD``, ``H15``, ``CD15``, ``C11``, ``CC``..."""
        if not isinstance(text, str) or not text:
            raise RobotStringError(f"robot string {text!r} is empty or not a string")
        shorthands = {"D": "DD", "H": "CD", "C": "CC"}
        if text[0] not in shorthands:
            raise RobotStringError(f"robot string '{text}' must start with D, H or C")
        if len(text) > 1 and text[1].isalpha():
            if text[0] == "H" or text[1] not in "DC":
                raise RobotStringError(f"robot string '{text}': unknown output type '{text[1]}'")
            io, rest = text[:2], text[2:]
        else:
            io, rest = shorthands[text[0]], text[1:]
        if rest and not rest.isdigit():
            raise RobotStringError(f"robot string '{text}': vision '{rest}' is not a number")
        if io == "DC":
            raise RobotStringError(
                f"robot string '{text}': discrete inputs with continuous outputs are not supported"
            )
        vision = int(rest) if rest else None
        try:
            return cls(IOType(io[0]), IOType(io[1]), vision)
        except RobotStringError as error:
            raise RobotStringError(f"robot string '{text}': {error}") from None

    def to_string(self) -> str:
        text = f"{self.inputs.value}{self.outputs.value}"
        return text if self.vision is None else f"{text}{self.vision}"

    def __str__(self) -> str:
        return self.to_string()

    @property
    def discrete_inputs(self) -> bool:
        return self.inputs is IOType.DISCRETE

    @property
    def discrete_outputs(self) -> bool:
        return self.outputs is IOType.DISCRETE

    @property
    def kind(self) -> str:
        """``discrete`` (DD), ``hybrid`` (CD) or ``continuous`` (CC)."""
        if self.discrete_inputs:
            return "discrete"
        return "hybrid" if self.discrete_outputs else "continuous"


def as_robot(robot: Robot | str) -> Robot:
    """A :class:`Robot` from a robot or its string."""
    return robot if isinstance(robot, Robot) else Robot.from_string(robot)


def robot_name(robot: Robot | str) -> str:
    """A robot as a message should name it: as the user spelled it, then its canonical string.

    ``H15`` reads ``H15 (CD15)``, ``CD15`` reads ``CD15``: an error about the
    user's ``--robot H15`` must show ``H15``, which a canonical ``CD15`` alone
    would hide.
    """
    canonical = as_robot(robot).to_string()
    if not isinstance(robot, str) or robot == canonical:
        return canonical
    return f"{robot} ({canonical})"
