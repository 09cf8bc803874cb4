"""``habitat_sim.metadata``: named for habitat-lab's rearrangement datasets; not supported."""

from navbench.habitat_sim._out_of_scope import placeholder

MetadataMediator = placeholder("habitat_sim.metadata.MetadataMediator", "no scene dataset metadata")
