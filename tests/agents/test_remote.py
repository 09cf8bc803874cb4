"""Remote agents: the wire format, the reference server on loopback, and failures that raise promptly."""

import json
import os
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

import navbench
from navbench.agents.plugins import resolve_agent
from navbench.agents.remote import AgentServer, RemoteAgent, RemoteAgentError, decode_arrays, encode_arrays
from navbench.episodes.io import load_dataset
from navbench.eval.runner import read_records


def _records(run_dir):
    """Records without what differs by design: the wall time and the agent's spec (a URL when remote)."""
    return sorted(({k: v for k, v in r.items() if k not in ("elapsed_s", "agent")}
                   for r in read_records(run_dir / "episodes.jsonl")), key=lambda r: r["episode_id"])


def _serve(spec, **options):
    agent = resolve_agent(spec, options)
    return AgentServer(agent.factory, spec, ("127.0.0.1", 0), options=agent.options).start()


def test_arrays_round_trip_bit_for_bit_with_dtype_and_shape():
    arrays = {"depth": np.random.default_rng(0).random((4, 5, 1), dtype=np.float32),
              "rgb": np.arange(24, dtype=np.uint8).reshape(2, 4, 3), "objectgoal": np.array([3], np.int64),
              "compass": np.array([-0.5], ">f4"), "empty": np.zeros((0, 2), np.float64)}
    body = encode_arrays(arrays, {"session": "s"})
    out, meta = decode_arrays(body)
    assert meta == {"session": "s"} and list(out) == list(arrays)
    for k, a in arrays.items():
        assert out[k].shape == a.shape and out[k].dtype == a.dtype.newbyteorder("=") and np.array_equal(out[k], a)
    assert len(body) < 4 + 300 + sum(a.nbytes for a in arrays.values())  # raw bytes, not JSON numbers
    for bad in (body[:-1], body + b"x", b"\x01"):
        with pytest.raises(ValueError):
            decode_arrays(bad)


def test_same_agent_in_process_and_served_gives_identical_records(agent_dir, pointnav10_file, tmp_path):
    """The reference server in its own process (`navbench serve-agent`, port 0) against in-process."""
    local = navbench.evaluate("walkmod:WalkAgent", episodes=pointnav10_file, options={"stop_after": 40},
                              out=tmp_path / "local")
    proc = subprocess.Popen([sys.executable, "-m", "navbench.cli", "serve-agent", "walkmod:WalkAgent",
                             "--agent-opt", "stop_after=40", "--port", "0"], stdout=subprocess.PIPE, text=True,
                            env=dict(os.environ, PYTHONPATH=os.pathsep.join([str(agent_dir), *sys.path])))
    try:
        line = proc.stdout.readline()  # "serving walkmod:WalkAgent at http://127.0.0.1:PORT (sensors: depth)"
        assert "sensors: depth" in line, line
        url = line.split(" at ")[1].split()[0]
        remote = navbench.evaluate(url, episodes=pointnav10_file, options={"timeout": 10}, out=tmp_path / "remote")
    finally:
        proc.terminate()
        proc.wait(timeout=10)
    assert local["num_episodes"] == remote["num_episodes"] == 10
    assert _records(tmp_path / "remote") == _records(tmp_path / "local")
    assert len({r["num_steps"] for r in _records(tmp_path / "local")}) > 1  # the observations steered it
    assert all(r["log"]["observations_crc32"] for r in _records(tmp_path / "remote"))  # and arrived bit for bit
    cfg = json.loads((tmp_path / "remote" / "config.json").read_text())
    assert cfg["agent"] == url and cfg["agent_options"] == {"timeout": 10}


@pytest.mark.parametrize("task", ["pointnav", "objectnav"])
def test_oracle_served_from_a_thread_matches_in_process(task, request, tmp_path):
    """The oracle plans on the episode's goals (ObjectNav: their view points), so those cross the wire whole."""
    episodes = request.getfixturevalue(f"{task}_file")
    server = _serve("oracle")
    try:
        navbench.evaluate(server.url, episodes=episodes, out=tmp_path / "remote")
    finally:
        server.stop()
    navbench.evaluate("oracle", episodes=episodes, out=tmp_path / "local")
    assert _records(tmp_path / "remote") == _records(tmp_path / "local")
    assert all(r["success"] for r in _records(tmp_path / "local"))


def _episode(pointnav_file):
    return load_dataset(pointnav_file).episodes[0]


OBS = {"depth": np.ones((8, 8, 1), np.float32), "pointgoal_with_gps_compass": np.array([3.0, 0.0], np.float32),
       "gps": np.zeros(2, np.float32), "compass": np.zeros(1, np.float32)}


