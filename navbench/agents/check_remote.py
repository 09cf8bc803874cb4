"""``navbench check-agent http://HOST:PORT``: exercise a remote agent server against the protocol of
docs/remote_agent.md and say what is wrong.

It renders one real observation of the task's env (the sensors ``/info`` lists, with the env's dtypes and
shapes), then checks ``/info``; ``/reset`` and ``/act`` for two interleaved sessions; the answers'
Content-Type, Content-Length and keep-alive; ``/log`` when ``/info`` offers it; that errors (an unknown
endpoint, a malformed body, an unknown session) are non-200 answers carrying ``{"error": "one line"}``;
that ``/close`` frees a session; and the time per ``/act`` round trip over ``steps`` steps. Slow steps are
told apart by timing ``GET /info``, which does no work: as slow, it is Nagle's algorithm meeting delayed
ACKs (~40 ms a step); fast, it is the agent's own time. Each check is one line.
"""

from __future__ import annotations

import http.client
import json
import socket
import statistics
import time
import uuid
from dataclasses import dataclass
from typing import Any
from urllib.parse import urlsplit

import numpy as np

from navbench.agents.remote import ARRAYS_TYPE, PROTOCOL, encode_arrays, episode_to_wire

SENSORS = ("rgb", "depth", "semantic")
SLOW_STEP_MS = 20.0  # per /act round trip on loopback; Nagle + delayed ACK costs ~40


@dataclass
class Check:
    name: str
    ok: bool
    detail: str = ""
    warning: bool = False  # a problem that does not break the protocol (speed, connection reuse)

    def line(self) -> str:
        tag = "ok  " if self.ok else ("WARN" if self.warning else "FAIL")
        return f"{tag}  {self.name}" + (f": {self.detail}" if self.detail else "")


@dataclass
class Answer:
    status: int
    body: Any  # the decoded JSON, or None when the body is not JSON
    raw: bytes
    headers: dict[str, str]
    will_close: bool
    seconds: float


class _Client:
    """One keep-alive connection with TCP_NODELAY, as navbench's client makes; counts reconnections."""

    def __init__(self, url: str, timeout: float):
        parts = urlsplit(url)
        if parts.scheme != "http" or not parts.hostname or parts.path not in ("", "/"):
            raise ValueError(f"check-agent {url!r}: expected http://HOST:PORT")
        self.host, self.port, self.timeout = parts.hostname, parts.port or 80, timeout
        self.conn: http.client.HTTPConnection | None = None
        self.connections = 0

    def request(self, method: str, path: str, body: bytes | None = None,
                content_type: str = "application/json") -> Answer:
        if self.conn is None:
            self.conn = http.client.HTTPConnection(self.host, self.port, timeout=self.timeout)
            self.conn.connect()
            self.conn.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            self.connections += 1
        headers = {"Content-Type": content_type} if body is not None else {}
        t0 = time.perf_counter()
        try:
            self.conn.request(method, path, body=body, headers=headers)
            resp = self.conn.getresponse()
            raw = resp.read()
        except (OSError, http.client.HTTPException):
            self.close()
            raise
        dt = time.perf_counter() - t0
        if resp.will_close:
            self.close()
        try:
            parsed = json.loads(raw) if raw else None
        except (json.JSONDecodeError, UnicodeDecodeError):
            parsed = None
        return Answer(resp.status, parsed, raw, {k.lower(): v for k, v in resp.getheaders()}, resp.will_close, dt)

    def post_json(self, path: str, payload: dict[str, Any]) -> Answer:
        return self.request("POST", path, json.dumps(payload).encode())

    def close(self) -> None:
        if self.conn is not None:
            self.conn.close()
            self.conn = None


SPLITS = {"objectnav": "val_seen"}  # the bundled split whose first episode is sent, when not the task's default


def check_split(task: str) -> str:
    """The bundled split of ``task`` whose first episode the check sends."""
    from navbench.tasks import get_task
    return SPLITS.get(task, get_task(task).default_split)


def run_config(task: str) -> dict[str, Any]:
    """The ``config`` of ``/reset`` as navbench's client sends it for the task's bundled split."""
    from navbench.paths import SCENES_DIR
    from navbench.tasks import get_task
    t, split = get_task(task), check_split(task)
    return {"task": task, "split": split, "episodes": str(t.split_file(split)),
            "scene_dir": str(SCENES_DIR), "success_distance": t.success_distance_for(split), "seed": 0, "env": {}}


