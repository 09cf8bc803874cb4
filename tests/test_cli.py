"""The CLI's ablation flags reach the agent's config and name the run."""

from types import SimpleNamespace

import pytest

from navbench.agents.memory_agent import MemoryAgentConfig
from navbench.cli import _agent_options, _label, build_parser


def _options(*flags):
    args = build_parser().parse_args(["run", "--agent", "memory", *flags])
    opts = _agent_options(args)
    return args, opts, _label(args, SimpleNamespace(agent_options=opts))


def test_memory_ablation_flags_are_recorded_and_labelled():
    _, opts, label = _options()
    assert opts["standoff"] and opts["recovery"] and opts["verify"] and opts["route"] and opts["guidance"]
    assert label == "memory"
    _, opts, label = _options("--no-standoff", "--no-recovery", "--rerank", "none", "--no-detour", "--no-route",
                              "--no-probe", "--no-guidance")
    assert not opts["standoff"] and not opts["recovery"] and not opts["rerank"] and not opts["detour"]
    assert not opts["route"] and not opts["probe"] and not opts["guidance"]
    assert label == "memory-norerank-norecover-nostandoff-nodetour-noroute-noprobe-noguidance"
    assert MemoryAgentConfig().goal_standoff > 0  # on by default; the flag turns it off
    assert MemoryAgentConfig().view_detour


def test_sample_actions_is_recorded_only_when_on_and_names_the_run():
    args = build_parser().parse_args(["run", "--task", "pointnav", "--agent", "pointnav", "--sample-actions"])
    opts = _agent_options(args)
    assert opts["sample_actions"] and _label(args, SimpleNamespace(agent_options=opts)) == "pointnav-sampled"
    args = build_parser().parse_args(["run", "--task", "pointnav", "--agent", "pointnav"])
    opts = _agent_options(args)  # argmax runs keep the config.json they had before the flag existed
    assert "sample_actions" not in opts and _label(args, SimpleNamespace(agent_options=opts)) == "pointnav"
    args = build_parser().parse_args(["run", "--agent", "oracle", "--sample-actions"])
    with pytest.raises(ValueError, match="PointNav policy"):  # the oracle has no policy to draw from: say so
        _agent_options(args)
    _, opts, label = _options("--sample-actions", "--sample-on-revisit", "--least-tried")  # memory drives with it
    assert opts["least_tried"] and label == "memory-sampled-revisit-leasttried"
    args = build_parser().parse_args(["run", "--task", "pointnav", "--agent", "pointnav", "--sample-actions",
                                      "--temperature", "0.5"])
    opts = _agent_options(args)
    assert opts["temperature"] == 0.5 and _label(args, SimpleNamespace(agent_options=opts)) == "pointnav-sampled_t0.5"
    for bad in (["--temperature", "0.5"], ["--sample-actions", "--temperature", "0"]):  # no draws to shape; T > 0
        args = build_parser().parse_args(["run", "--task", "pointnav", "--agent", "pointnav", *bad])
        with pytest.raises(ValueError, match="temperature"):
            _agent_options(args)
    args = build_parser().parse_args(["run", "--task", "pointnav", "--agent", "pointnav", "--sample-actions",
                                      "--temperature", "0.5", "--sample-on-revisit"])
    opts = _agent_options(args)
    assert opts["sample_on_revisit"]
    assert _label(args, SimpleNamespace(agent_options=opts)) == "pointnav-sampled_t0.5-revisit"
    args = build_parser().parse_args(["run", "--task", "pointnav", "--agent", "pointnav", "--sample-on-revisit"])
    with pytest.raises(ValueError, match="sample-on-revisit"):
        _agent_options(args)
    args = build_parser().parse_args(["run", "--task", "pointnav", "--agent", "pointnav", "--sample-actions",
                                      "--sample-on-revisit", "--least-tried"])
    opts = _agent_options(args)
    assert opts["least_tried"] and _label(args, SimpleNamespace(agent_options=opts)) == \
        "pointnav-sampled-revisit-leasttried"
    args = build_parser().parse_args(["run", "--task", "pointnav", "--agent", "pointnav", "--sample-actions",
                                      "--least-tried"])
    with pytest.raises(ValueError, match="least-tried"):  # it shapes the revisit draws: without them, say so
        _agent_options(args)