def test_server_gone_mid_episode_raises_promptly_with_the_reason(agent_dir, pointnav_file):
    server = _serve("walkmod:WalkAgent")
    agent = RemoteAgent(server.url, timeout=5)
    agent.reset(_episode(pointnav_file))
    assert agent.act(OBS) == 1
    server.stop()
    t0 = time.monotonic()
    with pytest.raises(RemoteAgentError, match=r"^http://127\.0\.0\.1:\d+/act: ") as err:
        agent.act(OBS)
    assert time.monotonic() - t0 < 2 and "\n" not in str(err.value)
    with pytest.raises(RemoteAgentError, match="/reset: .*(refused|reset)"):  # nobody listens any more
        agent.reset(_episode(pointnav_file))


def test_a_step_slower_than_the_timeout_raises_timed_out(agent_dir, pointnav_file):
    server = _serve("walkmod:SlowAgent")
    try:
        agent = RemoteAgent(server.url, timeout=0.3)
        agent.reset(_episode(pointnav_file))
        t0 = time.monotonic()
        with pytest.raises(RemoteAgentError, match=r"/act: timed out after 0.3 s"):
            agent.act(OBS)
        assert time.monotonic() - t0 < 2
    finally:
        server.stop()


def test_the_agents_exception_comes_back_in_one_line(agent_dir, pointnav_file):
    server = _serve("walkmod:RaisingAgent")
    try:
        agent = RemoteAgent(server.url, timeout=5)
        agent.reset(_episode(pointnav_file))
        with pytest.raises(RemoteAgentError, match=r"/act: HTTP 500: agent raised ZeroDivisionError: the agent's "
                                                   r"own bug \(walkmod.py:\d+\)$"):
            agent.act(OBS)
        agent.reset(_episode(pointnav_file))  # the server lives on: a new episode still starts
    finally:
        server.stop()


def test_sessions_keep_parallel_clients_apart(agent_dir, pointnav_file):
    server = _serve("walkmod:WalkAgent", stop_after=3)
    try:
        a, b = RemoteAgent(server.url, timeout=5), RemoteAgent(server.url, timeout=5)
        for agent in (a, b):
            agent.reset(_episode(pointnav_file))
        assert [a.act(OBS), a.act(OBS), b.act(OBS), a.act(OBS)] == [1, 1, 1, 0]  # a's third step stops
        with pytest.raises(RemoteAgentError, match="HTTP 400: bad request: unknown session"):
            RemoteAgent(server.url, timeout=5).act(OBS)
    finally:
        server.stop()


def test_nothing_listening_is_one_line_and_exit_2(tmp_path, pointnav_file, capsys):
    import socket

    from navbench.cli import main
    with socket.socket() as s:  # a port nobody listens on once closed
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    assert main(["run", "--episodes", str(pointnav_file), "--agent", f"http://127.0.0.1:{port}", "-q"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "refused" in err and "serve-agent" in err


def test_server_that_stops_mid_run_gives_failure_records_not_a_hang(agent_dir, pointnav10_file, tmp_path):
    server = _serve("walkmod:WalkAgent", stop_after=40)
    done = threading.Event()

    def stop_soon():
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline and not done.is_set():
            path = tmp_path / "run" / "episodes.jsonl"
            if path.is_file() and len(path.read_text().splitlines()) >= 3:
                break
            time.sleep(0.05)
        server.stop()

    stopper = threading.Thread(target=stop_soon, daemon=True)
    stopper.start()
    t0 = time.monotonic()
    try:
        summary = navbench.evaluate(server.url, episodes=pointnav10_file, options={"timeout": 2},
                                    out=tmp_path / "run")
    finally:
        done.set()
        stopper.join(timeout=25)
    assert time.monotonic() - t0 < 60
    recs = read_records(tmp_path / "run" / "episodes.jsonl")
    failed = [r for r in recs if r.get("failed")]
    assert len(recs) == 10 and failed and summary["num_episodes"] == 10
    assert all("127.0.0.1" in r["failure_reason"] and "\n" not in r["failure_reason"] for r in failed)


def test_served_agents_run_on_the_servers_device_whatever_the_client_sends(capsys):
    built = []

    def factory(cfg):
        built.append((cfg.device, cfg.precision))
        return _Still()

    server = AgentServer(factory, "still", ("127.0.0.1", 0), device="cuda:1", precision="bf16")
    try:
        server.session("s1", {"task": "pointnav", "device": "cpu", "precision": "fp32"})
        assert built == [("cuda:1", "bf16"), ("cuda:1", "bf16")]  # the probe agent, then the session's
    finally:
        server.server_close()
    from navbench.cli import main
    assert main(["serve-agent", "oracle", "--device", "cuda:99", "--port", "0"]) == 2  # no such device here
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "cuda:99" in err[0]


class _Still:
    sensors = ()

    def reset(self, episode):
        pass

    def act(self, observations):
        return 0
