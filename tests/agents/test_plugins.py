"""Plug-in agents: import paths and entry points on the command line, typed options, navbench.evaluate."""

import json
import sys
from pathlib import Path

import pytest

import navbench
from navbench.agents.plugins import parse_option, plugin_label, resolve_agent
from navbench.cli import main
from navbench.eval.runner import comparable, read_records


def _records(run_dir):
    return comparable(read_records(run_dir / "episodes.jsonl"))


def _cli(*argv):
    return main(["run", *map(str, argv), "--workers", "1", "-q"])


@pytest.mark.parametrize("text, expected", [
    ("k=3", ("k", 3)), ("k=0.5", ("k", 0.5)), ("k=true", ("k", True)), ("k=null", ("k", None)),
    ("k=[1, 2]", ("k", [1, 2])), ("k=runs/a.pt", ("k", "runs/a.pt")), ("k=", ("k", "")), ("k=a=b", ("k", "a=b")),
])
def test_agent_opt_values_are_json_literals_else_strings(text, expected):
    assert parse_option(text) == expected


@pytest.mark.parametrize("text", ["novalue", "=3", "not-an-identifier=1"])
def test_malformed_agent_opt_is_refused(text):
    with pytest.raises(ValueError, match="NAME=VALUE"):
        parse_option(text)


def test_labels_name_the_class_then_the_options_in_order():
    assert plugin_label("mypkg.agents:MyAgent", {}) == "MyAgent"
    assert plugin_label("mypkg.agents:MyAgent", {"b": 0.5, "a": "x/y"}, seed=2) == "MyAgent-a_x_y-b_0.5-seed2"
    assert plugin_label("http://10.1.2.3:8765", {"timeout": 5}) == "remote-10.1.2.3_8765-timeout_5"


