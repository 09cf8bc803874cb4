"""``habitat_sim.gfx``: named for habitat-lab's debug drawing; not supported."""

from navbench.habitat_sim._out_of_scope import placeholder

DebugLineRender = placeholder("habitat_sim.gfx.DebugLineRender", "no debug line rendering")
LightInfo = placeholder("habitat_sim.gfx.LightInfo", "no scene lights")
