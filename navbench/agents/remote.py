"""Agents in another process or on another machine, over HTTP: the client (``--agent http://HOST:PORT``)
and the reference server (``navbench serve-agent SPEC --port P``). The protocol is in docs/remote_agent.md.

The client gives every request a whole-request deadline (connect, send, receive) and a cap on the answer's
size, so a dead, stuck or hostile server makes ``reset``/``act`` raise :class:`RemoteAgentError` with a
one-line reason instead of hanging or growing the run. The server caps each request's size, the bytes it
buffers for all requests together, the requests it serves at once, JSON nesting, and how long a
connection may idle or take to send one request.
"""

from __future__ import annotations

import dataclasses
import http
import http.client
import json
import math
import socket
import struct
import threading
import time
import traceback
import uuid
from collections import OrderedDict
from collections.abc import Callable
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any
from urllib.parse import urlsplit

import numpy as np

from navbench.env.sensors import AGENT_POSE
from navbench.episodes.types import Episode, ObjectGoal
from navbench.safeio import printable

PROTOCOL = "navbench-agent/1"
ARRAYS_TYPE = "application/x-navbench-arrays"
DEFAULT_TIMEOUT = 30.0  # seconds per request: a VLM step on a busy GPU box can take a while
MAX_BODY = 64 << 20  # one request (a 1024x1024 RGB-D-semantic frame is 11 MB)
MAX_BUFFERED = 256 << 20  # the request bodies a server holds at once, all connections together
SMALL_BODY = 4 << 20  # bodies up to this size draw on a budget of their own (a quarter of MAX_BUFFERED)
MAX_REQUESTS = 32  # requests a server reads or serves at once; more are answered 503
MAX_JSON_HEADER = 1 << 20  # the JSON header of an arrays body, and a JSON body's nesting depth
MAX_JSON_DEPTH = 64
MAX_RESPONSE = 16 << 20  # the largest answer the client reads (a /log with the agent's episode log)
IDLE_TIMEOUT = 120.0  # seconds a server keeps a connection that sends nothing
REQUEST_TIMEOUT = 120.0  # seconds a client may take to send one request, headers and body


class RemoteAgentError(RuntimeError):
    """A remote agent did not answer (refused, timed out, disconnected) or answered an error."""


# ------------------------------------------------------------------------------------------------ wire
def encode_arrays(arrays: dict[str, Any], meta: dict[str, Any] | None = None) -> bytes:
    """``uint32 LE header length | JSON header | raw array bytes``; the header lists each array's name,
    dtype (numpy's ``dtype.str``, e.g. ``<f4``) and shape, in the order their bytes follow (C order)."""
    specs, blobs = [], []
    for name, value in arrays.items():
        a = np.ascontiguousarray(value)
        if a.dtype.byteorder == ">":
            a = a.astype(a.dtype.newbyteorder("<"))
        specs.append({"name": name, "dtype": a.dtype.str, "shape": list(a.shape)})
        blobs.append(a.tobytes())
    header = json.dumps({**(meta or {}), "arrays": specs}).encode()
    return struct.pack("<I", len(header)) + header + b"".join(blobs)


def decode_arrays(body: bytes) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """The arrays and the other header fields of an :func:`encode_arrays` body; ValueError if malformed."""
    if len(body) < 4:
        raise ValueError("array body shorter than its 4-byte header length")
    (n,) = struct.unpack_from("<I", body)
    if n > min(len(body) - 4, MAX_JSON_HEADER):
        raise ValueError(f"header length {n} exceeds the body or {MAX_JSON_HEADER} bytes")
    header = loads_bounded(body[4:4 + n])
    if not isinstance(header, dict) or not isinstance(header.get("arrays"), list):
        raise ValueError("header must be an object with an 'arrays' list")
    offset, arrays = 4 + n, {}
    for spec in header.pop("arrays"):
        if not isinstance(spec, dict) or not isinstance(spec.get("name"), str) or \
                not isinstance(spec.get("dtype"), str) or not isinstance(spec.get("shape"), list) or \
                not all(type(d) is int and 0 <= d <= len(body) for d in spec["shape"]) or len(spec["shape"]) > 8:
            raise ValueError("each array needs a name, a dtype string and a shape of at most 8 sizes")
        dtype = np.dtype(spec["dtype"])
        if dtype.hasobject:
            raise ValueError(f"array {spec['name']!r}: object dtype is not allowed")
        count = math.prod(spec["shape"])
        size = count * dtype.itemsize
        if offset + size > len(body):
            raise ValueError(f"array {spec['name']!r}: body ends before its {size} bytes")
        arrays[spec["name"]] = np.frombuffer(body, dtype, count, offset).reshape(spec["shape"]).copy()
        offset += size
    if offset != len(body):
        raise ValueError(f"{len(body) - offset} bytes after the last array")
    return arrays, header


