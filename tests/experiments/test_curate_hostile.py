"""Hostile requests to the curation page's server: each is a 4xx, and the server goes on.

The probes are an adversarial tester's: tokens that are not ASCII, JSON bodies
nested tens of thousands deep, NaN and infinities in a maze's fields, lone
surrogates (``"\\ud800"``) in any string of a body or a URL, file
names too long for the file system, link loops in the run folder, a damaged
agent behind an episode. The test client raises whatever the application does
not handle (a 500), so each probe fails loudly on a server that crashes on it;
a real server (uvicorn, on raw sockets) must also log no error for them.

One session of the toy learner (``tests/amaze/runs``) serves every test: it
waits at its select-2 question, its first stage's two branches trained.
"""

from __future__ import annotations

import json
import logging
import math
import socket
import threading
from collections.abc import Iterator

import pytest
import uvicorn
from fastapi.testclient import TestClient

from experiments.curate.server import COOKIE, MAX_MESSAGE, _problem
from experiments.curate.session import CurationSession, branch_folder
from tests.experiments.test_curate_server import CSRF, TOKEN, new_session, post, question

JSON = {"Content-Type": "application/json"}
#: The session and a client of its page that holds the token.
Served = tuple[CurationSession, TestClient]


@pytest.fixture(scope="module")
def served(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Served]:
    session, client = new_session(tmp_path_factory.mktemp("hostile") / "run")
    asked = question(session, client)
    post(client, "/api/answer", {"question": asked["id"], "answer": ["M4_6x6_C1", "M5_6x6_C1"]})
    assert question(session, client)["id"] == "select-2"
    yield session, client
    session.close()
    session.wait(60)


def still_serves(client: TestClient) -> None:
    """The server answers a normal request after the probes."""
    response = client.get("/api/state")
    assert response.status_code == 200
    assert response.json()["phase"] == "question"


def refused(response, status: int | tuple[int, ...]) -> str:
    """The error message of a refused request, checked to be ``status`` and short."""
    assert response.status_code in (status if isinstance(status, tuple) else (status,)), (
        response.status_code,
        response.text[:200],
    )
    message = response.json()["error"]
    assert 0 < len(message) <= MAX_MESSAGE
    return message


def raw_post(client: TestClient, path: str, body: bytes, **headers: str | bytes):
    """A post of ``body`` as it is (no JSON encoding), with the CSRF token unless overridden."""
    return client.post(path, content=body, headers={"X-CSRF-Token": CSRF, **JSON, **headers})


# -- tokens -----------------------------------------------------------------------------


@pytest.mark.parametrize(
    "query",
    [
        "token=%C3%A9",
        "token=%FF",
        "token=t0ken-for-test%C3%A9",
        "token=%00",
        "token=" + "x" * 5000,
        "token=%ED%A0%80",
    ],
    ids=["e-acute", "not-utf8", "token-and-more", "nul", "long", "surrogate"],
)
def test_a_token_of_any_text_in_the_query_is_a_403(served, query: str) -> None:
    _session, client = served
    bare = TestClient(client.app)
    refused(bare.get(f"/api/state?{query}"), 403)
    still_serves(client)


@pytest.mark.parametrize(
    "cookie",
    [b"\xe9", "é".encode(), b"t0ken-for-tests\xff", b"\x7f", b"\xed\xa0\x80"],
    ids=["latin-1", "utf-8", "token-and-more", "delete", "surrogate"],
)
def test_a_cookie_of_any_bytes_is_a_403(served, cookie: bytes) -> None:
    _session, client = served
    bare = TestClient(client.app)
    refused(bare.get("/api/state", headers={"Cookie": COOKIE.encode() + b"=" + cookie}), 403)
    still_serves(client)


@pytest.mark.parametrize(
    "csrf",
    [b"\xe9", "csrf-for-testsé".encode(), b"\xff" * 300, b"\xed\xa0\x80"],
    ids=["latin-1", "token-and-more", "long", "surrogate"],
)
def test_a_csrf_token_of_any_bytes_is_a_403(served, csrf: bytes) -> None:
    _session, client = served
    body = json.dumps({"string": "M4_5x5"}).encode()
    refused(raw_post(client, "/api/maze", body, **{"X-CSRF-Token": csrf}), 403)
    still_serves(client)


