"""The public API: what ``import navbench`` exports, ``evaluate``'s real signature, and its one-line
errors for settings that cannot apply."""

import inspect
import subprocess
import sys

import pytest

import navbench


def test_evaluate_shows_its_parameters():
    params = inspect.signature(navbench.evaluate).parameters
    assert list(params)[:4] == ["agent", "task", "split", "episodes"]
    for name in ("options", "limit", "shard", "seed", "out", "resume", "workers", "envs_per_worker", "backend",
                 "address", "retries", "step_timeout", "fail_fast", "progress", "video"):
        assert params[name].kind is inspect.Parameter.KEYWORD_ONLY, name
    assert "Args:" in navbench.evaluate.__doc__ and "Returns:" in navbench.evaluate.__doc__


def test_all_names_resolve_and_import_navbench_stays_light():
    for name in navbench.__all__:
        assert getattr(navbench, name) is not None, name
    assert navbench.Action.TURN_RIGHT == 3 and navbench.EpisodeRecord.__required_keys__ >= {"episode_id"}
    code = ("import sys, navbench; print(' '.join(sorted(m for m in sys.modules if m.startswith(('navbench.', "
            "'torch', 'trimesh', 'pyrender', 'cv2', 'pandas')))))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    # the task registry (for the Gymnasium ids) and the plain data its definitions name, nothing heavier
    # (navbench.metrics: the names of the measures, a leaf of plain functions)
    light = {"navbench._version", "navbench.episodes", "navbench.episodes.types", "navbench.scene",
             "navbench.scene.pose", "navbench.metrics"}
    assert "navbench.tasks" in out and not {m for m in out if not m.startswith("navbench.tasks")} - light, out


@pytest.mark.parametrize("kwargs,match", [
    ({"backend": "ray", "address": "auto", "workers": 2}, "--workers does not apply with --address"),
    ({"address": "auto"}, "--address applies to --backend ray only"),
    ({"resume": True, "overwrite": True}, "choose one"),
    ({"video": "some"}, "--video"),
    ({"agent": "oracle", "envs_per_worker": 4}, "--envs-per-worker"),
    ({"agent": "pointnav", "options": {"fusion": False}}, "takes no option 'fusion'"),
])
def test_settings_that_cannot_apply_are_one_line_errors(kwargs, match, tmp_path):
    kwargs = {"agent": "oracle", "task": "pointnav", "limit": 1, "out": tmp_path / "run", **kwargs}
    with pytest.raises(ValueError, match=match) as exc:
        navbench.evaluate(**kwargs)
    assert "\n" not in str(exc.value) and not (tmp_path / "run").exists()


@pytest.mark.parametrize("module", ["navbench", "navbench.api", "navbench.agents.base", "navbench.agents.options",
                                    "navbench.agents.registry", "navbench.env.config", "navbench.eval.config",
                                    "navbench.eval.worker"])
def test_docstring_examples_hold(module):
    import doctest
    import importlib
    result = doctest.testmod(importlib.import_module(module))
    assert result.attempted > 0 and result.failed == 0
