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
never a 500.
"""

from __future__ import annotations

import io
import json
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
from amaze.runs.folder import write_json
from experiments.curate.design import (
    DesignError,
    maze_card,
    parse_maze,
    spec_from_fields,
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


def _png(image: Image.Image) -> bytes:
    buffer = io.BytesIO()
    image.save(buffer, format="PNG")
    return buffer.getvalue()


def _cell_size(text: str) -> int:
    spec = parse_maze(text)[0]
    return max(6, min(48, PREVIEW_SIDE // max(spec.width, spec.height)))


def _problem(status: int, message: str, details: Any = None) -> JSONResponse:
    body: dict[str, Any] = {"error": message}
    if details is not None:
        body["details"] = details
    return JSONResponse(body, status_code=status)


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
        """The branch's agent on maze ``index`` of its stage: figures and a GIF's path."""
        mazes = session.stage_mazes(stage)
        if not 0 <= index < len(mazes):
            raise AnswerError(f"stage {stage} has no maze {index}", status=404)
        folder = session.out / "stages" / f"stage-{stage}" / f"branch-{branch}" / "episodes"
        figures_file = folder / f"maze-{index}.json"
        with self._lock:
            lock = self._making.setdefault(figures_file, threading.Lock())
        with lock:
            if not figures_file.is_file():
                agent = session.agent(stage, branch)
                maze = mazes[index]
                results, trajectory = record_episode(maze, session.description["robot"], agent)
                gif = folder / f"maze-{index}.gif"
                save_episode_gif(
                    maze,
                    trajectory,
                    gif,
                    fps=12,
                    max_frames=ANIMATION_FRAMES,
                    cell_size=_cell_size(maze),
                )
                write_json(
                    figures_file,
                    {
                        "maze": maze,
                        "success": bool(results.success[0]),
                        "steps": int(results.steps[0]),
                        "collisions": int(results.collisions[0]),
                        "paper_reward": round(float(results.paper_reward[0]), 4),
                    },
                )
        figures = json.loads(figures_file.read_text(encoding="utf-8"))
        gif_path = figures_file.with_suffix(".gif").relative_to(session.out)
        return {**figures, "gif": f"/files/{gif_path.as_posix()}"}


def create_app(session: CurationSession, token: str, csrf: str | None = None) -> FastAPI:
    """The page's application for ``session``, guarded by ``token`` (see the module docstring)."""
    csrf = csrf or secrets.token_urlsafe(24)
    app = FastAPI(title="amaze-curate", docs_url=None, redoc_url=None, openapi_url=None)
    templates = Jinja2Templates(directory=str(HERE / "templates"))
    pictures = _Pictures()
    seeds = np.random.default_rng(np.random.SeedSequence([session.description["seed"], 0x5EED]))
    seeds_lock = threading.Lock()
    run_folder = session.out.resolve()

    @app.middleware("http")
    async def guard(request: Request, call_next: Callable[[Request], Awaitable[Response]]):
        given = request.query_params.get("token")
        if given is not None and secrets.compare_digest(given, token):
            query = [(k, v) for k, v in request.query_params.multi_items() if k != "token"]
            target = request.url.path + (f"?{urlencode(query)}" if query else "")
            response: Response = RedirectResponse(target, status_code=303)
            response.set_cookie(COOKIE, token, httponly=True, samesite="strict")
            return response
        cookie = request.cookies.get(COOKIE)
        if cookie is None or not secrets.compare_digest(cookie, token):
            return _problem(403, "this page needs the token of the URL amaze-curate printed")
        if request.method not in ("GET", "HEAD", "POST"):
            return _problem(405, f"method {request.method} is not allowed")
        if request.method == "POST":
            sent = request.headers.get("x-csrf-token", "")
            if not secrets.compare_digest(sent, csrf):
                return _problem(403, "the request lacks the page's CSRF token")
            length = request.headers.get("content-length")
            if length is None or not length.isdigit():
                return _problem(411, "a post needs a Content-Length")
            if int(length) > MAX_BODY:
                return _problem(413, f"request body of {length} bytes (at most {MAX_BODY})")
            if not request.headers.get("content-type", "").startswith("application/json"):
                return _problem(415, "a post's body must be JSON")
        return await call_next(request)

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

    async def json_body(request: Request) -> dict[str, Any]:
        try:
            data = json.loads(await request.body())
        except (ValueError, UnicodeDecodeError):
            raise AnswerError("the request body is not JSON") from None
        if not isinstance(data, dict):
            raise AnswerError("the request body is not a JSON object")
        return data

    @app.get("/")
    def page(request: Request) -> Response:
        return templates.TemplateResponse(request, "curate.html", {"csrf": csrf})

    @app.get("/api/state")
    def state() -> dict[str, Any]:
        return session.state()

    @app.post("/api/maze")
    async def maze(request: Request) -> dict[str, Any]:
        data = await json_body(request)
        reference = data.get("reference")
        if reference is not None and not isinstance(reference, str):
            raise DesignError(f"reference {reference!r} is not a maze string")
        if "fields" in data:
            base = data.get("string")
            spec = spec_from_fields(data["fields"], base if isinstance(base, str) else None)
            text = spec.to_string()
        else:
            text = data.get("string")
            if not isinstance(text, str):
                raise DesignError(f"maze string {text!r} is not text")
        if data.get("new_seed") is True:
            with seeds_lock:
                text = with_new_seed(text, seeds)
        return maze_card(text, reference)

    @app.get("/api/maze.png")
    def maze_png(string: str = "") -> Response:
        canonical = parse_maze(string)[0].to_string()
        return Response(pictures.preview(canonical), media_type="image/png")

    @app.post("/api/answer")
    async def answer(request: Request) -> dict[str, Any]:
        data = await json_body(request)
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
        try:
            wanted = (run_folder / path).resolve()
            wanted.relative_to(run_folder)
        except (ValueError, OSError):
            raise AnswerError(f"no file {path!r} in the run folder", status=404) from None
        if not wanted.is_file():
            raise AnswerError(f"no file {path!r} in the run folder", status=404)
        return FileResponse(wanted)

    app.mount("/static", StaticFiles(directory=str(HERE / "static")), name="static")
    return app
