"""``meshrec serve``: a long-running HTTP service that loads the model library once and
answers recognitions with the JSON of the command line.

Endpoints (JSON in, JSON out):

* ``GET /health``: ``{"status": "ok", "models": [...], "version": ...}``.
* ``POST /recognize``: one touch ``{"curves": [...], "contact"?: [...], "normal"?: [...],
  "probe_radius"?: r}`` (r: the probe's ball-tip radius, the touch's units) or several
  touches of one object in one frame ``{"touches": [{"curves": ...}, ...]}``,
  either with an optional ``"units"``: the object ``meshrec recognize --json`` prints.
* ``POST /next-touch``: the same, plus optional ``"approach": [x, y, z]`` and ``"seed"``:
  the object ``meshrec next-touch --json`` prints.

A bad request (not JSON, NaN or Infinity, wrong types, no curves, touches the recognition
refuses) gets HTTP 400, a body over ``defaults.SERVICE_MAX_BODY_BYTES`` 413, a request
beyond ``defaults.SERVICE_MAX_WAITING`` queued ones 503, an error inside 500: always
``{"error": "one line"}``, and the service goes on answering.

The HTTP framework (Starlette, served by uvicorn: the ``service`` extra) is imported only
inside :func:`create_app` and :func:`run_serve`; the parser is built with the standard
library alone (see :mod:`meshrec.app.cli`).
"""

from __future__ import annotations

import asyncio
import json
import sys
import threading
import warnings

from meshrec import defaults
from meshrec.app.parallel import add_workers_args, model_workers

__all__ = ["add_serve_parser", "create_app", "run_serve"]

_UNIT_CHOICES = ("mm", "cm", "m", "in")  # meshrec.recognition.units.UNITS
_TOUCH_KEYS = ("curves", "contact", "normal", "probe_radius")


def add_serve_parser(sub, models_arg) -> None:
    """The ``serve`` subcommand; ``models_arg(parser)`` adds ``--models``,
    ``--model-units`` and ``--cache-dir``."""
    s = sub.add_parser(
        "serve",
        help="load the models once and answer recognitions over HTTP with JSON "
        "(GET /health, POST /recognize, POST /next-touch)",
    )
    models_arg(s)
    s.add_argument(
        "--host", default="127.0.0.1", help="address to listen on (default: 127.0.0.1)"
    )
    s.add_argument(
        "--port",
        type=int,
        default=8765,
        help="port to listen on (default: 8765; 0 picks a free one, printed at start)",
    )
    s.add_argument(
        "--probe-radius",
        type=float,
        default=None,
        metavar="R",
        help="the probe's ball-tip radius (touch units) for touches that give none",
    )
    add_workers_args(s)


class BadRequest(ValueError):
    """A request the service refuses: its HTTP status and one-line message."""

    def __init__(self, message: str, status: int = 400):
        super().__init__(message)
        self.status = status


def _reject_constant(name: str):
    raise BadRequest(f"request body: {name} is not a number JSON allows")