# -- bodies ----------------------------------------------------------------------------


@pytest.mark.parametrize("path", ["/api/answer", "/api/maze"])
@pytest.mark.parametrize(
    "body",
    [b"[" * 30000, b"[" * 200 + b"]" * 200, b'{"a":' * 12000, b"\xff\xfe", b"\xef\xbb\xbf{}"],
    ids=["open-arrays", "deep-arrays", "open-objects", "not-utf8", "bom"],
)
def test_a_body_that_is_no_usable_json_is_a_400(served, path: str, body: bytes) -> None:
    _session, client = served
    refused(raw_post(client, path, body), 400)
    still_serves(client)


@pytest.mark.parametrize(
    ("field", "named"),
    [
        ("width", "width"),
        ("height", "height"),
        ("seed", "seed"),
        ("clue_value", "clue lightness"),
        ("p_lure", "lure probability"),
        ("p_trap", "trap probability"),
    ],
)
@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf])
def test_a_field_that_is_not_finite_is_a_400_naming_it(
    served, field: str, named: str, value: float
) -> None:
    _session, client = served
    card = post(client, "/api/maze", {"string": "M4_10x10_C1"}).json()
    fields = {**card["fields"], "lure": True, "trap": True, field: value}
    body = json.dumps({"fields": fields}).encode()  # NaN and Infinity, as a script may send
    message = refused(raw_post(client, "/api/maze", body), 400)
    assert named in message
    still_serves(client)


def test_an_answer_that_is_not_finite_is_a_400(served) -> None:
    session, client = served
    for answer in (math.nan, -math.inf, [math.nan], {"branch": math.inf}):
        body = json.dumps({"question": "select-2", "answer": answer}).encode()
        refused(raw_post(client, "/api/answer", body), 400)
    assert session.phase == "question"  # nothing was taken
    still_serves(client)


#: Bodies whose strings hold a lone surrogate (JSON's ``\ud800`` escape), per route.
SURROGATES = {
    "/api/answer": [
        b'{"question": "\\ud800", "answer": 0}',
        b'{"question": "select-2", "answer": "\\ud800"}',
        b'{"question": "select-2", "answer": ["M4_5x5\\udfff", "M4_5x5"]}',
        b'{"question": "select-2", "answer": {"branch": "\\ud800"}}',
        b'{"\\ud800": "select-2"}',
        b'{"question": "select-2\\udc00\\ud800", "answer": 0}',
    ],
    "/api/maze": [
        b'{"string": "\\ud800"}',
        b'{"string": "M4_\\ud800_5x5"}',
        b'{"string": "M4_5x5", "reference": "M4_\\udbff"}',
        b'{"string": "M4_5x5", "new_seed": "\\ud800"}',
        b'{"fields": {"start": "\\ud800"}}',
        b'{"fields": {"start": "SW", "width": 5, "height": 5, "seed": 1, "unicursive": "\\udfff"}}',
        b'{"fields": "\\ud800", "string": "M4_5x5"}',
        b'{"fields": {"start": "SW"}, "string": "\\ud800"}',
        b'{"string": ["\\ud800"]}',
        b'{"string": "M4_5x5", "\\ud800": 1}',
        b'{"string": "' + b"x" * 1000 + b'\\ud800"}',
    ],
}


@pytest.mark.parametrize(
    ("path", "body"),
    [(path, body) for path, bodies in SURROGATES.items() for body in bodies],
    ids=[f"{path.rsplit('/', 1)[1]}-{i}" for path, b in SURROGATES.items() for i in range(len(b))],
)
def test_a_string_with_a_lone_surrogate_is_a_400_that_encodes(
    served, path: str, body: bytes
) -> None:
    session, client = served
    response = raw_post(client, path, body)
    message = refused(response, 400)
    assert "lone surrogate" in message
    assert "\\ud" in message  # named by its escape
    response.content.decode("utf-8")  # the answer is UTF-8 as it says
    assert session.phase == "question"  # nothing was taken
    still_serves(client)