def loads_bounded(data: bytes, max_depth: int = MAX_JSON_DEPTH) -> Any:
    """``json.loads`` refusing (ValueError) a document nested deeper than ``max_depth``."""
    try:
        doc = json.loads(data)
    except RecursionError:
        raise ValueError(f"JSON nested deeper than {max_depth} levels") from None
    stack = [(doc, 1)]
    while stack:
        node, depth = stack.pop()
        if isinstance(node, (dict, list)):
            if depth > max_depth:
                raise ValueError(f"JSON nested deeper than {max_depth} levels")
            stack.extend((v, depth + 1) for v in (node.values() if isinstance(node, dict) else node))
    return doc


def episode_to_wire(ep: Episode) -> dict[str, Any]:
    """An episode as Habitat's JSON has it, goals (with view points) inline and floats unrounded."""
    goals = []
    for g in ep.goals:
        d: dict[str, Any] = {"position": list(g.position), "radius": g.radius, **g.extra}
        if isinstance(g, ObjectGoal):
            d.update(object_id=g.object_id, object_name=g.object_name, object_category=g.object_category,
                     room_id=g.room_id, room_name=g.room_name,
                     view_points=[{"agent_state": {"position": list(v.agent_state.position),
                                                   "rotation": list(v.agent_state.rotation)}, "iou": v.iou}
                                  for v in g.view_points])
        goals.append(d)
    out = {"episode_id": ep.episode_id, "scene_id": ep.scene_id, "start_position": list(ep.start_position),
           "start_rotation": list(ep.start_rotation), "info": ep.info, "goals": goals, **ep.extra}
    if ep.object_category is not None:
        out["object_category"] = ep.object_category
    return out


def episode_from_wire(raw: dict[str, Any]) -> Episode:
    from pathlib import Path

    from navbench.episodes.io import _episode
    return _episode(raw, Path("<request>"))


# ---------------------------------------------------------------------------------------------- client
def _config_to_wire(cfg: Any) -> dict[str, Any]:
    """What a served factory may read of the run config (the client's agent options stay client-side)."""
    keys = ("task", "split", "episodes", "scene_dir", "success_distance", "seed", "env")
    return {k: getattr(cfg, k) for k in keys if hasattr(cfg, k)} if cfg is not None else {}


