"""``--config`` files are read under bounds: a YAML alias bomb, a cyclic alias or a file
too large is refused by name before it is expanded or read whole.

* the "billion laughs" (nine levels of ten aliases, a few hundred bytes) is
  refused once its node graph is counted, before anything is constructed;
* an alias inside its own anchor (an infinite document) is refused alike;
* legitimate aliases and merge keys still load;
* a document over the node budget is refused while it is composed;
* a file over the size cap (JSON or YAML) is refused from its size, and a
  file that reads longer than its size says (``/dev/zero``) after cap + 1 bytes;
* through ``amaze-train`` and ``amaze-evolve``: one ``error:`` line, exit 2.
"""

from __future__ import annotations

import itertools
import json
import os
import re
from pathlib import Path

import pytest
import yaml

from amaze.runs import config
from amaze.runs.config import (
    MAX_CONFIG_BYTES,
    MAX_YAML_NODES,
    read_config_file,
    read_json_object,
)


class BadFile(ValueError):
    """The caller's error class."""


def _bomb(levels: int = 9) -> str:
    """Ten aliases of ten aliases... ``levels`` deep: 10**levels scalars once expanded."""
    names = "abcdefghijklmnopqrstuvwxyz"[:levels]
    lines = ["a: &a [x,x,x,x,x,x,x,x,x,x]"]
    for below, name in itertools.pairwise(names):
        lines.append(f"{name}: &{name} [{','.join([f'*{below}'] * 10)}]")
    return "\n".join(lines) + "\n"


@pytest.fixture
def nothing_constructed(monkeypatch: pytest.MonkeyPatch) -> None:
    """Fail the test if yaml constructs a document (the expansion the budget prevents)."""

    def refuse(self: object, node: object) -> object:
        raise AssertionError("the document was constructed")

    monkeypatch.setattr(yaml.constructor.BaseConstructor, "construct_document", refuse)


def test_the_billion_laughs_is_refused_before_it_is_expanded(
    tmp_path: Path, nothing_constructed: None
) -> None:
    path = tmp_path / "bomb.yml"
    path.write_text(_bomb())
    assert path.stat().st_size < 400
    with pytest.raises(BadFile) as refused:
        read_config_file(path, BadFile)
    message = str(refused.value)
    assert str(path) in message and f"more than {MAX_YAML_NODES:,} YAML nodes" in message
    assert "aliases" in message


def test_an_alias_inside_its_own_anchor_is_refused(
    tmp_path: Path, nothing_constructed: None
) -> None:
    path = tmp_path / "cycle.yaml"
    path.write_text("policy_kwargs: &loop {net_arch: [64, *loop]}\n")
    with pytest.raises(BadFile, match=r"cycle\.yaml.*once its aliases are expanded"):
        read_config_file(path, BadFile)


def test_legitimate_aliases_still_load(tmp_path: Path) -> None:
    path = tmp_path / "config.yml"
    path.write_text(
        "layers: &layers [64, 64]\n"
        "common: &common {n_steps: 16, batch_size: 32}\n"
        "ppo:\n"
        "  <<: *common\n"
        "  policy_kwargs: {net_arch: {pi: *layers, vf: *layers}}\n"
        "a2c: {<<: *common, n_steps: 5}\n"
    )
    loaded = read_config_file(path, BadFile)
    assert loaded["ppo"] == {
        "n_steps": 16,
        "batch_size": 32,
        "policy_kwargs": {"net_arch": {"pi": [64, 64], "vf": [64, 64]}},
    }
    assert loaded["a2c"] == {"n_steps": 5, "batch_size": 32}


def test_the_node_budget_is_exact_and_holds_while_composing(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(config, "MAX_YAML_NODES", 1 + 2 + 2 * 10)  # mapping, 2 keys, 2 lists...
    path = tmp_path / "config.yml"
    path.write_text("a: &a [1, 2, 3, 4, 5, 6, 7, 8, 9]\nb: *a\n")  # ... of 9 scalars each
    assert read_config_file(path, BadFile) == {"a": list(range(1, 10)), "b": list(range(1, 10))}
    path.write_text("a: &a [1, 2, 3, 4, 5, 6, 7, 8, 9, 10]\nb: *a\n")
    with pytest.raises(BadFile, match="more than 23 YAML nodes once its aliases"):
        read_config_file(path, BadFile)
    path.write_text("a: [" + ", ".join(["1"] * 30) + "]\n")  # no alias: stopped while composed
    with pytest.raises(BadFile, match=r"config\.yml' holds more than 23 YAML nodes$"):
        read_config_file(path, BadFile)


@pytest.mark.parametrize("name", ["config.json", "config.yml"])
def test_a_file_over_the_size_cap_is_refused_by_name(tmp_path: Path, name: str) -> None:
    path = tmp_path / name
    with open(path, "wb") as stream:  # sparse: nothing is written, nothing should be read
        stream.truncate(MAX_CONFIG_BYTES + 1)
    with pytest.raises(
        BadFile, match=re.escape(f"{name}' is too large: {MAX_CONFIG_BYTES + 1:,} bytes")
    ):
        read_config_file(path, BadFile)


def test_the_json_reader_has_the_same_cap(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(config, "MAX_CONFIG_BYTES", 32)
    path = tmp_path / "trainer.json"
    path.write_text(json.dumps({"n_steps": 16}))
    assert read_json_object(path, BadFile, "saved trainer") == {"n_steps": 16}
    path.write_text(json.dumps({"n_steps": 16, "batch_size": 32}))
    with pytest.raises(BadFile, match=r"saved trainer '.*trainer\.json' is too large: 33 bytes"):
        read_json_object(path, BadFile, "saved trainer")


@pytest.mark.skipif(not os.path.exists("/dev/zero"), reason="needs /dev/zero")
@pytest.mark.parametrize("name", ["zero.json", "zero.yaml"])
def test_a_file_longer_than_its_size_is_read_to_the_cap_only(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, name: str
) -> None:
    monkeypatch.setattr(config, "MAX_CONFIG_BYTES", 1024)
    path = tmp_path / name
    path.symlink_to("/dev/zero")  # its size is 0, its content endless
    with pytest.raises(BadFile, match=re.escape(f"{name}' is too large: more than 1,024 bytes")):
        read_config_file(path, BadFile)


@pytest.mark.parametrize("command", ["amaze-train", "amaze-evolve"])
def test_the_commands_refuse_a_bomb_in_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], command: str
) -> None:
    if command == "amaze-train":
        from rl_baselines.cli import main
    else:
        from evolution.cli import main
    path = tmp_path / "bomb.yml"
    path.write_text(_bomb())
    assert main(["--config", str(path), "--out", str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith("error: config file "), err
    assert str(path) in err[0] and "YAML nodes" in err[0], err
    assert not (tmp_path / "run").exists()