def parse_body(raw: bytes, advice: bool) -> dict:
    """Check a request body and read its touches (no model is touched here).

    Parameters
    ----------
    raw : bytes
        The body: a JSON object, one touch or ``{"touches": [...]}``, with ``units`` and,
        for ``advice``, ``approach`` and ``seed``.
    advice : bool
        A /next-touch request.

    Returns
    -------
    dict
        ``touches`` (list of TouchData), ``units`` (str or None), ``approach`` ((3,) unit
        vector or None) and ``seed`` (int or None).

    Raises
    ------
    BadRequest
        Naming the problem on one line.
    """
    from meshrec.io.checks import check_vector, one_line
    from meshrec.io.touch import TouchData

    try:
        body = json.loads(raw, parse_constant=_reject_constant)
    except BadRequest:
        raise
    except RecursionError:
        raise BadRequest("request body: JSON nested too deeply") from None
    except ValueError as exc:  # JSONDecodeError, and UnicodeDecodeError for bad UTF-8
        raise BadRequest(f"request body: not valid JSON ({one_line(str(exc), 120)})") from None
    if not isinstance(body, dict):
        raise BadRequest(
            'request body: expected a JSON object, one touch {"curves": ...} or '
            '{"touches": [...]}'
        )
    options = ("units", "approach", "seed") if advice else ("units",)
    allowed = {"touches", *options} if "touches" in body else {*_TOUCH_KEYS, *options}
    unknown = sorted(set(body) - allowed)
    if unknown:
        hint = " (one touch, or 'touches': not both)" if "touches" in body else ""
        raise BadRequest(f"request body: unknown keys {one_line(unknown, 120)}{hint}")
    touches = []
    if "touches" in body:
        items = body["touches"]
        if not isinstance(items, list) or not items:
            raise BadRequest("request body: 'touches' must be a non-empty list of touches")
        if len(items) > defaults.SERVICE_MAX_TOUCHES:
            raise BadRequest(
                f"request body: more than {defaults.SERVICE_MAX_TOUCHES} touches "
                f"(defaults.SERVICE_MAX_TOUCHES), got {len(items)}"
            )
        for i, item in enumerate(items):
            touches.append(_touch(TouchData, item, f"touches[{i}]"))
    else:
        touch_part = {k: body[k] for k in _TOUCH_KEYS if k in body}
        touches.append(_touch(TouchData, touch_part, "touch"))
    units = body.get("units")
    if units is not None and (not isinstance(units, str) or units not in _UNIT_CHOICES):
        raise BadRequest(
            f"request body: 'units' must be one of {', '.join(_UNIT_CHOICES)} or null, "
            f"got {one_line(json.dumps(units), 40)}"
        )
    approach = body.get("approach")
    if approach is not None:
        if not isinstance(approach, list) or any(
            isinstance(v, bool) or not isinstance(v, (int, float)) for v in approach
        ):
            raise BadRequest("request body: 'approach' must be [x, y, z] numbers")
        try:
            approach = check_vector([float(v) for v in approach], "approach", unit=True)
        except (ValueError, OverflowError):
            raise BadRequest(
                "request body: 'approach' must be three finite numbers, not all zero"
            ) from None
    seed = body.get("seed")
    if seed is not None and (isinstance(seed, bool) or not isinstance(seed, int) or seed < 0):
        raise BadRequest(
            f"request body: 'seed' must be a non-negative integer, got "
            f"{one_line(json.dumps(seed), 40)}"
        )
    return {"touches": touches, "units": units, "approach": approach, "seed": seed}


def _touch(cls, obj, name: str):
    """One touch of a request, checked by :meth:`TouchData.from_dict`."""
    try:
        source = "<request>" if name == "touch" else f"<request {name}>"
        return cls.from_dict(obj, source=source, label=name)
    except ValueError as exc:
        raise BadRequest(str(exc)) from None


