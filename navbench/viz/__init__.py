"""Pictures of runs: top-down maps, episode videos, replay of finished runs, the HTML run report.

Reads scenes, episodes, envs and run records; nothing below the CLI imports it (the CLI does, lazily).
"""
