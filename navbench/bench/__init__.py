"""What ``navbench bench`` measures: speed of the simulator, geodesics and policy, and at scan scale.

Modules: :mod:`.speed` (``navbench bench``, on a bundled house), :mod:`.goal_tasks` (its goal-image
tasks beside PointNav), :mod:`.scan` (``navbench bench
--scan DIR``), :mod:`.scan_fixture` (the scan-like HM3D fixture it measures) and :mod:`.glb_writer`
(the fixture's GLB files). The policy's own figures come from :mod:`navbench.policy.speed`.
"""
