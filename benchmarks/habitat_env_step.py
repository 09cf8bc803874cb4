"""``habitat.Env.step`` on navbench's habitat_sim against navbench's own PointNav env, at the same sensors.

Run in the habitat virtualenv (``pip install -e ".[habitat]" -e compat/habitat-sim``), from the checkout root::

    PYOPENGL_PLATFORM=osmesa python benchmarks/habitat_env_step.py                # 5 repeats x 300 steps, chunks of 50
    PYOPENGL_PLATFORM=osmesa python benchmarks/habitat_env_step.py --profile 300  # cProfile of habitat.Env.step (CPU)
    PYOPENGL_PLATFORM=osmesa python benchmarks/habitat_env_step.py --layers       # whose code the extra time is

habitat-lab's ``benchmark/nav/pointnav/pointnav_habitat_test.yaml``, pointed at the bundled split
(``episodes/pointnav/val/val.json.gz``, ``scenes_dir=envs``), with navbench's default env's sensors and body
(:class:`navbench.env.config.EnvConfig`: RGB and depth 224x224, hfov 79, camera 0.88 m up, depth 0.5-5 m
normalised, radius 0.18 m, 0.25 m forward, 30 degree turns, no sliding), against
``navbench.env.pointnav.PointNavEnv`` with that config. Both run the same episodes (in the split's order) and the
same seeded random moves (never STOP) in chunks of ``--episode-steps`` (one episode each), the two envs one after
the other in one process; resets are not timed. Each repeat gives ms per step (wall) and CPU ms per step
(``time.process_time``: this process, the renderer's threads included, so less sensitive to other load on a
shared machine); printed are their medians and min-max over the repeats, the ratio habitat.Env / navbench of the
medians, and the ratio paired chunk by chunk (the two runs of a chunk are a fraction of a second apart, so load
that comes and goes moves it least), and how far apart the two agents end each chunk.
"""

from __future__ import annotations

import argparse
import cProfile
import json
import os
import pstats
import statistics
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SPLIT = os.path.join(ROOT, "episodes", "pointnav", "val", "val.json.gz")
SCENES = os.path.join(ROOT, "envs")


def lab_config(cfg):
    """habitat-lab's PointNav test config with ``cfg``'s (an EnvConfig) sensors and body, on the bundled split."""
    from habitat.config.default import get_config

    agent = "habitat.simulator.agents.main_agent"
    sensors = [f"{agent}.sim_sensors.{s}.{k}={v}" for s in ("rgb_sensor", "depth_sensor") for k, v in
               (("width", cfg.width), ("height", cfg.height), ("hfov", f"{cfg.hfov_deg:g}"),
                ("position", f"[0.0,{cfg.agent_height},0.0]"))]
    depth = [f"{agent}.sim_sensors.depth_sensor.{k}={v}" for k, v in
             (("min_depth", cfg.min_depth), ("max_depth", cfg.max_depth), ("normalize_depth", cfg.normalize_depth))]
    return get_config("benchmark/nav/pointnav/pointnav_habitat_test.yaml", overrides=[
        f"habitat.dataset.data_path={SPLIT}", f"habitat.dataset.scenes_dir={SCENES}", "habitat.dataset.split=val",
        "habitat.environment.iterator_options.shuffle=False", f"habitat.environment.max_episode_steps={cfg.max_steps}",
        f"habitat.simulator.forward_step_size={cfg.forward_step}",
        f"habitat.simulator.turn_angle={cfg.turn_angle_deg:g}",
        f"habitat.simulator.habitat_sim_v0.allow_sliding={cfg.allow_sliding}", f"{agent}.height={cfg.agent_height}",
        f"{agent}.radius={cfg.agent_radius}", f"{agent}.max_climb={cfg.max_climb}",
        *sensors, *depth])


