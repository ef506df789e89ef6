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
import re
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


#: What a value missing on the server would show as if the page printed it as it came.
NOT_WORDS = re.compile(r"\b(?:None|null|undefined|NaN)\b")


def no_missing_values(page) -> None:
    """The page's text shows no ``None``, ``null``, ``undefined`` or ``NaN``: a dash at most."""
    text = page.inner_text("body")
    assert not NOT_WORDS.search(text), NOT_WORDS.findall(text)


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
        # Trained in stage 1, chosen in stage 1: the stage numbers agree.
        wait_for_question(page, "Stage 1: choose the agent")
        wait_for_question(second, "Stage 1: choose the agent")
        wait_for_animations(page, 4)
        no_missing_values(page)
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
        no_missing_values(page)
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


#: Where the advised session's screenshots go (looked at by whoever changes the page).
SHOTS = Path(os.environ.get("AMAZE_CURATE_SHOTS", ARTIFACTS / "advised"))
#: The advised session: the same, with budget enough for its third stage and EDEnS advising.
ADVISED_SESSION = [*SESSION[:2], "--budget-steps", "60000", *SESSION[4:], "--advisor", "edens"]
#: The page names every bad field within this (the issue's half a second).
PROMPT_MS = 500


def shot(page, name: str) -> None:
    SHOTS.mkdir(parents=True, exist_ok=True)
    page.screenshot(path=str(SHOTS / f"{name}.png"), full_page=True)


def error_names(page, box: str, *words: str) -> float:
    """Seconds until the error box ``box`` names every one of ``words`` (fails past PROMPT_MS)."""
    started = page.evaluate("performance.now()")
    page.wait_for_function(
        "([box, words]) => { const t = document.querySelector(box).textContent;"
        " return words.every((w) => t.includes(w)); }",
        arg=[box, list(words)],
        timeout=PROMPT_MS,
    )
    return (page.evaluate("performance.now()") - started) / 1000