def sample_observation(task: str, sensors: tuple[str, ...]) -> tuple[dict[str, np.ndarray], Any]:
    """One observation as the task's env gives it to an agent reading ``sensors`` (the first episode of the
    bundled validation split, rendered), and that episode."""
    from navbench.env.config import EnvConfig
    from navbench.env.make import task_env
    from navbench.tasks import get_task
    cfg = EnvConfig(rgb="rgb" in sensors, depth="depth" in sensors, semantic="semantic" in sensors,
                    max_steps=get_task(task).max_steps)
    env = task_env(task, get_task(task).split_file(check_split(task)), config=cfg)
    try:
        episode = env.dataset.episodes[0]
        obs, _ = env.reset(seed=0, options={"episode": episode})
        return obs, episode
    finally:
        env.close()


def _answer_problem(a: Answer, want: str | None = None) -> str:
    """What is wrong with a 200 answer's framing and body ('' if nothing); ``want``: a key it must hold."""
    if a.status != 200:
        err = a.body.get("error") if isinstance(a.body, dict) else None
        return f"HTTP {a.status}" + (f": {err}" if err else f", body {a.raw[:120]!r}")
    if "content-length" not in a.headers:
        return "no Content-Length header (navbench reads bodies by their length; no chunked encoding)"
    if not a.headers.get("content-type", "").startswith("application/json"):
        return f"Content-Type {a.headers.get('content-type')!r}, not application/json"
    if not isinstance(a.body, dict):
        return f"body is not a JSON object: {a.raw[:120]!r}"
    if want is not None and want not in a.body:
        return f"answer {a.body!r} has no {want!r}"
    return ""


def _error_problem(a: Answer) -> str:
    """What is wrong with an error answer ('' if it is a non-200 status with a one-line JSON error)."""
    if a.status == 200:
        return f"answered 200 {a.raw[:120]!r}; expected a 4xx status with {{\"error\": ...}}"
    if not isinstance(a.body, dict) or not isinstance(a.body.get("error"), str):
        return f"HTTP {a.status} without a JSON {{\"error\": str}} body: {a.raw[:120]!r}"
    if "\n" in a.body["error"].strip():
        return f"HTTP {a.status}: the error is more than one line"
    if "content-length" not in a.headers:
        return f"HTTP {a.status} without a Content-Length header"
    return ""


