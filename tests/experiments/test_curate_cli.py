"""``amaze-curate`` as a user runs it: bad options, and a server killed mid-session that resumes."""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import httpx
import pytest

from amaze.errors import UsageError
from experiments.curate import cli
from experiments.curate.cli import exposure_warning, main

ROOT = Path(__file__).resolve().parents[2]
SESSION = ["--algo", "cmaes", "--budget-steps", "24000", "--stages", "3", "--branches", "2"]


@pytest.mark.parametrize(
    ("argv", "named"),
    [
        (["--algo", "sarsa", "--out", "x"], "sarsa"),
        (["--stages", "-1", "--out", "x"], "stages"),
        (["--branches", "0", "--out", "x"], "branches"),
        (["--budget-steps", "-5", "--out", "x"], "budget_steps"),
        (["--robot", "XY", "--out", "x"], "XY"),
        (["--target", "M4_Q", "--out", "x"], "'Q'"),
        (["--port", "70000", "--out", "x"], "70000"),
        (["--host", "256.1.1.1", "--out", "x"], "256.1.1.1"),
        ([], "--out"),
        (["--resume", "nowhere"], "nowhere"),
        (["--replay", "nowhere", "--out", "y"], "nowhere"),
        (["--replay", "nowhere"], "--out"),
        (["--advisor", "nobody", "--out", "x"], "unknown advisor 'nobody'"),
        (["--advisor", "human", "--out", "x"], "advisor 'human' cannot advise"),
        (["--advisor", "edens", "--stages", "1", "--out", "x"], "no effect with 1 stage"),
        (["--resume", "nowhere", "--advisor", "edens"], "--advisor edens would be ignored"),
        (["--replay", "a", "--out", "y", "--advisor", "edens"], "--advisor edens would be ignored"),
    ],
)
def test_bad_options_give_one_error_line_and_status_2(
    argv: list[str], named: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys
) -> None:
    monkeypatch.chdir(tmp_path)
    assert main([*argv, "--no-browser"]) == 2
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), captured.err
    assert named in lines[0]
    assert captured.out == ""
    assert not (tmp_path / "x").exists()


def test_serving_beyond_the_loopback_address_is_warned_of() -> None:
    for host in ("127.0.0.1", "127.0.0.2", "::1"):
        assert exposure_warning(host) is None
    for host in ("0.0.0.0", "192.0.2.7", "::", "example.org"):
        assert host in exposure_warning(host)


def test_a_folder_that_holds_something_else_is_refused(tmp_path: Path, capsys) -> None:
    (tmp_path / "notes.txt").write_text("mine")
    assert main(["--out", str(tmp_path), "--no-browser"]) == 2
    assert "not empty" in capsys.readouterr().err
    assert (tmp_path / "notes.txt").read_text() == "mine"


def test_only_a_persons_run_resumes_on_the_page(tmp_path: Path, capsys) -> None:
    from evolution.run import EvolutionRun

    out = tmp_path / "scripted"
    config = {"algo": "cmaes", "regime": "edhucat", "curator": "random", "stages": 2}
    EvolutionRun.fresh({**config, "branches": 1, "budget_steps": 4000}, out)
    assert main(["--resume", str(out), "--no-browser"]) == 2
    assert "'random'" in capsys.readouterr().err