class Pair:
    """habitat.Env and navbench's PointNavEnv, reset to the same episode together."""

    def __init__(self) -> None:
        import habitat

        from navbench.env.config import EnvConfig
        from navbench.env.pointnav import PointNavEnv

        cfg = EnvConfig()
        self.lab = habitat.Env(config=lab_config(cfg))
        self.nb = PointNavEnv(SPLIT, SCENES, cfg)
        self.episode = ""

    def reset(self) -> None:
        self.lab.reset()
        self.episode = self.lab.current_episode.episode_id
        self.nb.reset(options={"episode": self.episode})

    def close(self) -> None:
        self.lab.close()
        self.nb.close()


def timed(step, actions: list[int]) -> tuple[float, float]:
    """(wall, CPU) seconds per step of ``step`` over ``actions``."""
    w, c = time.perf_counter(), time.process_time()
    for a in actions:
        step(a)
    return (time.perf_counter() - w) / len(actions), (time.process_time() - c) / len(actions)


def measure(pair: Pair, repeats: int, steps: int, episode_steps: int, seed: int) -> dict:
    rng = np.random.default_rng(seed)
    envs = {"habitat.Env": pair.lab.step, "navbench": pair.nb.step}
    out: dict = {name: {"ms_per_step": [], "cpu_ms_per_step": []} for name in envs}
    out["max_position_gap_m"] = 0.0  # where the two agents end each chunk: the same moves give the same poses
    out["paired_wall_ratio"], out["paired_cpu_ratio"] = [], []
    for r in range(repeats):
        order = list(envs) if r % 2 == 0 else list(envs)[::-1]  # alternate who goes first
        totals = {name: [0.0, 0.0] for name in envs}
        # one episode per chunk: both envs reset to it (untimed), then step the same moves
        for start in range(0, steps, episode_steps):
            pair.reset()
            actions = [int(a) for a in rng.integers(1, 4, size=min(episode_steps, steps - start))]
            chunk = {}
            for name in order:
                chunk[name] = wall, cpu = timed(envs[name], actions)
                totals[name][0] += wall * len(actions)
                totals[name][1] += cpu * len(actions)
            # the two envs' runs of one chunk are seconds apart: their ratio moves less with the machine's load
            out["paired_wall_ratio"].append(chunk["habitat.Env"][0] / chunk["navbench"][0])
            out["paired_cpu_ratio"].append(chunk["habitat.Env"][1] / chunk["navbench"][1])
            gap = np.asarray(pair.lab.sim.get_agent_state().position, np.float64) - pair.nb._position
            out["max_position_gap_m"] = max(out["max_position_gap_m"], float(np.hypot(gap[0], gap[2])))
        for name, (wall, cpu) in totals.items():
            out[name]["ms_per_step"].append(1e3 * wall / steps)
            out[name]["cpu_ms_per_step"].append(1e3 * cpu / steps)
    return out


def layers(pair: Pair, chunks: int, episode_steps: int, seed: int) -> None:
    """CPU per step of each layer a habitat-lab step passes through, outermost first, against navbench's env:
    habitat-lab's ``habitat.Env.step`` (its task: measures and task sensors), its ``HabitatSim.step`` (its sensor
    suite over the simulator's observations), navbench's ``habitat_sim.Simulator.step`` (the simulator API), and
    navbench's ``PointNavEnv.step``. Each chunk replays the same moves through every layer from the same reset."""
    import navbench.habitat_sim as hs

    sim = pair.lab.sim
    fns = {"habitat.Env.step": pair.lab.step, "habitat-lab HabitatSim.step": sim.step,
           "navbench Simulator.step": lambda a: hs.Simulator.step(sim, a), "navbench env": pair.nb.step}
    rng = np.random.default_rng(seed)
    cpu: dict[str, list[float]] = {k: [] for k in fns}
    for _ in range(chunks):
        actions = [int(a) for a in rng.integers(1, 4, size=episode_steps)]
        for name, step in fns.items():
            pair.reset()
            cpu[name].append(timed(step, actions)[1])
    base = statistics.median(cpu["navbench env"])
    print(f"CPU per step by layer, median of {chunks} chunks of {episode_steps} moves, load average "
          f"{os.getloadavg()[0]:.1f} at the end")
    for name, v in cpu.items():
        print(f"  {name:28s} {1e3 * statistics.median(v):6.3f} ms  ({statistics.median(v) / base:.2f}x navbench env)")


