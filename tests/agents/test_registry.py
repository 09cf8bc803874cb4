"""The registry's factories build each agent with the decoding its recorded options say."""

import pytest

from navbench.agents.registry import AGENTS, DEFAULT_DECODING, agent_options
from navbench.eval.runner import RunConfig
from navbench.paths import POLICIES_DIR, SCENES_DIR


def _cfg(agent, options):
    return RunConfig(task="objectnav" if agent != "pointnav" else "pointnav", split=None, agent=agent,
                     episodes="unused.json", scene_dir=str(SCENES_DIR), success_distance=0.25, agent_options=options)


@pytest.mark.skipif(not (POLICIES_DIR / "pointnav_navbench.pth").is_file(), reason="no shipped PointNav checkpoint")
@pytest.mark.parametrize("agent", ["pointnav", "memory", "frontier"])
def test_policy_agents_decode_as_their_options_record(agent):
    built = AGENTS[agent](_cfg(agent, agent_options(agent)))  # .policy: the PointNavAgentPolicy it drives with
    assert built.policy.config.decoding == DEFAULT_DECODING[agent]
    built = AGENTS[agent](_cfg(agent, agent_options(agent, decoding="sample", temperature=0.5)))
    assert (built.policy.config.decoding, built.policy.config.temperature) == ("sample", 0.5)


def test_only_the_frontier_agent_explores():
    """`navbench viz` shades the seen cells by default for these (the spec says so, viz names no agent)."""
    assert [n for n, s in AGENTS.items() if s.explores] == ["frontier"]
