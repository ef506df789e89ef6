"""The ``amaze-curate`` command: an EDHuCAT run whose curator is a person at a browser page.

::

    amaze-curate --out runs/me                         # PPO, DD, 10 stages x 3 branches
    amaze-curate --out runs/me --algo cmaes --budget-steps 600000 --stages 5 --branches 2
    amaze-curate --out runs/me --advisor edens         # EDEnS proposes, you decide
    amaze-curate --resume runs/me                      # a killed server goes on
    amaze-curate --replay runs/me --out runs/me-again  # the same decisions, no page

It prints one line, the page's address with its token
(``http://127.0.0.1:PORT/?token=...``; ``--port 0`` takes any free port and
the line names it), opens the browser unless ``--no-browser``, and serves
until interrupted (Ctrl-C). The run folder is the curriculum loop's
(:mod:`amaze.runs.curriculum`): ``decisions.jsonl`` holds every decision with
the seconds the person took. Bad input prints one line ``error: ...`` and
exits with status 2; ``--resume`` checks every file the resumed run reads
(:mod:`experiments.curate.resume`) before it serves the page.
"""

from __future__ import annotations

import argparse
import ipaddress
import os
import secrets
import socket
import sys
import webbrowser
from collections.abc import Sequence
from pathlib import Path
from typing import Any, NoReturn

from amaze.errors import UsageError
from amaze.runs.command import CommandParser, run_command
from amaze.runs.config import read_json_object
from amaze.runs.curriculum import CurriculumRun
from amaze.runs.lifecycle import CONFIG_FILE, Run
from experiments.trainers import ALGORITHMS
from experiments.trainers import run_class as trainer

__all__ = ["entry_point", "exposure_warning", "main"]

DEFAULT_PORT = 8765


def parser() -> CommandParser:
    p = CommandParser(
        version=True,
        prog="amaze-curate",
        description="Curate a curriculum in your browser: an EDHuCAT run whose curator is you.",
    )
    run = p.add_argument_group("the run")
    run.add_argument("--out", metavar="DIR", help="the run folder to create")
    run.add_argument("--resume", metavar="DIR", help="continue the session in DIR")
    run.add_argument(
        "--replay", metavar="RUN_DIR", help="rerun RUN_DIR's decisions into --out, without a page"
    )
    run.add_argument("--algo", default="ppo", choices=ALGORITHMS, help="trainer (default: ppo)")
    run.add_argument("--robot", default="DD", help="robot (default: DD)")
    run.add_argument("--stages", type=int, default=10, metavar="S", help="stages (default: 10)")
    run.add_argument(
        "--branches", type=int, default=3, metavar="K", help="branches per stage (default: 3)"
    )
    run.add_argument(
        "--budget-steps",
        type=int,
        metavar="N",
        help="env steps of the whole run (default: the trainer's, 3000000)",
    )
    run.add_argument("--seed", type=int, default=0, help="the run's seed (default: 0)")
    run.add_argument("--target", metavar="MAZE", help="the maze the curriculum leads to")
    run.add_argument(
        "--advisor",
        metavar="NAME",
        help="an automated curator (edens, careful...) whose proposal the page shows at every"
        " decision, with its reasons and a button to take it; recorded with whether it was taken",
    )
    page = p.add_argument_group("the page")
    page.add_argument(
        "--host", default="127.0.0.1", help="address to serve on (default: 127.0.0.1)"
    )
    page.add_argument(
        "--port", type=int, default=DEFAULT_PORT, help=f"port, 0 for any (default: {DEFAULT_PORT})"
    )
    page.add_argument(
        "--no-browser", action="store_true", help="print the address without opening a browser"
    )
    return p


def _fresh(args: argparse.Namespace) -> tuple[type[Run], Any, Path]:
    """The trainer and the checked config of a new session in ``--out``."""
    if not args.out:
        raise UsageError("--out is required (or --resume DIR)")
    run_class = trainer(args.algo)
    data: dict[str, Any] = {
        "algo": args.algo,
        "robot": args.robot,
        "seed": args.seed,
        "regime": "edhucat",
        "curator": "human",
        "stages": args.stages,
        "branches": args.branches,
    }
    if args.budget_steps is not None:
        data["budget_steps"] = args.budget_steps
    if args.target is not None:
        data["target"] = args.target
    if args.advisor is not None:
        data["advisor"] = args.advisor
    config = run_class.config_class.from_dict(data).validate()
    out = Path(args.out)
    Run._check_new_folder(out, config.error)
    return run_class, config, out


def _resumed(folder: str) -> tuple[type[Run], Any, Path]:
    """The trainer and the config of the session in ``folder``, which must be a human one."""
    out = Path(folder)
    if not (out / CONFIG_FILE).is_file():
        raise UsageError(f"{folder!r} holds no run (no {CONFIG_FILE})")
    data = read_json_object(out / CONFIG_FILE, UsageError, "run config")
    run_class = trainer(data.get("algo"))
    config = run_class.read_config(out)
    if getattr(config, "curator", None) != "human":
        raise UsageError(
            f"{folder!r} holds a run whose curator is {getattr(config, 'curator', None)!r},"
            " not a person (resume it with its own command)"
        )
    return run_class, config, out