class RemoteAgent:
    """The agent protocol over HTTP. ``sensors`` come from the server's ``/info``, so the env renders
    only what the remote agent reads. Every failure raises :class:`RemoteAgentError` naming the URL."""

    def __init__(self, url: str, cfg: Any = None, timeout: float = DEFAULT_TIMEOUT):
        parts = urlsplit(url)
        if parts.scheme not in ("http", "https") or not parts.hostname or parts.path not in ("", "/"):
            raise ValueError(f"remote agent {url!r}: expected http://HOST:PORT")
        self.url = f"{parts.scheme}://{parts.netloc}"
        self.timeout = float(timeout)
        conn_cls = http.client.HTTPSConnection if parts.scheme == "https" else http.client.HTTPConnection
        self._connect = lambda: conn_cls(parts.hostname, parts.port, timeout=self.timeout)
        self._conn: http.client.HTTPConnection | None = None
        self.session = uuid.uuid4().hex
        self._session_open = False  # a /reset was answered: the server holds an agent for this session
        self.config = _config_to_wire(cfg)
        self.info = self._request("GET", "/info")
        if self.info.get("protocol") != PROTOCOL:
            raise RemoteAgentError(printable(f"{self.url}: speaks {self.info.get('protocol')!r}, not {PROTOCOL}"))
        sensors = self.info.get("sensors", [])
        # agent_pose: a served privileged agent's; a served agent is never given it (navbench.eval.worker.make_env)
        if not isinstance(sensors, list) or not all(s in ("rgb", "depth", "semantic", AGENT_POSE) for s in sensors):
            raise RemoteAgentError(printable(f"{self.url}/info: sensors {sensors!r} are not a list of rgb, depth, "
                                             f"semantic, {AGENT_POSE}"))
        self.sensors = tuple(sensors)

    def _request(self, method: str, path: str, body: bytes | None = None,
                 content_type: str = "application/json") -> dict[str, Any]:
        """One request within ``timeout`` seconds all told (connect, send, receive), its answer at most
        :data:`MAX_RESPONSE` bytes. A kept-alive connection the server has since closed is reopened once."""
        deadline = time.monotonic() + self.timeout
        for attempt in (0, 1):
            reused = self._conn is not None
            try:
                status, reason, data = self._exchange(method, path, body, content_type, deadline)
                break
            except (OSError, http.client.HTTPException, RemoteAgentError) as exc:
                self._disconnect()
                late = time.monotonic() >= deadline
                if reused and not late and attempt == 0 and isinstance(
                        exc, (http.client.RemoteDisconnected, ConnectionResetError, BrokenPipeError)):
                    continue  # the server closed an idle connection: the request never reached it
                if isinstance(exc, RemoteAgentError):
                    raise RemoteAgentError(f"{self.url}{path}: {exc}") from None
                reason = "timed out" if late or isinstance(exc, (socket.timeout, TimeoutError)) else \
                    (exc.strerror or str(exc) or type(exc).__name__) if isinstance(exc, OSError) else \
                    (str(exc) or type(exc).__name__)
                raise RemoteAgentError(printable(f"{self.url}{path}: {reason}")
                                       + (f" after {self.timeout:g} s" if reason == "timed out" else "")) from None
        try:
            answer = json.loads(data)
        except (ValueError, RecursionError):
            answer = None
        if status != 200:
            err = answer.get("error") if isinstance(answer, dict) else data[:200].decode(errors="replace")
            msg = (str(err or "").strip().splitlines() or [reason])[0]
            raise RemoteAgentError(printable(f"{self.url}{path}: HTTP {status}: {msg}", 400))
        if not isinstance(answer, dict):
            raise RemoteAgentError(printable(f"{self.url}{path}: answered {data[:80].decode(errors='replace')!r}, "
                                             f"not a JSON object"))
        return answer

    def _exchange(self, method: str, path: str, body: bytes | None, content_type: str, deadline: float
                  ) -> tuple[int, str, bytes]:
        """(status, reason, body) of one request; a watchdog closes the socket at ``deadline``, so a
        server that drips its answer a byte at a time cannot hold the call past it."""
        left = deadline - time.monotonic()
        if left <= 0:
            raise TimeoutError("timed out")
        if self._conn is None:
            self._conn = self._connect()
            self._conn.timeout = left
            self._conn.connect()
            self._conn.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        conn = self._conn
        conn.sock.settimeout(left)
        watchdog = threading.Timer(left, _abort, (conn,))
        watchdog.daemon = True
        watchdog.start()
        try:
            headers = {"Content-Type": content_type} if body is not None else {}
            conn.request(method, path, body=body, headers=headers)
            resp = conn.getresponse()
            length = resp.getheader("Content-Length")
            if length is not None and length.strip().isdigit() and int(length) > MAX_RESPONSE:
                raise RemoteAgentError(f"answer of {int(length)} bytes exceeds {MAX_RESPONSE}")
            data = resp.read(MAX_RESPONSE + 1)
            if len(data) > MAX_RESPONSE:
                raise RemoteAgentError(f"answer exceeds {MAX_RESPONSE} bytes")
            if not resp.isclosed() and resp.length:  # fewer bytes than announced are still to come
                raise http.client.IncompleteRead(data)
            if resp.will_close:
                self._disconnect()
            return resp.status, resp.reason, data
        finally:
            watchdog.cancel()
            if time.monotonic() >= deadline:
                raise TimeoutError("timed out")

    def _post_json(self, path: str, payload: dict[str, Any]) -> dict[str, Any]:
        return self._request("POST", path, json.dumps(payload, allow_nan=False).encode())

    def reset(self, episode: Episode) -> None:
        self._post_json("/reset", {"session": self.session, "episode": episode_to_wire(episode),
                                   "config": self.config})
        self._session_open = True

    def act(self, observations: dict[str, np.ndarray]) -> int:
        answer = self._request("POST", "/act", encode_arrays(observations, {"session": self.session}), ARRAYS_TYPE)
        action = answer.get("action")
        if not isinstance(action, int) or isinstance(action, bool):
            raise RemoteAgentError(printable(f"{self.url}/act: answered {action!r}, not an integer action"))
        return action

    def episode_log(self) -> dict[str, Any]:
        if not self.info.get("episode_log"):
            return {}
        return self._post_json("/log", {"session": self.session}).get("log") or {}

    # ---- the end of a session: the server frees its agent
    def close(self) -> None:
        """End the session (``POST /close``, so the server frees this client's agent; a server that is gone
        is not an error here) and close the connection. Called once the client's last episode is done."""
        if self._session_open:
            self._session_open = False
            try:
                self._post_json("/close", {"session": self.session})
            except RemoteAgentError:
                pass
        self._disconnect()

    def _disconnect(self) -> None:
        if self._conn is not None:
            self._conn.close()
            self._conn = None


