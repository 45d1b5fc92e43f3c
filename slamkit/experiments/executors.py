"""Where sweep cells run: an :class:`Executor` takes tasks and yields their outcomes as they finish.

Two implementations, one contract (``submit(fn, arg)``, then ``as_completed()`` yields
``(arg, outcome)`` in finishing order, each submitted task exactly once):

* :class:`LocalExecutor` -- a pool of ``workers`` local processes (``spawn``). Each worker is
  started with the BLAS/OpenMP thread variables of :data:`ONE_THREAD_ENV` set to 1, so N workers
  use N cores and not N x cores (the variables must be in the environment before the worker
  imports numpy, which is why they are set around the pool's life rather than in an
  initializer); a worker whose coordinator dies (``kill -9``) exits within half a second;
* :class:`RayExecutor` -- Ray tasks (``num_cpus=1`` each) on the Ray instance the process is
  connected to, or the one at ``address`` (``auto``: the cluster this machine belongs to; a
  ``HOST:PORT``, used as given; None: a new local instance bound to 127.0.0.1 that leaves no
  session folder behind, see :func:`start_local_ray`). ``ray`` is imported only when this executor is
  built (an optional extra, ``pip install slamkit[ray]``; importing it costs about a second).

Both keep only a few tasks per worker in flight and hold the rest in a backlog until a worker is
free: handing a 10,000-cell sweep to the pool at once made every completion wait on every pending
future (quadratic: 10,000 no-op cells took 270 s instead of about 25 s) and kept every pickled
task in the pool's queue.

A task that raises becomes a :class:`TaskFailure` outcome (its type and message), so one bad
cell never stops the others; a worker that dies (killed, out of memory) fails its task the same
way.
"""

from __future__ import annotations

import os
from collections import deque
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from dataclasses import dataclass
from typing import Any, Callable, Iterator, Protocol

from slamkit.errors import ConfigError
from slamkit.naming import PLUGINS_ENV, plugin_env

#: the thread-count variables of OpenBLAS, MKL, OpenMP, BLIS, Apple Accelerate and numexpr
ONE_THREAD_ENV = {name: "1" for name in (
    "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "BLIS_NUM_THREADS",
    "VECLIB_MAXIMUM_THREADS", "NUMEXPR_NUM_THREADS")}


#: tasks kept in flight per worker (or Ray CPU): enough that no worker waits for the coordinator
IN_FLIGHT_PER_WORKER = 4


@dataclass(frozen=True)
class TaskFailure:
    """A task that raised, or whose worker died: the exception's type and message."""

    error_type: str
    message: str


class Executor(Protocol):
    """Runs ``fn(arg)`` tasks somewhere and hands back their outcomes as they finish."""

    def submit(self, fn: Callable[[Any], Any], arg: Any) -> None: ...

    def as_completed(self) -> Iterator[tuple[Any, Any]]:
        """``(arg, fn(arg) or TaskFailure)`` for every task submitted, in finishing order."""
        ...

    def close(self) -> None: ...


def _failure(exc: BaseException) -> TaskFailure:
    return TaskFailure(type(exc).__name__, str(exc).splitlines()[0] if str(exc) else "")


def exit_with_parent(parent_pid: int, period_s: float = 0.5) -> None:
    """Worker initializer: end this worker when the coordinator is gone (killed with -9, its
    workers would otherwise wait on the task queue for ever, each holding its cell's lock)."""
    import threading
    import time

    def watch() -> None:
        while os.getppid() == parent_pid:
            time.sleep(period_s)
        os._exit(1)

    threading.Thread(target=watch, name="exit-with-parent", daemon=True).start()


class _Backlogged:
    """The bounded submission both executors share: ``submit`` queues, and at most
    ``self._in_flight`` tasks are started (``self._start(fn, arg)`` returns the handle
    ``as_completed`` waits on); ``_top_up`` starts more as tasks finish."""

    _in_flight: int

    def _init_backlog(self, in_flight: int) -> None:
        self._pending: dict[Any, Any] = {}
        self._backlog: deque[tuple[Callable[[Any], Any], Any]] = deque()
        self._in_flight = in_flight

    def _start(self, fn: Callable[[Any], Any], arg: Any) -> Any:
        raise NotImplementedError

    def submit(self, fn: Callable[[Any], Any], arg: Any) -> None:
        self._backlog.append((fn, arg))
        self._top_up()

    def _top_up(self) -> None:
        while self._backlog and len(self._pending) < self._in_flight:
            fn, arg = self._backlog.popleft()
            self._pending[self._start(fn, arg)] = arg