def _describe(config: Any) -> dict[str, Any]:
    return {
        "algo": config.algo,
        "robot": config.robot,
        "seed": config.seed,
        "stages": config.stages,
        "branches": config.branches,
        "budget_steps": config.budget_steps,
        "target": config.target,
        "advisor": getattr(config, "advisor", None),
    }


def exposure_warning(host: str) -> str | None:
    """The warning printed when the page is served beyond this machine (``None`` on loopback)."""
    try:
        if ipaddress.ip_address(host).is_loopback:
            return None
    except ValueError:
        pass
    return (
        f"warning: serving on {host}, not the loopback address: anyone who can reach it"
        " and has the page's address can curate this run"
    )


def _listen(host: str, port: int) -> socket.socket:
    """A listening socket on ``host:port`` (port 0: a free one)."""
    try:
        family = socket.AF_INET6 if ipaddress.ip_address(host).version == 6 else socket.AF_INET
    except ValueError:
        family = socket.AF_INET
    if not 0 <= port <= 65535:
        raise UsageError(f"port {port} is not in 0..65535")
    sock = socket.socket(family, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        sock.bind((host, port))
    except OSError as problem:
        sock.close()
        raise UsageError(f"cannot serve on {host}:{port}: {problem.strerror or problem}") from None
    sock.listen(64)
    return sock


def _loop_class(run_class: type[Run], config: Any) -> type[CurriculumRun]:
    """The trainer's curriculum loop that runs ``config`` (an EDHuCAT config)."""
    base = run_class.run_class_for(config)
    assert issubclass(base, CurriculumRun)
    return base


def _serve(args: argparse.Namespace, base: type[CurriculumRun], config: Any, out: Path) -> int:
    import uvicorn

    from experiments.curate.server import create_app
    from experiments.curate.session import CurationSession

    session = CurationSession(out, _describe(config))
    browser_run = session.run_class(base)
    sock = _listen(args.host, args.port)
    token = secrets.token_urlsafe(24)
    app = create_app(session, token)
    host, port = sock.getsockname()[:2]
    shown = f"[{host}]" if ":" in host else host
    url = f"http://{shown}:{port}/?token={token}"
    warning = exposure_warning(host)
    if warning:
        print(warning, file=sys.stderr)
    print(url, flush=True)
    if args.resume:
        session.start(lambda: browser_run.resume(out))
    else:
        session.start(lambda: browser_run.fresh(config, out))
    print(
        f"amaze-curate: run folder {out}; Ctrl-C stops the page (amaze-curate --resume {out}"
        " goes on)",
        file=sys.stderr,
        flush=True,
    )
    if not args.no_browser:
        webbrowser.open(url)
    server = uvicorn.Server(
        uvicorn.Config(app, log_level="warning", lifespan="off", access_log=False)
    )
    interrupted = False
    try:
        server.run(sockets=[sock])
    except KeyboardInterrupt:
        interrupted = True
    # The server stops only on a signal (Ctrl-C, kill): a session stopped before its end
    # exits with 130 even where SIGINT was ignored (uvicorn then returns, not raises).
    phase = session.phase  # before close(), which ends a question left unanswered
    status = 1 if phase == "failed" else 130 if interrupted or phase != "finished" else 0
    session.close()
    if phase != "finished":
        print(f"amaze-curate: stopped; amaze-curate --resume {out} goes on", file=sys.stderr)
    if not session.wait(timeout=2.0):
        # Training is under way in the worker (torch, numba): end the process now, as a
        # kill would. Every file of the run is written atomically, so the run resumes.
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(status)
    return status


def _run(argv: Sequence[str]) -> int:
    args = parser().parse_args(list(argv))
    for mode in ("replay", "resume"):
        if getattr(args, mode) and args.advisor is not None:
            raise UsageError(
                f"--advisor {args.advisor} would be ignored: --{mode} takes the run's own"
                " advisor from its config.json; leave --advisor out"
            )
    if args.replay:
        if not args.out:
            raise UsageError("--replay needs --out, the folder of the new run")
        data = read_json_object(Path(args.replay) / CONFIG_FILE, UsageError, "run config")
        result = trainer(data.get("algo")).replay(args.replay, args.out)
        print(result.headline)
        print(f"run folder: {result.out} ({', '.join(result.outputs)})")
        return 0
    if args.resume:
        from experiments.curate.resume import check_resume

        run_class, config, out = _resumed(args.resume)
        base = _loop_class(run_class, config)
        # Every file the resume reads is checked before the page is served.
        check_resume(base, out)
    else:
        run_class, config, out = _fresh(args)
        base = _loop_class(run_class, config)
    return _serve(args, base, config, out)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command; return the exit status (2 for bad input)."""
    return run_command(lambda: _run(sys.argv[1:] if argv is None else argv))


def entry_point() -> NoReturn:
    """Console-script entry point."""
    raise SystemExit(main())


if __name__ == "__main__":
    entry_point()
