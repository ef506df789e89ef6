"""Robot strings are strict: discrete inputs take no vision; messages name the robot as given."""

from __future__ import annotations

import pytest

from amaze.agents.robot import Robot, RobotStringError, robot_name


@pytest.mark.parametrize("text", ["DD15", "D11", "DD5", "D65", "DD0", "D10001", "DD01"])
def test_a_vision_on_discrete_inputs_is_refused(text):
    with pytest.raises(RobotStringError, match=rf"robot string '{text}': DD \(discrete inputs\)"
                       " takes no vision size"):  # fmt: skip
        Robot.from_string(text)


def test_the_error_suggests_the_image_robots_of_that_vision():
    with pytest.raises(RobotStringError, match=r"write DD, or H15 / CC15 for 15x15 images"):
        Robot.from_string("DD15")
    with pytest.raises(RobotStringError, match=r"got 10001; write DD$"):
        Robot.from_string("D10001")  # not a vision any robot can have


def test_the_constructor_refuses_a_vision_on_discrete_inputs_too():
    with pytest.raises(RobotStringError, match="takes no vision size, got 11"):
        Robot("D", "D", 11)
    assert Robot("D", "D").to_string() == "DD"
    assert Robot().vision is None


@pytest.mark.parametrize(("text", "canonical"), [("D", "DD"), ("DD", "DD"), ("H11", "CD11")])
def test_robots_without_a_stray_vision_still_parse(text, canonical):
    assert Robot.from_string(text).to_string() == canonical


@pytest.mark.parametrize(
    ("given", "named"),
    [("H15", "H15 (CD15)"), ("CD15", "CD15"), ("C", "C (CC15)"), ("DD", "DD"),
     (Robot.from_string("H7"), "CD7")],
)  # fmt: skip
def test_robot_name_keeps_the_spelling_of_the_user(given, named):
    assert robot_name(given) == named