@pytest.mark.parametrize(
    "path",
    [
        "/api/maze.png?string=%ED%A0%80",
        "/api/maze.png?string=M4_%ED%A0%80_5x5",
        "/api/maze.png?string=%FF%FE",
        "/files/%ED%A0%80",
        "/files/a%FFb",
        "/api/episode/%ED%A0%80/0/0",
        "/api/episode/1/0/%FF",
        "/static/%ED%A0%80",
    ],
    ids=["png", "png-in-string", "png-bytes", "file", "file-bytes", "episode", "ff", "static"],
)
def test_a_surrogate_or_bad_bytes_in_a_url_is_a_4xx_that_encodes(served, path: str) -> None:
    _session, client = served
    response = client.get(path)
    refused(response, (400, 404))
    response.content.decode("utf-8")
    still_serves(client)


def test_an_error_message_quoting_a_lone_surrogate_still_encodes() -> None:
    """Whatever a message quotes, the answer is UTF-8 (the surrogate written as its escape)."""
    response = _problem(400, "token '\ud800' and more", details=[None, "bad '\udfff'"])
    data = json.loads(response.body.decode("utf-8"))
    assert data == {"error": "token '\\ud800' and more", "details": [None, "bad '\\udfff'"]}


@pytest.mark.parametrize(
    "length",
    ["²", "1" * 5000, "-1", "0x10", ""],
    ids=["superscript", "long", "negative", "hex", "empty"],
)
def test_a_content_length_that_is_no_number_is_refused(served, length: str) -> None:
    _session, client = served
    headers = {"X-CSRF-Token": CSRF, **JSON, "Content-Length": length.encode()}
    response = client.post("/api/maze", content=b"{}", headers=headers)
    refused(response, (400, 411, 413))
    still_serves(client)


# -- files ------------------------------------------------------------------------------


def test_files_that_cannot_be_named_or_reached_are_404s(served) -> None:
    session, client = served
    out = session.out
    (out / "loop").symlink_to("loop")
    (out / "ping").symlink_to("pong")
    (out / "pong").symlink_to("ping")
    for path in (
        "a" * 300,
        "stages/" + "b" * 300 + "/result.json",
        "/".join(["c" * 200] * 30),
        "loop",
        "ping",
        "pong/x",
        "loop/config.json",
        "%00",
        "%C3%A9" * 200,
    ):
        refused(client.get(f"/files/{path}"), 404)
    assert client.get("/files/config.json").status_code == 200
    still_serves(client)


# -- episodes ---------------------------------------------------------------------------


def damage_agent(session: CurationSession, stage: int, branch: int) -> None:
    """Every file of a branch's saved learner overwritten, whatever the learner's format."""
    agent = branch_folder(session.out, stage, branch) / "agent"
    files = [path for path in agent.iterdir() if path.is_file()]
    assert files
    for path in files:
        path.write_bytes(b"\x00damaged\xff")


def test_a_branch_whose_agent_cannot_be_read_is_a_409(served) -> None:
    session, client = served
    damage_agent(session, 1, 1)
    message = refused(client.get("/api/episode/1/1/0"), 409)
    assert "agent cannot be read" in message
    assert client.get("/api/episode/1/0/0").status_code == 200  # the other branch plays
    still_serves(client)


@pytest.mark.parametrize(
    "path",
    [
        "/api/episode/1/" + "9" * 300 + "/0",
        "/api/episode/" + "9" * 300 + "/0/0",
        "/api/episode/1/0/" + "9" * 300,
        "/api/episode/1/2/0",
        "/api/episode/1/-1/0",
        "/api/episode/1/" + "9" * 5000 + "/0",
        "/api/episode/1/1e3/0",
    ],
    ids=["long-branch", "long-stage", "long-maze", "branch-2", "branch-1", "longer", "float"],
)
def test_an_episode_of_no_branch_is_a_4xx(served, path: str) -> None:
    _session, client = served
    refused(client.get(path), (400, 404))
    still_serves(client)