class LocalExecutor(_Backlogged):
    """A ``spawn`` process pool of ``workers`` processes with BLAS pinned to one thread each."""

    def __init__(self, workers: int | None = None):
        self.workers = int(workers or min(2, os.cpu_count() or 1))
        if self.workers < 1:
            raise ConfigError(f"--workers must be >= 1, got {self.workers}")
        import multiprocessing

        # the workers inherit the environment when they start (lazily, on submit): keep the
        # variables set for the executor's life and restore the caller's values on close,
        # and the plug-in modules this process imported (config plugins:, --plugin): the workers
        # import them before their first registry lookup
        self._saved_env = {k: os.environ.get(k) for k in (*ONE_THREAD_ENV, PLUGINS_ENV, "PYTHONPATH")}
        os.environ.update({**ONE_THREAD_ENV, **plugin_env()})
        self._pool = ProcessPoolExecutor(self.workers, mp_context=multiprocessing.get_context("spawn"),
                                         initializer=exit_with_parent, initargs=(os.getpid(),))
        self._init_backlog(IN_FLIGHT_PER_WORKER * self.workers)

    def _start(self, fn: Callable[[Any], Any], arg: Any) -> Future:
        return self._pool.submit(fn, arg)

    def as_completed(self) -> Iterator[tuple[Any, Any]]:
        while self._pending:
            done, _ = wait(list(self._pending), return_when=FIRST_COMPLETED)
            for future in done:
                arg = self._pending.pop(future)
                exc = future.exception()
                self._top_up()
                yield arg, (_failure(exc) if exc is not None else future.result())

    def close(self) -> None:
        self._backlog.clear()
        for future in self._pending:
            future.cancel()
        self._pool.shutdown(wait=True, cancel_futures=True)
        for k, v in self._saved_env.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v

    def __enter__(self) -> "LocalExecutor":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class RayExecutor(_Backlogged):
    """Ray tasks of one CPU each, with the same one-thread BLAS environment as the local pool.

    Uses the Ray connection the process already has (``ray.init`` called by the user or a test);
    otherwise connects to ``address`` and disconnects on close. Workers on other machines write
    the cells to the same ``--out`` path, which must therefore be on a shared file system."""

    def __init__(self, address: str | None = None):
        try:
            import ray
        except ImportError:
            raise ConfigError("--executor ray needs the 'ray' package: pip install 'slamkit[ray]'") from None
        self._ray = ray
        self._owns_connection = not ray.is_initialized()
        self._local: LocalRay | None = None
        if self._owns_connection:
            if address is None:
                self._local = start_local_ray()
            else:  # an existing cluster is used as it was set up
                ray.init(address=address, include_dashboard=False, log_to_driver=False)
        self._remote: dict[Callable, Any] = {}
        # the cluster's CPUs when the sweep starts (an autoscaler adding nodes later is not seen)
        self._init_backlog(IN_FLIGHT_PER_WORKER * max(1, int(ray.cluster_resources().get("CPU", 1))))

    def _start(self, fn: Callable[[Any], Any], arg: Any) -> Any:
        if fn not in self._remote:
            # env_vars merge into the job's runtime environment (a user's PYTHONPATH stays)
            self._remote[fn] = self._ray.remote(num_cpus=1, max_retries=0,
                                                runtime_env={"env_vars": {**ONE_THREAD_ENV, **plugin_env()}})(fn)
        return self._remote[fn].remote(arg)

    def as_completed(self) -> Iterator[tuple[Any, Any]]:
        ray = self._ray
        while self._pending:
            done, _ = ray.wait(list(self._pending), num_returns=1)
            for ref in done:
                arg = self._pending.pop(ref)
                self._top_up()
                try:
                    outcome = ray.get(ref)
                except Exception as exc:  # noqa: BLE001 - a task error or a dead worker fails the task
                    cause = getattr(exc, "cause", None)
                    outcome = _failure(cause if isinstance(cause, BaseException) else exc)
                yield arg, outcome

    def close(self) -> None:
        self._backlog.clear()
        for ref in self._pending:
            self._ray.cancel(ref, force=True)
        self._pending.clear()
        if self._local is not None:
            self._local.shutdown()
            self._local = None
        elif self._owns_connection:
            self._ray.shutdown()
        self._owns_connection = False

    def __enter__(self) -> "RayExecutor":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


#: Ray's authentication variables: a token, a token file, or the mode (``disabled``, ``token``)
RAY_TOKEN_ENV = "RAY_AUTH_TOKEN"
_RAY_AUTH_ENV = (RAY_TOKEN_ENV, "RAY_AUTH_TOKEN_PATH", "RAY_AUTH_MODE")