def _abort(conn: http.client.HTTPConnection) -> None:
    """Unblock a request past its deadline: shut the socket down under the reading thread."""
    sock = conn.sock
    if sock is not None:
        try:
            sock.shutdown(socket.SHUT_RDWR)
        except OSError:
            pass


def probe(url: str, timeout: float = 5.0) -> dict[str, Any]:
    """The server's ``/info``, or a one-line ValueError: a run fails before it starts, not per episode."""
    try:
        agent = RemoteAgent(url, timeout=timeout)
    except RemoteAgentError as exc:
        raise ValueError(f"remote agent {exc} (is `navbench serve-agent` running there?)") from None
    agent.close()
    return agent.info


# ---------------------------------------------------------------------------------------------- server
@dataclasses.dataclass
class ServedConfig:
    """The run config a served agent's factory gets: the client's task, episodes and env settings, this
    server's agent and options. ``env_config`` renders what the agent reads, as the runner's does."""
    task: str = "pointnav"
    split: str | None = None
    agent: str = ""
    episodes: str = ""
    scene_dir: str = ""
    success_distance: float = 0.2
    seed: int = 0
    env: dict[str, Any] = dataclasses.field(default_factory=dict)
    agent_options: dict[str, Any] = dataclasses.field(default_factory=dict)
    envs_per_worker: int = 1
    label: str = ""
    device: str = "cpu"  # the server's (serve-agent --device), never the client's: its agents run here
    precision: str = "fp32"

    def env_config(self, sensors: tuple[str, ...]):
        from navbench.env.config import EnvConfig
        base = EnvConfig(success_distance=self.success_distance, **self.env)
        return dataclasses.replace(base, rgb="rgb" in sensors, depth="depth" in sensors,
                                   semantic="semantic" in sensors)


class _Session:
    """One client's agent; a batched-only agent is driven through slot 0."""

    def __init__(self, agent: Any):
        self.agent, self.lock = agent, threading.Lock()
        self.batched = not callable(getattr(agent, "act", None))

    def reset(self, episode: Episode) -> None:
        self.agent.reset_env(0, episode) if self.batched else self.agent.reset(episode)

    def act(self, obs: dict[str, np.ndarray]) -> int:
        action = self.agent.act_batch([obs])[0] if self.batched else self.agent.act(obs)
        if isinstance(action, Exception):  # a batched agent's way of saying this episode's step failed
            raise action
        return int(action)