def check_server(url: str, task: str = "pointnav", steps: int = 200, timeout: float = 10.0,
                 log=print) -> list[Check]:
    """Run every check against the server at ``url``, calling ``log`` with each result's line as it is
    known; the results. ValueError (one line) when the server cannot be reached at all."""
    from navbench.tasks import get_task
    actions = get_task(task).actions  # the action space of the task's bundled split (navbench's EnvConfig)
    client = _Client(url, timeout)
    checks: list[Check] = []

    def report(name: str, problem: str, warning: bool = False, detail: str = "") -> bool:
        c = Check(name, not problem, problem or detail, warning)
        checks.append(c)
        log(c.line())
        return c.ok

    def call(name: str, *args: Any, **kw: Any) -> Answer | None:
        try:
            return client.request(*args, **kw)
        except (OSError, http.client.HTTPException) as exc:
            reason = "timed out" if isinstance(exc, (socket.timeout, TimeoutError)) else \
                (getattr(exc, "strerror", None) or str(exc) or type(exc).__name__)
            report(name, f"{reason} (timeout {timeout:g} s)")
            return None

    # ---- /info
    try:
        info = client.request("GET", "/info")
    except (OSError, http.client.HTTPException) as exc:
        raise ValueError(f"check-agent {url}/info: {getattr(exc, 'strerror', None) or exc}") from None
    problem = _answer_problem(info, "protocol")
    body = info.body if isinstance(info.body, dict) else {}
    sensors = body.get("sensors")
    if not problem and body.get("protocol") != PROTOCOL:
        problem = f"protocol {body.get('protocol')!r}, expected {PROTOCOL!r}"
    if not problem and not isinstance(body.get("name"), str):
        problem = f"name {body.get('name')!r} is not a string"
    if not problem and (not isinstance(sensors, list) or any(s not in SENSORS for s in sensors)
                        or len(set(sensors)) != len(sensors)):
        problem = f"sensors {sensors!r}: expected a list of distinct names from {', '.join(SENSORS)}"
    if not problem and not isinstance(body.get("episode_log", False), bool):
        problem = f"episode_log {body.get('episode_log')!r} is not true or false"
    if not report("GET /info", problem, detail=f"{body.get('name')!r}, sensors [{', '.join(sensors or [])}], "
                  f"episode_log {bool(body.get('episode_log'))}"):
        client.close()
        return checks
    sensors_t = tuple(sensors)
    obs, episode = sample_observation(task, sensors_t)
    shapes = ", ".join(f"{k} {np.dtype(v.dtype).str}{list(v.shape)}" for k, v in obs.items())
    config = run_config(task)
    wire_episode = episode_to_wire(episode)

    # ---- two sessions, interleaved
    sa, sb = uuid.uuid4().hex, uuid.uuid4().hex
    for sid, name in ((sa, "A"), (sb, "B")):
        a = call(f"POST /reset (session {name})", "POST", "/reset",
                 json.dumps({"session": sid, "episode": wire_episode, "config": config}).encode())
        if a is None:
            client.close()
            return checks
        report(f"POST /reset (session {name})", _answer_problem(a))

    def act(sid: str) -> tuple[Answer | None, str]:
        a = call("POST /act", "POST", "/act", encode_arrays(obs, {"session": sid}), ARRAYS_TYPE)
        if a is None:
            return None, "no answer"
        problem = _answer_problem(a, "action")
        if not problem:
            action = a.body["action"]
            if not isinstance(action, int) or isinstance(action, bool) or not 0 <= action < len(actions):
                problem = (f"action {action!r}: expected an integer 0-{len(actions) - 1} "
                           f"({', '.join(f'{i} {a}' for i, a in enumerate(actions))})")
        return a, problem

    first, problem = act(sa)
    if first is None:
        client.close()
        return checks
    report("POST /act (session A)", problem, detail=f"observations {shapes} -> {first.body!r}")
    second, problem = act(sb)
    if second is not None:
        report("POST /act (session B, interleaved)", problem)

    # ---- framing and connection reuse
    report("keep-alive", "the server closes the connection after an answer: every step pays a new TCP "
           "connection (answer with HTTP/1.1 and keep the connection open)" if first.will_close else "",
           warning=True)

    # ---- latency
    times, bad = [], ""
    for _ in range(max(1, steps)):
        a, problem = act(sa)
        if a is None or problem:
            bad = problem
            break
        times.append(a.seconds * 1000)
    if bad or not times:
        report(f"{steps} x POST /act", bad or "no answer")
    else:
        med, p95 = statistics.median(times), sorted(times)[int(0.95 * (len(times) - 1))]
        hint = ""
        if med > SLOW_STEP_MS:
            # The stall also holds back /info, which does no work: then it is the connection, not the agent.
            info_ms = [a.seconds * 1000 for a in (call("GET /info", "GET", "/info") for _ in range(5)) if a]
            stalled = bool(info_ms) and statistics.median(info_ms) > SLOW_STEP_MS
            hint = (f"median {med:.1f} ms per step (p95 {p95:.1f}) is slow; "
                    + ("GET /info is as slow: ~40 ms is Nagle's algorithm meeting delayed ACKs: set TCP_NODELAY "
                       "on the server's sockets and write each answer's headers and body in one send" if stalled
                       else "GET /info is fast, so the time is the agent's own"))
        report(f"latency over {len(times)} steps", hint, warning=True,
               detail=f"median {med:.2f} ms, p95 {p95:.2f} ms per /act round trip (this client's encoding "
                      f"included; {client.connections} connection(s))")

    # ---- /log
    if body.get("episode_log"):
        a = call("POST /log", "POST", "/log", json.dumps({"session": sa}).encode())
        if a is not None:
            problem = _answer_problem(a, "log")
            if not problem and not isinstance(a.body["log"], dict):
                problem = f"log {a.body['log']!r} is not a JSON object"
            report("POST /log", problem)

    # ---- errors
    a = call("GET /no-such-endpoint", "GET", "/no-such-endpoint")
    if a is not None:
        report("unknown endpoint -> error", _error_problem(a))
    a = call("POST /act (malformed body)", "POST", "/act", b"\x05\x00\x00\x00{bad", ARRAYS_TYPE)
    if a is not None:
        report("malformed /act body -> error", _error_problem(a))
    a = call("POST /act (unknown session)", "POST", "/act", encode_arrays(obs, {"session": uuid.uuid4().hex}),
             ARRAYS_TYPE)
    if a is not None:
        report("unknown session -> error", _error_problem(a))

    # ---- /close frees the session; the other session lives on
    a = call("POST /close", "POST", "/close", json.dumps({"session": sa}).encode())
    if a is not None:
        problem = _answer_problem(a)
        if not problem:
            after = call("POST /act after /close", "POST", "/act", encode_arrays(obs, {"session": sa}), ARRAYS_TYPE)
            if after is not None and after.status == 200:
                problem = "the session still answers /act after /close (its agent was not freed)"
        report("POST /close frees the session", problem)
        other, problem = act(sb)
        if other is not None:
            report("session B unaffected by closing A", problem)
    try:
        client.post_json("/close", {"session": sb})
    except (OSError, http.client.HTTPException):
        pass
    client.close()
    return checks
