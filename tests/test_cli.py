"""The CLI's ablation flags reach the agent's config and name the run."""

from types import SimpleNamespace

from navbench.agents.memory_agent import MemoryAgentConfig
from navbench.cli import _agent_options, _label, build_parser


def _options(*flags):
    args = build_parser().parse_args(["run", "--agent", "memory", *flags])
    opts = _agent_options(args)
    return args, opts, _label(args, SimpleNamespace(agent_options=opts))


def test_memory_ablation_flags_are_recorded_and_labelled():
    _, opts, label = _options()
    assert opts["standoff"] and opts["recovery"] and opts["verify"] and opts["route"] and label == "memory"
    _, opts, label = _options("--no-standoff", "--no-recovery", "--rerank", "none", "--no-detour", "--no-route",
                              "--no-probe")
    assert not opts["standoff"] and not opts["recovery"] and not opts["rerank"] and not opts["detour"]
    assert not opts["route"] and not opts["probe"]
    assert label == "memory-norerank-norecover-nostandoff-nodetour-noroute-noprobe"
    assert MemoryAgentConfig().goal_standoff > 0  # on by default; the flag turns it off
    assert MemoryAgentConfig().view_detour
