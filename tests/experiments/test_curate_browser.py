"""A whole human curation session in a real headless Chromium, then its replay.

``amaze-curate`` runs as a user starts it (a subprocess, port 0, no browser
opened); Playwright drives Debian's ``chromium`` through the page: a bad maze
string shows its error inline, valid mazes are designed (typed and with the
controls), agents are chosen, training is waited for, the final page is
reached. The run folder's ``decisions.jsonl`` must hold exactly what was
clicked, and ``--replay`` of it must give the same curriculum and agent.
Screenshots of each step go to ``test-artifacts/curate/`` (or
``$AMAZE_TEST_ARTIFACTS/curate/``).

Without a Chromium the test is skipped, unless ``AMAZE_REQUIRE_BROWSER=1``
(CI sets it, after installing Debian's ``chromium``), where it fails.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from amaze.maze.spec import MazeSpec

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[2]
ARTIFACTS = Path(os.environ.get("AMAZE_TEST_ARTIFACTS", ROOT / "test-artifacts")) / "curate"
LAPTOP = {"width": 1366, "height": 860}
NARROW = {"width": 420, "height": 860}
#: A tiny session: 3 stages x 2 branches of CMA-ES, a few generations each.
SESSION = ["--algo", "cmaes", "--budget-steps", "24000", "--stages", "3", "--branches", "2"]
TIMEOUT_MS = 120_000


def chromium_path() -> str | None:
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    return None


@pytest.fixture(scope="module")
def browser() -> Iterator[object]:
    path = chromium_path()
    if path is None:
        if os.environ.get("AMAZE_REQUIRE_BROWSER") == "1":
            pytest.fail("AMAZE_REQUIRE_BROWSER=1 but no chromium is installed")
        pytest.skip("no chromium installed (apt-get install chromium)")
    sync_api = pytest.importorskip("playwright.sync_api")
    with sync_api.sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=path, args=["--no-sandbox"])
        yield browser
        browser.close()


class Server:
    """``amaze-curate`` in a subprocess; ``url`` is the line it prints."""

    def __init__(self, *args: str) -> None:
        environment = {**os.environ, "NUMBA_NUM_THREADS": "1", "PYTHONUNBUFFERED": "1"}
        self.process = subprocess.Popen(
            [sys.executable, "-m", "experiments.curate.cli", *args, "--port", "0", "--no-browser"],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            cwd=ROOT,
            env=environment,
        )
        self.errors: list[str] = []
        threading.Thread(target=self._drain, daemon=True).start()
        assert self.process.stdout is not None
        self.url = self.process.stdout.readline().strip()
        assert self.url.startswith("http://127.0.0.1:"), (self.url, self.errors)

    def _drain(self) -> None:
        assert self.process.stderr is not None
        self.errors.extend(self.process.stderr)

    def stop(self) -> None:
        self.process.send_signal(signal.SIGINT)
        try:
            self.process.wait(timeout=20)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()


def shoot(page, name: str) -> None:
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    page.screenshot(path=str(ARTIFACTS / f"{name}.png"), full_page=True)


def canonical(text: str) -> str:
    return MazeSpec.from_string(text).to_string()


def wait_for_question(page, heading: str) -> None:
    page.wait_for_function(
        "text => document.querySelector('#view h2')?.textContent.startsWith(text)",
        arg=heading,
        timeout=TIMEOUT_MS,
    )


def wait_for_animations(page, count: int) -> None:
    page.wait_for_function(
        "n => document.querySelectorAll('.episode img.animation').length === n",
        arg=count,
        timeout=TIMEOUT_MS,
    )


def test_a_whole_session_in_chromium_is_recorded_and_replays(browser, tmp_path: Path) -> None:
    out = tmp_path / "me"
    server = Server("--out", str(out), *SESSION)
    try:
        context = browser.new_context(viewport=LAPTOP)
        page = context.new_page()
        problems: list[str] = []
        page.on("pageerror", lambda error: problems.append(str(error)))
        page.goto(server.url)
        assert "token" not in page.url  # the token moved into a cookie

        # Stage 1: design 2 mazes. A bad string first: its error shows by the field.
        wait_for_question(page, "Stage 1: design 2 mazes")
        page.fill("#maze-string-0", "M4_7x7_Q")
        error = page.locator("#maze-error-0")
        error.filter(has_text="'Q'").wait_for(timeout=TIMEOUT_MS)
        assert page.locator("#submit-mazes").is_disabled()
        shoot(page, "01-bad-maze-string")
        page.fill("#maze-string-0", "M11_6x6_C1")
        page.locator("#maze-figures-0").filter(has_text="simple").wait_for(timeout=TIMEOUT_MS)
        assert error.text_content() == ""
        # The second maze with the controls: 6 wide, with clues, then a new seed.
        page.fill("#maze-width-1", "6")
        page.locator("#maze-width-1").dispatch_event("change")
        page.wait_for_function(
            "() => document.querySelector('#maze-string-1').value.includes('_6x5')"
        )
        page.check("#maze-clue-1")
        page.wait_for_function(
            "() => document.querySelector('#maze-string-1').value.includes('_C')"
        )
        before = page.input_value("#maze-string-1")
        page.click("#maze-new-seed-1")
        page.wait_for_function(
            "old => document.querySelector('#maze-string-1').value !== old", arg=before
        )
        page.locator("#submit-mazes:enabled").wait_for(timeout=TIMEOUT_MS)
        stage1 = [canonical("M11_6x6_C1"), page.input_value("#maze-string-1")]
        assert MazeSpec.from_string(stage1[1]).width == 6
        assert MazeSpec.from_string(stage1[1]).clue
        shoot(page, "02-designed-mazes")
        page.click("#submit-mazes")

        # A second tab sees the same state.
        second = context.new_page()
        second.goto(server.url.split("?")[0])
        wait_for_question(page, "Stage 2: choose the agent")
        wait_for_question(second, "Stage 2: choose the agent")
        wait_for_animations(page, 4)
        shoot(page, "03-choose-an-agent")
        page.set_viewport_size(NARROW)
        shoot(page, "04-choose-an-agent-narrow")
        page.set_viewport_size(LAPTOP)
        second.close()
        page.click('.candidate[data-branch="1"] button.choose')

        # Stage 2: the suggestions as they are, then the final choice.
        wait_for_question(page, "Stage 2: design 2 mazes")
        page.locator("#submit-mazes:enabled").wait_for(timeout=TIMEOUT_MS)
        stage2 = [page.input_value("#maze-string-0"), page.input_value("#maze-string-1")]
        shoot(page, "05-design-stage-2")
        page.click("#submit-mazes")
        page.locator("#training, .candidate").first.wait_for(timeout=TIMEOUT_MS)
        shoot(page, "06-training-or-next")
        wait_for_question(page, "Choose the final agent")
        wait_for_animations(page, 4)
        page.click('.candidate[data-branch="0"] button.choose')
        page.locator("#final").wait_for(timeout=TIMEOUT_MS)
        page.locator("#curriculum-figure:not([hidden])").wait_for(timeout=TIMEOUT_MS)
        shoot(page, "07-final")
        page.set_viewport_size(NARROW)
        shoot(page, "08-final-narrow")
        summary = json.loads((out / "summary.json").read_text())
        shown = page.text_content("#final-success")
        assert shown == f"{summary['success_rate']:.3f}"
        link = page.locator('#final a[href="/files/summary.json"]')
        assert link.count() == 1
        assert problems == []
        context.close()
    finally:
        server.stop()

    decisions = [json.loads(line) for line in (out / "decisions.jsonl").read_text().splitlines()]
    made = [(d["stage"], d["kind"], d.get("choice"), d.get("mazes")) for d in decisions]
    assert made == [
        (0, "generate", None, [decisions[0]["mazes"][0]]),
        (1, "select", 0, None),
        (1, "generate", None, stage1),
        (2, "select", 1, None),
        (2, "generate", None, stage2),
        (3, "select", 0, None),
    ]
    assert {d["curator"] for d in decisions} == {"human"}
    assert decisions[1]["forced"] is True
    assert all(d["seconds"] > 0 for d in decisions[2:])  # the time the person took

    again = tmp_path / "again"
    replay = subprocess.run(
        [sys.executable, "-m", "experiments.curate.cli", "--replay", str(out), "--out", str(again)],
        capture_output=True,
        text=True,
        cwd=ROOT,
        env={**os.environ, "NUMBA_NUM_THREADS": "1"},
        timeout=600,
    )
    assert replay.returncode == 0, replay.stderr
    replayed = [json.loads(line) for line in (again / "decisions.jsonl").read_text().splitlines()]
    assert [(d["stage"], d["kind"], d.get("choice"), d.get("mazes")) for d in replayed] == made
    first, second_run = (json.loads((p / "summary.json").read_text()) for p in (out, again))
    assert second_run["curriculum"] == first["curriculum"]
    assert second_run["success_rate"] == first["success_rate"]
    champion = "stages/stage-2/branch-0/agent/champion.npz"
    with np.load(out / champion) as expected, np.load(again / champion) as got:
        assert sorted(expected.files) == sorted(got.files)
        for name in expected.files:
            assert np.array_equal(expected[name], got[name]), name