class Service:
    """The library and the lock behind the endpoints (the HTTP layer is in create_app).

    One recognition runs at a time (:attr:`lock`): see :func:`create_app` for why.
    """

    def __init__(
        self,
        library,
        models_units: str | None,
        method: str = defaults.SEARCH_METHOD,
        probe_radius: float | None = None,
        workers=None,
    ):
        from meshrec.contact.probe import check_probe_radius

        self.library = library
        self.models_units = models_units
        self.method = method
        # the ball-tip radius of touches that give none (``--probe-radius``)
        self.workers = workers  # a ModelWorkers held for the service's life, or None
        self.probe_radius = (
            None if probe_radius is None else check_probe_radius(probe_radius, "--probe-radius")
        )
        self.lock = threading.Lock()

    def answer(self, job: dict, advice: bool) -> dict:
        """The JSON document for a parsed request (:func:`parse_body`), under the lock.

        Raises
        ------
        BadRequest
            If a touch allows no geometry estimate or the recognition refuses the touches
            (a unit mismatch, sizes).
        """
        with self.lock:
            return self._answer(job, advice)

    def _answer(self, job: dict, advice: bool) -> dict:
        from meshrec.app import inputs
        from meshrec.app.cli import recognition_to_json
        from meshrec.app.commands_advice import advice_to_json
        from meshrec.io.checks import one_line
        from meshrec.recognition.advice import next_touch
        from meshrec.recognition.recognize import recognize
        from meshrec.recognition.units import UNIT_MISMATCH
        from meshrec.registration.register import touch_geometry

        several = len(job["touches"]) > 1
        # The warnings machinery is process-wide: recorded here, under the lock, so that
        # each request gets its own (as the CLI's --json lists them).
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                units = inputs.touch_units(job["units"], self.models_units, '"units":')
                touches, geometries = [], []
                for i, touch in enumerate(job["touches"]):
                    name = f"touches[{i}]" if several else "touch"
                    if touch.probe_radius is None and self.probe_radius is not None:
                        touch = inputs.with_probe_radius(touch, self.probe_radius)
                    touch = inputs.touch_in_units(touch, units, self.models_units)
                    try:
                        geometries.append(touch_geometry(touch))
                    except ValueError as exc:
                        raise ValueError(f"{name}: {exc}") from exc
                    touches.append(touch)
                rec = recognize(
                    touches,
                    self.library,
                    method=self.method,
                    geometry=geometries,
                    workers=self.workers,
                )
                if advice:
                    found = next_touch(
                        rec, self.library, approach=job["approach"], rng=job["seed"]
                    )
            except ValueError as exc:
                text = one_line(str(exc), None)
                if UNIT_MISMATCH in text:
                    text += (
                        ' (give the touch\'s unit as "units" in the request, and the '
                        "models' with --model-units or a meshrec.json note in their folder)"
                    )
                raise BadRequest(text) from None
        if advice:
            return advice_to_json(found, rec.verdict, units, self.models_units)
        shown = list(dict.fromkeys(str(w.message) for w in caught))
        return recognition_to_json(rec, None, warnings=shown)