def envs_of(res: dict) -> list[str]:
    return [k for k, v in res.items() if isinstance(v, dict)]


def profile(pair: Pair, steps: int, episode_steps: int, seed: int, top: int) -> None:
    rng = np.random.default_rng(seed)
    prof = cProfile.Profile(time.thread_time)  # this thread's CPU: waits for a shared machine's cores not counted
    for start in range(0, steps, episode_steps):
        pair.reset()
        actions = [int(a) for a in rng.integers(1, 4, size=min(episode_steps, steps - start))]
        prof.enable()
        for a in actions:
            pair.lab.step(a)
        prof.disable()
    pstats.Stats(prof).sort_stats("cumulative").print_stats(top)
    pstats.Stats(prof).sort_stats("tottime").print_stats(top)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--repeats", type=int, default=5)
    p.add_argument("--steps", type=int, default=300, help="timed steps per env and repeat")
    p.add_argument("--episode-steps", type=int, default=50, help="steps before both envs move to the next episode")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--profile", type=int, default=0, metavar="STEPS",
                   help="instead: cProfile habitat.Env.step over STEPS steps")
    p.add_argument("--layers", action="store_true",
                   help="instead: CPU per step of habitat-lab's and navbench's layers of a step")
    p.add_argument("--top", type=int, default=35, help="functions listed by --profile")
    p.add_argument("--json", action="store_true", help="also print the per-repeat figures as JSON")
    args = p.parse_args(argv)
    if args.repeats < 1 or args.steps < 1 or args.episode_steps < 1:
        p.error("--repeats, --steps and --episode-steps must be positive")
    if args.episode_steps >= 500:
        p.error("--episode-steps must be under 500, the episodes' step limit")

    import habitat_sim

    pair = Pair()
    try:
        pair.reset()
        for a in [1, 2, 3] * 7:  # warm-up: shaders, first frames
            pair.lab.step(a)
            pair.nb.step(a)
        if args.profile:
            profile(pair, args.profile, args.episode_steps, args.seed, args.top)
            return 0
        if args.layers:
            layers(pair, 8 * args.repeats, args.episode_steps, args.seed)
            return 0
        res = measure(pair, args.repeats, args.steps, args.episode_steps, args.seed)
    finally:
        pair.close()

    def med(name: str, key: str) -> float:
        return statistics.median(res[name][key])

    load = os.getloadavg()[0]
    print(f"habitat.Env.step (habitat_sim {habitat_sim.__version__}) vs navbench PointNavEnv.step, RGB-D 224x224, "
          f"{args.repeats} repeats x {args.steps} steps, {os.cpu_count()} CPUs, load average {load:.1f} at the end")
    for name in envs_of(res):
        w, c = res[name]["ms_per_step"], res[name]["cpu_ms_per_step"]
        print(f"  {name:12s} {med(name, 'ms_per_step'):6.2f} ms/step (min-max {min(w):.2f}-{max(w):.2f}), "
              f"CPU {med(name, 'cpu_ms_per_step'):6.2f} ms/step (min-max {min(c):.2f}-{max(c):.2f})")
    ratio_w = med("habitat.Env", "ms_per_step") / med("navbench", "ms_per_step")
    ratio_c = med("habitat.Env", "cpu_ms_per_step") / med("navbench", "cpu_ms_per_step")
    pw, pc = (np.percentile(res[k], [25, 50, 75]) for k in ("paired_wall_ratio", "paired_cpu_ratio"))
    print(f"  ratio habitat.Env / navbench (goal <= 1.25x): of the medians wall {ratio_w:.2f}x, CPU {ratio_c:.2f}x; "
          f"paired by episode chunk (median [quartiles] of {len(res['paired_cpu_ratio'])}) wall {pw[1]:.2f}x "
          f"[{pw[0]:.2f}, {pw[2]:.2f}], CPU {pc[1]:.2f}x [{pc[0]:.2f}, {pc[2]:.2f}]")
    print(f"  the agents' positions after each chunk's moves differ by at most {res['max_position_gap_m']:.1e} m")
    if args.json:
        print(json.dumps(res))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