#: Ray takes a node address of 127.0.0.1 given to ``ray.init(_node_ip_address=...)`` as "this
#: machine" and replaces it by the machine's reachable address (``resolve_ip_for_localhost``), so
#: every gRPC server then listened on all interfaces (measured with Ray 2.60: GCS, raylet, workers
#: and the driver on ``::``, the runtime-env agent on the LAN address). With this variable at 0 on
#: Linux Ray takes the loopback address as the node's, as it does on macOS and Windows, and each
#: server binds 127.0.0.1 (the rule of ray-project/ray#59852: a loopback node address stays local)
_RAY_LOOPBACK_ENV = "RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER"


@dataclass
class LocalRay:
    """A local Ray instance this process started (:func:`start_local_ray`): ``shutdown()`` stops
    it, removes its session folder ``temp_dir`` and the token variable it set."""

    temp_dir: str
    token_set: bool

    def shutdown(self) -> None:
        import shutil

        import ray

        try:
            ray.shutdown()
        finally:
            if self.token_set:
                os.environ.pop(RAY_TOKEN_ENV, None)
                self.token_set = False
            shutil.rmtree(self.temp_dir, ignore_errors=True)


def start_local_ray(**init_kwargs: Any) -> LocalRay:
    """Start a new local Ray instance that only this machine can reach and that leaves nothing
    behind: no dashboard, workers' logs not streamed here, every server bound to 127.0.0.1
    (see :data:`_RAY_LOOPBACK_ENV`), its session folder in a fresh ``slamkit-ray-*`` folder of the
    system temp folder (``_temp_dir``; Ray's default ``/tmp/ray/session_*`` folders outlived every
    run) that :meth:`LocalRay.shutdown` removes, and token authentication kept on with its token
    in this process's environment.

    Ray >= 2.5x turns token authentication on for a new local instance and, when no token is
    configured, writes one to ``~/.ray/auth_token``: a file outside the results folder that
    outlives the run. A fresh random token in ``RAY_AUTH_TOKEN`` (inherited by the instance's
    processes) gives the same protection and writes nothing. A user's own token or mode
    (``RAY_AUTH_TOKEN``, ``RAY_AUTH_TOKEN_PATH``, ``RAY_AUTH_MODE``) is left to Ray."""
    import secrets
    import shutil
    import tempfile

    token_set = not any(os.environ.get(k) for k in _RAY_AUTH_ENV)
    if token_set:
        os.environ[RAY_TOKEN_ENV] = secrets.token_hex(32)
    # Ray's own choice of system temp folder (RAY_TMPDIR, else TMPDIR, else /tmp); a short path:
    # the session's Unix sockets must fit 107 bytes
    temp_dir = tempfile.mkdtemp(prefix="slamkit-ray-", dir=os.environ.get("RAY_TMPDIR") or None)
    previous_env = os.environ.get(_RAY_LOOPBACK_ENV)
    os.environ[_RAY_LOOPBACK_ENV] = "0"  # inherited by the processes the instance starts
    constants = None
    try:
        import ray
        from ray._private import ray_constants as constants

        # ray imported before this call derived the constant from the variable already
        constants.ENABLE_RAY_CLUSTER = False
        ray.init(address=None, include_dashboard=False, log_to_driver=False, _temp_dir=temp_dir, **init_kwargs)
    except BaseException:
        if token_set:
            os.environ.pop(RAY_TOKEN_ENV, None)
        shutil.rmtree(temp_dir, ignore_errors=True)
        raise
    finally:
        # back to what this process had: a later ray.init(address=...) of a real cluster needs
        # the machine's reachable address again
        if previous_env is None:
            os.environ.pop(_RAY_LOOPBACK_ENV, None)
        else:
            os.environ[_RAY_LOOPBACK_ENV] = previous_env
        if constants is not None:
            constants.ENABLE_RAY_CLUSTER = constants.env_bool(_RAY_LOOPBACK_ENV, not constants.IS_WINDOWS_OR_OSX)
    return LocalRay(temp_dir, token_set)


def make_executor(kind: str, workers: int | None = None, address: str | None = None) -> LocalExecutor | RayExecutor:
    """The executor ``--executor`` names: ``local`` (``workers`` processes) or ``ray``."""
    if kind == "local":
        if address is not None:
            raise ConfigError("--address is for --executor ray; the local pool has no address")
        return LocalExecutor(workers)
    if kind == "ray":
        return RayExecutor(address)
    raise ConfigError(f"unknown executor {kind!r}; known: local, ray")
