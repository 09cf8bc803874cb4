"""``habitat_sim._ext``: where habitat-sim keeps its compiled bindings; here, their Python counterparts."""