def test_import_path_on_the_cli_and_evaluate_give_identical_records(agent_dir, pointnav_file, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert _cli("--episodes", pointnav_file, "--agent", "walkmod:WalkAgent", "--agent-opt", "stop_after=30",
                "--agent-opt", "turn=0.25") == 0
    cli_dir = tmp_path / "runs" / "pointnav" / "smoke" / "WalkAgent-stop_after_30-turn_0.25"
    cfg = json.loads((cli_dir / "config.json").read_text())
    assert cfg["agent"] == "walkmod:WalkAgent" and cfg["agent_options"] == {"stop_after": 30, "turn": 0.25}
    assert cfg["label"] == cli_dir.name

    import walkmod
    summary = navbench.evaluate(walkmod.WalkAgent, episodes=pointnav_file, options={"stop_after": 30, "turn": 0.25},
                                out=tmp_path / "api")
    assert _records(tmp_path / "api") == _records(cli_dir)
    assert summary == json.loads((cli_dir / "summary.json").read_text())
    assert json.loads((tmp_path / "api" / "config.json").read_text()) == cfg
    assert any(r["num_steps"] > 1 for r in _records(cli_dir))  # the agent moved: records compare something
    # config.json names the agent and its options, so the CLI resumes a run navbench.evaluate wrote
    assert _cli("--episodes", pointnav_file, "--agent", "walkmod:WalkAgent", "--agent-opt", "stop_after=30",
                "--agent-opt", "turn=0.25", "--out", tmp_path / "api", "--resume") == 0
    assert _records(tmp_path / "api") == _records(cli_dir)


def test_plugin_factory_pickles_as_its_spec_and_builds_from_it(agent_dir):
    import pickle

    from navbench.agents.plugins import PluginFactory

    factory = resolve_agent("walkmod:make_walker", {"stop_after": 4}).factory
    assert isinstance(factory, PluginFactory)
    clone = pickle.loads(pickle.dumps(factory))
    agent = clone(type("Cfg", (), {"task": "pointnav"})())
    assert type(agent.agent).__name__ == "WalkAgent" and agent.stop_after == 4  # inside habitat_compat's adapter


@pytest.mark.slow  # spawns two workers that import navbench and the plug-in
def test_factory_gets_the_run_config_and_spawned_workers_reimport_it(agent_dir, pointnav_file, tmp_path):
    one = navbench.evaluate("walkmod:make_walker", episodes=pointnav_file, options={"stop_after": 12},
                            out=tmp_path / "one", limit=4)
    two = navbench.evaluate("walkmod:make_walker", episodes=pointnav_file, options={"stop_after": 12},
                            out=tmp_path / "two", limit=4, workers=2)
    assert _records(tmp_path / "one") == _records(tmp_path / "two") and one == two
    assert {r["num_steps"] for r in _records(tmp_path / "one")} <= set(range(1, 13))


def test_batched_agents_are_stepped_batched(agent_dir, pointnav_file, tmp_path):
    import walkmod
    batch = walkmod.BatchWalkAgent(num_envs=3)
    navbench.evaluate(batch, episodes=pointnav_file, out=tmp_path / "batch")
    navbench.evaluate(walkmod.WalkAgent, episodes=pointnav_file, out=tmp_path / "single")
    assert batch.largest_batch == 3
    # the batched runner keeps no decision log; all else matches the one-at-a-time run
    assert [{**r, "agent": None, "log": None} for r in _records(tmp_path / "batch")] == \
        [{**r, "agent": None, "log": None} for r in _records(tmp_path / "single")]


class _StopBatch:
    """A batch agent as a newcomer writes one: no ``sensors``; STOP after two forward steps."""

    def __init__(self, num_envs=None):
        if num_envs is not None:
            self.num_envs = num_envs
        self.steps, self.widths = {}, []

    def reset_env(self, i, episode):
        self.steps[i] = 0

    def act_batch(self, observations):
        self.widths.append(sum(o is not None for o in observations))
        out = []
        for i, o in enumerate(observations):
            self.steps[i] = self.steps.get(i, 0) + (o is not None)
            out.append(navbench.Action.MOVE_FORWARD if self.steps[i] <= 2 else navbench.Action.STOP)
        return out


@pytest.mark.parametrize("num_envs", [None, 3])
def test_a_batch_agent_needs_no_sensors(pointnav_file, tmp_path, num_envs):
    agent = _StopBatch(num_envs)
    summary = navbench.evaluate(agent, episodes=pointnav_file, out=tmp_path / "run")
    recs = read_records(tmp_path / "run" / "episodes.jsonl")
    assert summary["num_failed"] == 0 and len(recs) == summary["num_episodes"] > 0
    assert all(r["num_steps"] == 3 and r["stop_called"] for r in recs)
    assert max(agent.widths) == (num_envs or 1)


@pytest.mark.parametrize("argv, needle", [
    (["--agent", "walkmod:WalkAgent", "--agent-opt", "speed=2"],
     "agent 'walkmod:WalkAgent' takes no option 'speed' (it takes: stop_after, turn, wall)"),
    (["--agent", "walkmod:Nope"], "agent 'walkmod:Nope': module 'walkmod' has no 'Nope'"),
    (["--agent", "nomod_xyz:Agent"], "agent 'nomod_xyz:Agent'"),
    (["--agent", "walkmod:WalkAgent", "--decoding", "argmax"], "--decoding: not read by agent 'walkmod:WalkAgent'"),
    (["--agent", "walkmod:WalkAgent", "--perception", "oracle"], "--perception: not read by agent"),
    (["--agent", "oracle", "--agent-opt", "fusion=false"], "agent 'oracle' takes no option 'fusion'"),
])
def test_bad_plugin_input_is_one_line_and_exit_2(agent_dir, pointnav_file, argv, needle, capsys):
    assert _cli("--episodes", pointnav_file, *argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and needle in err, err


def test_builtins_take_agent_opt_for_their_own_keys():
    assert resolve_agent("pointnav", {"decoding": "argmax"}).label == "pointnav-argmax"
    assert resolve_agent("memory", {"fusion": False}).options["fusion"] is False


def test_installed_entry_point_is_listed_and_runs_by_name(plugin_site, pointnav_file, tmp_path, capsys):
    assert main(["agents"]) == 0
    listing = capsys.readouterr().out
    assert any(line.split()[:4] == ["walker", "their-agent", "1.2", "their_agent:WalkAgent"]
               for line in listing.splitlines()), listing
    assert "oracle" in listing and "built-in" in listing
    assert _cli("--episodes", pointnav_file, "--agent", "walker", "--agent-opt", "stop_after=5", "--limit", "2",
                "--out", tmp_path / "ep") == 0
    recs = _records(tmp_path / "ep")
    assert len(recs) == 2 and all(r["agent"] == "walker" and r["num_steps"] <= 5 for r in recs)
    assert json.loads((tmp_path / "ep" / "config.json").read_text())["agent_options"] == {"stop_after": 5}
    summary = navbench.evaluate("walker-factory", episodes=pointnav_file, limit=2, out=tmp_path / "ep2")
    assert summary["num_episodes"] == 2 and summary["agent"] == "walker-factory"


def test_the_shipped_example_runs_and_records_a_rerunnable_agent(tmp_path, monkeypatch):
    import importlib.util

    from navbench.paths import SCENES_DIR
    example = SCENES_DIR.parent / "examples" / "evaluate_agent.py"
    spec = importlib.util.spec_from_file_location("examples.evaluate_agent", example)
    module = importlib.util.module_from_spec(spec)
    monkeypatch.setitem(sys.modules, "examples.evaluate_agent", module)
    spec.loader.exec_module(module)
    summary = module.main(limit=2, out=tmp_path / "run")
    assert summary["num_episodes"] == 2 and summary["complete"]
    cfg = json.loads((tmp_path / "run" / "config.json").read_text())
    assert cfg["agent"] == "examples.evaluate_agent:GoalSeeker" and cfg["agent_options"] == {"turn": 0.3}


@pytest.mark.slow  # builds a venv and pip-installs a package into it
def test_pip_installed_plugin_runs_by_name(tmp_path, pointnav_file, agent_module_source):
    """``pip install their-agent`` into a fresh venv that sees this environment's packages through a
    .pth file; then ``navbench agents`` there lists it and ``navbench run --agent walker`` runs it."""
    import subprocess
    import sysconfig

    pkg = tmp_path / "their-agent"
    (pkg / "their_agent").mkdir(parents=True)
    (pkg / "their_agent" / "__init__.py").write_text(agent_module_source)
    (pkg / "pyproject.toml").write_text(
        '[build-system]\nrequires = ["setuptools"]\nbuild-backend = "setuptools.build_meta"\n'
        '[project]\nname = "their-agent"\nversion = "1.2"\n'
        '[project.entry-points."navbench.agents"]\nwalker = "their_agent:WalkAgent"\n')
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True)
    py = venv / "bin" / "python"
    purelib = subprocess.run([py, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                             capture_output=True, text=True, check=True).stdout.strip()
    repo = Path(navbench.__file__).resolve().parents[1]
    (Path(purelib) / "host.pth").write_text(f"{repo}\n{sysconfig.get_paths()['purelib']}\n")
    subprocess.run([py, "-m", "pip", "install", "-q", "--no-deps", "--no-build-isolation", str(pkg)], check=True,
                   timeout=300)
    listing = subprocess.run([py, "-m", "navbench.cli", "agents"], capture_output=True, text=True, check=True).stdout
    assert any(line.split()[:3] == ["walker", "their-agent", "1.2"] for line in listing.splitlines()), listing
    subprocess.run([py, "-m", "navbench.cli", "run", "--episodes", str(pointnav_file), "--agent", "walker",
                    "--limit", "2", "--workers", "1", "-q", "--out", str(tmp_path / "run")], check=True, timeout=300,
                   cwd=tmp_path)
    assert len(read_records(tmp_path / "run" / "episodes.jsonl")) == 2


class _Walker:
    """Defined at module level, so workers can import it by name."""
    num_envs = 3

    def __init__(self, stop_after: int = 4, device: str = "cpu"):
        self.stop_after, self.device = stop_after, device

    def reset(self, episode=None):
        pass

    def act(self, observations):
        return 1

    def act_batch(self, observations):
        return [1] * len(observations)


def test_one_function_resolves_every_form_an_agent_takes():
    from navbench.agents.plugins import Bound, PluginFactory, ResolvedAgent

    spec = f"{_Walker.__module__}:_Walker"
    by_class = resolve_agent(_Walker, {"stop_after": 2}, device="cpu")
    assert isinstance(by_class, ResolvedAgent) and by_class.spec == spec and by_class.device == "cpu"
    assert isinstance(by_class.factory, PluginFactory) and by_class.batches and by_class.envs_per_worker == 3
    built = by_class.factory(type("Cfg", (), {"device": "cpu", "task": "pointnav"})())
    assert built.stop_after == 2 and built.device == "cpu"  # the run's device reaches a plug-in that takes one

    def make(cfg, stop_after=1):
        return _Walker(stop_after)
    local = resolve_agent(make, {}, seed=3, envs_per_worker=2)
    assert isinstance(local.factory, Bound) and local.batches is None and local.envs_per_worker == 2
    assert local.label.endswith("seed3")

    walker = _Walker()
    instance = resolve_agent(walker, device="auto")
    assert isinstance(instance.factory, Bound) and instance.device in ("cpu", "cuda:0")
    assert instance.factory(None) is instance.factory(None) is walker  # batched: handed out as it is
    with pytest.raises(ValueError, match="options apply to an agent class or factory"):
        resolve_agent(_Walker(), {"stop_after": 1})

    class Single:
        def reset(self):
            pass

        def act(self, observations):
            return 0
    with pytest.raises(ValueError, match="--envs-per-worker applies to agents that step episodes in batches"):
        resolve_agent(Single, {}, envs_per_worker=2)
    with pytest.raises(ValueError, match="expected an agent spec string, class, factory or instance"):
        resolve_agent(42)
    with pytest.raises(ValueError, match="device 'gpu'"):
        resolve_agent("oracle", device="gpu")
    builtin = resolve_agent("pointnav", {"decoding": "argmax"})
    assert builtin.builtin and builtin.envs_per_worker == 8 and builtin.label == "pointnav-argmax"


def test_the_api_holds_no_agent_resolution():
    import ast

    import navbench.api
    tree = ast.parse(Path(navbench.api.__file__).read_text())
    from_agents = {(n.module, a.name) for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)
                   and (n.module or "").startswith("navbench.agents") for a in n.names}
    assert from_agents == {("navbench.agents.plugins", "resolve_agent"), ("navbench.agents.registry", "default_agent")}
    assert not [n.name for n in ast.walk(tree) if isinstance(n, ast.ClassDef)]


def test_a_habitat_agent_is_checked_and_adapted_once_where_it_is_loaded(monkeypatch):
    """One place (habitat_compat.AgentTarget) checks a plug-in and adapts what it builds, for a spec, a class and
    an instance alike; an instance is wrapped once, not on every build."""
    from navbench.agents import habitat_compat

    calls = []
    real = habitat_compat.check_agent
    monkeypatch.setattr(habitat_compat, "check_agent", lambda spec, target: calls.append(spec) or real(spec, target))

    class Habitatish:  # habitat-lab's protocol: reset() and an action name
        def reset(self):
            pass

        def act(self, observations):
            return "move_forward"

    for agent in (f"{_Walker.__module__}:_Walker", _Walker, Habitatish()):
        calls.clear()
        resolve_agent(agent)
        assert len(calls) == 1, agent
    hab = resolve_agent(Habitatish())
    first = hab.factory(None)
    assert isinstance(first, habitat_compat.HabitatAgent) and hab.factory(None) is first
    assert first.act({}) == 1
