"""Connecting to Ray: the lazy import, a fast reachability probe, and ``ray.init``.

``--ray`` without a value: Ray's default (``$RAY_ADDRESS``, else a new local instance);
``--ray local``: always a new local instance; ``--ray auto``: the cluster started with
``ray start`` on this machine; ``--ray HOST:PORT``: that cluster's head (its GCS port,
6379 by default). An address that cannot be reached fails in seconds with one line
(``ray.init`` itself retries for minutes): the host is resolved and connected to with a
short timeout, then a subprocess asks the GCS for its cluster id (Ray's own client,
killed after :data:`PROBE_TIMEOUT_S`).
"""

from __future__ import annotations

import contextlib
import logging
import os
import socket
import subprocess
import sys
from collections.abc import Iterator
from typing import Any

from ..apps.common import CliError

#: Seconds for the TCP connect and for the GCS probe of an address.
CONNECT_TIMEOUT_S = 3.0
PROBE_TIMEOUT_S = 10.0

MISSING_RAY = "--ray needs the ray extra: pip install 'stb_hydra[ray]'"

# Exit codes of the probe subprocess.
_PROBE_OK, _PROBE_AUTH = 0, 3
_PROBE = """
import sys
from ray._raylet import GcsClient
try:
    GcsClient(address=sys.argv[1]).check_alive([], timeout=2)
except Exception as exc:
    print(type(exc).__name__ + ": " + " ".join(str(exc).split())[:300], file=sys.stderr)
    sys.exit(3 if "Authentication" in type(exc).__name__ else 1)
"""


def import_ray() -> Any:
    """The ``ray`` module, or :class:`CliError` naming the extra."""
    try:
        import ray
    except ImportError:
        raise CliError(MISSING_RAY) from None
    return ray


def _host_port(address: str) -> tuple[str, int]:
    addr = address.split("://", 1)[-1]
    host, sep, port = addr.rpartition(":")
    if not sep:
        host, port = addr, "6379"
    host = host.strip("[]")
    try:
        return host, int(port)
    except ValueError:
        raise CliError(f"bad --ray address '{address}': use HOST:PORT, auto or local") from None


def probe(address: str) -> None:
    """Raise :class:`CliError` within seconds unless a Ray GCS answers at ``address``."""
    host, port = _host_port(address)
    where = f"Ray cluster at {address}"
    try:
        socket.getaddrinfo(host, port)
    except OSError:
        raise CliError(f"cannot reach {where}: unknown host '{host}'") from None
    try:
        with socket.create_connection((host, port), timeout=CONNECT_TIMEOUT_S):
            pass
    except OSError as exc:
        why = "timed out" if isinstance(exc, TimeoutError) else (exc.strerror or str(exc))
        raise CliError(f"cannot reach {where}: {why.lower()}") from None
    if address.startswith("ray://"):
        return  # Ray Client server: not a GCS; ray.init checks it
    env = dict(os.environ, RAY_gcs_rpc_server_connect_timeout_s="3")
    try:
        res = subprocess.run(
            [sys.executable, "-c", _PROBE, f"{host}:{port}"],
            env=env,
            capture_output=True,
            text=True,
            timeout=PROBE_TIMEOUT_S,
        )
    except subprocess.TimeoutExpired:
        raise CliError(
            f"cannot reach {where}: no Ray GCS answered within {PROBE_TIMEOUT_S:g} s"
        ) from None
    if res.returncode == _PROBE_AUTH:
        raise CliError(
            f"{where} uses token authentication: set RAY_AUTH_MODE=token and its token "
            "(RAY_AUTH_TOKEN or ~/.ray/auth_token)"
        )
    if res.returncode != _PROBE_OK:
        lines = [ln for ln in res.stderr.splitlines() if ln.strip() and not ln.startswith("[")]
        why = lines[-1] if lines else f"probe exited with status {res.returncode}"
        raise CliError(f"cannot reach {where}: {why}")


@contextlib.contextmanager
def connected(address: str | None) -> Iterator[Any]:
    """``ray`` connected to ``address`` (see the module doc) for the block. A Ray
    already initialised in this process (tests, notebooks) is used as it is and left
    running; one started here is shut down at the end."""
    ray = import_ray()
    if ray.is_initialized():
        yield ray
        return
    kwargs: dict[str, Any] = {
        "include_dashboard": False,
        "log_to_driver": False,
        "logging_level": logging.WARNING,
        "configure_logging": True,
    }
    if not address:
        address = os.environ.get("RAY_ADDRESS") or "local"
    if address not in ("auto", "local"):
        probe(address)
    if address == "local":
        # a private instance: Ray's notice about its token authentication is noise here
        kwargs["logging_level"] = logging.ERROR
    try:
        ray.init(address=address, **kwargs)
    except (ConnectionError, RuntimeError, ValueError) as exc:
        msg = " ".join(str(exc).split())
        raise CliError(f"cannot connect to Ray ({address or 'default'}): {msg[:300]}") from None
    try:
        yield ray
    finally:
        ray.shutdown()


def cluster_resources(ray: Any) -> dict[str, float]:
    """The cluster's total resources (``CPU``, ``GPU``, ...)."""
    try:
        return dict(ray.cluster_resources())
    except Exception:  # noqa: BLE001 - informational only
        return {}


def add_ray_arguments(p: Any, render: bool = False) -> None:
    """``--ray [ADDRESS]`` (and, for ``stb render``, the worker shape) on a verb's
    parser."""
    p.add_argument(
        "--ray",
        nargs="?",
        const="",
        default=None,
        metavar="ADDRESS",
        help="run on Ray (the ray extra): HOST:PORT of a cluster's head, auto (the "
        "cluster started on this machine), local (a new local instance), or nothing "
        "($RAY_ADDRESS, else a new local instance)",
    )
    if render:
        p.add_argument(
            "--workers", type=int, help="--ray: render workers (default: as many as fit)"
        )
        p.add_argument(
            "--worker-cpus", type=int, default=1, help="--ray: CPUs per render worker (default 1)"
        )
        p.add_argument(
            "--worker-gpus",
            type=float,
            help="--ray: GPUs per render worker (default: 1 when the cluster has GPUs, else 0)",
        )
