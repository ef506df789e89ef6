"""The page's web server: FastAPI over a :class:`~experiments.curate.session.CurationSession`.

Routes (every one needs the token, see below):

* ``GET /``: the page (a Jinja2 template; the script in ``static/`` draws it
  from ``/api/state``, polled every second);
* ``GET /api/state``: the session's state (:meth:`CurationSession.state`);
* ``POST /api/maze``: a maze card (:func:`~experiments.curate.design.maze_card`)
  for a typed ``string`` or the form's ``fields``, optionally with a ``new_seed``;
* ``GET /api/maze.png?string=...``: a preview picture of a maze;
* ``POST /api/answer``: the person's answer to the waiting question;
* ``GET /api/episode/{stage}/{branch}/{maze}``: a finished branch's agent on
  one of its stage's mazes: figures and an animated GIF (made once, kept in
  the branch's folder under ``episodes/``);
* ``GET /api/curriculum.png``: the curriculum so far;
* ``GET /files/{path}``: a file of the run folder; ``GET /static/{path}``: the
  page's own files.

**Safety.** The server binds to 127.0.0.1 unless told otherwise. A random
token is required for every request: in the query (``?token=``, the URL the
command prints), which sets an HTTP-only, same-site cookie and redirects to
the same path without it, or in that cookie; anything else gets 403. Posts
also carry the page's CSRF token in the ``X-CSRF-Token`` header and a JSON
body of at most :data:`MAX_BODY` bytes. ``/files/`` serves nothing outside
the run folder (404), and bad input gets a 4xx answer naming the problem,
never a 500: tokens of any text compare (as bytes), bodies are read by
:func:`amaze.validation.parse_json` (UTF-8, nesting bounded), numbers must be
finite, strings must be Unicode text (a lone surrogate, ``"\\ud800"``, is a
400), file names too long or looping links are 404s, and a branch whose
agent cannot be read is a 409 naming the file. Every error message is made
encodable (:func:`_clipped`), whatever text of the request it quotes.
"""

from __future__ import annotations

import hmac
import io
import os
import secrets
import threading
from collections import OrderedDict
from collections.abc import Awaitable, Callable
from pathlib import Path
from typing import Any
from urllib.parse import urlencode

import numpy as np
from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import FileResponse, JSONResponse, RedirectResponse, Response
from fastapi.staticfiles import StaticFiles
from fastapi.templating import Jinja2Templates
from PIL import Image
from starlette.exceptions import HTTPException as StarletteHTTPException

from amaze.agents.trajectories import save_episode_gif
from amaze.curriculum.picture import render_curriculum
from amaze.evaluation.policy import record_episode
from amaze.maze.render import render_maze
from amaze.runs.config import read_json_object
from amaze.runs.folder import write_json
from amaze.validation import parse_json
from experiments.curate.design import (
    DesignError,
    maze_card,
    parse_maze,
    spec_from_fields,
    strict_maze,
    with_new_seed,
)
from experiments.curate.session import AnswerError, CurationSession

__all__ = ["COOKIE", "MAX_BODY", "create_app"]

HERE = Path(__file__).parent
#: The cookie that carries the token after the first visit.
COOKIE = "amaze_curate_token"
#: Largest request body (bytes): K maze strings and a little JSON.
MAX_BODY = 64 * 1024
#: About the long side, in pixels, of previews and animations.
PREVIEW_SIDE = 280
#: Frames of an animation at most (long episodes are sampled).
ANIMATION_FRAMES = 120
#: Previews kept in memory.
PREVIEW_CACHE = 256
#: Longest message of an error answer: messages quote what the request sent, which may be long.
MAX_MESSAGE = 300


def _png(image: Image.Image) -> bytes:
    buffer = io.BytesIO()
    image.save(buffer, format="PNG")
    return buffer.getvalue()