class AgentServer(ThreadingHTTPServer):
    """Serves agents made by ``make_agent(config)``, one per client session (at most ``max_sessions``,
    the least recently used dropped first). ``stop()`` also closes open keep-alive connections.

    A request body is at most ``max_body`` bytes, all bodies being read or served at most ``max_buffered``
    together, at most ``max_requests`` requests are served at once (more wait briefly, then get 503); a
    connection that sends nothing for ``idle_timeout`` seconds, or takes more than ``request_timeout`` to
    send one request, is closed."""
    daemon_threads = True
    request_queue_size = 128  # the listen backlog

    def __init__(self, make_agent: Callable[[ServedConfig], Any], name: str,
                 address: tuple[str, int] = ("127.0.0.1", 0),
                 options: dict[str, Any] | None = None, scene_dir: str | None = None, task: str = "pointnav",
                 max_sessions: int = 64, max_body: int = MAX_BODY, max_buffered: int = MAX_BUFFERED,
                 max_requests: int = MAX_REQUESTS, idle_timeout: float = IDLE_TIMEOUT,
                 request_timeout: float = REQUEST_TIMEOUT, device: str = "cpu", precision: str = "fp32"):
        self.make_agent, self.name, self.options = make_agent, name, dict(options or {})
        self.device, self.precision = device, precision
        self.scene_dir, self.max_sessions = scene_dir, max_sessions
        self.max_body, self.max_buffered = max_body, max_buffered
        self.idle_timeout, self.request_timeout = idle_timeout, request_timeout
        self.slots = threading.BoundedSemaphore(max_requests)
        self.buffered, self.buffered_lock = {False: 0, True: 0}, threading.Lock()
        self.sessions: OrderedDict[str, _Session] = OrderedDict()
        self.sessions_lock = threading.Lock()
        self.connections: set[socket.socket] = set()
        # One agent built up front answers /info (its sensors) and fails a bad spec before serving.
        probe_agent = make_agent(ServedConfig(task=task, agent=name, agent_options=self.options,
                                              scene_dir=scene_dir or "", device=device, precision=precision))
        self.sensors = tuple(getattr(probe_agent, "sensors", ("rgb", "depth")))
        self.has_log = callable(getattr(probe_agent, "episode_log", None))
        super().__init__(address, _Handler)

    @property
    def url(self) -> str:
        host, port = self.server_address[:2]
        return f"http://{host}:{port}"

    def session(self, sid: str, config: dict[str, Any] | None) -> _Session:
        with self.sessions_lock:
            if sid in self.sessions:
                self.sessions.move_to_end(sid)
                return self.sessions[sid]
        if config is None:
            raise KeyError(f"unknown session {sid!r}: POST /reset first")
        known = {f.name for f in dataclasses.fields(ServedConfig)}
        cfg = ServedConfig(**{k: v for k, v in config.items() if k in known})
        cfg.agent, cfg.agent_options = self.name, dict(self.options)
        cfg.device, cfg.precision = self.device, self.precision
        if self.scene_dir:
            cfg.scene_dir = self.scene_dir
        s = _Session(self.make_agent(cfg))
        with self.sessions_lock:
            self.sessions[sid] = s
            while len(self.sessions) > self.max_sessions:
                self.sessions.popitem(last=False)
        return s

    def reserve(self, n: int, small: bool) -> bool:
        """Count ``n`` more buffered bytes, unless that would pass ``max_buffered``. Small requests (a
        step's frames) have a budget of their own, so large bodies cannot crowd them out."""
        with self.buffered_lock:
            cap = self.max_buffered // 4 if small else self.max_buffered
            if self.buffered[small] + n > cap:
                return False
            self.buffered[small] += n
            return True

    def unreserve(self, n: int, small: bool) -> None:
        with self.buffered_lock:
            self.buffered[small] -= n

    def handle_error(self, request: Any, client_address: Any) -> None:
        """A client gone mid-request is routine (a stopped run); anything else is printed as usual."""
        import sys
        if not isinstance(sys.exc_info()[1], (ConnectionError, TimeoutError)):
            super().handle_error(request, client_address)

    def start(self) -> AgentServer:
        """Serve from a daemon thread (tests, notebooks); ``stop()`` ends it."""
        self._thread = threading.Thread(target=self.serve_forever, daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        self.shutdown()
        self.server_close()
        for conn in list(self.connections):
            try:
                conn.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass


class _TooLarge(Exception):
    """A request's line and headers exceed :data:`MAX_HEADER_BYTES`."""


MAX_HEADER_BYTES = 64 << 10  # a request's line and headers


class _Reader:
    """The connection's input for one handler: an idle timeout while waiting for a request, then a
    deadline for the whole request (line, headers, body), however slowly its bytes drip in, and a cap on
    the bytes of its line and headers."""

    def __init__(self, raw: Any, sock: socket.socket, idle: float, per_request: float) -> None:
        self.raw, self.sock, self.idle, self.per_request = raw, sock, idle, per_request
        self.next_request()

    def next_request(self) -> None:
        self.deadline: float | None = None
        self.header_budget = MAX_HEADER_BYTES

    def _wait(self) -> None:
        if self.deadline is None:
            self.sock.settimeout(self.idle)
            return
        left = self.deadline - time.monotonic()
        if left <= 0:
            raise TimeoutError("request not received within its deadline")
        self.sock.settimeout(min(left, self.idle))

    def readline(self, limit: int = -1) -> bytes:
        limit = MAX_HEADER_BYTES + 1 if limit is None or limit < 0 else limit
        out = bytearray()
        while len(out) < limit:
            self._wait()
            buf = self.raw.peek(1)[:limit - len(out)]
            if not buf:
                break
            if self.deadline is None:
                self.deadline = time.monotonic() + self.per_request
            i = buf.find(b"\n")
            out += self.raw.read(i + 1 if i >= 0 else len(buf))
            if i >= 0:
                break
        self.header_budget -= len(out)
        if self.header_budget < 0:
            raise _TooLarge()
        return bytes(out)

    def read1(self, n: int) -> bytes:
        self._wait()
        return self.raw.read1(n)

    def close(self) -> None:
        self.raw.close()


class _Handler(BaseHTTPRequestHandler):
    protocol_version = "HTTP/1.1"  # keep-alive: one connection per client for a whole run
    server: AgentServer

    def setup(self) -> None:
        super().setup()
        # Headers and body go out in two writes: without this, Nagle's algorithm and the client's delayed
        # ACK hold every answer back ~40 ms.
        self.connection.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.rfile = _Reader(self.rfile, self.connection, self.server.idle_timeout,  # type: ignore[assignment]
                             self.server.request_timeout)
        self.server.connections.add(self.connection)

    def handle_one_request(self) -> None:
        self.rfile.next_request()
        try:
            super().handle_one_request()
        except _TooLarge:
            self._raw_answer(431, f"request line and headers exceed {MAX_HEADER_BYTES} bytes")

    def _raw_answer(self, status: int, error: str) -> None:
        """An answer when the request could not be parsed far enough for send_response; closes."""
        data = json.dumps({"error": error}).encode()
        self.close_connection = True
        self.connection.settimeout(self.server.idle_timeout)
        self.wfile.write(f"HTTP/1.1 {status} {http.HTTPStatus(status).phrase}\r\nContent-Type: application/json"
                         f"\r\nContent-Length: {len(data)}\r\nConnection: close\r\n\r\n".encode() + data)

    def finish(self) -> None:
        self.server.connections.discard(self.connection)
        super().finish()

    def log_message(self, format: str, *args: Any) -> None:  # a request per step: too many to print
        pass

    def _send(self, status: int, payload: dict[str, Any], close: bool = False) -> None:
        data = json.dumps(payload).encode()
        self.connection.settimeout(self.server.idle_timeout)
        self.send_response(status)
        self.send_header("Content-Type", "application/json")
        self.send_header("Content-Length", str(len(data)))
        if close:  # the request's body was not read: the connection cannot carry another request
            self.send_header("Connection", "close")
            self.close_connection = True
        self.end_headers()
        self.wfile.write(data)

    def do_GET(self) -> None:
        if self.path != "/info":
            return self._send(404, {"error": f"no such endpoint: GET {self.path}"})
        self._send(200, {"protocol": PROTOCOL, "name": self.server.name, "sensors": list(self.server.sensors),
                         "episode_log": self.server.has_log})

    def _body(self) -> tuple[bytes, int] | None:
        """The request body and the buffer bytes it holds, or None after answering 4xx/503 (and closing)."""
        lengths = self.headers.get_all("Content-Length") or []
        if self.headers.get("Transfer-Encoding") is not None or len(lengths) != 1 or \
                not lengths[0].strip().isdigit():
            self._send(411, {"error": "a request needs one Content-Length, a non-negative integer "
                                      "(no chunked transfer encoding)"}, close=True)
            return None
        n = int(lengths[0])
        cap = self.server.max_body if self.path == "/act" else min(self.server.max_body, MAX_JSON_HEADER * 16)
        if n > cap:
            self._send(413, {"error": f"body of {n} bytes exceeds {cap}"}, close=True)
            return None
        parts, held, small = [], 0, n <= SMALL_BODY
        try:
            while held < n:
                want = min(n - held, 1 << 20)
                if not self.server.reserve(want, small):
                    self._send(503, {"error": "server busy: too many request bytes buffered, retry later"},
                               close=True)
                    return None
                chunk = self.rfile.read1(want)
                self.server.unreserve(want - len(chunk), small)
                if not chunk:
                    raise ConnectionError("client closed the connection mid-body")
                held += len(chunk)
                parts.append(chunk)
        except BaseException:
            self.server.unreserve(held, small)
            raise
        return b"".join(parts), held

    def do_POST(self) -> None:
        got = self._body()
        if got is None:
            return
        body, held = got
        try:
            if not self.server.slots.acquire(timeout=5.0):
                return self._send(503, {"error": "server busy: too many requests at once, retry later"})
            try:
                self._serve_post(body)
            finally:
                self.server.slots.release()
        finally:
            self.server.unreserve(held, held <= SMALL_BODY)

    def _serve_post(self, body: bytes) -> None:
        try:
            if self.path == "/act":
                obs, meta = decode_arrays(body)
            else:
                meta = loads_bounded(body or b"{}")
            if not isinstance(meta, dict):
                raise TypeError(f"expected a JSON object, got {type(meta).__name__}")
        except (ValueError, KeyError, TypeError) as exc:
            return self._send(400, {"error": printable(f"bad request: {exc}")})
        try:
            if self.path == "/reset":
                try:
                    episode = episode_from_wire(meta["episode"])
                    config = meta.get("config") or {}
                    if not isinstance(config, dict):
                        raise TypeError(f"config must be an object, got {type(config).__name__}")
                except (ValueError, TypeError) as exc:
                    return self._send(400, {"error": printable(f"bad request: {exc}")})
                s = self.server.session(str(meta["session"]), config)
                with s.lock:
                    s.reset(episode)
                return self._send(200, {"ok": True})
            if self.path == "/act":
                s = self.server.session(str(meta["session"]), None)
                with s.lock:
                    return self._send(200, {"action": s.act(obs)})
            if self.path == "/log":
                s = self.server.session(str(meta["session"]), None)
                with s.lock:
                    log = s.agent.episode_log() if self.server.has_log else {}
                return self._send(200, {"log": log})
            if self.path == "/close":
                with self.server.sessions_lock:
                    self.server.sessions.pop(str(meta.get("session")), None)
                return self._send(200, {"ok": True})
            return self._send(404, {"error": f"no such endpoint: POST {self.path}"})
        except KeyError as exc:
            return self._send(400, {"error": printable(f"bad request: {exc.args[0] if exc.args else exc}")})
        except Exception as exc:  # the agent's own failure: reported to the client, the server lives on
            where = traceback.extract_tb(exc.__traceback__)[-1]
            return self._send(500, {"error": f"agent raised {type(exc).__name__}: {printable(str(exc))} "
                                             f"({where.filename.rsplit('/', 1)[-1]}:{where.lineno})"})
