"""Agents in another process or on another machine, over HTTP: the client (``--agent http://HOST:PORT``)
and the reference server (``navbench serve-agent SPEC --port P``). The protocol is in docs/remote_agent.md.

The client enforces a per-request socket timeout, so a dead or stuck server makes ``reset``/``act``
raise :class:`RemoteAgentError` with a one-line reason instead of hanging the run.
"""

from __future__ import annotations

import dataclasses
import http.client
import json
import math
import socket
import struct
import threading
import traceback
import uuid
from collections import OrderedDict
from collections.abc import Callable
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any
from urllib.parse import urlsplit

import numpy as np

from navbench.episodes.types import Episode, ObjectGoal

PROTOCOL = "navbench-agent/1"
ARRAYS_TYPE = "application/x-navbench-arrays"
DEFAULT_TIMEOUT = 30.0  # seconds per request: a VLM step on a busy GPU box can take a while
MAX_BODY = 256 << 20


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
    header = json.loads(body[4:4 + n])
    offset, arrays = 4 + n, {}
    for spec in header.pop("arrays"):
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
            raise RemoteAgentError(f"{self.url}: speaks {self.info.get('protocol')!r}, not {PROTOCOL}")
        self.sensors = tuple(self.info.get("sensors", ()))

    def _request(self, method: str, path: str, body: bytes | None = None,
                 content_type: str = "application/json") -> dict[str, Any]:
        try:
            if self._conn is None:
                self._conn = self._connect()
                self._conn.connect()
                self._conn.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            headers = {"Content-Type": content_type} if body is not None else {}
            self._conn.request(method, path, body=body, headers=headers)
            resp = self._conn.getresponse()
            data = resp.read()
        except (OSError, http.client.HTTPException) as exc:
            self._disconnect()
            reason = "timed out" if isinstance(exc, (socket.timeout, TimeoutError)) else \
                (exc.strerror or str(exc) or type(exc).__name__) if isinstance(exc, OSError) else \
                (str(exc) or type(exc).__name__)
            raise RemoteAgentError(f"{self.url}{path}: {reason}"
                                   + (f" after {self.timeout:g} s" if reason == "timed out" else "")) from None
        try:
            answer = json.loads(data) if data else {}
        except json.JSONDecodeError:
            answer = {"error": data[:200].decode(errors="replace")}
        if resp.status != 200:
            msg = str(answer.get("error", "")).splitlines()[0] if answer.get("error") else resp.reason
            raise RemoteAgentError(f"{self.url}{path}: HTTP {resp.status}: {msg}")
        return answer

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
            raise RemoteAgentError(f"{self.url}/act: answered {action!r}, not an integer action")
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
    the least recently used dropped first). ``stop()`` also closes open keep-alive connections."""
    daemon_threads = True

    def __init__(self, make_agent: Callable[[ServedConfig], Any], name: str,
                 address: tuple[str, int] = ("127.0.0.1", 0),
                 options: dict[str, Any] | None = None, scene_dir: str | None = None, task: str = "pointnav",
                 max_sessions: int = 64):
        self.make_agent, self.name, self.options = make_agent, name, dict(options or {})
        self.scene_dir, self.max_sessions = scene_dir, max_sessions
        self.sessions: OrderedDict[str, _Session] = OrderedDict()
        self.sessions_lock = threading.Lock()
        self.connections: set[socket.socket] = set()
        # One agent built up front answers /info (its sensors) and fails a bad spec before serving.
        probe_agent = make_agent(ServedConfig(task=task, agent=name, agent_options=self.options,
                                              scene_dir=scene_dir or ""))
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
        if self.scene_dir:
            cfg.scene_dir = self.scene_dir
        s = _Session(self.make_agent(cfg))
        with self.sessions_lock:
            self.sessions[sid] = s
            while len(self.sessions) > self.max_sessions:
                self.sessions.popitem(last=False)
        return s

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


class _Handler(BaseHTTPRequestHandler):
    protocol_version = "HTTP/1.1"  # keep-alive: one connection per client for a whole run
    server: AgentServer

    def setup(self) -> None:
        super().setup()
        # Headers and body go out in two writes: without this, Nagle's algorithm and the client's delayed
        # ACK hold every answer back ~40 ms.
        self.connection.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.server.connections.add(self.connection)

    def finish(self) -> None:
        self.server.connections.discard(self.connection)
        super().finish()

    def log_message(self, format: str, *args: Any) -> None:  # a request per step: too many to print
        pass

    def _send(self, status: int, payload: dict[str, Any]) -> None:
        data = json.dumps(payload).encode()
        self.send_response(status)
        self.send_header("Content-Type", "application/json")
        self.send_header("Content-Length", str(len(data)))
        self.end_headers()
        self.wfile.write(data)

    def do_GET(self) -> None:
        if self.path != "/info":
            return self._send(404, {"error": f"no such endpoint: GET {self.path}"})
        self._send(200, {"protocol": PROTOCOL, "name": self.server.name, "sensors": list(self.server.sensors),
                         "episode_log": self.server.has_log})

    def do_POST(self) -> None:
        try:
            n = int(self.headers.get("Content-Length", "0"))
            if n > MAX_BODY:
                return self._send(413, {"error": f"body of {n} bytes exceeds {MAX_BODY}"})
            body = self.rfile.read(n)
            if self.path == "/act":
                obs, meta = decode_arrays(body)
            else:
                meta = json.loads(body or b"{}")
        except (ValueError, KeyError, TypeError) as exc:
            return self._send(400, {"error": f"bad request: {exc}"})
        try:
            if self.path == "/reset":
                s = self.server.session(str(meta["session"]), meta.get("config") or {})
                with s.lock:
                    s.reset(episode_from_wire(meta["episode"]))
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
            return self._send(400, {"error": f"bad request: {exc.args[0] if exc.args else exc}"})
        except Exception as exc:  # the agent's own failure: reported to the client, the server lives on
            where = traceback.extract_tb(exc.__traceback__)[-1]
            return self._send(500, {"error": f"agent raised {type(exc).__name__}: {exc} "
                                             f"({where.filename.rsplit('/', 1)[-1]}:{where.lineno})"})