def create_app(service: Service, max_body: int = defaults.SERVICE_MAX_BODY_BYTES):
    """The Starlette application answering for ``service``.

    Concurrency: the event loop reads and checks requests (bodies, JSON, touches) at
    once, so /health and bad requests are answered while a recognition runs; the
    recognitions themselves run in worker threads, one at a time under
    ``service.lock``. Serialised rather than parallel because a recognition is CPU-bound
    Python work that holds the GIL for most of its time (threads would share one core
    and gain nothing; processes would each hold the whole library), because its warnings
    are recorded through Python's process-wide warnings state (parallel requests would
    mix them), and because the library's models are not promised safe for concurrent
    use. Each request gets its own recognition and document, so results cannot mix; a
    queued request waits for those before it (at most ``defaults.SERVICE_MAX_WAITING``
    wait, later ones get 503 at once). A queued request whose client disconnects is
    dropped, not answered (checked every ``defaults.SERVICE_DISCONNECT_POLL`` seconds
    while it waits, and when its turn comes): a recognition under way runs to its end. For
    parallel throughput run one service per core.
    """
    from starlette.applications import Starlette
    from starlette.concurrency import run_in_threadpool
    from starlette.exceptions import HTTPException
    from starlette.requests import ClientDisconnect
    from starlette.responses import JSONResponse, Response
    from starlette.routing import Route

    from meshrec._version import __version__
    from meshrec.io.checks import one_line

    state = {"pending": 0}
    turn = asyncio.Lock()  # the requests' turns, in order of arrival (service.lock inside)

    async def turn_of(request) -> bool:
        """Wait for this request's turn (``turn`` then held) while its client is still
        connected, checked every ``defaults.SERVICE_DISCONNECT_POLL`` seconds and once
        more when the turn comes; False (``turn`` not held) when the client has gone."""
        # one acquire, waited on in steps (cancelling and acquiring again would lose the
        # request's place in the queue)
        acquiring = asyncio.ensure_future(turn.acquire())
        while True:
            done, _ = await asyncio.wait({acquiring}, timeout=defaults.SERVICE_DISCONNECT_POLL)
            if done:
                break
            if await request.is_disconnected():
                acquiring.cancel()
                try:
                    await acquiring
                except asyncio.CancelledError:
                    return False
                turn.release()  # the turn came just as the wait was given up
                return False
        if await request.is_disconnected():
            turn.release()
            return False
        return True

    def error(status: int, message: str, headers=None):
        return JSONResponse(
            {"error": one_line(message, defaults.SERVICE_ERROR_CHARS)}, status, headers=headers
        )

    async def body_of(request) -> bytes:
        """The request's body, or BadRequest 413 when it is over ``max_body``: the rest
        of an oversized body (up to ``defaults.SERVICE_DRAIN_BYTES``) is read and dropped
        first: a client that sends its whole body before reading the answer (Python's
        urllib) otherwise has the connection reset under it and never sees the 413 (a
        black-box probe, stop 32)."""
        length = request.headers.get("content-length")
        declared = None
        if length is not None:
            if not length.isdigit():
                raise BadRequest(f"bad Content-Length {one_line(length, 40)!r}")
            declared = int(length)
            if declared > max_body and declared > defaults.SERVICE_DRAIN_BYTES:
                # too much to read for nothing: refused at once, the connection closed
                raise BadRequest(_too_large(declared, max_body), 413)
        chunks, total = [], 0
        async for chunk in request.stream():
            total += len(chunk)
            if total > defaults.SERVICE_DRAIN_BYTES:
                break
            if total <= max_body:
                chunks.append(chunk)
        if total > max_body:
            raise BadRequest(_too_large(declared, max_body), 413)
        return b"".join(chunks)

    def endpoint(advice: bool):
        async def handle(request):
            try:
                raw = await body_of(request)
                job = await run_in_threadpool(parse_body, raw, advice)
                if state["pending"] >= defaults.SERVICE_MAX_WAITING + 1:  # + the running one
                    return error(
                        503,
                        f"busy: {state['pending']} requests queued or running "
                        "(defaults.SERVICE_MAX_WAITING); retry later",
                        headers={"Retry-After": "1"},
                    )
                state["pending"] += 1
                try:
                    if not await turn_of(request):
                        # the client has gone: nobody would read the answer
                        sys.stderr.write(
                            "meshrec: serve: a request's client left before its turn: "
                            "not answered\n"
                        )
                        return Response(status_code=499)
                    try:
                        doc = await run_in_threadpool(service.answer, job, advice)
                    finally:
                        turn.release()
                finally:
                    state["pending"] -= 1
            except BadRequest as exc:
                return error(exc.status, str(exc))
            except ClientDisconnect:
                return Response(status_code=400)
            # Same text as the CLI's --json (json.dumps), a JSON object per response.
            return Response(json.dumps(doc), media_type="application/json")

        return handle

    async def health(request):
        return JSONResponse(
            {"status": "ok", "models": list(service.library.names), "version": __version__}
        )

    async def http_error(request, exc):
        return error(exc.status_code, str(exc.detail), headers=getattr(exc, "headers", None))

    async def internal_error(request, exc):
        # One line on the server's stderr and in the answer; never a traceback page.
        message = f"internal error: {type(exc).__name__}: {one_line(str(exc), 200)}"
        sys.stderr.write(f"meshrec: serve: {message}\n")
        return error(500, message)

    return Starlette(
        routes=[
            Route("/health", health, methods=["GET"]),
            Route("/recognize", endpoint(advice=False), methods=["POST"]),
            Route("/next-touch", endpoint(advice=True), methods=["POST"]),
        ],
        exception_handlers={HTTPException: http_error, Exception: internal_error},
    )


def _too_large(length: int | None, limit: int) -> str:
    got = "" if length is None else f", got {length}"
    return (
        f"request body over {limit} bytes (defaults.SERVICE_MAX_BODY_BYTES){got}: "
        "send fewer points or touches"
    )