@pytest.fixture(scope="module")
def killed_session(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A person's session of 2 stages x 2 branches (CMA-ES) killed at its final selection.

    Made as a scripted run whose config then names the person as its curator,
    and whose last decision and final files are removed: what a server killed
    while the person looks at the last stage's branches leaves.
    """
    from evolution.run import EvolutionRun

    out = tmp_path_factory.mktemp("killed") / "me"
    config = {"algo": "cmaes", "regime": "edhucat", "curator": "random", "stages": 2}
    EvolutionRun.fresh({**config, "branches": 2, "budget_steps": 12000}, out)
    decisions = out / "decisions.jsonl"
    assert len(decisions.read_text().splitlines()) == 4  # both stages played
    for name in ("summary.json", "curriculum.png", "progress.png", "trajectories"):
        shutil.rmtree(out / name) if (out / name).is_dir() else (out / name).unlink()
    decisions.write_text("".join(decisions.read_text().splitlines(keepends=True)[:3]))
    data = json.loads((out / "config.json").read_text())
    (out / "config.json").write_text(json.dumps({**data, "curator": "human"}))
    # the branches were trained under that config: they record its digest
    digest = EvolutionRun(out, EvolutionRun.read_config(out)).config_digest
    for name in ("result.json", "branch.json"):
        for path in out.glob(f"stages/**/{name}"):
            _set(path, config_sha256=digest)
    return out


def _lines(path: Path, change: Callable[[list[dict]], list[dict]]) -> None:
    lines = [json.loads(line) for line in path.read_text().splitlines()]
    path.write_text("".join(json.dumps(line) + "\n" for line in change(lines)))


def _damage(folder: Path) -> None:
    for path in folder.iterdir():
        path.write_bytes(b"\x00damaged")


def _set(path: Path, **values: object) -> None:
    path.write_text(json.dumps({**json.loads(path.read_text()), **values}))


BRANCH = Path("stages/stage-1/branch-1")
#: Damage done to a killed session, and what the error line names.
TAMPERED = {
    "choice out of range": (
        lambda out: _lines(out / "decisions.jsonl", lambda d: [d[0], {**d[1], "choice": 5}, d[2]]),
        "choice 5",
    ),
    "decisions lost": (
        lambda out: _lines(out / "decisions.jsonl", lambda d: d[:1]),
        "does not give branch 0 of stage 1",
    ),
    "decisions not JSON": (
        lambda out: (out / "decisions.jsonl").write_text("[" * 30000),
        "decisions.jsonl",
    ),
    "another maze decided": (
        lambda out: _lines(
            out / "decisions.jsonl",
            lambda d: [*d[:2], {**d[2], "mazes": ["M4_6x6_C1", d[2]["mazes"][1]]}],
        ),
        "branch-0/result.json",
    ),
    "result of another stage": (
        lambda out: _set(out / BRANCH / "result.json", stage=2),
        "branch-1/result.json",
    ),
    "result damaged": (
        lambda out: (out / BRANCH / "result.json").write_bytes(b"\xff"),
        "branch-1/result.json",
    ),
    "agent damaged": (lambda out: _damage(out / BRANCH / "agent"), str(BRANCH / "agent")),
    "agent missing": (
        lambda out: shutil.rmtree(out / BRANCH / "agent"),
        str(BRANCH / "agent"),
    ),
}


def _snapshot(folder: Path) -> dict[str, bytes]:
    return {
        str(path.relative_to(folder)): path.read_bytes()
        for path in sorted(folder.rglob("*"))
        if path.is_file()
    }


@pytest.mark.parametrize("damage", TAMPERED, ids=list(TAMPERED))
def test_a_resume_with_bad_files_is_refused_before_the_page_is_served(
    damage: str,
    killed_session: Path,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    out = tmp_path / "me"
    shutil.copytree(killed_session, out)
    tamper, named = TAMPERED[damage]
    tamper(out)
    before = _snapshot(out)

    def serve(host: str, port: int) -> None:
        raise AssertionError("the page is served for a session that cannot resume")

    monkeypatch.setattr(cli, "_listen", serve)
    assert main(["--resume", str(out), "--no-browser"]) == 2
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), captured.err
    assert named in lines[0]
    assert captured.out == ""
    assert _snapshot(out) == before  # nothing changed


def test_a_resume_checks_every_agent_the_summary_reads(
    killed_session: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys
) -> None:
    out = tmp_path / "me"
    shutil.copytree(killed_session, out)

    def serve(host: str, port: int) -> None:
        raise UsageError("the page would be served now")

    monkeypatch.setattr(cli, "_listen", serve)
    assert main(["--resume", str(out), "--no-browser"]) == 2
    assert capsys.readouterr().err == "error: the page would be served now\n"
    # stage 1 was trained from stage 0's agent already, but the summary reads it again
    _damage(out / "stages" / "stage-0" / "branch-0" / "agent")
    assert main(["--resume", str(out), "--no-browser"]) == 2
    assert "stage-0/branch-0/agent" in capsys.readouterr().err


class Page:
    """The page's side over HTTP: the token's cookie, the CSRF token, the state."""

    def __init__(self, url: str) -> None:
        self.client = httpx.Client(timeout=60)
        page = self.client.get(url, follow_redirects=True)
        assert page.status_code == 200
        self.base = url.split("/?")[0]
        self.csrf = re.search(r'name="csrf-token" content="([^"]+)"', page.text).group(1)

    def question(self, wanted: str, timeout: float = 300) -> dict:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            state = self.client.get(f"{self.base}/api/state").json()
            assert state["phase"] != "failed", state["error"]
            if state["question"] and state["question"]["id"] == wanted:
                return state["question"]
            time.sleep(0.2)
        raise AssertionError(f"no question {wanted} in {timeout} s")

    def answer(self, question: str, answer: object) -> None:
        response = self.client.post(
            f"{self.base}/api/answer",
            json={"question": question, "answer": answer},
            headers={"X-CSRF-Token": self.csrf},
        )
        assert response.status_code == 200, response.text


def start(*args: str, stderr: int = subprocess.DEVNULL) -> tuple[subprocess.Popen, str]:
    """``amaze-curate ARGS`` on any free port, and the address it printed."""
    process = subprocess.Popen(
        [sys.executable, "-m", "experiments.curate.cli", *args, "--port", "0", "--no-browser"],
        stdout=subprocess.PIPE,
        stderr=stderr,
        text=True,
        cwd=ROOT,
        env={**os.environ, "NUMBA_NUM_THREADS": "1"},
    )
    assert process.stdout is not None
    return process, process.stdout.readline().strip()


@pytest.mark.slow
def test_a_killed_server_resumes_where_it_stopped(tmp_path: Path) -> None:
    out = tmp_path / "me"
    process, url = start("--out", str(out), *SESSION)
    try:
        assert re.fullmatch(r"http://127\.0\.0\.1:\d+/\?token=[\w-]{20,}", url)
        page = Page(url)
        page.question("generate-1")
        page.answer("generate-1", ["M4_6x6_C1", "M5_6x6_C1"])
        page.question("select-2")
    finally:
        process.kill()  # SIGKILL: no goodbye
        process.wait()
    lines = (out / "decisions.jsonl").read_text().splitlines()
    assert [json.loads(line)["kind"] for line in lines] == ["generate", "select", "generate"]

    process, url = start("--resume", str(out))
    try:
        page = Page(url)
        asked = page.question("select-2")  # the stage is not trained again: it is asked at once
        assert [r["maze"] for r in asked["candidates"][1]["results"]] == ["M4_6x6_C1", "M5_6x6_C1"]
        page.answer("select-2", 1)
        asked = page.question("generate-2")
        page.answer("generate-2", asked["suggestions"])
        page.question("select-3")
        page.answer("select-3", 0)
        deadline = time.monotonic() + 300
        while page.client.get(f"{page.base}/api/state").json()["phase"] != "finished":
            assert time.monotonic() < deadline
            time.sleep(0.2)
    finally:
        process.terminate()
        process.wait()
    summary = json.loads((out / "summary.json").read_text())
    assert summary["final_lineage"] == [0, 1, 0]
    assert summary["curator"] == "human"


@pytest.mark.slow
def test_ctrl_c_during_training_stops_cleanly_and_the_run_resumes(tmp_path: Path) -> None:
    out = tmp_path / "me"
    process, url = start("--out", str(out), "--budget-steps", "3000000", stderr=subprocess.PIPE)
    page = Page(url)
    deadline = time.monotonic() + 120
    while not page.client.get(f"{page.base}/api/state").json()["training"]["branches"]:
        assert time.monotonic() < deadline
        time.sleep(0.2)
    process.send_signal(signal.SIGINT)  # PPO is training its first branch
    _, errors = process.communicate(timeout=60)
    assert process.returncode == 130, errors
    assert "terminate called" not in errors and "Traceback" not in errors
    assert f"amaze-curate --resume {out} goes on" in errors
    assert (out / "config.json").is_file()
    assert main(["--resume", str(out), "--port", "70000", "--no-browser"]) == 2  # checked, intact