def test_damaged_episode_figures_are_made_again(served) -> None:
    session, client = served
    first = client.get("/api/episode/1/0/1").json()
    kept = branch_folder(session.out, 1, 0) / "episodes" / "maze-1.json"
    kept.write_bytes(b"[" * 30000)
    again = client.get("/api/episode/1/0/1")
    assert again.status_code == 200
    assert again.json() == first
    still_serves(client)


# -- a real server ---------------------------------------------------------------------


@pytest.fixture
def real_server(served) -> Iterator[int]:
    """The session's application served by uvicorn on a free port, in a thread."""
    _session, client = served
    sock = socket.socket()
    sock.bind(("127.0.0.1", 0))
    sock.listen(16)
    config = uvicorn.Config(
        client.app, log_level="warning", lifespan="off", access_log=False, log_config=None
    )
    server = uvicorn.Server(config)
    thread = threading.Thread(target=server.run, kwargs={"sockets": [sock]}, daemon=True)
    thread.start()
    yield sock.getsockname()[1]
    server.should_exit = True
    thread.join(10)
    sock.close()


def send(port: int, head: bytes, body: bytes = b"") -> int:
    """The status of one raw HTTP/1.1 request (``head``: request line and headers)."""
    with socket.create_connection(("127.0.0.1", port), timeout=30) as connection:
        connection.sendall(head + b"\r\nConnection: close\r\n\r\n" + body)
        answer = b""
        while b"\r\n" not in answer:
            chunk = connection.recv(4096)
            if not chunk:
                break
            answer += chunk
    return int(answer.split(b" ", 2)[1])


def test_a_real_server_answers_every_probe_and_logs_no_error(
    served, real_server: int, caplog: pytest.LogCaptureFixture
) -> None:
    session, _client = served
    damage_agent(session, 1, 1)
    if not (session.out / "spiral").is_symlink():
        (session.out / "spiral").symlink_to("spiral")
    port = real_server
    cookie = f"Cookie: {COOKIE}={TOKEN}".encode()
    post_head = cookie + f"\r\nX-CSRF-Token: {CSRF}\r\nContent-Type: application/json".encode()
    nested = b"[" * 30000
    nan = b'{"fields": {"width": NaN, "height": 5, "seed": 1, "start": "SW"}}'
    surrogate = b'{"string": "M4_\\ud800", "question": "\\udfff", "answer": ["\\ud800"]}'
    probes = [
        (b"GET /api/state?token=%C3%A9 HTTP/1.1\r\nHost: x", b""),
        (b"GET /api/state HTTP/1.1\r\nHost: x\r\nCookie: " + COOKIE.encode() + b"=\xe9", b""),
        (
            b"POST /api/maze HTTP/1.1\r\nHost: x\r\n"
            + cookie
            + b"\r\nX-CSRF-Token: \xe9\r\nContent-Type: application/json\r\nContent-Length: 2",
            b"{}",
        ),
        *(
            (
                f"POST {path} HTTP/1.1\r\nHost: x\r\n".encode()
                + post_head
                + f"\r\nContent-Length: {len(body)}".encode(),
                body,
            )
            for path in ("/api/answer", "/api/maze")
            for body in (nested, nan, surrogate)
        ),
        (b"GET /files/" + b"a" * 300 + b" HTTP/1.1\r\nHost: x\r\n" + cookie, b""),
        (b"GET /files/%ED%A0%80 HTTP/1.1\r\nHost: x\r\n" + cookie, b""),
        (b"GET /api/maze.png?string=M4_%ED%A0%80 HTTP/1.1\r\nHost: x\r\n" + cookie, b""),
        (b"GET /files/spiral HTTP/1.1\r\nHost: x\r\n" + cookie, b""),
        (b"GET /api/episode/1/1/0 HTTP/1.1\r\nHost: x\r\n" + cookie, b""),
    ]
    with caplog.at_level(logging.WARNING):
        for head, body in probes:
            status = send(port, head, body)
            assert 400 <= status < 500, (head[:60], status)
        assert send(port, b"GET /api/state HTTP/1.1\r\nHost: x\r\n" + cookie) == 200
    errors = [r for r in caplog.records if r.levelno >= logging.ERROR]
    assert not errors, [r.getMessage() for r in errors]