def _cell_size(text: str) -> int:
    spec = parse_maze(text)[0]
    return max(6, min(48, PREVIEW_SIDE // max(spec.width, spec.height)))


def _same(given: str | None, expected: str) -> bool:
    """Whether a token from a request is ``expected``, in constant time, for any text.

    ``secrets.compare_digest`` refuses strings with non-ASCII characters (a
    ``TypeError``); the bytes of any text compare. Lone surrogates are kept
    (``surrogatepass``): their bytes are not UTF-8, so they never match.
    """
    if given is None:
        return False
    return hmac.compare_digest(
        given.encode("utf-8", "surrogatepass"), expected.encode("utf-8", "surrogatepass")
    )


def _body_length(header: str | None) -> int | None:
    """The ``Content-Length`` header as a number, ``None`` if it is missing or not one.

    Only ASCII digits count (``str.isdigit`` accepts ``"²"``, which ``int``
    refuses); a value longer than any allowed body is capped rather than
    converted (``int`` refuses strings of thousands of digits).
    """
    if header is None or not (header.isascii() and header.isdigit()):
        return None
    return MAX_BODY + 1 if len(header) > len(str(MAX_BODY)) else int(header)


def _clipped(message: str) -> str:
    """``message`` cut to :data:`MAX_MESSAGE` characters and made encodable as UTF-8.

    Messages quote what a request sent: a lone surrogate (``"\\ud800"`` in a
    JSON body) is written as its escape, ``\\ud800``, so the answer encodes.
    """
    message = message.encode("utf-8", "backslashreplace").decode("utf-8")
    return message if len(message) <= MAX_MESSAGE else message[: MAX_MESSAGE - 3] + "..."


def _problem(status: int, message: str, details: Any = None) -> JSONResponse:
    """An error answer: ``{"error": message}``, with ``details`` (a list of messages or None)."""
    body: dict[str, Any] = {"error": _clipped(message)}
    if isinstance(details, list):
        body["details"] = [d if d is None else _clipped(str(d)) for d in details]
    elif details is not None:
        body["details"] = _clipped(str(details))
    return JSONResponse(body, status_code=status)


def _not_unicode(value: Any) -> str | None:
    """Where parsed JSON holds a string (a key or a value) that is not Unicode text, else None.

    JSON's ``\\ud800`` escape gives a lone surrogate, which no encoding
    writes. Walked without recursion; the answer names the string and the
    surrogate's place, the text around it escaped with :func:`ascii`
    (``"string 'M4_\\ud800' (character 3)"``).
    """
    stack = [(value, "string")]
    while stack:
        item, kind = stack.pop()
        if isinstance(item, dict):
            stack.extend((key, "key") for key in item)
            stack.extend((child, "string") for child in item.values())
        elif isinstance(item, list):
            stack.extend((child, "string") for child in item)
        elif isinstance(item, str):
            try:
                item.encode("utf-8")
            except UnicodeEncodeError as problem:
                at = problem.start
                return f"{kind} {item[max(0, at - 20) : at + 20]!a} (character {at})"
    return None


class _Pictures:
    """Previews by maze string (a small cache) and animations made once, one at a time."""

    def __init__(self) -> None:
        self._previews: OrderedDict[str, bytes] = OrderedDict()
        self._lock = threading.Lock()
        self._making: dict[Path, threading.Lock] = {}

    def preview(self, text: str) -> bytes:
        with self._lock:
            if text in self._previews:
                self._previews.move_to_end(text)
                return self._previews[text]
        data = _png(render_maze(text, cell_size=_cell_size(text), sign_kinds=True))
        with self._lock:
            self._previews[text] = data
            while len(self._previews) > PREVIEW_CACHE:
                self._previews.popitem(last=False)
        return data

    def episode(self, session: CurationSession, stage: int, branch: int, index: int) -> dict:
        """The branch's agent on maze ``index`` of its stage: figures and a GIF's path.

        The figures and the GIF are kept in the branch's ``episodes/``; a kept
        pair that cannot be read (damaged, half gone) is made again.
        """
        mazes = session.stage_mazes(stage)
        if not 0 <= index < len(mazes):
            raise AnswerError(f"stage {stage} has no maze {index}", status=404)
        figures_file = session.finished_branch(stage, branch) / "episodes" / f"maze-{index}.json"
        gif = figures_file.with_suffix(".gif")
        with self._lock:
            lock = self._making.setdefault(figures_file, threading.Lock())
        with lock:
            figures = _kept_figures(figures_file)
            if figures is None or not gif.is_file():
                agent = session.agent(stage, branch)
                figures = _record(mazes[index], session.description["robot"], agent, gif)
                write_json(figures_file, figures)
        return {**figures, "gif": f"/files/{gif.relative_to(session.out).as_posix()}"}


def _kept_figures(path: Path) -> dict[str, Any] | None:
    """The figures of an episode made before, ``None`` if there are none or they are damaged."""
    try:
        return read_json_object(path, AnswerError, "episode figures")
    except AnswerError:
        return None


def _record(maze: str, robot: str, agent: Any, gif: Path) -> dict[str, Any]:
    """``agent`` on ``maze``: its animation saved to ``gif``, and its figures."""
    results, trajectory = record_episode(maze, robot, agent)
    save_episode_gif(
        maze, trajectory, gif, fps=12, max_frames=ANIMATION_FRAMES, cell_size=_cell_size(maze)
    )
    return {
        "maze": maze,
        "success": bool(results.success[0]),
        "steps": int(results.steps[0]),
        "collisions": int(results.collisions[0]),
        "normalized_reward": round(float(results.normalized_reward[0]), 4),
    }


def _run_file(run_folder: Path, path: str) -> Path:
    """The readable file ``path`` of the run folder (already resolved); 404 for anything else.

    Links are followed, but only to files inside the run folder; names too long
    for the file system, link loops and files that cannot be read are 404s too.
    """
    missing = AnswerError(f"no file {path!r} in the run folder", status=404)
    try:
        wanted = (run_folder / path).resolve()
        wanted.relative_to(run_folder)
        readable = wanted.is_file() and os.access(wanted, os.R_OK)
    except (ValueError, OSError, RuntimeError):  # RuntimeError: a link loop (Python < 3.13)
        raise missing from None
    if not readable:
        raise missing
    return wanted


def create_app(session: CurationSession, token: str, csrf: str | None = None) -> FastAPI:
    """The page's application for ``session``, guarded by ``token`` (see the module docstring)."""
    csrf = csrf or secrets.token_urlsafe(24)
    app = FastAPI(title="amaze-curate", docs_url=None, redoc_url=None, openapi_url=None)
    templates = Jinja2Templates(directory=str(HERE / "templates"))
    pictures = _Pictures()
    seeds = np.random.default_rng(np.random.SeedSequence([session.description["seed"], 0x5EED]))
    run_folder = session.out.resolve()
    _add_guard(app, token, csrf)
    _add_error_handlers(app)
    _add_page_routes(app, session, templates, csrf)
    _add_maze_routes(app, pictures, seeds)
    _add_run_routes(app, session, pictures, run_folder)
    app.mount("/static", StaticFiles(directory=str(HERE / "static")), name="static")
    return app


def _add_guard(app: FastAPI, token: str, csrf: str) -> None:
    """The middleware that checks every request: token, method, and a post's CSRF token and body.

    A request carrying the token in its query is redirected to the same path
    without it, with the token set in an HTTP-only, same-site cookie; anything
    without the token gets 403 before any route runs.
    """

    @app.middleware("http")
    async def guard(request: Request, call_next: Callable[[Request], Awaitable[Response]]):
        given = request.query_params.get("token")
        if _same(given, token):
            query = [(k, v) for k, v in request.query_params.multi_items() if k != "token"]
            target = request.url.path + (f"?{urlencode(query)}" if query else "")
            response: Response = RedirectResponse(target, status_code=303)
            response.set_cookie(COOKIE, token, httponly=True, samesite="strict")
            return response
        if not _same(request.cookies.get(COOKIE), token):
            return _problem(403, "this page needs the token of the URL amaze-curate printed")
        if request.method not in ("GET", "HEAD", "POST"):
            return _problem(405, f"method {request.method} is not allowed")
        if request.method == "POST":
            if not _same(request.headers.get("x-csrf-token"), csrf):
                return _problem(403, "the request lacks the page's CSRF token")
            length = _body_length(request.headers.get("content-length"))
            if length is None:
                return _problem(411, "a post needs a Content-Length")
            if length > MAX_BODY:
                return _problem(413, f"a request body of at most {MAX_BODY} bytes")
            if not request.headers.get("content-type", "").startswith("application/json"):
                return _problem(415, "a post's body must be JSON")
        return await call_next(request)


def _add_error_handlers(app: FastAPI) -> None:
    """Answer every known problem with a 4xx naming it (``{"error": ...}``), never a 500."""

    @app.exception_handler(AnswerError)
    async def answer_error(request: Request, problem: AnswerError) -> JSONResponse:
        return _problem(problem.status, str(problem), problem.details)

    @app.exception_handler(DesignError)
    async def design_error(request: Request, problem: DesignError) -> JSONResponse:
        return _problem(400, str(problem))

    @app.exception_handler(RequestValidationError)
    async def bad_request(request: Request, problem: RequestValidationError) -> JSONResponse:
        first = problem.errors()[0] if problem.errors() else {}
        where = ".".join(str(p) for p in first.get("loc", ()))
        return _problem(400, f"bad request: {where}: {first.get('msg', 'invalid')}")

    @app.exception_handler(StarletteHTTPException)
    async def http_error(request: Request, problem: StarletteHTTPException) -> JSONResponse:
        return _problem(problem.status_code, str(problem.detail))


async def _json_body(request: Request) -> dict[str, Any]:
    """A post's body: a JSON object of at most :data:`MAX_BODY` bytes, else an :class:`AnswerError`.

    The guard checked the ``Content-Length`` header; this checks what came.
    Every string in it, keys included, must be Unicode text (no lone surrogate).
    """
    body = await request.body()
    if len(body) > MAX_BODY:  # the guard checked the header; this is what came
        raise AnswerError(f"a request body of at most {MAX_BODY} bytes", status=413)
    data = parse_json(body, "the request body", error=AnswerError)
    if not isinstance(data, dict):
        raise AnswerError("the request body is not a JSON object")
    bad = _not_unicode(data)
    if bad is not None:
        raise AnswerError(f"the request body's {bad} holds a lone surrogate, which is not text")
    return data


def _add_page_routes(
    app: FastAPI, session: CurationSession, templates: Jinja2Templates, csrf: str
) -> None:
    """``GET /``: the page (with its CSRF token); ``GET /api/state``: the session's state."""

    @app.get("/")
    def page(request: Request) -> Response:
        return templates.TemplateResponse(request, "curate.html", {"csrf": csrf})

    @app.get("/api/state")
    def state() -> dict[str, Any]:
        return session.state()


def _add_maze_routes(app: FastAPI, pictures: _Pictures, seeds: np.random.Generator) -> None:
    """``POST /api/maze``: a maze card; ``GET /api/maze.png``: a maze's preview.

    New seeds are drawn from ``seeds`` (a generator seeded by the session's
    seed), one request at a time.
    """
    seeds_lock = threading.Lock()

    @app.post("/api/maze")
    async def maze(request: Request) -> dict[str, Any]:
        data = await _json_body(request)
        reference = data.get("reference")
        if reference is not None and not isinstance(reference, str):
            raise DesignError(f"reference {reference!r} is not a maze string")
        if "fields" in data:
            base = data.get("string")
            spec = spec_from_fields(data["fields"], base if isinstance(base, str) else None)
            text = spec.to_string()
        else:
            text = data.get("string")
            if text is None:
                raise DesignError("the maze string is missing")
            if not isinstance(text, str):
                raise DesignError(f"maze string {text!r} is not text")
            strict_maze(text)  # every bad token named, those without effect too
        if data.get("new_seed") is True:
            with seeds_lock:
                text = with_new_seed(text, seeds)
        return maze_card(text, reference)

    @app.get("/api/maze.png")
    def maze_png(string: str = "") -> Response:
        canonical = parse_maze(string)[0].to_string()
        return Response(pictures.preview(canonical), media_type="image/png")


def _add_run_routes(
    app: FastAPI, session: CurationSession, pictures: _Pictures, run_folder: Path
) -> None:
    """The routes of the run: the person's answers, episodes, the curriculum and its files."""

    @app.post("/api/answer")
    async def answer(request: Request) -> dict[str, Any]:
        data = await _json_body(request)
        session.answer(data.get("question"), data.get("answer"))
        return {"ok": True}

    @app.get("/api/episode/{stage}/{branch}/{index}")
    def episode(stage: int, branch: int, index: int) -> dict[str, Any]:
        return pictures.episode(session, stage, branch, index)

    @app.get("/api/curriculum.png")
    def curriculum_png() -> Response:
        records = session.records()
        if not records:
            raise AnswerError("no stage is finished yet", status=404)
        return Response(
            _png(render_curriculum(records, finished=session.phase == "finished")),
            media_type="image/png",
        )

    @app.get("/files/{path:path}")
    def files(path: str) -> Response:
        return FileResponse(_run_file(run_folder, path))