def _bind(host: str, port: int):
    """A listening TCP socket on ``host``:``port`` (0: a free port).

    Raises
    ------
    ValueError
        If the address cannot be bound (in use, unknown host), in one line.
    """
    import socket

    try:
        infos = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)
        family, kind, proto, _, address = infos[0]
        sock = socket.socket(family, kind, proto)
    except OSError as exc:
        raise ValueError(f"--host {host}: {exc.strerror or exc}") from None
    try:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.bind(address)
        sock.listen(128)
    except OSError as exc:
        sock.close()
        raise ValueError(f"cannot listen on {host}:{port}: {exc.strerror or exc}") from None
    return sock


def run_serve(args, err=None) -> int:
    """Load the library, then answer HTTP requests until interrupted.

    Parameters
    ----------
    args : argparse.Namespace
        ``models``, ``model_units``, ``cache_dir``, ``host``, ``port``, ``workers``,
        ``scheduler`` and optionally ``probe_radius`` (the ball-tip radius of touches that
        give none).
    err : text stream, optional
        Where the one start-up line goes (default: ``sys.stderr``).

    Returns
    -------
    int
        0 if the server stops by itself. Ctrl-C (SIGINT) ends it with KeyboardInterrupt
        once the requests under way are answered, which the command line turns into one
        line and status 130; SIGTERM ends it likewise, with that signal's status. Where
        the process ignores the signal (SIGINT in the background of a non-interactive
        shell), the server still stops on it: one line on ``err`` and 128 plus the
        signal's number (130 for SIGINT, 143 for SIGTERM).

    Raises
    ------
    ValueError
        If the service extra is not installed, the model folder cannot be read, the
        address cannot be bound, or ``probe_radius`` is negative or not finite.
    """
    err = sys.stderr if err is None else err
    if not 0 <= args.port <= 65535:  # before the library is loaded
        raise ValueError(f"--port must be 0 to 65535, got {args.port}")
    probe_radius = getattr(args, "probe_radius", None)
    if probe_radius is not None:  # before the library is loaded, too
        from meshrec.contact.probe import check_probe_radius

        check_probe_radius(probe_radius, "--probe-radius")
    try:
        import starlette  # noqa: F401
        import uvicorn
    except ImportError as exc:
        raise ValueError(
            f"meshrec serve needs the service extra ({exc.name} is missing): "
            "pip install 'meshrec[service]'"
        ) from None
    from meshrec.app import inputs

    folder = inputs.model_folder(args.models)
    units = inputs.model_units(folder, args.model_units)
    library = inputs.library(args, folder)  # indexed (or read from the cache) once, here
    workers = model_workers(args, library)  # held for the service's life
    try:
        sock = _bind(args.host, args.port)
    except BaseException:
        workers.close()
        raise
    host, port = sock.getsockname()[:2]
    shown = f"[{host}]" if ":" in host else host
    app = create_app(Service(library, units, probe_radius=probe_radius, workers=workers))
    config = uvicorn.Config(app, log_level="warning", access_log=False, lifespan="off")
    server = _server_class()(config)
    err.write(
        f"meshrec: serving {len(library)} models of {folder} on http://{shown}:{port} "
        "(Ctrl-C stops)\n"
    )
    err.flush()
    try:
        server.run(sockets=[sock])
    finally:
        sock.close()
        workers.close()
    if server.stopped_by is not None:
        # A signal stopped the server and, raised again after its graceful shutdown, did
        # not end the process: the process ignores it (a service started in the background
        # of a non-interactive shell ignores SIGINT). Not a stop by itself: say so, and
        # give the signal's status.
        import signal

        name = {signal.SIGINT: "interrupted", signal.SIGTERM: "terminated"}.get(
            server.stopped_by, f"stopped by signal {int(server.stopped_by)}"
        )
        err.write(f"meshrec: {name}\n")
        err.flush()
        return 128 + int(server.stopped_by)
    return 0


def _server_class():
    """uvicorn.Server with the signal that stopped it (made here: uvicorn is the optional
    ``service`` extra)."""
    import uvicorn

    class Server(uvicorn.Server):
        """uvicorn's server, remembering the first signal that stopped it."""

        stopped_by = None

        def handle_exit(self, sig, frame) -> None:
            if self.stopped_by is None:
                self.stopped_by = sig
            super().handle_exit(sig, frame)

    return Server
