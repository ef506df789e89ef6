"""Curators from other distributions, found through the ``amaze.curators`` entry points."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from amaze.curriculum.curators import (
    BUILTIN_CURATORS,
    CuratorContext,
    CuratorError,
    curator_class,
    curator_names,
    make_curator,
)
from tests.amaze.runs.toy_curriculum import ToyConfig, ToyRun

PLUGIN = Path(__file__).parents[2] / "data" / "curator_plugin"
CONTEXT = CuratorContext(target="M4_6x6_C1", seed=1, stages=3, branches=2)


@pytest.fixture
def plugin(monkeypatch: pytest.MonkeyPatch) -> None:
    """The test distribution on sys.path (syspath_prepend also clears the import caches)."""
    monkeypatch.syspath_prepend(str(PLUGIN))


def test_the_plugin_is_not_there_without_its_distribution() -> None:
    assert "first-branch" not in curator_names()
    with pytest.raises(CuratorError, match=r"unknown curator 'first-branch' \(choose from careful"):
        curator_class("first-branch")


def test_a_plugin_is_listed_and_built(plugin: None) -> None:
    names = curator_names()
    assert names[: len(BUILTIN_CURATORS)] == list(BUILTIN_CURATORS)
    assert "first-branch" in names
    assert names.count("careful") == 1  # a plug-in cannot take a built-in name
    curator = make_curator("first-branch", CONTEXT)
    assert type(curator).__name__ == "FirstBranchCurator"
    assert curator.context is CONTEXT
    assert curator_class("careful").__module__ == "amaze.curriculum.strategies"


def test_broken_plugins_are_reported_by_name(plugin: None) -> None:
    with pytest.raises(CuratorError, match=r"'not-a-class' \(amaze_toy_curator:NOT_A_CLASS\)"):
        make_curator("not-a-class", CONTEXT)
    with pytest.raises(
        CuratorError, match=r"'missing-module' \(amaze_toy_curator_absent:Curator\) cannot be"
    ):
        make_curator("missing-module", CONTEXT)


def test_a_run_plays_a_plugin_curator_to_the_end(plugin: None, tmp_path: Path) -> None:
    config = ToyConfig(
        regime="edhucat", curator="first-branch", stages=3, branches=2, budget_steps=2500
    )
    result = ToyRun.fresh(config, tmp_path / "run")
    lines = (tmp_path / "run" / "decisions.jsonl").read_text().splitlines()
    decisions = [json.loads(line) for line in lines]
    assert [(d["stage"], d["kind"]) for d in decisions] == [
        (0, "generate"),
        (1, "select"),
        (1, "generate"),
        (2, "select"),
        (2, "generate"),
        (3, "select"),
    ]
    assert {d["curator"] for d in decisions} == {"first-branch"}
    assert all(d["choice"] == 0 for d in decisions if d["kind"] == "select")
    assert result.summary["curator"] == "first-branch"
    assert result.summary["final_lineage"] == [0, 0, 0]
