"""The curation page's server without a browser: token, CSRF, limits, files, answers, a session.

The session runs the curriculum loop of the toy learner (``tests/amaze/runs``):
cheap and deterministic, so the whole protocol between the page and the loop
is exercised in a second or two.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path

import pytest
from fastapi.testclient import TestClient
from hypothesis import given, settings
from hypothesis import strategies as st

from amaze.curriculum.human import PERSON_VALIDATION
from amaze.maze.spec import MazeSpec
from experiments.curate.server import COOKIE, MAX_BODY, create_app
from experiments.curate.session import CurationSession
from tests.amaze.runs.toy_curriculum import ToyRun

TOKEN = "t0ken-for-tests"
CSRF = "csrf-for-tests"
CONFIG = {
    "regime": "edhucat",
    "curator": "human",
    "stages": 3,
    "branches": 2,
    "budget_steps": 6000,
    "target": "M5_8x8_C1",
}
DESCRIPTION = {"algo": "toy", "robot": "DD", "seed": 0, "stages": 3, "branches": 2}
WAIT = 60.0


def new_session(
    out: Path, resume: bool = False, config: dict | None = None
) -> tuple[CurationSession, TestClient]:
    session = CurationSession(out, {**DESCRIPTION, "budget_steps": 6000, "target": "M5_8x8_C1"})
    run_class = session.run_class(ToyRun)
    if resume:
        session.start(lambda: run_class.resume(out))
    else:
        session.start(lambda: run_class.fresh(config or CONFIG, out))
    client = TestClient(create_app(session, TOKEN, csrf=CSRF))
    client.cookies.set(COOKIE, TOKEN)
    return session, client


def post(client: TestClient, path: str, body: object, **headers: str):
    return client.post(path, json=body, headers={"X-CSRF-Token": CSRF, **headers})


def question(session: CurationSession, client: TestClient) -> dict:
    assert session.wait_for("question", WAIT), session.error
    return client.get("/api/state").json()["question"]


@pytest.fixture
def live(tmp_path: Path) -> Iterator[tuple[CurationSession, TestClient]]:
    session, client = new_session(tmp_path / "run")
    yield session, client
    session.close()
    session.wait(WAIT)


# -- the token and the CSRF token -------------------------------------------------------


def test_every_request_needs_the_token(live) -> None:
    _session, client = live
    bare = TestClient(client.app)
    for path in ("/", "/api/state", "/static/curate.js", "/files/config.json", "/api/maze.png"):
        response = bare.get(path)
        assert response.status_code == 403, path
        assert "token" in response.json()["error"]
    wrong = TestClient(client.app)
    wrong.cookies.set(COOKIE, "wrong")
    assert wrong.get("/api/state").status_code == 403
    assert bare.get("/api/state?token=wrong").status_code == 403
    # the token of the printed URL sets the cookie and leaves the address bar
    response = bare.get(f"/?token={TOKEN}", follow_redirects=False)
    assert response.status_code == 303
    assert response.headers["location"] == "/"
    cookie = response.headers["set-cookie"]
    assert f"{COOKIE}={TOKEN}" in cookie and "HttpOnly" in cookie and "SameSite=strict" in cookie
    assert bare.get("/api/state").status_code == 200  # the cookie carries it now


def test_posts_need_the_csrf_token_json_and_a_bounded_body(live) -> None:
    _session, client = live
    assert client.post("/api/maze", json={"string": "M4_5x5"}).status_code == 403
    wrong = client.post("/api/maze", json={"string": "M4_5x5"}, headers={"X-CSRF-Token": "no"})
    assert wrong.status_code == 403
    form = client.post("/api/maze", data={"string": "M4_5x5"}, headers={"X-CSRF-Token": CSRF})
    assert form.status_code == 415
    big = post(client, "/api/maze", {"string": "M4_5x5", "pad": "x" * MAX_BODY})
    assert big.status_code == 413
    broken = client.post(
        "/api/maze",
        content=b"{not json",
        headers={"X-CSRF-Token": CSRF, "Content-Type": "application/json"},
    )
    assert broken.status_code == 400
    assert client.put("/api/state").status_code == 405
    page = client.get("/")
    assert f'content="{CSRF}"' in page.text


# -- files ----------------------------------------------------------------------------


def test_no_request_reads_a_file_outside_the_run_folder(live, tmp_path: Path) -> None:
    session, client = live
    question(session, client)  # the run folder exists and has a config
    assert client.get("/files/config.json").status_code == 200
    secret = tmp_path / "secret.txt"
    secret.write_text("not for the page")
    (session.out / "link").symlink_to(secret)
    for path in (
        "/files/../secret.txt",
        "/files/%2e%2e/secret.txt",
        "/files/..%2fsecret.txt",
        f"/files/{secret}",
        "/files//etc/passwd",
        "/files/link",
        "/files/stages",
        "/files/missing.json",
        "/static/../server.py",
        "/static/%2e%2e/server.py",
    ):
        response = client.get(path)
        assert response.status_code == 404, path
        assert "not for the page" not in response.text


# -- mazes ----------------------------------------------------------------------------


def test_a_maze_card_from_a_string_or_the_fields(live) -> None:
    _session, client = live
    card = post(client, "/api/maze", {"string": "M4_10x10_C1", "reference": "M4_5x5_U"}).json()
    assert card["string"] == "M4_10x10_C1"
    assert card["class"] == "simple"
    assert card["fields"]["clue"] is True and card["fields"]["width"] == 10
    assert card["comparison"]["changes"] == [
        "size 5x5 → 10x10",
        "no longer unicursive",
        "clues added",
    ]
    fields = {**card["fields"], "trap": True, "p_trap": 0.5, "height": 12}
    changed = post(client, "/api/maze", {"fields": fields, "string": card["string"]}).json()
    assert changed["string"] == "M4_10x12_C1_t0.5_T.5"
    fresh = post(client, "/api/maze", {"string": "M4_10x10_C1", "new_seed": True}).json()
    assert fresh["string"] != "M4_10x10_C1"
    assert MazeSpec.from_string(fresh["string"]).where(seed=4).to_string() == "M4_10x10_C1"
    picture = client.get("/api/maze.png", params={"string": "M4_10x10_C1"})
    assert picture.status_code == 200 and picture.content[:4] == b"\x89PNG"


@pytest.mark.parametrize(
    ("body", "named"),
    [
        ({"string": "M4_10x10_Q"}, "'Q'"),
        ({"string": "M4_1x10"}, "1"),
        ({"string": ""}, "empty"),
        ({"string": "M4_" + "5" * 400}, "characters"),
        ({"string": 12}, "12"),
        ({"fields": {"width": 500}}, "start"),
        ({"fields": "wide"}, "wide"),
        ({"reference": 3, "string": "M4_5x5"}, "reference"),
    ],
)
def test_a_bad_maze_is_a_400_naming_the_value(live, body: dict, named: str) -> None:
    _session, client = live
    response = post(client, "/api/maze", body)
    assert response.status_code == 400
    assert named in response.json()["error"]


@pytest.mark.parametrize(
    ("string", "named"),
    [
        ("M4_7x7_Ux_l.25", ["'Ux'", "'l.25'"]),  # both without effect: each named
        ("M4_7x7_Q_Zq_Ux", ["'Q'", "'Zq'", "'Ux'"]),  # the parser stops at 'Q': all named
        ("M4_150x7_Q", ["'Q'", "width 150"]),
        ("M4_7x7_C2_L2", ["'C2'", "'L2'"]),
    ],
)
def test_every_bad_token_of_a_maze_string_is_named(live, string: str, named: list) -> None:
    session, client = live
    response = post(client, "/api/maze", {"string": string})
    assert response.status_code == 400
    for words in named:
        assert words in response.json()["error"], (words, response.json())
    # an answer is checked as strictly: the agent never trains on what was not meant
    asked = question(session, client)
    bad = post(client, "/api/answer", {"question": asked["id"], "answer": [string, "M4_5x5"]})
    assert bad.status_code == 400 and named[0] in bad.json()["details"][0]


def test_bad_fields_are_named(live) -> None:
    _session, client = live
    card = post(client, "/api/maze", {"string": "M4_10x10_C1"}).json()
    for change, named in (
        ({"width": 500}, "width 500"),
        ({"seed": -1}, "seed -1"),
        ({"seed": 1.5}, "seed 1.5"),
        ({"start": "XX"}, "start 'XX'"),
        ({"clue_value": 0}, "clue lightness 0"),
        ({"lure": True, "p_lure": 2}, "lure probability 2"),
        ({"unicursive": "yes"}, "unicursive 'yes'"),
    ):
        response = post(client, "/api/maze", {"fields": {**card["fields"], **change}})
        assert response.status_code == 400, change
        assert named in response.json()["error"], (change, response.json())


def test_bad_input_never_gives_a_500(live) -> None:
    _session, client = live
    for path in (
        "/api/episode/x/0/0",
        "/api/episode/0/0/99",
        "/api/episode/9/0/0",
        "/api/episode/-1/-1/-1",
        "/api/maze.png",
        "/api/maze.png?string=%00",
        "/nowhere",
    ):
        response = client.get(path)
        assert 400 <= response.status_code < 500, (path, response.status_code)
        assert "error" in response.json()
    for body in (None, [], "x", {"question": None}, {"question": "select-9", "answer": 0}):
        response = post(client, "/api/answer", body)
        assert 400 <= response.status_code < 500, body


# -- a whole session --------------------------------------------------------------------


def test_a_whole_session_over_http_records_the_persons_decisions(live) -> None:
    session, client = live
    asked = question(session, client)
    assert (asked["id"], asked["kind"], asked["k"]) == ("generate-1", "generate", 2)
    assert len(asked["suggestions"]) == 2
    assert asked["target"]["comparison"]["reference"] == asked["parent"]["string"]
    bad = post(client, "/api/answer", {"question": "generate-1", "answer": ["M4_5x5", "M4_Q"]})
    assert bad.status_code == 400
    assert bad.json()["details"][0] is None and "'Q'" in bad.json()["details"][1]
    short = post(client, "/api/answer", {"question": "generate-1", "answer": ["M4_5x5"]})
    assert short.status_code == 400
    stage1 = ["M4_6x6_C1", "M5_6x6_C1"]
    assert post(client, "/api/answer", {"question": "generate-1", "answer": stage1}).json()
    # the same answer again, from a second tab: the question is gone
    again = post(client, "/api/answer", {"question": "generate-1", "answer": stage1})
    assert again.status_code == 409

    asked = question(session, client)
    assert asked["id"] == "select-2"
    assert [c["branch"] for c in asked["candidates"]] == [0, 1]
    for candidate in asked["candidates"]:  # on the target's family too
        assert candidate["family"]["mazes"] == PERSON_VALIDATION
        assert 0 <= candidate["family"]["success_rate"] <= 1
    assert asked["advice"] is None
    assert [r["maze"] for r in asked["candidates"][1]["results"]] == stage1
    episode = client.get("/api/episode/1/1/0").json()
    assert episode["maze"] == stage1[0]
    assert client.get(episode["gif"]).content[:6] == b"GIF89a"
    assert (session.out / "stages/stage-1/branch-1/episodes/maze-0.gif").is_file()
    assert client.get("/api/curriculum.png").content[:4] == b"\x89PNG"
    for choice in (2, -1, True, "1", None):
        response = post(client, "/api/answer", {"question": "select-2", "answer": choice})
        assert response.status_code == 400, choice
    assert post(client, "/api/answer", {"question": "select-2", "answer": 1}).json()

    asked = question(session, client)
    assert asked["id"] == "generate-2"
    # how the chosen agent did on its own maze, the design step's first figure
    assert asked["last_result"]["maze"] == stage1[1]
    assert asked["last_result"]["branch"] == 1 and len(asked["last_result"]["success"]) == 4
    assert asked["last_result"]["family"]["mazes"] == PERSON_VALIDATION
    stage2 = asked["suggestions"]
    post(client, "/api/answer", {"question": "generate-2", "answer": stage2})
    asked = question(session, client)
    assert asked["id"] == "select-3"
    post(client, "/api/answer", {"question": "select-3", "answer": 0})
    assert session.wait_for("finished", WAIT), session.error

    state = client.get("/api/state").json()
    assert state["final"]["figures"]["final_lineage"] == [0, 1, 0]
    assert "summary.json" in state["final"]["files"]
    assert [d["kind"] for d in state["history"]["decisions"]] == [
        "generate",
        "select",
        "generate",
        "select",
        "generate",
        "select",
    ]
    lines = (session.out / "decisions.jsonl").read_text().splitlines()
    made = [json.loads(line) for line in lines]
    assert made[2]["mazes"] == stage1
    assert made[4]["mazes"] == stage2
    assert [d.get("choice") for d in made] == [None, 0, None, 1, None, 0]
    assert {d["curator"] for d in made} == {"human"}
    training = state["training"]
    assert training["steps"] == 6000  # the toy learner spends its allowances exactly
    assert [(b["branch"], b["done"]) for b in training["branches"]] == [(0, True), (1, True)]


def test_an_advised_session_shows_each_proposal_and_records_what_was_taken(
    tmp_path: Path,
) -> None:
    session, client = new_session(tmp_path / "run", config={**CONFIG, "advisor": "edens"})
    try:
        asked = question(session, client)
        advice = asked["advice"]
        assert advice["advisor"] == "edens" and advice["kind"] == "generate"
        assert asked["suggestions"] == advice["mazes"]  # the editors start from the proposal
        assert [r["maze"] for r in advice["reasons"]] == advice["mazes"]
        assert {"operators", "distance", "difficulty"} <= set(advice["reasons"][1])
        mine = ["M4_6x6_C1", advice["mazes"][1]]  # one kept, one overridden
        assert post(client, "/api/answer", {"question": asked["id"], "answer": mine}).json()

        asked = question(session, client)
        advice = asked["advice"]
        assert advice["kind"] == "select" and advice["choice"] in advice["front"]
        assert [row["branch"] for row in advice["criteria"]] == [0, 1]
        post(client, "/api/answer", {"question": asked["id"], "answer": advice["choice"]})

        asked = question(session, client)
        post(client, "/api/answer", {"question": asked["id"], "answer": asked["advice"]["mazes"]})
        asked = question(session, client)
        other = 1 - asked["advice"]["choice"]
        post(client, "/api/answer", {"question": asked["id"], "answer": other})
        assert session.wait_for("finished", WAIT), session.error
        history = client.get("/api/state").json()["history"]["decisions"]
        assert [d["accepted"] for d in history] == [None, None, [False, True], True, [True, True],
                                                    False]  # fmt: skip
        assert {d["advisor"] for d in history[2:]} == {"edens"}
    finally:
        session.close()
        session.wait(WAIT)
    lines = [
        json.loads(line) for line in (session.out / "decisions.jsonl").read_text().splitlines()
    ]
    assert [d.get("accepted") for d in lines] == [d["accepted"] for d in history]
    assert lines[2]["proposal"]["mazes"][1] == lines[2]["mazes"][1]


def test_a_stopped_server_resumes_at_the_waiting_question(tmp_path: Path) -> None:
    out = tmp_path / "run"
    session, client = new_session(out)
    first = question(session, client)
    post(client, "/api/answer", {"question": first["id"], "answer": ["M4_6x6_C1", "M5_6x6_C1"]})
    assert question(session, client)["id"] == "select-2"
    session.close()  # the server stops while the person thinks
    assert session.wait(WAIT)
    assert session.phase == "failed" and "resume" in (session.error or "")

    session, client = new_session(out, resume=True)
    asked = question(session, client)
    assert asked["id"] == "select-2"  # asked again, nothing lost
    assert [r["maze"] for r in asked["candidates"][0]["results"]] == ["M4_6x6_C1", "M5_6x6_C1"]
    history = client.get("/api/state").json()["history"]
    assert [d["kind"] for d in history["decisions"]] == ["generate", "select", "generate"]
    post(client, "/api/answer", {"question": "select-2", "answer": 0})
    asked = question(session, client)
    post(client, "/api/answer", {"question": asked["id"], "answer": asked["suggestions"]})
    asked = question(session, client)
    post(client, "/api/answer", {"question": asked["id"], "answer": 1})
    assert session.wait_for("finished", WAIT), session.error
    assert client.get("/api/state").json()["final"]["figures"]["final_lineage"] == [0, 0, 1]


# -- any input ------------------------------------------------------------------------

_IDLE = CurationSession(Path("unused-run-folder"), {**DESCRIPTION, "budget_steps": 0})
_IDLE_CLIENT = TestClient(create_app(_IDLE, TOKEN, csrf=CSRF))
_IDLE_CLIENT.cookies.set(COOKIE, TOKEN)
#: Strings that look like small maze strings, with random tokens.
MAZE_LIKE = r"M\d{1,3}_\dx\d(_[A-Za-z]{1,2}[.\d]*)*"
_JSON = st.recursive(
    st.none()
    | st.booleans()
    | st.integers()
    | st.floats(allow_nan=False, allow_infinity=False)
    | st.text(max_size=30),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=12), inner),
    max_leaves=12,
)


@settings(max_examples=50, deadline=None)
@given(
    string=st.text(max_size=60)
    | st.from_regex(r"M\d{1,3}_\dx\d(_[A-Za-z]{1,2}[.\d]*)*", fullmatch=True),
    fields=st.dictionaries(
        st.sampled_from(["width", "height", "seed", "start", "clue", "p_lure", "trap_value"]),
        _JSON,
    ),
    answer=_JSON,
)
def test_no_input_gives_a_500(string: str, fields: dict, answer: object) -> None:
    for body in ({"string": string}, {"fields": fields, "string": string}, answer):
        response = post(_IDLE_CLIENT, "/api/maze", body)
        # 415: a JSON null is no body at all
        assert response.status_code in (200, 400, 415), (body, response.text)
    picture = _IDLE_CLIENT.get("/api/maze.png", params={"string": string})
    assert picture.status_code in (200, 400)
    response = post(_IDLE_CLIENT, "/api/answer", {"question": string, "answer": answer})
    assert response.status_code == 409  # nothing is asked


# -- nothing of Python's on the page ------------------------------------------------------


def test_no_none_reaches_the_page(live) -> None:
    """Every answer the page shows, good or bad, is free of Python's ``None``.

    A missing value is JSON's ``null`` (the page shows a dash) and a message
    says what is missing in words: the page, the state at every step of a
    session, the maze cards, the episodes, and the errors to requests whose
    values are ``null``.
    """
    session, client = live
    seen: list[tuple[str, str]] = [("GET /", client.get("/").text)]

    def keep(where: str, response) -> dict:
        seen.append((where, response.text))
        return response.json()

    fields = post(client, "/api/maze", {"string": "M4_10x10_C1_l.25_L.25"}).json()["fields"]
    for key in fields:
        keep(f"fields {key} null", post(client, "/api/maze", {"fields": {**fields, key: None}}))
    for body in ({"string": None}, {}, {"fields": None}, {"string": "M4_5x5", "reference": None}):
        keep(f"maze {body}", post(client, "/api/maze", body))
    for body in (
        {"question": None, "answer": 0},
        {"answer": ["M4_5x5"]},
        {"question": "generate-1", "answer": None},
        {"question": "generate-1", "answer": [None, None]},
    ):
        keep(f"answer {body}", post(client, "/api/answer", body))
    for _ in range(4):  # generate-1, select-2, generate-2, select-3: the toy session
        assert session.wait_for("question", WAIT), session.error
        asked = keep("state", client.get("/api/state"))["question"]
        if asked["kind"] == "generate":
            reference = asked["parent"]["string"]
            for maze in asked["suggestions"]:
                keep("card", post(client, "/api/maze", {"string": maze, "reference": reference}))
            answer = asked["suggestions"]
        else:
            null = {"question": asked["id"], "answer": None}
            keep("select null", post(client, "/api/answer", null))
            stage = asked["stage"] - 1
            for candidate in asked["candidates"]:
                for result in candidate["results"]:
                    path = f"/api/episode/{stage}/{candidate['branch']}/{result['index']}"
                    keep(path, client.get(path))
            answer = asked["candidates"][0]["branch"]
        assert post(client, "/api/answer", {"question": asked["id"], "answer": answer}).json()
    assert session.wait_for("finished", WAIT), session.error
    assert keep("final state", client.get("/api/state"))["final"]["headline"]
    shown = [(where, text) for where, text in seen if "None" in text]
    assert not shown, shown
    errors = [json.loads(text)["error"] for _, text in seen if text.startswith('{"error"')]
    assert "the maze string is missing" in errors
    assert "width is missing" in errors
    assert "the answer names no question" in errors
    assert any(e.startswith("the answer names no branch") for e in errors)
