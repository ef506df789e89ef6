"""Ray, the optional engine for work past one machine: connecting to it, and its checks.

The local backend (processes on this machine) is the default everywhere;
``--backend ray`` hands population evaluation (``amaze-evolve --actors N``),
study runs (``amaze-experiment run``) and replicates (``--replicates K``) to
Ray. Ray is an optional extra (``pip install 'amaze-evo[ray]'``) and is only
imported by :func:`import_ray`, when a command asks for it.

``--address`` says which cluster: none starts a private one on this machine
(all its cores, no dashboard, gone when the command ends); ``auto`` joins the
cluster that ``ray start`` started on this machine; ``HOST:PORT`` joins the
cluster whose head is there. A process already connected (a test session's
shared cluster, a notebook's ``ray.init``) keeps its connection.
"""

from __future__ import annotations

import argparse
import signal
import threading
from types import ModuleType
from typing import Any

from amaze.errors import UsageError

__all__ = [
    "BACKENDS",
    "add_backend_arguments",
    "check_backend",
    "cluster_cpus",
    "connect",
    "import_ray",
]

#: The execution backends of ``--backend``.
BACKENDS: tuple[str, ...] = ("local", "ray")
#: How to install Ray, for error messages.
RAY_INSTALL = "pip install 'amaze-evo[ray]'"


def check_backend(backend: Any, address: Any = None) -> str:
    """``backend`` if it is one of :data:`BACKENDS`, else :class:`UsageError`.

    ``--address`` belongs to Ray: giving it with the local backend is refused
    rather than silently ignored.
    """
    if backend not in BACKENDS:
        raise UsageError(f"--backend {backend!r} is not one of {', '.join(BACKENDS)}")
    if address is not None and backend != "ray":
        raise UsageError(f"--address {address!r} needs --backend ray")
    return str(backend)


def add_backend_arguments(group: argparse._ActionsContainer) -> None:
    """Add ``--backend`` and ``--address`` to ``group`` (a parser or one of its groups)."""
    group.add_argument(
        "--backend",
        choices=BACKENDS,
        default="local",
        help="where the work runs: this machine's processes (default) or a Ray cluster",
    )
    group.add_argument(
        "--address",
        metavar="ADDR",
        help="the Ray cluster (with --backend ray): 'auto' for the one `ray start` runs"
        " here, HOST:PORT for another; default: a private one on this machine",
    )


def import_ray() -> ModuleType:
    """The ``ray`` module, or a :class:`UsageError` saying how to install it."""
    try:
        import ray
    except ImportError:
        raise UsageError(
            f"--backend ray needs Ray, which is not installed: {RAY_INSTALL}"
        ) from None
    return ray


def connect(address: str | None = None) -> ModuleType:
    """Connect this process to Ray (see the module docstring); return the ``ray`` module.

    An unreachable ``address`` raises :class:`UsageError` naming it. The
    process keeps its own handling of SIGTERM, which ``ray.init`` replaces
    with an immediate exit (a study runner stops its runs on SIGTERM first).
    """
    ray = import_ray()
    if ray.is_initialized():
        return ray
    options: dict[str, Any] = {"include_dashboard": False, "log_to_driver": True}
    if address is None:
        options["configure_logging"] = True
        options["logging_level"] = "warning"
    main_thread = threading.current_thread() is threading.main_thread()
    sigterm = signal.getsignal(signal.SIGTERM) if main_thread else None
    try:
        ray.init(address=address, **options)
    except (ConnectionError, ValueError, RuntimeError) as problem:
        raise UsageError(f"--address {address!r}: cannot connect to Ray: {problem}") from None
    finally:
        if main_thread and sigterm is not None:
            signal.signal(signal.SIGTERM, sigterm)
    return ray


def cluster_cpus(ray: ModuleType) -> int:
    """The CPUs of the cluster ``ray`` is connected to (at least 1)."""
    return max(1, int(ray.cluster_resources().get("CPU", 1)))