def test_an_advised_session_takes_and_overrides_proposals_and_replays(
    browser, tmp_path: Path
) -> None:
    """EDEnS advises a person: proposals shown with reasons, taken in one click or overridden.

    The size fields are typed at a person's speed (80 ms a key) while the
    page talks to the server: no character is lost and no field re-rendered
    under the cursor. Every bad field and every bad token is named within
    half a second. ``decisions.jsonl`` records each proposal and whether it
    was taken, and ``--replay`` reaches the same agent.
    """
    out = tmp_path / "advised"
    server = Server("--out", str(out), *ADVISED_SESSION)
    try:
        context = browser.new_context(viewport=LAPTOP)
        page = context.new_page()
        problems: list[str] = []
        page.on("pageerror", lambda error: problems.append(str(error)))
        page.goto(server.url)

        # Stage 1: the advisor's mazes, with their reasons, fill the editors.
        wait_for_question(page, "Stage 1: design 2 mazes")
        page.locator("#advice").wait_for(timeout=TIMEOUT_MS)
        assert "edens proposes 2 mazes" in page.text_content("#advice h3")
        assert "distance to the target" in page.text_content("#advice")
        assert "expected difficulty" in page.text_content("#advice")
        proposed = [page.text_content(f'.proposed-maze[data-index="{i}"] code') for i in range(2)]
        assert [page.input_value(f"#maze-string-{i}") for i in range(2)] == proposed
        page.locator("#last-result").filter(has_text="rotations").wait_for(timeout=TIMEOUT_MS)
        assert "target's family" in page.text_content("#last-result")
        assert "waiting for you" in page.text_content("#overall-text")
        page.locator("#submit-mazes:enabled").wait_for(timeout=TIMEOUT_MS)
        shot(page, "01-design-with-proposal")

        # A typo with two bad tokens: both named, fast; nothing can be sent.
        page.fill("#maze-string-0", "M4_7x7_Ux_l.25")
        took = error_names(page, "#maze-error-0", "'Ux'", "'l.25'")
        assert page.locator("#submit-mazes").is_disabled()
        assert page.locator("#take-proposal").is_enabled()
        shot(page, "02-every-bad-token-named")
        # The fields stay usable under a bad string.
        assert page.locator("#maze-width-0").is_enabled()
        page.click("#use-proposal-0")  # back to the advisor's first maze
        page.wait_for_function(
            "m => document.querySelector('#maze-string-0').value === m", arg=proposed[0]
        )
        # the error goes once the string is checked again (on a loaded machine, not at once)
        page.wait_for_function(
            "() => document.querySelector('#maze-error-0').textContent === ''",
            timeout=PROMPT_MS * 4,
        )

        # Override the second maze: its size typed at a person's speed.
        page.click("#maze-width-1")
        page.keyboard.press("Control+A")
        page.keyboard.type("150", delay=80)
        error_names(page, "#maze-error-1", "width 150")
        shot(page, "03-bad-width-named")
        page.keyboard.press("Control+A")
        page.keyboard.type("12", delay=80)
        page.keyboard.press("Tab")
        page.keyboard.press("Control+A")
        page.keyboard.type("15", delay=80)
        page.wait_for_function(
            "() => document.querySelector('#maze-string-1').value.includes('_12x15')",
            timeout=PROMPT_MS * 4,
        )
        page.wait_for_timeout(600)  # answers still coming must not touch what was typed
        assert page.input_value("#maze-width-1") == "12"
        assert page.input_value("#maze-height-1") == "15"
        assert page.text_content("#maze-error-1") == ""
        page.locator("#submit-mazes:enabled").wait_for(timeout=TIMEOUT_MS)
        assert page.text_content("#maze-origin-1") == "yours"
        assert page.text_content("#maze-origin-0") == "the advisor's maze 1"
        stage1 = [proposed[0], page.input_value("#maze-string-1")]
        assert MazeSpec.from_string(stage1[1]).width == 12
        assert MazeSpec.from_string(stage1[1]).height == 15
        shot(page, "04-typed-size-kept")
        page.click("#submit-mazes")

        # Stage 1's agents: results on the target's family, the advisor's pick marked; take it.
        wait_for_question(page, "Stage 1: choose the agent")
        wait_for_animations(page, 4)
        pick = int(page.get_attribute(".candidate.proposed", "data-branch") or -1)
        assert pick in (0, 1)
        assert page.locator(".candidate.proposed .pill.advisor").count() == 1
        assert page.locator(".candidate tr.family").count() == 4  # 2 rows x 2 candidates
        assert "difficulty reached" in page.text_content("#advice table")
        assert "waiting for you" in page.text_content("#overall-text")
        shot(page, "05-choose-with-proposal")
        page.click("#take-proposal")

        # Stage 2: the advisor's mazes taken as they are, in one click.
        wait_for_question(page, "Stage 2: design 2 mazes")
        page.locator("#take-proposal").wait_for(timeout=TIMEOUT_MS)
        stage2 = [page.text_content(f'.proposed-maze[data-index="{i}"] code') for i in range(2)]
        shot(page, "06-design-stage-2")
        page.click("#take-proposal")

        # The final choice: the advisor's pick overridden.
        wait_for_question(page, "Choose the final agent (stage 2)")
        assert "evaluation suite. Success" in page.text_content("#view")  # words apart
        wait_for_animations(page, 4)
        final_pick = int(page.get_attribute(".candidate.proposed", "data-branch") or -1)
        other = 1 - final_pick
        shot(page, "07-final-choice")
        page.click(f'.candidate[data-branch="{other}"] button.choose')
        page.locator("#final").wait_for(timeout=TIMEOUT_MS)
        page.wait_for_function(
            "() => document.querySelectorAll('#decisions tbody tr').length === 6"
        )
        taken = [cell.text_content() for cell in page.locator("td.advice-taken").all()]
        assert taken == ["–", "–", "kept 1 of 2", "taken", "kept 2 of 2", "overridden"]
        assert "advisor edens" in page.text_content("#run-description")
        words = page.text_content("#final")
        assert "normalized_reward" not in words and "R̄" in words
        assert "Rbar" not in page.content()
        shot(page, "08-final-with-history")
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
        (2, "select", pick, None),
        (2, "generate", None, stage2),
        (3, "select", other, None),
    ]
    assert ["proposal" in d for d in decisions] == [False, False, True, True, True, True]
    assert [d.get("accepted") for d in decisions] == [
        None, None, [True, False], True, [True, True], False,
    ]  # fmt: skip
    assert decisions[2]["proposal"]["advisor"] == "edens"
    assert decisions[2]["proposal"]["mazes"] == proposed
    reasons = decisions[2]["proposal"]["reasons"]
    assert [r["maze"] for r in reasons] == proposed
    assert all({"operators", "distance", "difficulty"} <= set(r) for r in reasons)
    assert decisions[3]["proposal"]["choice"] == pick
    assert decisions[5]["proposal"]["choice"] == final_pick
    assert len(decisions[5]["proposal"]["criteria"]) == 2
    print(f"bad tokens named in {took:.3f} s")

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
    assert [d.get("accepted") for d in replayed] == [d.get("accepted") for d in decisions]
    champion = f"stages/stage-2/branch-{other}/agent/champion.npz"
    with np.load(out / champion) as expected, np.load(again / champion) as got:
        for name in expected.files:
            assert np.array_equal(expected[name], got[name]), name
    first, second_run = (json.loads((p / "summary.json").read_text()) for p in (out, again))
    assert second_run["success_rate"] == first["success_rate"]
